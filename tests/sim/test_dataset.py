"""Dataset specs: validation names the key, draws depend only on (spec seed, index, parameter)."""

import math
from pathlib import Path

import numpy as np
import pytest

from evedge.sim.dataset import (PARAMETERS, DatasetError, draw_parameters, load_dataset, parse_dataset,
                                sequence_scene)
from evedge.sim.scene import SceneError

SMALL = Path(__file__).resolve().parents[2] / "scenes" / "datasets" / "small.toml"


def _spec(count=8, seed=5, **params):
    return {"dataset": {"count": count, "seed": seed}, "parameters": params}


def test_shipped_spec_loads_and_every_sequence_is_a_valid_scene():
    spec = load_dataset(SMALL)
    assert spec.name == "small" and spec.count == 6
    assert {"speed_px_s", "direction_deg", "contrast", "noise_rate_hz", "family"} <= set(spec.swept)
    families = set()
    for i in range(spec.count):
        seq = spec.sequence(i)
        scene = sequence_scene(spec, seq)
        families.add(scene.kind)
        assert scene.name == seq.name == f"seq_{i:05d}"
        assert scene.seed == seq.seed
        assert 40 <= seq.params["speed_px_s"] <= 320
        assert scene.source == f"small[{i}]"  # not the spec's path: bytes must not depend on it
    assert families == {"stripes", "shapes"}


CASES = [
    ({"dataset": {"seed": 1}}, "dataset.count", "missing"),
    ({"dataset": {"count": 0}}, "dataset.count", "must be >= 1"),
    ({"dataset": {"count": 2, "sed": 1}}, "dataset.sed", "unknown key"),
    ({"parameters": {}}, "dataset", "missing table"),
    (_spec(speeed_px_s=3), "parameters.speeed_px_s", "unknown key"),
    (_spec(speed_px_s=-3), "parameters.speed_px_s", "must be >= 0"),
    (_spec(speed_px_s="fast"), "parameters.speed_px_s", "expected a number"),
    (_spec(speed_px_s={"uniform": [3]}), "parameters.speed_px_s.uniform", "expected [low, high]"),
    (_spec(speed_px_s={"uniform": [5, 3]}), "parameters.speed_px_s.uniform", "low <= high"),
    (_spec(speed_px_s={"log_uniform": [0, 3]}), "parameters.speed_px_s.log_uniform", "low > 0"),
    (_spec(speed_px_s={"normal": [0, 3]}), "parameters.speed_px_s.normal", "unknown distribution"),
    (_spec(speed_px_s={}), "parameters.speed_px_s", "empty table"),
    (_spec(speed_px_s={"uniform": [1, 2], "choice": [1]}), "parameters.speed_px_s.choice", "exactly one"),
    (_spec(speed_px_s={"uniform": [1, 2], "x": 1}), "parameters.speed_px_s.x", "unknown key"),
    (_spec(contrast={"uniform": [0.5, 2]}), "parameters.contrast.uniform[1]", "must be <= 1"),
    (_spec(contrast={"choice": [0.5, 0.2, 0]}), "parameters.contrast.choice[2]", "must be > 0"),
    (_spec(contrast={"choice": []}), "parameters.contrast.choice", "non-empty"),
    (_spec(shape_count={"uniform": [1, 3]}), "parameters.shape_count.uniform", "'integers' or 'choice'"),
    (_spec(shape_count=2.5), "parameters.shape_count", "expected an integer"),
    (_spec(speed_px_s={"integers": [1, 3]}), "parameters.speed_px_s.integers", "for integer parameters"),
    (_spec(family="mesh"), "parameters.family", "must be one of"),
    (_spec(family={"uniform": [0, 1]}), "parameters.family.uniform", "fixed value or 'choice'"),
    (_spec(sensor="64y48"), "parameters.sensor", "WIDTHxHEIGHT"),
    (_spec(sensor={"choice": ["dvs128", "0x4"]}), "parameters.sensor.choice[1]", "WIDTHxHEIGHT"),
    (_spec(shape_kind={"choice": ["circle", "polygon"]}), "parameters.shape_kind.choice[1]", "must be one of"),
    (_spec(duration_s=1e13), "parameters.duration_s", "must be <= "),
]


@pytest.mark.parametrize("data,key,problem", CASES)
def test_errors_name_the_key(data, key, problem):
    with pytest.raises(DatasetError) as err:
        parse_dataset(data, "bad.toml")
    msg = str(err.value)
    assert msg.startswith(f"bad.toml: key '{key}': "), msg
    assert problem in msg, msg
    assert isinstance(err.value, SceneError) and isinstance(err.value, ValueError)


def test_unreadable_and_invalid_toml(tmp_path):
    with pytest.raises(DatasetError, match="cannot read"):
        load_dataset(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[dataset\ncount = 2")
    with pytest.raises(DatasetError, match="bad.toml: not valid TOML"):
        load_dataset(bad)


def test_draws_reproduce_and_differ_between_sequences():
    spec = parse_dataset(_spec(count=50, speed_px_s={"log_uniform": [10, 1000]},
                               noise_rate_hz={"choice": [0, 1, 5]}, shape_count={"integers": [1, 3]},
                               family="shapes", shape_radius_px={"uniform": [2, 4]}))
    a = [draw_parameters(spec, i) for i in range(spec.count)]
    b = [draw_parameters(spec, i) for i in reversed(range(spec.count))][::-1]
    assert a == b  # order of drawing does not matter
    speeds = np.array([p["speed_px_s"] for p in a])
    assert len(set(speeds)) == spec.count and np.all((speeds >= 10) & (speeds < 1000))
    # log-uniform: about half below the geometric mean (100); loose bound, 50 draws
    assert 10 <= np.count_nonzero(speeds < 100) <= 40
    assert {p["noise_rate_hz"] for p in a} == {0.0, 1.0, 5.0}
    assert {p["shape_count"] for p in a} == {1, 2, 3}
    assert all(len(p["shape_radius_px"]) == p["shape_count"] for p in a)
    assert len({spec.sequence(i).seed for i in range(spec.count)}) == spec.count
    other = parse_dataset(dict(spec.raw, dataset={"count": 50, "seed": 6}))
    assert draw_parameters(other, 0)["speed_px_s"] != a[0]["speed_px_s"]


def test_adding_a_parameter_keeps_the_other_draws():
    base = parse_dataset(_spec(speed_px_s={"uniform": [10, 20]}))
    more = parse_dataset(_spec(speed_px_s={"uniform": [10, 20]}, contrast={"uniform": [0.2, 0.9]}))
    for i in range(base.count):
        assert draw_parameters(base, i)["speed_px_s"] == draw_parameters(more, i)["speed_px_s"]
        assert base.sequence(i).seed == more.sequence(i).seed


def test_fixed_values_and_defaults():
    spec = parse_dataset(_spec(count=1, speed_px_s=42, sensor="40x30"))
    p = draw_parameters(spec, 0)
    assert p["speed_px_s"] == 42.0 and p["sensor"] == "40x30"
    assert p["contrast"] == PARAMETERS["contrast"].default
    assert spec.swept == ()
    with pytest.raises(ValueError, match=r"index must be an integer in \[0, 1\)"):
        draw_parameters(spec, 1)


def test_scene_geometry_of_a_stripes_sequence():
    spec = parse_dataset(_spec(count=1, speed_px_s=50, direction_deg=90, angle_deg=30, contrast=0.5,
                               mean_intensity=0.4, sensor="64x48"))
    scene = sequence_scene(spec, spec.sequence(0))
    (layer,) = scene.objects
    assert layer.velocity_px_s == pytest.approx((0.0, 50.0), abs=1e-12)
    assert layer.angle_rad == pytest.approx(math.radians(30))
    assert (layer.dark, layer.light) == pytest.approx((0.2, 0.6))
    assert layer.rows == (0, 48)


def test_shapes_never_overlap_and_radius_is_recorded():
    spec = parse_dataset(_spec(count=3, family="shapes", sensor="32x24", shape_count=6,
                               shape_radius_px={"uniform": [3, 30]}))
    for i in range(spec.count):
        seq = spec.sequence(i)
        shapes = seq.scene["shapes"]
        assert [s["radius_px"] for s in shapes] == seq.params["shape_radius_px"]
        for a in range(len(shapes)):
            for b in range(a):
                d = math.dist(shapes[a]["center_px"], shapes[b]["center_px"])
                assert d > shapes[a]["radius_px"] + shapes[b]["radius_px"]
        sequence_scene(spec, seq)


def test_too_bright_combination_is_an_invalid_scene_naming_the_key():
    spec = parse_dataset(_spec(count=1, mean_intensity=0.9, contrast=0.5))
    with pytest.raises(SceneError, match=r"\[0\]: key 'stripes\[0\]\.light': must be <= 1"):
        sequence_scene(spec, spec.sequence(0))


def test_boxes_family_is_a_mesh_scene_moving_at_the_requested_image_speed():
    spec = parse_dataset(_spec(count=4, family="boxes", sensor="32x24", speed_px_s=80, direction_deg=90,
                               box_count={"integers": [1, 4]}, box_depth_m={"uniform": [2, 4]},
                               box_size_m={"uniform": [0.2, 5]}))
    for i in range(spec.count):
        seq = spec.sequence(i)
        scene = sequence_scene(spec, seq)
        assert scene.kind == "mesh" and len(scene.objects) == seq.params["box_count"]
        assert len(seq.params["box_depth_m"]) == seq.params["box_count"] and seq.params["shape_kind"] == []
        z_ref = np.mean(seq.params["box_depth_m"])
        # image speed of a point at the mean depth: f |v| / z (f = width for a 'WxH' sensor)
        v = np.asarray(scene.motion["velocity_m_s"])
        assert 32 * np.hypot(v[0], v[1]) / z_ref == pytest.approx(80)
        assert v[0] == pytest.approx(0, abs=1e-12) and v[1] < 0  # image moves +y: camera moves -y
        for box, size, z in zip(scene.objects, seq.params["box_size_m"], seq.params["box_depth_m"]):
            assert box["size_m"] == (size,) * 3 and box["center_m"][2] == z
            assert size <= 0.8 * (32 / math.ceil(math.sqrt(seq.params["box_count"] * 32 / 24))) / 32 * z + 1e-12


def test_boxes_sequence_renders(tmp_path):
    from evedge.sim import simulate

    spec = parse_dataset(_spec(count=1, family="boxes", sensor="24x18", duration_s=0.01, frame_rate_hz=100,
                               box_count=2, speed_px_s=100))
    scene = sequence_scene(spec, spec.sequence(0))
    # boxes render exactly (no OpenGL): no failure here may be skipped as "no GL stack"
    assert scene.setup_3d["render"]["method"] == "exact"
    rec = simulate(scene, progress=False)
    assert rec.events.shape[0] > 0 and rec.edges.images.any()
    speed = np.hypot(rec.truth["vx_px_s"], rec.truth["vy_px_s"])
    assert 50 < np.nanmedian(speed[rec.truth["is_signal"]]) < 200  # 100 px/s at the mean depth


def test_parameters_of_another_family_are_none_and_leave_the_others_alone():
    data = _spec(count=20, family={"choice": ["stripes", "shapes"]}, period_px={"uniform": [10, 30]},
                 shape_count={"integers": [1, 3]}, speed_px_s={"uniform": [10, 20]})
    spec = parse_dataset(data)
    fixed = parse_dataset(dict(data, parameters=dict(data["parameters"], family="stripes")))
    for i in range(spec.count):
        p, q = draw_parameters(spec, i), draw_parameters(fixed, i)
        if p["family"] == "stripes":
            assert p["shape_count"] is None and p["shape_kind"] == [] and 10 <= p["period_px"] < 30
        else:
            assert p["period_px"] is None and p["shape_count"] in (1, 2, 3)
            assert len(p["shape_kind"]) == p["shape_count"]
        assert p["speed_px_s"] == q["speed_px_s"]  # the family's draw does not shift the others
        sequence_scene(spec, spec.sequence(i))


def test_shipped_specs_by_name():
    from evedge.sim.dataset import dataset_path, shipped_datasets

    assert {"small", "sweep_stripes"} <= set(shipped_datasets())
    assert load_dataset(dataset_path("small")).name == "small"
    assert dataset_path(SMALL) == SMALL
    with pytest.raises(DatasetError, match=r"tiny: no such file, and no shipped dataset spec .*small"):
        dataset_path("tiny")
    with pytest.raises(DatasetError, match="cannot read"):
        load_dataset(dataset_path("missing/tiny.toml"))
