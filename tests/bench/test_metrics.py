"""Each registered metric against hand-computed answers; the results table round trip."""

import math

import numpy as np
import pytest

from evedge.bench.metrics import METRICS, GradeInput
from evedge.bench.results import ResultsTable, read_results
from evedge.events import Frames, SensorSize, make_events

TRUTH = np.dtype([("vx_px_s", float), ("vy_px_s", float), ("nx", float), ("ny", float), ("lifetime_us", float),
                  ("is_signal", bool)])


def _inp(n, **kw):
    ev = make_events(np.arange(n) % 4, np.zeros(n), np.arange(n) * 100, np.ones(n, bool))
    sections = kw.pop("sections", {"all": (0, 10**9)})
    return GradeInput(ev, SensorSize(4, 1), sections, **kw)


def _rows(name, inp):
    return {(r["reference"], r["section"], r["metric"]): r["value"] for r in METRICS.get(name).factory(inp)}


def test_lifetime_error_known_answer():
    truth = np.zeros(6, TRUTH)
    truth["lifetime_us"] = [10_000, 10_000, 10_000, 10_000, np.inf, 5_000]
    truth["is_signal"] = [True, True, True, True, True, False]  # the last is noise: left out
    est = np.array([11_000, 9_000, 20_000, np.nan, 3_000, 5_000.0])
    # sections: the first two events (t = 0, 100) are "early"
    got = _rows("lifetime_error", _inp(6, truth=truth, lifetime_us=est,
                                       sections={"early": (0, 150), "all": (0, 10**9)}))
    # usable: events 0-3 (finite truth, signal); errors 0.1, 0.1, 1.0; event 3 unestimated
    assert got[("truth", "all", "median_rel_error")] == pytest.approx(0.1)
    assert got[("truth", "all", "p90_rel_error")] == pytest.approx(0.1 + 0.8 * 0.9)  # numpy linear quantile
    assert got[("truth", "all", "share_estimated")] == pytest.approx(0.75)
    assert got[("truth", "all", "n_events")] == 4
    assert got[("truth", "early", "median_rel_error")] == pytest.approx(0.1)
    assert got[("truth", "early", "share_estimated")] == 1.0
    assert _rows("lifetime_error", _inp(6, lifetime_us=est)) == {}  # no truth: no rows
    # speed bands: truth 10 ms = 100 px/s, in the band 100-200 px/s with all four usable events
    assert got[("truth", "speed 100-200 px/s", "n_events")] == 4
    assert got[("truth", "speed 100-200 px/s", "median_rel_error")] == pytest.approx(0.1)
    assert not any(k[1].startswith("speed 50-100") for k in got)  # empty bands give no rows


def test_normal_flow_error_known_answer():
    truth = np.zeros(3, TRUTH)
    # flow (100, 100) px/s, normal (1, 0): true normal flow (100, 0)
    truth["vx_px_s"], truth["vy_px_s"], truth["nx"], truth["ny"] = 100.0, 100.0, 1.0, 0.0
    truth["is_signal"] = True
    vx = np.array([100.0, 0.0, np.nan])   # exact; 90 degrees off with magnitude 200 (error 1.0); none
    vy = np.array([0.0, 200.0, np.nan])
    got = _rows("normal_flow_error", _inp(3, truth=truth, vx_px_s=vx, vy_px_s=vy))
    assert got[("truth_flow", "all", "median_angle_error_deg")] == pytest.approx(45.0)  # median of 0 and 90
    assert got[("truth_flow", "all", "median_rel_magnitude_error")] == pytest.approx(0.5)  # median of 0 and 1
    assert got[("truth_flow", "all", "share_estimated")] == pytest.approx(2 / 3)
    # a flow pointing backwards is 180 degrees off
    got = _rows("normal_flow_error", _inp(1, truth=truth[:1], vx_px_s=np.array([-100.0]), vy_px_s=np.array([0.0])))
    assert got[("truth_flow", "all", "median_angle_error_deg")] == pytest.approx(180.0)


def test_noise_filter_known_answer():
    truth = np.zeros(6, TRUTH)
    truth["is_signal"] = [True, True, True, False, False, False]
    kept = np.array([True, True, False, False, False, True])
    got = _rows("noise_filter", _inp(6, truth=truth, kept=kept))
    # removed: events 2 (signal), 3, 4 (noise) -> precision 2/3; noise 3, 4, 5 -> recall 2/3; signal kept 2/3
    assert got[("noise_labels", "all", "noise_precision")] == pytest.approx(2 / 3)
    assert got[("noise_labels", "all", "noise_recall")] == pytest.approx(2 / 3)
    assert got[("noise_labels", "all", "signal_kept")] == pytest.approx(2 / 3)
    none_removed = _rows("noise_filter", _inp(6, truth=truth, kept=np.ones(6, bool)))
    assert math.isnan(none_removed[("noise_labels", "all", "noise_precision")])  # 0/0 is undefined, not 0
    assert none_removed[("noise_labels", "all", "noise_recall")] == 0.0


def test_cdm_frames_known_answer():
    """A vertical line shifted by one pixel scores exactly 95 against the exact edges (see bench/cdm.py)."""
    size = SensorSize(8, 6)
    exact = np.zeros((2, 6, 8), bool)
    exact[:, :, 3] = True
    det = np.zeros((3, 6, 8), bool)
    det[0, :, 3] = True   # identical: 100
    det[1, :, 4] = True   # shifted by 1: 95
    inp = _inp(4, edge_t_us=np.array([1000, 2000, 2500]), edge_images=det,
               exact_edges=Frames([1000, 2000], exact), sections={"all": (0, 10**9)})
    inp.sensor_size = size
    got = _rows("cdm", inp)
    assert got[("exact", "frame_0", "cdm")] == 100.0
    assert got[("exact", "frame_1", "cdm")] == pytest.approx(95.0)
    assert got[("exact", "all", "median_cdm")] == pytest.approx(97.5)
    assert got[("exact", "all", "n_frames")] == 2
    assert got[("", "all", "frames_without_reference")] == 1  # no exact map at 2500 us


def test_results_table_round_trip(tmp_path):
    t = ResultsTable()
    t.add(experiment="e", dataset="d", reference="exact", method="intra", display="predecessor", section="slow",
          metric="median_cdm", value=88.123456789)
    t.add(experiment="e", method="time", variant="acc_1ms", metric="median_cdm", value=None)
    csv_path, h5_path = t.save(tmp_path / "r")
    for p in (csv_path, h5_path):
        back = read_results(p)
        assert back.rows[0] == t.rows[0]
        assert back.rows[1]["variant"] == "acc_1ms" and math.isnan(back.rows[1]["value"])
    assert t.value(method="intra", section="slow") == 88.123456789
    assert t.rows[0]["variant"] == "intra"  # defaults to the method
    with pytest.raises(ValueError, match="unknown column"):
        t.add(experiment="e", method="m", metric="x", value=1, colour="red")
    with pytest.raises(ValueError, match="'metric' is required"):
        t.add(experiment="e", method="m", value=1)
    with pytest.raises(ValueError, match="must be a number"):
        t.add(experiment="e", method="m", metric="x", value="high")
    bad = tmp_path / "bad.csv"
    bad.write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match="bad.csv: header"):
        read_results(bad)
