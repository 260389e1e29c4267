"""``evedge detect`` end to end on a small synthetic recording written as ECD text."""

import dataclasses
import os

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
    img = np.asarray(Image.open(pngs[1])) == 0  # black edges on white, as the report draws them
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
    res = CliRunner().invoke(detect, [str(bad), "-o", str(out), "--sensor", "10x10", "--overwrite"])
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


def test_detect_bad_options_are_clear_errors(tmp_path, edge_events):
    """nan/inf rates and windows, unsorted or int64-overflowing instants: a usage error naming the option."""
    ev, _ = edge_events(10, 10, 1000, 0.0)
    src = tmp_path / "events.txt"
    _write_ecd(src, ev)
    base = [str(src), "-o", str(tmp_path / "o"), "--sensor", "10x10", "--quiet"]
    cases = [
        (["--fps", "nan"], "--fps"),
        (["--fps", "inf"], "--fps"),
        (["--method", "time", "--window-ms", "nan"], "--window-ms"),
        (["--method", "time", "--window-ms", "1e-9"], "--window-ms"),
        (["--method", "time", "--times", "20000,10000"], "--times"),
        (["--method", "count", "--times", "20000,10000"], "--times"),
        (["--times", "99999999999999999999"], "--times"),
        (["--tiles", "0"], "--tiles"),
        (["--tiles", "11"], "--tiles"),  # more strips than the 10 rows
    ]
    for extra, option in cases:
        res = CliRunner().invoke(detect, base + extra)
        assert res.exit_code == 2, (extra, res.output)
        assert option in res.output, extra
        assert isinstance(res.exception, SystemExit), (extra, res.exception)  # not an escaped exception


def test_detect_refuses_to_replace_what_it_did_not_write(tmp_path, edge_events):
    ev, _ = edge_events(10, 10, 1000, 0.0)
    src = tmp_path / "events.txt"
    _write_ecd(src, ev)
    out = tmp_path / "o"
    out.mkdir()
    (out / "thesis.tex").write_text("mine")
    for extra in ([], ["--overwrite"]):
        res = CliRunner().invoke(detect, [str(src), "-o", str(out), "--sensor", "10x10", "--quiet", *extra])
        assert res.exit_code == 1 and isinstance(res.exception, SystemExit), res.output
        assert ("already exists; pass --overwrite" if not extra else "thesis.tex is not written by this command") \
            in res.output
    assert [p.name for p in out.iterdir()] == ["thesis.tex"] and len(list(tmp_path.iterdir())) == 2  # no temp left


def test_detect_rerun_replaces_frames_and_sort_option(tmp_path, edge_events):
    ev, _ = edge_events(10, 10, 1000, 0.0)
    src = tmp_path / "events.txt"
    _write_ecd(src, ev)
    out = tmp_path / "o"
    args = [str(src), "-o", str(out), "--sensor", "10x10", "--quiet", "--method", "time"]
    assert CliRunner().invoke(detect, args + ["--times", "1000,2000,3000"]).exit_code == 0
    keep = out / "edges" / "notes.txt"
    keep.write_text("mine")
    res = CliRunner().invoke(detect, args + ["--times", "5000", "--overwrite"])
    assert res.exit_code == 1 and "notes.txt was not written by evedge detect" in res.output
    assert keep.read_text() == "mine" and len(list((out / "edges").glob("*.png"))) == 3  # nothing touched
    keep.unlink()
    res = CliRunner().invoke(detect, args + ["--times", "5000"])
    assert res.exit_code == 1 and "already exists; pass --overwrite to replace it" in res.output
    res = CliRunner().invoke(detect, args + ["--times", "5000", "--overwrite"])
    assert res.exit_code == 0 and "replaced the earlier output" in res.stderr
    pngs = sorted(p.name for p in (out / "edges").glob("*.png"))
    assert pngs == ["edges_000000_5000us.png"]  # the three frames of the first run are gone
    mask = os.umask(0o022)
    os.umask(mask)
    assert (out / "detection.h5").stat().st_mode & 0o777 == 0o666 & ~mask  # as open() would, not mkstemp's 0600
    # an unsorted file: an error that suggests --sort, and --sort reads it
    unsorted = tmp_path / "unsorted.txt"
    unsorted.write_text("0.002 1 1 1\n0.001 2 2 0\n")
    res = CliRunner().invoke(detect, [str(unsorted), "-o", str(out), "--sensor", "10x10", "--quiet", "--overwrite"])
    assert res.exit_code == 1 and "--sort" in res.output
    res = CliRunner().invoke(detect, [str(unsorted), "-o", str(out), "--sensor", "10x10", "--quiet", "--sort",
                                      "--overwrite"])
    assert res.exit_code == 0, res.output


def test_detect_refuses_a_frame_rate_that_cannot_fit(tmp_path, edge_events):
    """--fps 1e9 over a recording would allocate terabytes of frames: refuse it up front."""
    ev, _ = edge_events(10, 10, 1000, 0.0)
    src = tmp_path / "events.txt"
    _write_ecd(src, ev)
    res = CliRunner().invoke(detect, [str(src), "-o", str(tmp_path / "o"), "--sensor", "10x10", "--quiet",
                                      "--fps", "1e12"])
    assert res.exit_code == 2 and isinstance(res.exception, SystemExit), res.output
    assert "--fps" in res.output and "GiB" in res.output
    assert not (tmp_path / "o").exists()


def test_detect_warns_when_no_frame_fits(tmp_path):
    """A recording shorter than one frame period gets no frame at the default rate: say so on stderr."""
    src = tmp_path / "one.txt"
    src.write_text("0.001 1 1 1\n0.002 2 2 0\n")
    res = CliRunner().invoke(detect, [str(src), "-o", str(tmp_path / "o"), "--sensor", "10x10", "--quiet"])
    assert res.exit_code == 0, res.output
    assert "0 edge frames" in res.stdout
    assert "no edge frame" in res.stderr and "--times" in res.stderr
    res = CliRunner().invoke(detect, [str(src), "-o", str(tmp_path / "o2"), "--sensor", "10x10",
                                      "--quiet", "--times", "1500"])
    assert res.exit_code == 0 and "1 edge frames" in res.stdout and res.stderr == ""


def test_detect_time_range_edges_and_seed_bounds(tmp_path):
    """Times near the int64 limit, instants of opposite sign beyond int64 differences, a seed beyond int64."""
    from evedge.events import Recording, SensorSize, make_events
    from evedge.io import write_recording

    n = 300
    t = np.iinfo(np.int64).max - np.arange(n)[::-1] * 1000  # the last event at 2**63 - 1 us
    near_max = write_recording(tmp_path / "late.h5", Recording(
        make_events(np.arange(n) % 10, np.full(n, 1), t, np.ones(n, bool)), SensorSize(10, 10)))
    for method in ("time", "intra"):
        out = tmp_path / f"late_{method}"
        res = CliRunner().invoke(detect, [str(near_max), "-o", str(out), "--quiet", "--method", method, "--fps", "20"])
        assert res.exit_code == 0, res.output
        with h5py.File(out / "detection.h5") as f:
            t = f["edges/t_us"][()]
        assert t.size and (t > 9 * 10**18).all()  # never a frame at -2**63 us
    src = tmp_path / "events.txt"
    src.write_text("0.001 1 1 1\n0.002 2 2 0\n")
    res = CliRunner().invoke(detect, [str(src), "-o", str(tmp_path / "o"), "--sensor", "10x10", "--quiet",
                                      "--method", "time", "--times", "-5000000000000000000,5000000000000000000"])
    assert res.exit_code == 0, res.output  # non-decreasing: accepted (np.diff would have wrapped)
    res = CliRunner().invoke(detect, [str(src), "-o", str(tmp_path / "o2"), "--sensor", "10x10", "--quiet",
                                      "--seed", str(2**63)])
    assert res.exit_code == 2 and "--seed" in res.output and isinstance(res.exception, SystemExit)


def test_detect_refuses_a_sensor_that_cannot_fit_before_work(tmp_path):
    src = tmp_path / "events.txt"
    src.write_text("0.001 1 1 1\n0.002 2 2 0\n")
    res = CliRunner().invoke(detect, [str(src), "-o", str(tmp_path / "o"), "--sensor", "30000x30000", "--quiet",
                                      "--times", "1500"])
    assert res.exit_code == 1 and isinstance(res.exception, SystemExit), res.output
    assert "30000x30000 sensor" in res.output and "GiB; this machine has" in res.output
    assert not (tmp_path / "o").exists()


def test_detect_never_writes_or_deletes_through_a_link(tmp_path):
    src = tmp_path / "events.txt"
    src.write_text("0.001 1 1 1\n0.002 2 2 0\n")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    victim = elsewhere / "edges_000000_1000us.png"  # a frame-named file outside the output
    victim.write_bytes(b"precious")
    out = tmp_path / "o"
    out.mkdir()
    (out / "edges").symlink_to(elsewhere)
    for extra in ([], ["--overwrite"]):
        res = CliRunner().invoke(detect, [str(src), "-o", str(out), "--sensor", "10x10", "--quiet", "--times", "1500",
                                          *extra])
        assert res.exit_code == 1, res.output
    assert "symbolic link" in res.output
    assert victim.read_bytes() == b"precious" and sorted(p.name for p in elsewhere.iterdir()) == [victim.name]
    link = tmp_path / "link_out"
    link.symlink_to(elsewhere)
    res = CliRunner().invoke(detect, [str(src), "-o", str(link), "--sensor", "10x10", "--quiet", "--times", "1500",
                                      "--overwrite"])
    assert res.exit_code == 1 and "is a symbolic link" in res.output
    assert sorted(p.name for p in elsewhere.iterdir()) == [victim.name]


def test_detect_seed_is_honoured_by_random_methods_and_refused_by_the_others(tmp_path, edge_events):
    """--seed reaches Mueggler's RANSAC (the output equals the library's with that seed) and intra's;
    time and count accumulation draw no random numbers and refuse it with a clear error."""
    from evedge.detector.mueggler import MuegglerParams, estimate_lifetimes_mueggler

    ev, _ = edge_events(20, 16, 400, 0.3, n_edges=2, spacing_px=8, subpixel_px=0.3, jitter_frac=0.05, rng=2)
    src = tmp_path / "events.txt"
    _write_ecd(src, ev)
    size = SensorSize(20, 16)
    got = {}
    for method in ("mueggler", "intra"):
        for seed in (0, 5):
            out = tmp_path / f"{method}{seed}"
            res = CliRunner().invoke(detect, [str(src), "-o", str(out), "--sensor", "20x16", "--method", method,
                                              "--times", "20000", "--seed", str(seed), "--quiet"])
            assert res.exit_code == 0, res.output
            with h5py.File(out / "detection.h5") as f:
                got[method, seed] = f["lifetimes/lifetime_us"][:]
    want = estimate_lifetimes_mueggler(ev, size, MuegglerParams(seed=5))["lifetime_us"]
    np.testing.assert_array_equal(got["mueggler", 5], want)
    assert not np.array_equal(got["mueggler", 0], got["mueggler", 5], equal_nan=True)
    assert not np.array_equal(got["intra", 0], got["intra", 5], equal_nan=True)
    for method in ("time", "count"):
        res = CliRunner().invoke(detect, [str(src), "-o", str(tmp_path / method), "--sensor", "20x16",
                                          "--method", method, "--seed", "5", "--quiet"])
        assert res.exit_code == 2
        assert f"method {method!r} has no parameter 'seed'" in res.output  # i8's CLI: --seed is --param seed


def test_detect_params_config_and_self_description(tmp_path, edge_events):
    """--param and --config reach the estimator and the buffer, and are echoed; the file names its source."""
    from evedge.detector import BufferParams, IntraParams
    from evedge.io.detection import file_sha256, read_detection

    ev, _ = edge_events(20, 16, 400, 0.3, n_edges=2, spacing_px=8)
    src = tmp_path / "events.txt"
    _write_ecd(src, ev)
    cfg = tmp_path / "c.toml"
    cfg.write_text('display = "lifetime_only"\n[params]\ndelta_px = 0.1\nseed = 4\n[buffer]\ntau_min_us = 3000\n')
    out = tmp_path / "out"
    res = CliRunner().invoke(detect, [str(src), "-o", str(out), "--sensor", "20x16", "--times", "20000", "--quiet",
                                      "--config", str(cfg), "--param", "seed=7", "--param", "buffer.mode=causal"])
    assert res.exit_code == 0, res.output
    d = read_detection(out / "detection.h5")
    assert d.metadata["params"]["delta_px"] == 0.1 and d.metadata["params"]["seed"] == 7  # --param wins
    assert d.metadata["params"]["window_size"] == 5  # every parameter, defaults included
    assert d.metadata["filter_params"] == {**dataclasses.asdict(BufferParams()), "mode": "causal", "tau_min_us": 3000}
    assert d.metadata["display"] == "lifetime_only" and d.metadata["method"] == "intra"
    assert d.metadata["source"]["sha256"] == file_sha256(src) and d.metadata["source"]["path"] == str(src.resolve())
    assert set(d.metadata["versions"]) >= {"evedge", "numpy", "python"}
    assert d.events.tobytes() == ev.tobytes()
    want = run_detect(ev, SensorSize(20, 16), params=IntraParams(delta_px=0.1, seed=7),
                      buffer_params=BufferParams(tau_min_us=3000, mode="causal"))
    assert d.lifetimes["lifetime_us"].tobytes() == want.lifetimes["lifetime_us"].tobytes()
    np.testing.assert_array_equal(d.lifetimes["kept"], want.kept)
    for bad, msg in ((["--param", "nope=1"], "no parameter 'nope'"), (["--param", "delta_px=3"], "delta_px"),
                     (["--param", "novalue"], "key=value"), (["--method", "canny"], "unknown method 'canny'"),
                     (["--method", "mueggler", "--param", "buffer.tau_min_us=5"], "no noise filter")):
        res = CliRunner().invoke(detect, [str(src), "-o", str(tmp_path / "bad"), "--sensor", "20x16", "--quiet", *bad])
        assert res.exit_code == 2 and msg in res.output, (bad, res.output)


def test_detect_default_display_is_the_reports_primary(tmp_path, edge_events):
    from evedge.bench.methods import PRIMARY_DISPLAY
    from evedge.io.detection import read_detection

    ev, _ = edge_events(10, 10, 1000, 0.0)
    src = tmp_path / "events.txt"
    _write_ecd(src, ev)
    res = CliRunner().invoke(detect, [str(src), "-o", str(tmp_path / "o"), "--sensor", "10x10", "--quiet"])
    assert res.exit_code == 0, res.output
    assert read_detection(tmp_path / "o" / "detection.h5").metadata["display"] == PRIMARY_DISPLAY
    help_text = " ".join(CliRunner().invoke(detect, ["--help"]).output.split())
    assert "Default predecessor" in help_text and "primary display" in help_text


def test_detect_streams_chunks_with_the_library_result(tmp_path, edge_events, monkeypatch):
    """Chunked estimation + edge image in one pass (small chunks here) gives the library's bytes:
    detect()'s lifetimes and keep mask, edge_frames' maps; --no-png writes no PNG; --compress the same data;
    --tiles 2 (the buffer's passes at once, the estimator's strips, streamed in chunks) the same bytes."""
    import evedge.detector.cli as cli_mod
    from evedge.detector import edge_frames
    from evedge.io.detection import read_detection

    monkeypatch.setattr(cli_mod, "_CHUNK", 97)
    ev, _ = edge_events(24, 20, 700, 0.4, n_edges=3, spacing_px=7, subpixel_px=0.3, jitter_frac=0.05, rng=4)
    src = tmp_path / "events.txt"
    _write_ecd(src, ev)
    size = SensorSize(24, 20)
    times = [int(v) for v in np.linspace(int(ev["t"][0]) - 10, int(ev["t"][-1]) + 10, 9)]
    # the built-in estimator through plain columns; another (mueggler) through the records' path
    runs = [("intra", extra) for extra in ((), ("--no-png",), ("--compress",), ("--tiles", "2"),
                                           ("--tiles", "3", "--no-png"))] + [("mueggler", ("--no-png",))]
    wants = {}
    for method, extra in runs:
        if method not in wants:
            want = run_detect(ev, size, method=method)
            frames = edge_frames(ev[want.kept], want.lifetimes[want.kept], size, times, display="predecessor")
            assert want.lifetimes["valid"].sum() > 50 and frames.any()  # (not a vacuous comparison)
            wants[method] = want, frames
        want, want_frames = wants[method]
        out = tmp_path / (f"o_{method}" + "".join(extra))
        res = CliRunner().invoke(detect, [str(src), "-o", str(out), "--sensor", "24x20", "--quiet", "--times",
                                          ",".join(map(str, times)), "--method", method, *extra])
        assert res.exit_code == 0, res.output
        d = read_detection(out / "detection.h5")
        for name in ("lifetime_us", "vx_px_s", "vy_px_s", "valid"):
            assert d.lifetimes[name].tobytes() == want.lifetimes[name].tobytes(), name
        np.testing.assert_array_equal(d.lifetimes["kept"], want.kept)
        np.testing.assert_array_equal(d.edges.images, want_frames)
        assert (out / "edges").exists() == ("--no-png" not in extra)

def _index_entries(nbi) -> int:
    """Specialisations recorded in a numba cache index file (numba's own format: version, then (stamp, overloads))."""
    import pickle

    with open(nbi, "rb") as f:
        pickle.load(f)
        _, overloads = pickle.loads(f.read())
    return len(overloads)


def test_detect_cold_cache_compiles_the_estimator_ahead_once(tmp_path, edge_events):
    """Empty numba cache: the estimator's kernel is compiled by the child (this process loads it from the
    cache), each kernel has exactly one specialisation, and the output is the library's."""
    import subprocess
    import sys

    from evedge.io.detection import read_detection

    ev, _ = edge_events(20, 16, 400, 0.3, n_edges=2, spacing_px=8)
    src = tmp_path / "events.txt"
    _write_ecd(src, ev)
    cache = tmp_path / "numba_cache"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "NUMBA_DEBUG_CACHE": "1", "EVEDGE_COMPILE_AHEAD": "1"}
    proc = subprocess.run([sys.executable, "-m", "evedge.cli", "detect", str(src), "-o", str(tmp_path / "out"),
                           "--sensor", "20x16", "--times", "20000", "--quiet", "--no-png"],
                          env=env, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    log = proc.stdout + proc.stderr
    intra = [line for line in log.splitlines() if "_intra_stream" in line and "[cache]" in line]
    assert any("data loaded" in line for line in intra), intra  # compiled by the child, loaded here
    assert not any("data saved" in line for line in intra), intra
    indexes = sorted(cache.rglob("*.nbi"))
    for kernel in ("_intra_stream", "_edge_update", "_kept_columns", "_expand_columns"):  # (the plain path's too)
        assert any(kernel in p.name for p in indexes), kernel
    assert {p.name: _index_entries(p) for p in indexes} == {p.name: 1 for p in indexes}
    got = read_detection(tmp_path / "out" / "detection.h5")
    assert got.lifetimes["lifetime_us"].tobytes() == run_detect(ev, SensorSize(20, 16)).lifetimes["lifetime_us"].tobytes()


def test_compile_ahead_is_off_when_asked_or_unknown(monkeypatch):
    """No child with EVEDGE_COMPILE_AHEAD=0, for a method without known kernels, or with a warm cache."""
    from evedge.detector import _precompile
    from evedge.detector.pipeline import detect as run

    monkeypatch.setenv("EVEDGE_COMPILE_AHEAD", "0")
    assert _precompile.start("intra", _precompile.SAMPLE_SENSOR, {}) is None
    monkeypatch.setenv("EVEDGE_COMPILE_AHEAD", "1")
    assert not _precompile.is_cold("time") and _precompile.start("time", _precompile.SAMPLE_SENSOR, {}) is None
    ev = _precompile.sample_events(_precompile.SAMPLE_SENSOR)
    run(ev, _precompile.SAMPLE_SENSOR)  # compiled or loaded: the cache now holds the kernel
    assert not _precompile.is_cold("intra")
    assert _precompile.start("intra", _precompile.SAMPLE_SENSOR, {}) is None
