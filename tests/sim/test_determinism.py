"""Same seed -> same bytes; any chunking -> the same bytes as one chunk."""

import numpy as np
import pytest

from evedge.sim import parse_scene, simulate


def _scene(stripes_dict, seed=5):
    d = stripes_dict(width=24, height=12, duration_s=0.08, velocity_px_s=[140.0, 30.0], angle_deg=15.0)
    d["scene"]["seed"] = seed
    d["events"].update(contrast_sigma=0.03, noise_rate_hz=40.0, jitter_us=30.0, refractory_us=50.0)
    return parse_scene(d, "det.toml")


def _bytes(rec):
    return (rec.events.tobytes(), rec.truth.tobytes(), rec.frames.images.tobytes(), rec.edges.images.tobytes(),
            rec.frames.t_us.tobytes())


def test_same_seed_same_bytes(stripes_dict):
    a = simulate(_scene(stripes_dict), progress=False)
    b = simulate(_scene(stripes_dict), progress=False)
    assert _bytes(a) == _bytes(b)
    assert a.events.shape[0] > 500 and (~a.truth["is_signal"]).sum() > 10
    c = simulate(_scene(stripes_dict), seed=6, progress=False)
    assert c.events.tobytes() != a.events.tobytes()


@pytest.mark.parametrize("chunk_s", [0.0031, 0.017])
def test_chunked_equals_one_shot(stripes_dict, chunk_s):
    one = simulate(_scene(stripes_dict), progress=False, chunk_s=10.0)
    many = simulate(_scene(stripes_dict), progress=False, chunk_s=chunk_s)
    assert _bytes(one) == _bytes(many)


def test_recording_contents(stripes_dict):
    rec = simulate(_scene(stripes_dict), progress=False, frame_rate_hz=100.0)
    assert rec.frames.images.dtype == np.float32
    assert rec.frames.images.min() >= 0.0 and rec.frames.images.max() <= 1.0
    np.testing.assert_array_equal(rec.frames.t_us, np.arange(9) * 10000)
    assert rec.edges.images.dtype == bool and rec.edges.images.any()
    assert np.all(np.diff(rec.events["t"]) >= 0)
    assert rec.events["t"].max() <= 80000
    md = rec.metadata
    assert md["seed"] == 5 and md["scene"]["scene"]["kind"] == "stripes"
    assert {"numpy", "numba", "evedge"} <= set(md["versions"])
    assert md["n_signal"] + md["n_noise"] == rec.events.shape[0]


def test_frames_and_edges_match_render_frame_and_edge_map(stripes_dict):
    from evedge.sim import edge_map, render_frame

    scene = _scene(stripes_dict)
    rec = simulate(scene, progress=False, frame_rate_hz=50.0)
    t = rec.frames.t_us[2] / 1e6
    np.testing.assert_array_equal(rec.frames.images[2], render_frame(scene, t).astype(np.float32))
    np.testing.assert_array_equal(rec.edges.images[2], edge_map(scene, t))
    with pytest.raises(TypeError, match="scene must be a Scene"):
        simulate(42)


def test_shapes_geometric_steps_chunked_equals_one_shot():
    """The shapes' geometric steps with sub-sampled pixels: any chunking and a rerun give the same bytes."""
    import copy
    import tomllib
    from pathlib import Path

    data = tomllib.loads((Path(__file__).resolve().parents[2] / "scenes" / "shapes_translation.toml").read_text())
    data = copy.deepcopy(data)
    data["scene"]["duration_s"] = 0.06
    data["motion"].update(frequency_hz=2.0, chirp_hz_s=0.0)
    data["events"].update(jitter_us=20.0)
    data.pop("sections", None)
    scene = parse_scene(data, "shapes.toml")
    one = simulate(scene, progress=False, chunk_s=10.0, frame_rate_hz=0)
    assert one.metadata["sampling_used"] == "geometric" and one.events.shape[0] > 5000
    for chunk_s in (0.0031, 0.017):
        many = simulate(scene, progress=False, chunk_s=chunk_s, frame_rate_hz=0)
        assert (one.events.tobytes(), one.truth.tobytes()) == (many.events.tobytes(), many.truth.tobytes())
