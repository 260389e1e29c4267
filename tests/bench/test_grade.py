"""evedge grade: an evedge detection file and the plain layouts give the same grade; mismatches are refused."""

import dataclasses

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from evedge.bench.cli import grade as grade_cmd
from evedge.bench.grade import GradeError, grade, grade_recording, load_detections
from evedge.bench.results import read_results
from evedge.detector.cli import detect as detect_cmd
from evedge.events import Recording
from evedge.io import write_recording
from evedge.io.detection import read_detection, write_detection


@pytest.fixture(scope="module")
def graded(tmp_path_factory, moving_edge):
    tmp = tmp_path_factory.mktemp("grade")
    truth = np.zeros(moving_edge.events.size, dtype=moving_edge.truth.dtype.descr + [("nx", "f8"), ("ny", "f8")])
    for name in moving_edge.truth.dtype.names:
        truth[name] = moving_edge.truth[name]
    truth["nx"], truth["ny"] = 1.0, 0.0
    rec = dataclasses.replace(moving_edge, truth=truth)
    data = write_recording(tmp / "edge.h5", rec)
    res = CliRunner().invoke(detect_cmd, [str(data), "-o", str(tmp / "det"), "--at-frames", "--quiet"])
    assert res.exit_code == 0, res.output
    out = tmp / "grade"
    res = CliRunner().invoke(grade_cmd, [str(data), "-d", str(tmp / "det" / "detection.h5"), "-o", str(out)])
    assert res.exit_code == 0, res.output
    return tmp, data, rec, out


def test_grade_of_an_evedge_detection(graded):
    tmp, data, rec, out = graded
    table = read_results(out / "grade.csv")
    det = read_detection(tmp / "det" / "detection.h5")
    # the lifetime error recomputed here from the file's columns and the truth
    tr = rec.truth["lifetime_us"]
    ok = rec.truth["is_signal"] & np.isfinite(tr)
    est = np.where(det.lifetimes["valid"], det.lifetimes["lifetime_us"], np.nan)
    err = np.abs(est[ok & np.isfinite(est)] / tr[ok & np.isfinite(est)] - 1)
    assert table.value(metric="median_rel_error", section="all") == pytest.approx(np.median(err))
    assert table.value(metric="share_estimated", section="all", reference="truth") == pytest.approx(
        np.isfinite(est[ok]).mean())
    assert set(table.unique("section")) >= {"slow", "fast", "all"}
    assert table.unique("method") == ["intra"] and table.unique("display") == ["predecessor"]
    for metric in ("median_angle_error_deg", "noise_recall", "median_cdm"):
        assert np.isfinite(table.value(metric=metric, section="all", **(
            {"reference": "exact"} if metric == "median_cdm" else {})))
    html = (out / "report.html").read_text()
    assert "proposed (intra-pixel-area)" in html and "median_rel_error" in html and "data:image/png" in html
    assert (out / "grade.h5").exists() and (out / "grade.png").exists()


def test_plain_layouts_grade_the_same(graded, tmp_path):
    tmp, data, rec, out = graded
    d = read_detection(tmp / "det" / "detection.h5")
    lt = np.where(d.lifetimes["valid"], d.lifetimes["lifetime_us"], np.nan)
    cols = {"lifetime_us": lt, "vx_px_s": d.lifetimes["vx_px_s"], "vy_px_s": d.lifetimes["vy_px_s"],
            "kept": d.lifetimes["kept"]}
    np.savez(tmp_path / "p.npz", **cols, edge_t_us=d.edges.t_us, edge_images=d.edges.images)
    with h5py.File(tmp_path / "p.h5", "w") as f:
        for k, v in cols.items():
            f[k] = v
        f["edges/t_us"], f["edges/images"] = d.edges.t_us, d.edges.images
    with open(tmp_path / "p.csv", "w") as f:
        f.write("lifetime_us,vx_px_s,vy_px_s,kept\n")
        for row in zip(*cols.values()):
            f.write(",".join(repr(float(v)) if i < 3 else str(int(v)) for i, v in enumerate(row)) + "\n")
    want = grade_recording(rec, load_detections(tmp / "det" / "detection.h5"), dataset="x")
    def key(t, drop_frames=False):
        return {(r["reference"], r["section"], r["metric"]): r["value"] for r in t.rows
                if not (drop_frames and r["reference"] in ("exact", "canny_matlab_0.3", ""))}
    for name in ("p.npz", "p.h5"):
        got = grade_recording(rec, load_detections(tmp_path / name, method="mine"), dataset="x")
        assert key(got) == pytest.approx(key(want), nan_ok=True)
        assert got.unique("method") == ["mine"]
    got = grade_recording(rec, load_detections(tmp_path / "p.csv"), dataset="x")  # no frames in CSV
    assert key(got, True) == pytest.approx(key(want, True), nan_ok=True) and got.unique("method") == ["p"]


def test_mismatching_detections_are_refused(graded, tmp_path):
    tmp, data, rec, out = graded
    d = read_detection(tmp / "det" / "detection.h5")
    moved = d.events.copy()
    moved["x"][17] = (moved["x"][17] + 1) % rec.sensor_size.width
    write_detection(tmp_path / "moved.h5", dataclasses.replace(d, events=moved))
    with pytest.raises(GradeError, match=r"event 17 differs \(field 'x'\)"):
        grade(data, tmp_path / "moved.h5", tmp_path / "o1")
    write_detection(tmp_path / "short.h5", dataclasses.replace(d, events=d.events[:-1], lifetimes=d.lifetimes[:-1]))
    with pytest.raises(GradeError, match=f"{d.events.size - 1} events vs {d.events.size}"):
        grade(data, tmp_path / "short.h5", tmp_path / "o2")
    other = write_recording(tmp_path / "other.h5", Recording(rec.events, rec.sensor_size, truth=rec.truth,
                                                            metadata={"other": 1}))
    digest_only = write_detection(tmp_path / "digest.h5", dataclasses.replace(d, events=None))
    with pytest.raises(GradeError, match="sha256"):
        grade(other, digest_only, tmp_path / "o3")
    np.savez(tmp_path / "few.npz", lifetime_us=np.ones(5))
    with pytest.raises(GradeError, match="column 'lifetime_us' has 5 rows"):
        grade(data, tmp_path / "few.npz", tmp_path / "o4")
    np.savez(tmp_path / "big.npz", edge_t_us=np.array([0]), edge_images=np.zeros((1, 3, 3), bool))
    with pytest.raises(GradeError, match="edge frames are 3x3"):
        grade(data, tmp_path / "big.npz", tmp_path / "o5")
    with pytest.raises(GradeError, match="is an evedge recording"):
        load_detections(data)
    (tmp_path / "bad.csv").write_text("lifetime_us,colour\n1,red\n")
    with pytest.raises(GradeError, match="header must name columns"):
        load_detections(tmp_path / "bad.csv")
    res = CliRunner().invoke(grade_cmd, [str(data), "-d", str(tmp_path / "moved.h5"), "-o", str(tmp_path / "o6")])
    assert res.exit_code == 1 and "event 17 differs" in res.output and "Traceback" not in res.output
    assert not (tmp_path / "o6" / "grade.csv").exists()
