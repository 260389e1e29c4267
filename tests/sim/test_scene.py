"""Scene files: the shipped scenes load; errors name the file, the key and the problem."""

import copy
from pathlib import Path

import pytest

from evedge.sim import SceneError, load_scene, parse_scene, simulate

SCENES = Path(__file__).resolve().parents[2] / "scenes"


@pytest.mark.parametrize("name", ["stripes", "shapes_translation", "shapes_rotation", "boxes_3d"])
def test_shipped_scenes_load(name):
    scene = load_scene(SCENES / f"{name}.toml")
    assert scene.name == name
    assert scene.duration_s > 0


def test_shipped_scene_facts():
    stripes = load_scene(SCENES / "stripes.toml")
    assert (stripes.sensor.width, stripes.sensor.height) == (128, 128)
    speeds = sorted(abs(layer.velocity_px_s[0]) for layer in stripes.objects)
    assert len(speeds) == 2 and speeds[0] < speeds[1]
    tr = load_scene(SCENES / "shapes_translation.toml")
    assert (tr.sensor.width, tr.sensor.height) == (240, 180)
    assert [s.name for s in tr.sections] == ["slow", "fast"]
    assert tr.motion.max_speed_px_s(*[tr.sections[1].start_s, tr.sections[1].end_s], 240, 180) > \
        2 * tr.motion.max_speed_px_s(tr.sections[0].start_s, tr.sections[0].end_s, 240, 180)


def test_sections_reach_metadata():
    scene = load_scene(SCENES / "shapes_translation.toml")
    rec = simulate(scene, duration_s=0.002, progress=False, frame_rate_hz=0)
    assert rec.metadata["sections"][1] == {"name": "fast", "start_us": 1400000, "end_us": 2000000}


def _base():
    return {
        "scene": {"kind": "shapes", "duration_s": 0.1},
        "sensor": {"preset": "davis240"},
        "shapes": [{"kind": "circle", "center_px": [50, 50], "radius_px": 10}],
    }


def _mutate(path, value):
    d = _base()
    node = d
    for k in path[:-1]:
        node = node[k]
    if value is KeyError:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return d


CASES = [
    (("scene", "duration_s"), KeyError, "scene.duration_s", "missing"),
    (("scene", "duration_s"), -1.0, "scene.duration_s", "must be >"),
    (("scene", "duration_s"), "long", "scene.duration_s", "expected a number"),
    (("scene", "kind"), "blob", "scene.kind", "must be one of"),
    (("scene", "durration_s"), 1.0, "scene.durration_s", "unknown key"),
    (("sensor", "preset"), "dvs999", "sensor.preset", "unknown preset"),
    (("sensor",), {"width": 100}, "sensor.height", "give a preset or both width and height"),
    (("events",), {"contrast_pos": 0}, "events.contrast_pos", "must be >"),
    (("events",), {"lambda": 2.0}, "events.lambda", "must be <= 1"),
    (("shapes",), [{"kind": "circle", "center_px": [1, 2, 3], "radius_px": 2}], "shapes[0].center_px",
     "expected an array of 2"),
    (("shapes",), [{"kind": "circle", "center_px": [1, 2]}], "shapes[0].radius_px", "missing"),
    (("shapes",), [{"kind": "star", "center_px": [1, 2], "radius_px": 3, "inner_ratio": 1.5}],
     "shapes[0].inner_ratio", "must be < 1"),
    (("shapes",), [{"kind": "circle", "center_px": [1, 2], "radius_px": 2, "intensity": 1.5}],
     "shapes[0].intensity", "must be <= 1"),
    (("motion",), {"frequency_hz": -1}, "motion.frequency_hz", "must be >="),
    (("shapes",), [], "shapes", "at least one [[shapes]]"),
    (("shapes",), [{"kind": "polygon", "vertices_px": [[0, 0], [1, 1]]}], "shapes[0].vertices_px",
     "at least 3 finite"),
    (("shapes",), [{"kind": "polygon", "vertices_px": [[0, 0], [1], [2, 2]]}], "shapes[0].vertices_px",
     "expected an array of [x, y] pairs"),
    (("shapes",), [{"kind": "polygon"}], "shapes[0].vertices_px", "missing"),
    (("scene", "seed"), 1.5, "scene.seed", "expected an integer"),
    (("sections",), [{"name": "a", "start_s": 0.05, "end_s": 0.01}], "sections[0].end_s", "must be > start_s"),
    (("sections",), [{"name": "a", "start_s": 0.0, "end_s": 5.0}], "sections[0].end_s", "must be <= scene.duration_s"),
    # beyond these the run never ends or times wrap around int64 microseconds
    (("scene", "duration_s"), 1e300, "scene.duration_s", "must be <= 9000000000.0"),
    (("events",), {"noise_rate_hz": 1e300}, "events.noise_rate_hz", "must be <= 1000000.0"),
    (("events",), {"jitter_us": 1e300}, "events.jitter_us", "must be <= 1000000000000.0"),
    (("events",), {"noise_rate_hz": 10**400}, "events.noise_rate_hz", "must be finite, got an integer of 401 digits"),
    (("shapes",), [{"kind": "circle", "center_px": [10**400, 2], "radius_px": 2}], "shapes[0].center_px",
     "expected an array of 2 finite numbers"),
    (("scene", "frame_rate_hz"), 2**63, "scene.frame_rate_hz", "must be <= 1000000.0"),
    (("events",), {"min_step_s": 1e-300, "min_rate_hz": 1e300}, "events.min_rate_hz", "must be <= 1000000.0"),
    (("events",), {"min_step_s": 1e-300}, "events.min_step_s", "must be >= 1e-09"),
]


@pytest.mark.parametrize("path,value,key,problem", CASES)
def test_errors_name_file_key_problem(path, value, key, problem):
    with pytest.raises(SceneError) as info:
        parse_scene(_mutate(path, value), source="scenes/bad.toml")
    msg = str(info.value)
    assert msg.startswith("scenes/bad.toml: ")
    assert f"'{key}'" in msg
    assert problem in msg


def test_stripes_errors(tmp_path):
    d = {
        "scene": {"kind": "stripes", "duration_s": 0.1},
        "sensor": {"preset": "dvs128"},
        "stripes": [{"rows_fraction": [0.0, 0.6], "period_px": 10, "velocity_px_s": [1, 0]},
                    {"rows_fraction": [0.5, 1.0], "period_px": 10, "velocity_px_s": [1, 0]}],
    }
    with pytest.raises(SceneError, match=r"x.toml: key 'stripes\[1\].rows_fraction': rows .* overlap"):
        parse_scene(copy.deepcopy(d), "x.toml")
    d["stripes"][1]["rows_fraction"] = [0.6, 1.0]
    d["stripes"][1]["period_px"] = 0
    with pytest.raises(SceneError, match=r"key 'stripes\[1\].period_px': must be > 0"):
        parse_scene(d, "x.toml")


def test_file_level_errors(tmp_path):
    bad = tmp_path / "broken.toml"
    bad.write_text("[scene\nkind = 1\n")
    with pytest.raises(SceneError, match="broken.toml: not valid TOML"):
        load_scene(bad)
    with pytest.raises(SceneError, match="missing.toml: cannot read scene file"):
        load_scene(tmp_path / "missing.toml")
    nohead = tmp_path / "nohead.toml"
    nohead.write_text('[sensor]\npreset = "dvs128"\n')
    with pytest.raises(SceneError, match="nohead.toml: key 'scene': missing table"):
        load_scene(nohead)


def test_sensor_presets_and_overrides():
    d = _base()
    s = parse_scene(d, "a.toml").sensor
    assert (s.width, s.height, s.fx, s.cx) == (240, 180, 199.092, 132.192)
    d["sensor"] = {"preset": "davis240", "width": 100, "height": 80}
    s = parse_scene(d, "a.toml").sensor
    assert (s.width, s.height, s.fx, s.fy, s.cx, s.cy) == (100, 80, 100.0, 100.0, 49.5, 39.5)
    d["sensor"] = {"width": 64, "height": 48, "fx": 50.0, "cy": 20.0}
    s = parse_scene(d, "a.toml").sensor
    assert (s.fx, s.fy, s.cx, s.cy) == (50.0, 50.0, 31.5, 20.0)


def test_analytic_path_never_imports_pyrender(tmp_path):
    import subprocess
    import sys

    code = ("import sys; from evedge.sim import simulate; "
            f"simulate({str(SCENES / 'stripes.toml')!r}, duration_s=0.002, progress=False); "
            "print('pyrender' in sys.modules, 'OpenGL' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]


def test_simulate_and_converter_params_bound_what_the_scene_bounds():
    from evedge.sim import ConverterParams

    with pytest.raises(ValueError, match=r"duration_s must be <= 9e\+09"):
        simulate(parse_scene(_base()), duration_s=1e100, progress=False)
    for name, value in (("lambda_", 2.0), ("noise_rate_hz", 1e300), ("jitter_us", 1e300)):
        with pytest.raises(ValueError, match=f"ConverterParams.{name} must be <= "):
            ConverterParams(**{name: value})


def test_numpy_scalars_are_numbers_and_non_finite_times_are_refused():
    import numpy as np

    from evedge.sim import edge_map, render_frame

    scene = parse_scene(_base())
    a = simulate(scene, duration_s=np.float64(0.01), frame_rate_hz=np.int64(100), chunk_s=np.float32(0.005),
                 progress=False)
    b = simulate(scene, duration_s=0.01, frame_rate_hz=100.0, chunk_s=0.005, progress=False)
    np.testing.assert_array_equal(a.events, b.events)
    assert len(a.frames) == 2
    for func in (render_frame, edge_map):
        with pytest.raises(ValueError, match=f"{func.__name__}: t_s must be a finite number of seconds, got nan"):
            func(scene, float("nan"))


def test_a_run_that_cannot_fit_in_memory_is_refused_before_work():
    from dataclasses import replace

    scene = parse_scene(_base(), source="scenes/noisy.toml")
    noisy = replace(scene, params=replace(scene.params, noise_rate_hz=1e6), duration_s=0.05)
    with pytest.raises(MemoryError, match=r"about 2.16e\+09 noise events at noise_rate_hz=1e\+06\).* needs about "
                                          r"\d+ GiB; this machine has"):
        simulate(noisy, progress=False)


@pytest.mark.parametrize("preset", ["davis346", "dvxplorer", "gen3", "gen4"])
def test_sensor_presets_in_scenes(preset):
    from evedge.sensors import sensor_model

    m = sensor_model(preset)
    d = _base()
    d["sensor"] = {"preset": preset}
    d["events"] = {"preset": preset, "contrast_neg": 0.31}
    s = parse_scene(d, "p.toml")
    assert (s.sensor.width, s.sensor.height, s.sensor.fx) == (m.width, m.height, m.fx)
    assert (s.params.contrast_pos, s.params.refractory_us) == (m.contrast_pos, m.refractory_us)
    assert s.params.contrast_neg == 0.31  # an explicit key overrides the preset
    d["events"] = {"preset": "gen9"}
    with pytest.raises(SceneError, match="key 'events.preset': unknown preset 'gen9'"):
        parse_scene(d, "p.toml")


def test_with_sensor_rescales_bands():
    from evedge.sim.scene import with_sensor

    s = with_sensor(load_scene(SCENES / "stripes.toml"), "gen4")
    assert (s.sensor.width, s.sensor.height) == (1280, 720)
    assert [layer.rows for layer in s.objects] == [(0, 360), (360, 720)]
    assert s.params == load_scene(SCENES / "stripes.toml").params


@pytest.mark.parametrize("name", ["stripes", "shapes_translation"])
def test_gen4_memory_is_bounded(name):
    """1280x720 stripes and shapes: the working memory is the per-pixel state, not the duration.

    Peak traced allocation (numpy buffers included) minus the output stays under
    160 MiB (13 float64 arrays of 0.92 Mpx are 94 MiB), for 2 ms and for 4 ms.
    The shapes take geometric steps with sub-sampled pixels (their scratch is per pixel too).
    """
    import tracemalloc

    from evedge.sim.scene import with_sensor

    s = with_sensor(load_scene(SCENES / f"{name}.toml"), "gen4")
    simulate(s, duration_s=0.0005, frame_rate_hz=0, progress=False)  # compile outside the trace
    extra = []
    for d in (0.002, 0.004):
        tracemalloc.start()
        rec = simulate(s, duration_s=d, frame_rate_hz=0, progress=False, chunk_s=0.001)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        out = rec.events.nbytes + rec.truth.nbytes
        assert rec.events.shape[0] > (3_000 if name == "stripes" else 100)
        extra.append((peak - 2 * out) / 2**20)
    assert max(extra) < 160, extra
    assert abs(extra[1] - extra[0]) < 20, extra
