"""Ground truth: lifetimes of moving stripes, the SAE slope, shapes' normals and flow."""

import math

import numpy as np
import pytest

from evedge.sim import parse_scene, simulate
from evedge.sim.motion import PlanarMotion
from evedge.sim.planar import Polygon, ShapesRenderer


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, -50.0])
def test_stripe_lifetime_is_one_over_normal_speed(stripes_dict, angle_deg):
    v = 120.0
    d = stripes_dict(width=20, height=12, duration_s=0.12, velocity_px_s=[v, 0.0], angle_deg=angle_deg)
    rec = simulate(parse_scene(d, "s.toml"), progress=False, frame_rate_hz=0)
    truth = rec.truth[rec.truth["is_signal"]]
    assert truth.shape[0] > 200
    want = 1e6 / (v * math.cos(math.radians(angle_deg)))
    np.testing.assert_allclose(truth["lifetime_us"], want, rtol=1e-12)
    np.testing.assert_allclose(truth["vx_px_s"], v)
    np.testing.assert_allclose(np.hypot(truth["nx"], truth["ny"]), 1.0)
    # the gradient direction is the stripe normal, up to its sign
    a = math.radians(angle_deg)
    np.testing.assert_allclose(np.abs(truth["nx"] * math.cos(a) + truth["ny"] * math.sin(a)), 1.0)


def test_stripe_polarity_matches_gradient_direction(stripes_dict):
    # motion along +x: the brightness at a pixel rises (ON) when the brighter side (+n) comes from behind,
    # i.e. when n points against the motion
    d = stripes_dict(width=20, height=4, duration_s=0.1, velocity_px_s=[100.0, 0.0])
    rec = simulate(parse_scene(d, "s.toml"), progress=False, frame_rate_hz=0)
    on = rec.events["p"]
    np.testing.assert_array_equal(rec.truth["nx"][on] < 0, True)
    np.testing.assert_array_equal(rec.truth["nx"][~on] > 0, True)


@pytest.mark.parametrize("angle_deg", [0.0, 30.0])
def test_sae_slope_matches_truth_lifetime(stripes_dict, angle_deg):
    """One edge sweeps the sensor; the plane fitted to the last timestamp per pixel has slope 1/(v cos a)."""
    v = 200.0
    a = math.radians(angle_deg)
    w = h = 20
    span = w * math.cos(a) + h * abs(math.sin(a))
    dur = (span + 4.0) / (v * math.cos(a))
    # period 1000 px, the light->dark boundary u = 0 starts 2 px before the sensor's first corner
    d = stripes_dict(width=w, height=h, duration_s=dur, velocity_px_s=[v, 0.0], angle_deg=angle_deg,
                     period_px=1000.0, duty=0.5, phase_px=-2.0 - 500.0)
    rec = simulate(parse_scene(d, "edge.toml"), progress=False, frame_rate_hz=0)
    ev = rec.events
    assert ev.shape[0] > w * h
    sae = np.full((h, w), -1, np.int64)
    sae[ev["y"], ev["x"]] = ev["t"]  # events are time-sorted: the last write is the latest
    assert np.all(sae >= 0)
    yy, xx = np.mgrid[0:h, 0:w]
    coef, *_ = np.linalg.lstsq(np.column_stack([xx.ravel(), yy.ravel(), np.ones(xx.size)]),
                               sae.ravel().astype(float), rcond=None)
    slope_us_per_px = math.hypot(coef[0], coef[1])
    want = 1e6 / (v * math.cos(a))
    assert slope_us_per_px == pytest.approx(want, rel=0.01)
    np.testing.assert_allclose(rec.truth["lifetime_us"][rec.truth["is_signal"]], want, rtol=1e-12)
    # and the plane's direction is the edge normal
    assert math.atan2(coef[1], coef[0]) == pytest.approx(a, abs=0.02)


def test_shapes_truth_normals_and_flow_in_translation():
    sq = np.array([[10.0, 8.0], [22.0, 8.0], [22.0, 20.0], [10.0, 20.0]])
    m = PlanarMotion(velocity_px_s=(80.0, 0.0))
    r = ShapesRenderer(40, 28, [Polygon(sq, 0.1)], m, background=0.9)
    # pixel on the left edge and the right edge at t = 0.05 s (square moved by 4 px)
    vx, vy, nx, ny = r.point_truth(np.array([14.0, 26.0, 20.0]), np.array([14.0, 14.0, 8.0]), np.full(3, 0.05))
    np.testing.assert_allclose(vx, 80.0)
    np.testing.assert_allclose(vy, 0.0)
    # dark shape: the gradient points outward (left edge: -x, right edge: +x, top edge: -y)
    np.testing.assert_allclose(np.stack([nx, ny], 1), [[-1, 0], [1, 0], [0, -1]], atol=1e-12)


def test_shapes_simulation_truth_consistent_with_rotation():
    d = {
        "scene": {"kind": "shapes", "duration_s": 0.05, "seed": 1, "background": 0.8},
        "sensor": {"width": 40, "height": 30},
        "motion": {"angular_velocity_deg_s": 90.0},
        "shapes": [{"kind": "hexagon", "center_px": [26.0, 15.0], "radius_px": 8.0, "intensity": 0.2},
                   {"kind": "circle", "center_px": [10.0, 14.0], "radius_px": 5.0, "intensity": 0.3}],
    }
    rec = simulate(parse_scene(d, "rot.toml"), progress=False, frame_rate_hz=0)
    ev, tr = rec.events, rec.truth
    assert ev.shape[0] > 100 and tr["is_signal"].all()
    w = math.radians(90.0)
    cx, cy = 19.5, 14.5
    np.testing.assert_allclose(tr["vx_px_s"], -w * (ev["y"] - cy), atol=1e-9)
    np.testing.assert_allclose(tr["vy_px_s"], w * (ev["x"] - cx), atol=1e-9)
    dot = np.abs(tr["vx_px_s"] * tr["nx"] + tr["vy_px_s"] * tr["ny"])
    np.testing.assert_allclose(tr["lifetime_us"], 1e6 / dot)
    # events of the circle: their normal is radial from the circle's centre (which moves < 1 px here)
    near_circle = np.hypot(ev["x"] - 10.0, ev["y"] - 14.0) < 7
    radial = np.stack([ev["x"][near_circle] - 10.0, ev["y"][near_circle] - 14.0], 1).astype(float)
    cosang = np.sum(radial * np.stack([tr["nx"][near_circle], tr["ny"][near_circle]], 1), 1) / np.hypot(*radial.T)
    assert np.all(np.abs(cosang) > 0.8)


def test_motion_scalar_and_array_state_agree():
    m = PlanarMotion(center_px=(3.0, 4.0), velocity_px_s=(5.0, -2.0), acceleration_px_s2=(1.0, 0.5),
                     amplitude_px=(7.0, 2.0), angle_rad=0.1, angular_velocity_rad_s=0.3,
                     angular_acceleration_rad_s2=-0.2, angle_amplitude_rad=0.25, frequency_hz=0.7, chirp_hz_s=0.4)
    ts = np.array([0.0, 0.37, 1.9])
    arr = m.state(ts)
    for k, t in enumerate(ts):
        np.testing.assert_allclose(m.state(float(t)), [a[k] for a in arr], rtol=1e-14, atol=1e-14)
    # the speed bound holds on a dense grid over the sensor
    yy, xx = np.mgrid[0:20, 0:30].astype(float)
    for t in np.linspace(0.0, 2.0, 41):
        vx, vy = m.flow_at(xx, yy, t)
        assert np.hypot(vx, vy).max() <= m.max_speed_px_s(t, t, 30, 20) + 1e-9


def test_log_gradient_direction_at_is_the_full_frame_computation():
    from evedge.sim.truth import gradient_direction, log_gradient_direction_at

    rng = np.random.default_rng(1)
    img = rng.uniform(0, 1, (9, 13))
    img[4, :] = 0.5  # flat rows and columns: zero gradients (NaN directions) too
    img[:, 6] = 0.5
    y, x = np.divmod(np.arange(img.size), 13)
    want = gradient_direction(np.log(img + 1e-3), x, y)
    got = log_gradient_direction_at(img.ravel(), 1e-3, x, y, 13, 9)
    for a, b in zip(got, want):
        assert a.tobytes() == b.tobytes()


def ref_stripes_point_truth(r, x, y, t_s):
    """The stripes' point truth in numpy (the reference of the kernel)."""
    vx, vy = np.zeros_like(x), np.zeros_like(x)
    nx, ny = np.full_like(x, np.nan), np.full_like(x, np.nan)
    k_of = r._layer_of_row[np.clip(y.astype(np.int64), 0, r.height - 1)]
    for k, layer in enumerate(r.layers):
        sel = k_of == k
        n0, n1 = layer.normal
        v0, v1 = layer.velocity_px_s
        vx[sel], vy[sel] = v0, v1
        u = n0 * (x[sel] - v0 * t_s[sel]) + n1 * (y[sel] - v1 * t_s[sel]) - layer.phase_px
        rr = np.mod(u, layer.period_px)
        sign = np.where(np.abs(rr - layer.duty * layer.period_px) < np.minimum(rr, layer.period_px - rr), 1.0, -1.0)
        if layer.dark > layer.light:
            sign = -sign
        nx[sel], ny[sel] = sign * n0, sign * n1
    return vx, vy, nx, ny


def test_stripes_point_truth_kernel_matches_reference():
    from evedge.sim.planar import StripeLayer, StripesRenderer

    r = StripesRenderer(40, 20, [StripeLayer((0, 10), 7.0, 0.4, (30.0, -12.0), phase_px=1.3),
                                 StripeLayer((12, 20), 5.0, -1.0, (-50.0, 5.0), dark=0.9, light=0.1, duty=0.3)])
    rng = np.random.default_rng(0)
    x = rng.integers(0, 40, 3000).astype(float)
    y = rng.integers(0, 20, 3000).astype(float)
    t = rng.uniform(0, 2, 3000)
    got = np.stack(r.point_truth(x, y, t))
    want = np.stack(ref_stripes_point_truth(r, x, y, t))
    assert np.isnan(got[2]).sum() > 100  # rows 10-11 belong to no layer
    assert got.tobytes() == want.tobytes()


def ref_shapes_motion_truth(r, x, y, t_s):
    """The shapes' motion field and object points in numpy (PlanarMotion.state and flow_at: the kernel's reference)."""
    m = r.motion
    theta, w, sx, sy, v0x, v0y = m.state(t_s)
    c, s = np.cos(theta), np.sin(theta)
    cx, cy = m.center_px
    rx, ry = x - cx - sx, y - cy - sy
    fx, fy = m.flow_at(x, y, t_s)
    return fx, fy, cx + c * rx + s * ry, cy - s * rx + c * ry


@pytest.mark.parametrize("motion", [
    PlanarMotion(amplitude_px=(22.0, 7.0), frequency_hz=0.25, chirp_hz_s=1.0, angle_rad=0.3),
    PlanarMotion(center_px=(20.0, 15.0), angle_amplitude_rad=0.25, frequency_hz=0.5, chirp_hz_s=1.0,
                 velocity_px_s=(5.0, -3.0), angular_velocity_rad_s=0.4),
])
def test_shapes_point_truth_kernel_matches_reference(motion):
    from evedge.sim._exact import _shapes_truth_points

    r = ShapesRenderer(40, 30, [Polygon(np.array([[10.0, 10.0], [25.0, 12.0], [18.0, 24.0]]), 0.2)], motion)
    rng = np.random.default_rng(1)
    x, y, t = rng.uniform(0, 40, 2000), rng.uniform(0, 30, 2000), rng.uniform(0, 2, 2000)
    out = [np.empty(2000) for _ in range(6)]
    _shapes_truth_points(x, y, t, r._motion_params(), *motion.center_px, r._translation_geometry() is None, *out)
    qx, qy, vx, vy = out[:4]
    want = ref_shapes_motion_truth(r, x, y, t)
    for got, ref in zip((vx, vy, qx, qy), want):
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9)
    vx2, vy2, nx, ny = r.point_truth(x, y, t)
    np.testing.assert_array_equal(vx2, vx)
    np.testing.assert_allclose(np.hypot(nx, ny), 1.0, atol=1e-12)
