"""``evedge simulate`` writes a readable recording."""

import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from evedge.io import read_events
from evedge.sim.cli import simulate

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def test_simulate_h5_roundtrip(tmp_path):
    out = tmp_path / "s.h5"
    res = CliRunner().invoke(simulate, [str(SCENES / "stripes.toml"), "-o", str(out), "--duration", "0.01",
                                        "--seed", "3", "--quiet"])
    assert res.exit_code == 0, res.output
    rec = read_events(out)
    assert rec.events.shape[0] > 100
    assert rec.truth is not None and set(rec.truth.dtype.names) >= {"lifetime_us", "is_signal"}
    sig = rec.truth["is_signal"]
    np.testing.assert_allclose(np.unique(np.asarray(rec.truth["lifetime_us"])[sig]), [8000.0, 20000.0])
    assert rec.frames is not None and rec.edges is not None
    assert rec.metadata["seed"] == 3 and rec.metadata["scene_name"] == "stripes"


def test_simulate_ecd(tmp_path):
    out = tmp_path / "ecd"
    res = CliRunner().invoke(simulate, [str(SCENES / "stripes.toml"), "-o", str(out), "--duration", "0.005",
                                        "--format", "ecd", "--quiet"])
    assert res.exit_code == 0, res.output
    assert (out / "events.txt").stat().st_size > 0


def test_simulate_bad_scene_names_file_and_key(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[scene]\nkind = "stripes"\nduration_s = -1\n[sensor]\npreset = "dvs128"\n')
    res = CliRunner().invoke(simulate, [str(bad), "-o", str(tmp_path / "x.h5")])
    assert res.exit_code != 0
    assert "bad.toml" in res.output and "scene.duration_s" in res.output


def _run(args):
    return CliRunner().invoke(simulate, [str(SCENES / "stripes.toml"), "--quiet", *args])


def test_unwritable_output_is_refused_before_simulating(tmp_path):
    (tmp_path / "adir").mkdir()
    (tmp_path / "afile").write_text("x")
    for args, message in [
        (["-o", str(tmp_path / "nodir" / "s.h5")], "folder .*nodir of .*s.h5 does not exist"),
        (["-o", str(tmp_path / "adir")], "adir is an existing folder; --format h5 writes a file"),
        (["-o", str(tmp_path / "afile"), "--format", "ecd"], "afile is an existing file; --format ecd writes a folder"),
    ]:
        res = _run(args)
        assert res.exit_code == 2, res.output
        assert res.exception is None or isinstance(res.exception, SystemExit)
        assert re.search(message, res.output), res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adir", "afile"]


def test_bad_overrides_are_an_error_line_not_a_traceback(tmp_path):
    for args, message in [
        (["--duration", "nan"], "Error: duration_s must be a positive number, got nan"),
        (["--frame-rate", "inf"], "Error: frame_rate_hz must be >= 0, got inf"),
        (["--frame-rate", "1e12"], r"Error: frame_rate_hz must be <= 1e6"),
    ]:
        res = _run(["-o", str(tmp_path / "s.h5"), *args])
        assert res.exit_code == 1, res.output
        assert isinstance(res.exception, SystemExit), res.exception  # a ClickException, not a crash
        assert re.search(message, res.output), res.output
    assert list(tmp_path.iterdir()) == []


def test_frames_too_big_for_memory_is_named():
    from evedge.sim import simulate as run

    with pytest.raises(MemoryError, match=r"simulate: 128x128 for 1e\+07 s \(10000000000001 frames at "
                                          r"frame_rate_hz=1e\+06.* needs about .* GiB"):
        run(SCENES / "stripes.toml", duration_s=1e7, frame_rate_hz=1e6, progress=False)


def test_an_existing_output_is_replaced_only_with_overwrite(tmp_path):
    from evedge.io import read_hdf5

    out = tmp_path / "s.h5"
    assert _run(["-o", str(out), "--duration", "0.005", "--frame-rate", "0"]).exit_code == 0
    first = out.read_bytes()
    res = _run(["-o", str(out), "--duration", "0.01", "--frame-rate", "0"])
    assert res.exit_code == 1 and "already exists; pass --overwrite to replace it" in res.output
    assert out.read_bytes() == first
    res = _run(["-o", str(out), "--duration", "0.01", "--frame-rate", "0", "--overwrite"])
    assert res.exit_code == 0 and "replaced the earlier output" in res.stderr
    assert read_hdf5(out).metadata["duration_s"] == 0.01
    folder = tmp_path / "ecd"
    assert _run(["-o", str(folder), "--duration", "0.005", "--format", "ecd"]).exit_code == 0
    res = _run(["-o", str(folder), "--duration", "0.005", "--format", "ecd"])
    assert res.exit_code == 1 and "pass --overwrite" in res.output


def test_simulate_sensor_preset(tmp_path):
    out = tmp_path / "g.h5"
    res = CliRunner().invoke(simulate, [str(SCENES / "stripes.toml"), "-o", str(out), "--duration", "0.0005",
                                        "--sensor", "gen4", "--frame-rate", "0", "--quiet"])
    assert res.exit_code == 0, res.output
    assert "1280x720" in res.output
    res = CliRunner().invoke(simulate, [str(SCENES / "stripes.toml"), "-o", str(out), "--sensor", "gen9"])
    assert res.exit_code != 0 and "unknown sensor preset 'gen9'" in res.output and "gen4" in res.output


def test_simulate_video_and_frames(tmp_path):
    import cv2

    x = np.arange(32)
    frames = [np.clip(40 + 180 * ((x[None, :] - 3 * k) % 16 < 8), 0, 255).astype(np.uint8).repeat(12, 0)
              for k in range(6)]
    video = tmp_path / "v.avi"
    wr = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"FFV1"), 100.0, (32, 12), isColor=False)
    for f in frames:
        wr.write(f)
    wr.release()
    out = tmp_path / "v.h5"
    res = CliRunner().invoke(simulate, ["--video", str(video), "-o", str(out), "--contrast", "0.3",
                                        "--refractory-us", "50", "--upsample", "2", "--quiet"])
    assert res.exit_code == 0, res.output
    rec = read_events(out)
    assert rec.events.shape[0] > 100 and (rec.sensor_size.width, rec.sensor_size.height) == (32, 12)
    assert rec.events["t"].max() <= 50000 and "t_ns" in rec.truth.dtype.names
    folder = tmp_path / "f"
    folder.mkdir()
    for k, f in enumerate(frames):
        cv2.imwrite(str(folder / f"{k:03d}.png"), f)
    res = CliRunner().invoke(simulate, ["--frames", str(folder), "-o", str(tmp_path / "f.h5"), "--rate", "100",
                                        "--sensor", "dvs128", "--quiet"])
    assert res.exit_code == 0, res.output
    assert "128x128" in res.output
    res = CliRunner().invoke(simulate, ["--frames", str(folder), "-o", str(tmp_path / "g.h5"), "--quiet"])
    assert res.exit_code != 0 and "no frame times" in res.output
    res = CliRunner().invoke(simulate, [str(SCENES / "stripes.toml"), "--video", str(video), "-o", str(out)])
    assert res.exit_code != 0 and "exactly one of SCENE" in res.output
    res = CliRunner().invoke(simulate, [str(SCENES / "stripes.toml"), "--rate", "3", "-o", str(out)])
    assert res.exit_code != 0 and "--rate applies to --video/--frames only" in res.output


def test_simulate_video_with_the_gen4_preset(tmp_path):
    """``--video --sensor gen4``: frames resized to 1280x720 and the preset's pixel settings."""
    import cv2

    from evedge.sensors import sensor_model

    x = np.arange(64)
    video = tmp_path / "v.avi"
    wr = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"FFV1"), 100.0, (64, 36), isColor=False)
    for k in range(3):
        wr.write(np.clip(40 + 180 * ((x[None, :] - k) % 32 < 16), 0, 255).astype(np.uint8).repeat(36, 0))
    wr.release()
    out = tmp_path / "v.h5"
    res = CliRunner().invoke(simulate, ["--video", str(video), "-o", str(out), "--sensor", "gen4", "--quiet"])
    assert res.exit_code == 0, res.output
    assert "1280x720" in res.output
    rec = read_events(out)
    m = sensor_model("gen4")
    conv = rec.metadata["converter"]
    assert (rec.sensor_size.width, rec.sensor_size.height) == (1280, 720) and rec.events.shape[0] > 1000
    assert (conv["contrast_pos"], conv["contrast_neg"], conv["refractory_us"]) == (m.contrast_pos, m.contrast_neg,
                                                                                   m.refractory_us)
