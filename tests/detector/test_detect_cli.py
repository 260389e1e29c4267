"""``evedge detect`` end to end on a small synthetic recording written as ECD text."""

import h5py
import numpy as np
from click.testing import CliRunner
from PIL import Image

from evedge.detector.cli import detect
from evedge.detector.pipeline import detect as run_detect
from evedge.events import SensorSize


def _write_ecd(path, ev):
    with open(path, "w") as f:
        for e in ev:
            f.write(f"{e['t'] / 1e6:.6f} {e['x']} {e['y']} {int(e['p'])}\n")


def test_detect_intra_writes_lifetimes_and_frames(tmp_path, edge_events):
    ev, tau = edge_events(20, 16, 400, 0.3, n_edges=2, spacing_px=8)
    src = tmp_path / "events.txt"
    _write_ecd(src, ev)
    out = tmp_path / "out"
    res = CliRunner().invoke(detect, [str(src), "-o", str(out), "--sensor", "20x16", "--times", "20000,40000", "--quiet"])
    assert res.exit_code == 0, res.output
    with h5py.File(out / "detection.h5") as f:
        lt = f["lifetimes/lifetime_us"][:]
        valid = f["lifetimes/valid"][:]
        np.testing.assert_array_equal(f["edges/t_us"][:], [20000, 40000])
        frames = f["edges/images"][:]
    want = run_detect(ev, SensorSize(20, 16))
    np.testing.assert_array_equal(valid, want.lifetimes["valid"])
    np.testing.assert_allclose(lt, want.lifetimes["lifetime_us"], equal_nan=True)
    assert np.nanmedian(lt) == np.float64(np.nanmedian(want.lifetimes["lifetime_us"]))
    pngs = sorted((out / "edges").glob("*.png"))
    assert len(pngs) == 2
    img = np.asarray(Image.open(pngs[1])) > 0
    np.testing.assert_array_equal(img, frames[1])
    assert frames[1].any()
    assert not list(out.glob(".*tmp"))  # no temp files left


def test_detect_time_method_and_bad_file(tmp_path, edge_events):
    ev, _ = edge_events(10, 10, 1000, 0.0)
    src = tmp_path / "events.txt"
    _write_ecd(src, ev)
    out = tmp_path / "o"
    res = CliRunner().invoke(detect, [str(src), "-o", str(out), "--sensor", "10x10", "--method", "time",
                                      "--window-ms", "2", "--fps", "500", "--quiet"])
    assert res.exit_code == 0, res.output
    with h5py.File(out / "detection.h5") as f:
        assert "lifetimes" not in f and f["edges/images"].shape[1:] == (10, 10)
    bad = tmp_path / "bad.txt"
    bad.write_text("not events\n")
    res = CliRunner().invoke(detect, [str(bad), "-o", str(out), "--sensor", "10x10"])
    assert res.exit_code != 0 and "bad.txt" in res.output
    res = CliRunner().invoke(detect, [str(src), "-o", str(out), "--times", "a,b"])
    assert res.exit_code != 0 and "--times" in res.output


def test_detect_baseline_methods(tmp_path, edge_events):
    ev, _ = edge_events(16, 16, 500, 0.4, n_edges=2, spacing_px=8)
    src = tmp_path / "events.txt"
    _write_ecd(src, ev)
    for method, extra in (("mueggler", []), ("count", ["--count", "50"])):
        out = tmp_path / method
        res = CliRunner().invoke(detect, [str(src), "-o", str(out), "--sensor", "16x16", "--method", method,
                                          "--times", "10000,20000", "--quiet", *extra])
        assert res.exit_code == 0, res.output
        with h5py.File(out / "detection.h5") as f:
            assert f["edges/images"].shape == (2, 16, 16)
            assert f["edges/images"][1].any()
            assert ("lifetimes" in f) == (method == "mueggler")
