"""3-D box scenes through the simulator: events with per-event truth, depth/flow maps, IMU, keyframed cameras."""

import numpy as np
import pytest

from evedge.sim import parse_scene, simulate


def _scene():
    return parse_scene({
        "scene": {"kind": "mesh", "duration_s": 0.03, "seed": 2, "background": 0.7, "frame_rate_hz": 100},
        "sensor": {"width": 48, "height": 36, "fx": 40.0},
        "camera": {"velocity_m_s": [0.5, 0.0, 0.0]},
        "boxes": [{"center_m": [0.0, 0.0, 2.0], "size_m": [0.6, 0.6, 0.6], "face_intensities": 0.15}],
    }, "mesh.toml")


@pytest.fixture(scope="module")
def rec():
    # box scenes render exactly (no OpenGL), so no failure here may be skipped as "no GL stack"
    scene = _scene()
    assert scene.setup_3d["render"]["method"] == "exact"
    return simulate(scene, progress=False)


def test_mesh_scene_events_and_truth(rec):
    ev, tr = rec.events, rec.truth
    assert ev.shape[0] > 50
    sig = tr["is_signal"]
    assert sig.all()
    # camera moves +x: the scene moves -x at fx v / Z = 40 * 0.5 / 1.7 px/s (front face at Z = 1.7 m)
    np.testing.assert_allclose(np.median(tr["vx_px_s"]), -20.0 / 1.7, rtol=0.05)
    np.testing.assert_allclose(np.hypot(tr["nx"], tr["ny"]), 1.0)
    # the box's vertical sides make the events: gradient mostly along x, lifetime ~ 1.7e6 / 20 us
    assert np.median(np.abs(tr["nx"])) > 0.9
    assert np.median(tr["lifetime_us"]) == pytest.approx(1.7e6 / 20.0, rel=0.1)
    assert rec.metadata["scene_kind"] == "mesh" and "numba" in rec.metadata["versions"]
    assert rec.edges.images.any()


def test_mesh_scene_exports_depth_flow_and_imu(rec, tmp_path):
    assert set(rec.maps) == {"depth_m", "flow_x_px_s", "flow_y_px_s"}
    depth = rec.maps["depth_m"]
    assert depth.images.dtype == np.float32 and depth.t_us.tolist() == rec.frames.t_us.tolist()
    # the box's front face at z = 1.7 m is seen at the image centre; the corners see the background
    assert depth.images[0, 18, 24] == pytest.approx(1.7, rel=1e-6) and np.isinf(depth.images[0, 0, 0])
    np.testing.assert_allclose(rec.maps["flow_x_px_s"].images[0, 18, 24], -40 * 0.5 / 1.7, rtol=1e-5)
    imu = rec.imu
    assert imu["t_us"][0] == 0 and imu["t_us"][-1] == 30000 and imu.size == 31  # 1 kHz default
    np.testing.assert_allclose(imu["ay_m_s2"], -9.80665)  # at constant velocity only gravity is felt
    np.testing.assert_allclose(imu["wx_rad_s"], 0.0)
    from evedge.io.hdf5 import read_hdf5, write_recording

    path = write_recording(tmp_path / "mesh.h5", rec)
    back = read_hdf5(path)
    assert back.imu.tobytes() == imu.tobytes()
    for name, stack in rec.maps.items():
        assert back.maps[name].images.tobytes() == stack.images.tobytes()


def _keyframed(**camera):
    data = {
        "scene": {"kind": "mesh", "duration_s": 0.04, "seed": 2, "background": 0.7, "frame_rate_hz": 50},
        "sensor": {"width": 48, "height": 36, "fx": 40.0},
        "camera": camera,
        "boxes": [{"center_m": [0.0, 0.0, 2.0], "size_m": [0.6, 0.6, 0.6], "face_intensities": [0.2, 0.9, 0.4, 0.5, 0.3, 0.6]}],
        "imu": {"rate_hz": 500},
    }
    return parse_scene(data, "keyframes.toml")


def test_keyframed_camera_scene_gives_exact_flow_truth():
    # an arc with a yaw towards the box: the flow truth at each event is the motion field there, then
    scene = _keyframed(keyframes=[
        {"t_s": 0.0, "position_m": [-0.1, 0.0, 0.0], "rotation_rpy_deg": [0, 0, 2]},
        {"t_s": 0.02, "position_m": [0.0, 0.02, 0.05], "rotation_rpy_deg": [0, 1, 0]},
        {"t_s": 0.04, "position_m": [0.1, 0.0, 0.08], "rotation_rpy_deg": [0, 0, -2]},
    ])
    rec = simulate(scene, progress=False)
    assert rec.events.size > 100 and rec.imu.size == 21
    r = scene.build_renderer()
    try:
        ev, tr = rec.events, rec.truth
        # the events' times are rounded to us: the flow there equals the truth to the flow's change in 0.5 us
        vx, vy = r.flow_at(ev["x"], ev["y"], ev["t"] * 1e-6)
        close = np.hypot(vx - tr["vx_px_s"], vy - tr["vy_px_s"]) <= 1e-2 * np.hypot(vx, vy) + 1e-6
        assert close.mean() > 0.97  # the rest: events beside an occlusion boundary that crossed it within 0.5 us
        np.testing.assert_allclose(rec.imu["wy_rad_s"][[0, -1]] < 0, True)  # yawing from +2 to -2 deg
    finally:
        r.close()


@pytest.mark.parametrize("camera, message", [
    (dict(keyframes=[{"t_s": 0.0, "position_m": [0, 0, 0]}]), "at least 2 keyframes"),
    (dict(keyframes=[{"t_s": 0.0, "position_m": [0, 0, 0]}, {"t_s": 0.0, "position_m": [1, 0, 0]}]),
     r"camera.keyframes\[1\].t_s.*increase strictly"),
    (dict(keyframes=[{"t_s": 0.0, "position_m": [0, 0, 0]}, {"t_s": 0.01, "position_m": [1, 0, 0]}]),
     "must cover the scene"),
    (dict(velocity_m_s=[1, 0, 0], keyframes=[{"t_s": 0.0, "position_m": [0, 0, 0]},
                                             {"t_s": 1.0, "position_m": [1, 0, 0]}]), "not both"),
    (dict(keyframes=[{"t_s": 0.0, "position_m": [0, 0]}, {"t_s": 1.0, "position_m": [1, 0, 0]}]),
     r"keyframes\[0\].position_m"),
])
def test_keyframe_scene_errors_name_the_key(camera, message):
    from evedge.sim import SceneError

    with pytest.raises(SceneError, match=message):
        _keyframed(**camera)


def test_per_event_truth_on_a_box_is_the_closed_form(rec):
    # camera translating at 0.5 m/s along x, no rotation: a pixel sees the box's front face
    # (z = 1.7 m, |x|, |y| <= 0.3 m; the side faces stay hidden while the camera's x < 0.3 m)
    # or the background (at infinity): flow -f V / Z = -40 * 0.5 / 1.7 px/s or 0, vy = 0
    ev, tr = rec.events, rec.truth
    t = ev["t"] * 1e-6
    fx, cx, cy = 40.0, 23.5, 17.5
    X = (ev["x"] - cx) / fx * 1.7 + 0.5 * t
    Y = (ev["y"] - cy) / fx * 1.7
    on_face = (np.abs(X) <= 0.3) & (np.abs(Y) <= 0.3)
    want = np.where(on_face, -fx * 0.5 / 1.7, 0.0)
    ok = np.isclose(tr["vx_px_s"], want, rtol=1e-9, atol=1e-9) & (np.abs(tr["vy_px_s"]) <= 1e-9)
    # an event's exact time is within 0.5 us of its stamp: only a pixel centre the outline crosses
    # within that time (< 1e-5 px) may see the other side
    near = np.minimum(np.abs(np.abs(X) - 0.3), np.abs(np.abs(Y) - 0.3)) < 1e-5
    assert on_face.sum() > 20 and (~on_face).sum() > 5
    assert np.all(ok | near)
