"""Sweeps: a 2-worker LocalCluster makes and grades 4 tiny sequences; parallel = serial grades; resume."""

import csv
import math
import subprocess
import sys
import time

import numpy as np
import pytest

from evedge.bench.cdm import cdm
from evedge.bench.methods import METHODS, edge_maps
from evedge.bench.results import read_results
from evedge.bench.sweep import GradeTask, grade_sequence, load_sweep, parse_sweep, run_sweep
from evedge.io import read_hdf5
from evedge.parallel import dask_client
from evedge.sim.dataset import DatasetError
from evedge.sim.dataset_run import read_manifest

SPEC = {
    "dataset": {"name": "tiny", "seed": 4, "count": 4},
    "parameters": {"family": {"choice": ["stripes", "shapes"]}, "sensor": "32x24", "duration_s": 0.04,
                   "frame_rate_hz": 100, "speed_px_s": {"log_uniform": [80, 240]},
                   "noise_rate_hz": {"choice": [0, 2]}, "shape_radius_px": 5, "shape_count": 2},
    "sweep": {"warmup_s": 0.02},
}


@pytest.fixture(scope="module")
def client():
    with dask_client(workers=2) as c:
        yield c
    import psutil

    deadline = time.monotonic() + 10
    while True:
        left = []
        for p in psutil.Process().children(recursive=True):
            try:
                if "resource_tracker" not in " ".join(p.cmdline()):
                    left.append(p)
            except psutil.NoSuchProcess:
                pass
        if not left or time.monotonic() > deadline:
            break
        time.sleep(0.1)
    assert left == [], "the cluster left worker processes behind"


@pytest.fixture(scope="module")
def swept(client, tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep")
    res = run_sweep(parse_sweep(SPEC, "tiny.toml"), out, client=client, progress=False)
    return out, res


def _all(table, **where):
    return table.query(section="all", **where)


def test_sweep_grades_every_sequence_and_method(swept):
    out, res = swept
    assert res["graded"] == 4 and res["failed"] == {} and res["reused"] == 0
    table = read_results(out / "results.csv")
    assert len(read_results(out / "results.h5")) == len(table) == res["rows"]
    assert set(table.unique("experiment")) == {"sweep"}
    assert table.unique("dataset") == [f"seq_{i:05d}" for i in range(4)]
    cdm_rows = _all(table, metric="median_cdm", reference="exact")
    assert len(cdm_rows) == 4 * len(METHODS)
    assert {r["variant"] for r in cdm_rows} == set(METHODS)
    assert all(0 <= r["value"] <= 100 for r in cdm_rows)
    assert {r["display"] for r in cdm_rows if r["variant"] == "proposed_noclear"} == {"lifetime_only"}
    assert {r["method"] for r in cdm_rows if r["variant"].startswith("acc_")} == {"time", "count"}
    # per-event metrics once per lifetime method, not once per display policy
    lt = _all(table, metric="median_rel_error", reference="truth")
    assert {(r["method"], r["variant"]) for r in lt} == {("intra", "proposed"), ("mueggler", "mueggler")}
    assert len(lt) == 8 and all(0 <= r["value"] < 10 for r in lt)
    est = [r["value"] for r in _all(table, metric="share_estimated")]
    assert est and all(0 <= v <= 1 for v in est)
    # parameters per sequence, joined on the dataset column, are those the manifest drew
    manifest = {r["name"]: r for r in read_manifest(out / "dataset").values()}
    with open(out / "sequences.csv", newline="") as f:
        seqs = list(csv.DictReader(f))
    assert [s["dataset"] for s in seqs] == sorted(manifest)
    for s in seqs:
        assert float(s["speed_px_s"]) == manifest[s["dataset"]]["params"]["speed_px_s"]
    report = (out / "report.md").read_text()
    for fig in res["figures"]:
        assert fig.stat().st_size > 1000 and fig.name in report
    assert {f.name for f in res["figures"]} == {"sweep_median_cdm.png", "sweep_median_rel_error.png",
                                                "sweep_share_estimated.png"}


def test_parallel_grades_equal_a_direct_serial_computation(swept, tmp_path):
    out, _ = swept
    table = read_results(out / "results.csv")
    path = out / "dataset" / "sequences" / "seq_00001.h5"
    rec = read_hdf5(path)
    sel = rec.edges.t_us >= 20_000
    times, truth = rec.edges.t_us[sel], rec.edges.images[sel]
    n = int(round(truth.reshape(truth.shape[0], -1).sum(axis=1).mean()))
    maps, runs = edge_maps(rec.events, rec.sensor_size, times, methods=("proposed", "acc_30ms", "acc_count"),
                           count_n=max(1, n))
    inside = times <= rec.events["t"][-1]  # section 'all' ends with the last event
    assert inside.sum() >= 1
    for m in ("proposed", "acc_30ms", "acc_count"):
        expected = np.median([cdm(maps[m][k], truth[k]) for k in np.flatnonzero(inside)])
        got = table.value(dataset="seq_00001", variant=m, metric="median_cdm", reference="exact", section="all")
        assert got == pytest.approx(expected, rel=1e-12, abs=1e-12)
    # lifetime error of the proposed method from its own run and the truth
    run = runs["proposed"]
    tr = rec.truth[run.kept]
    ok = tr["is_signal"] & run.lifetimes["valid"] & (tr["lifetime_us"] > 0)
    err = np.abs(run.lifetimes["lifetime_us"][ok] / tr["lifetime_us"][ok] - 1)
    got = table.value(dataset="seq_00001", variant="proposed", metric="median_rel_error", section="all")
    assert got == pytest.approx(np.median(err), rel=1e-12)
    # and the task itself, run here, gives the worker's rows
    serial = grade_sequence(GradeTask(str(path), "seq_00001", "x", tuple(METHODS), 0.02, 0, str(tmp_path / "g.json")))
    mine = [r for r in table if r["dataset"] == "seq_00001"]
    assert len(serial["rows"]) == len(mine)
    for a, b in zip(serial["rows"], mine):
        assert {k: v for k, v in a.items() if k != "value"} == {k: v for k, v in b.items() if k != "value"}
        assert (math.isnan(a["value"]) and math.isnan(b["value"])) or a["value"] == pytest.approx(b["value"],
                                                                                                  rel=1e-12)


def test_rerun_reuses_grades_and_regrades_a_remade_sequence(swept, client):
    out, _ = swept
    before = (out / "results.csv").read_bytes()
    res = run_sweep(parse_sweep(SPEC, "tiny.toml"), out, client=client, progress=False)
    assert (res["graded"], res["reused"]) == (4, 4)
    (out / "dataset" / "sequences" / "seq_00002.h5").unlink()
    res = run_sweep(parse_sweep(SPEC, "tiny.toml"), out, client=client, progress=False)
    # the sequence is remade with the same bytes, so its sha256 and hence its grades are reused
    assert (res["graded"], res["reused"]) == (4, 4)
    assert (out / "results.csv").read_bytes() == before
    # other methods: every grade is redone
    other = dict(SPEC, sweep={"warmup_s": 0.02, "methods": ["acc_1ms"]})
    res = run_sweep(parse_sweep(other, "tiny.toml"), out, client=client, progress=False)
    assert (res["graded"], res["reused"]) == (4, 0)
    assert read_results(out / "results.csv").unique("variant") == ["acc_1ms"]


@pytest.mark.parametrize("sweep,key,problem", [
    ({"methods": ["proposed", "canny"]}, "sweep.methods[1]", "unknown method 'canny'"),
    ({"methods": ["time"]}, "sweep.methods[0]", "compared as ['acc_1ms', 'acc_30ms']"),
    ({"canny_settings": 9}, "sweep.canny_settings", "must be <= 3"),
    ({"methods": []}, "sweep.methods", "non-empty"),
    ({"warmup_s": -1}, "sweep.warmup_s", "must be >= 0"),
    ({"warmup": 1}, "sweep.warmup", "unknown key"),
])
def test_sweep_errors_name_the_key(sweep, key, problem):
    with pytest.raises(DatasetError) as err:
        parse_sweep(dict(SPEC, sweep=sweep), "s.toml")
    assert str(err.value).startswith(f"s.toml: key '{key}': ") and problem in str(err.value)


def test_a_sweep_needs_edge_maps():
    data = dict(SPEC, parameters=dict(SPEC["parameters"], frame_rate_hz=0))
    with pytest.raises(DatasetError, match="key 'parameters.frame_rate_hz': a sweep grades edge maps"):
        parse_sweep(data, "s.toml")


def test_the_shipped_dataset_spec_is_a_sweep_spec():
    from pathlib import Path

    s = load_sweep(Path(__file__).resolve().parents[2] / "scenes" / "datasets" / "small.toml")
    assert s.methods == tuple(METHODS) and s.dataset.count == 6


def test_sweep_command_reports_a_bad_spec_without_traceback(tmp_path):
    from click.testing import CliRunner

    from evedge.cli import main

    bad = tmp_path / "bad.toml"
    bad.write_text('[dataset]\ncount = 2\n[sweep]\nmethods = ["proposed", "nope"]\n')
    res = CliRunner().invoke(main, ["bench", "sweep", str(bad), "-o", str(tmp_path / "o")])
    assert res.exit_code == 1
    assert "key 'sweep.methods[1]': unknown method 'nope'" in res.output
    assert res.exception is None or isinstance(res.exception, SystemExit)
    assert not (tmp_path / "o").exists()


def test_sweep_refuses_a_folder_that_is_not_an_earlier_sweep(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    proc = subprocess.run([sys.executable, "-m", "evedge.cli", "bench", "sweep", "small", "-o", str(out),
                           "--no-progress"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "is not an earlier sweep output" in proc.stderr and "Traceback" not in proc.stderr
    assert [p.name for p in out.iterdir()] == ["notes.txt"]
