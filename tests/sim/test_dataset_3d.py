"""3-D scenes in datasets: the boxes family carries the 3-D truth (per-event flow, depth/flow maps, IMU)."""

import math
from pathlib import Path

import numpy as np

from evedge.io import read_hdf5
from evedge.sim.dataset import load_dataset, parse_dataset, sequence_scene
from evedge.sim.dataset_run import SequenceTask, generate_sequence

ROOT = Path(__file__).resolve().parents[2]

SPEC = {
    "dataset": {"name": "boxes3d", "seed": 7, "count": 2},
    "parameters": {"family": "boxes", "sensor": "32x24", "duration_s": 0.03, "frame_rate_hz": 100,
                   "speed_px_s": {"uniform": [80, 160]}, "direction_deg": {"uniform": [0, 360]},
                   "angular_velocity_deg_s": {"uniform": [-30, 30]}, "box_count": {"integers": [1, 3]},
                   "box_depth_m": {"uniform": [2, 4]}, "box_size_m": 0.5},
}


def test_boxes_sequences_carry_the_3d_truth(tmp_path):
    spec = parse_dataset(SPEC, "boxes3d.toml")
    for i in range(spec.count):
        row = generate_sequence(SequenceTask(spec, i, str(tmp_path), ("evedge",)))
        assert row["status"] == "ok", row["error"]
        (rel,) = row["files"]
        rec = read_hdf5(tmp_path / rel)
        assert rec.events.size > 20
        # depth and flow maps at the frame times, IMU at 1 kHz, all read back from the file
        assert set(rec.maps) == {"depth_m", "flow_x_px_s", "flow_y_px_s"}
        assert rec.maps["depth_m"].t_us.tolist() == rec.frames.t_us.tolist()
        assert rec.imu.size == 31
        # the drawn roll rate is the gyroscope's z reading; no acceleration: gravity only
        roll = math.radians(row["params"]["angular_velocity_deg_s"])
        np.testing.assert_allclose(rec.imu["wz_rad_s"], roll, rtol=1e-12)
        np.testing.assert_allclose(np.linalg.norm([rec.imu[f"a{a}_m_s2"] for a in "xyz"], axis=0), 9.80665)
        # per-event flow: the exact renderer's motion field at the event's pixel and time
        scene = sequence_scene(spec, spec.sequence(i))
        r = scene.build_renderer()
        try:
            vx, vy = r.flow_at(rec.events["x"], rec.events["y"], rec.events["t"] * 1e-6)
            got = rec.truth
            close = np.hypot(vx - got["vx_px_s"], vy - got["vy_px_s"]) <= 1e-3 * np.hypot(vx, vy) + 1e-6
            assert close.mean() > 0.97  # the rest: pixel centres an outline crosses within 0.5 us
            speed = np.hypot(got["vx_px_s"], got["vy_px_s"])
            assert 0.3 * row["params"]["speed_px_s"] < np.median(speed) < 3 * row["params"]["speed_px_s"]
        finally:
            r.close()
    # same spec, same bytes
    again = tmp_path / "again"
    again.mkdir()
    row = generate_sequence(SequenceTask(spec, 1, str(again), ("evedge",)))
    (rel,) = row["files"]
    assert (again / rel).read_bytes() == (tmp_path / rel).read_bytes()


def test_shipped_boxes_dataset_spec():
    spec = load_dataset(ROOT / "scenes" / "datasets" / "boxes.toml")
    assert spec.count == 4
    for i in range(spec.count):
        scene = sequence_scene(spec, spec.sequence(i))
        assert scene.kind == "mesh" and 1 <= len(scene.objects) <= 4
        assert scene.setup_3d["render"]["method"] == "exact"
