"""The robustness grid (bench.robustness): figures against hand-counted answers, Dask = serial, same seed = same row."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from evedge.bench.robustness import CellTask, _signal_distance, build, cells, run_cell, run_grid, score, tasks
from evedge.detector.intra import noise_params
from evedge.detector.result import empty_lifetimes
from evedge.events import make_events

TRUTH = [("is_signal", bool), ("lifetime_us", float)]


def _rec(x, t, p, signal, lifetime):
    ev = make_events(np.asarray(x), np.zeros(len(x)), np.asarray(t), np.asarray(p, bool))
    return SimpleNamespace(events=ev, truth=np.array(list(zip(signal, lifetime)), dtype=TRUTH))


def test_signal_distance_counts_same_pixel_same_polarity_signal_only():
    rec = _rec(x=[0, 0, 0, 1, 0], t=[0, 1000, 1400, 1500, 5000], p=[1, 0, 1, 1, 1],
               signal=[True, True, False, False, False], lifetime=[2000.0, 1000.0, np.nan, np.nan, np.nan])
    d = _signal_distance(rec.events, rec.truth)
    # event 2: 1400 us after the signal event 0 (same pixel, same polarity, lifetime 2000): 0.7;
    # event 1 has the other polarity; event 3 another pixel (no signal there); event 4: 5000 / 2000
    np.testing.assert_allclose(d, [0.0, 0.0, 0.7, math.inf, 2.5])


def test_signal_distance_predicts_the_passage_from_a_neighbour():
    """A signal event at x=0, t=0, flow +1000 px/s (lifetime 1000 us): the edge reaches x=1 at 1000 us, x=2 never
    (not a neighbour); a noise event at x=1, 1300 us, is 0.3 lifetimes off; at x=1, 3000 us, 2 lifetimes."""
    ev = make_events(np.array([0, 1, 1, 2]), np.zeros(4), np.array([0, 1300, 3000, 1500]), np.ones(4, bool))
    dtype = [("is_signal", bool), ("lifetime_us", float), ("vx_px_s", float), ("vy_px_s", float)]
    truth = np.array([(True, 1000.0, 1000.0, 0.0)] + [(False, np.nan, np.nan, np.nan)] * 3, dtype=dtype)
    np.testing.assert_allclose(_signal_distance(ev, truth), [0.0, 0.3, 2.0, math.inf])
    # after the passage only: the event at x=1, 1300 us, is 0.3 lifetimes after the edge reached x=1; one at 700 us
    # (before it) is 0.3 lifetimes off both ways, but no passage precedes it
    ev2 = make_events(np.array([0, 1, 1]), np.zeros(3), np.array([0, 1300, 700]), np.ones(3, bool))
    truth2 = truth[:3]
    np.testing.assert_allclose(_signal_distance(ev2, truth2, after_only=True), [0.0, 0.3, math.inf])
    np.testing.assert_allclose(_signal_distance(ev2, truth2), [0.0, 0.3, 0.3])


def test_score_known_answer():
    # steady state from 100 ms after the first event; signal: 4 steady events, 3 estimated (ratios 1.1, 3, 0.9)
    rec = _rec(x=[0, 1, 2, 3, 4, 1, 5], t=[0, 150_000, 150_010, 150_020, 150_030, 150_400, 160_000],
               p=[1] * 7, signal=[True, True, True, True, True, False, False], lifetime=[1000.0] * 5 + [np.nan] * 2)
    lt = empty_lifetimes(7)
    lt["valid"] = [True, True, True, True, False, True, False]
    lt["lifetime_us"] = [500.0, 1100.0, 3000.0, 900.0, np.nan, 700.0, np.nan]
    s = score(rec, lt)
    assert s["med"] == pytest.approx(0.1)  # |ratio - 1| = 0.1, 2, 0.1
    assert s["over2x"] == pytest.approx(1 / 3)
    assert s["sig"] == pytest.approx(3 / 4)
    assert s["noise"] == pytest.approx(1 / 2)
    assert s["noise_floor"] == pytest.approx(1 / 2)  # the noise event at x=1, 0.4 lifetimes after the signal
    assert s["noise_in_floor"] == 1.0 and s["noise_off_floor"] == 0.0  # that one estimated, the one at x=5 not
    assert s["noise_after"] == pytest.approx(1 / 2) and s["noise_in_after"] == 1.0  # it fired after the passage
    assert s["first"] == pytest.approx(0.5)
    assert (s["n_signal"], s["n_noise"]) == (4, 2)


def test_grid_cells_and_unknown_kind():
    assert len(cells(quick=True)) == 72 and len(cells(quick=False)) == 210
    with pytest.raises(ValueError, match="unknown cell kind 'cubes'"):
        build("cubes", 32, 24, 1)


GRID = [("stripes", dict(angle_deg=20, speed=200, r=3.0, noise_hz=2.0)),
        ("shapes", dict(speed=100.0, r=5.0, noise_hz=0.0)),
        ("stripes", dict(angle_deg=0, speed=2000, r=1.3, noise_hz=5.0))]
# the noise preset (the option types numba compiles for the other tests too), not one of its rules alone
METHODS = (("intra", "intra", noise_params()), ("mueggler", "mueggler", None))


def _strip_cpu(rows):
    """The rows without their CPU times (which depend on the machine), NaN comparable to NaN."""
    return [{k: "nan" if isinstance(v, float) and math.isnan(v) else v for k, v in r.items()
             if not k.endswith("cpu_s")} for r in rows]


def test_dask_rows_equal_serial_rows_and_same_seed_same_row():
    ts = tasks(GRID, 32, 24, 3, METHODS)
    serial, fail_s = run_grid(ts, workers=0, progress=False)
    dask, fail_d = run_grid(ts, workers=2, progress=False)
    assert not fail_s and not fail_d
    assert _strip_cpu(dask) == _strip_cpu(serial)
    assert _strip_cpu([run_cell(ts[0])]) == _strip_cpu(serial[:1])
    assert serial[0]["intra_n_noise"] > 0 and 0 <= serial[0]["intra_noise"] <= 1
    assert serial[0]["intra_noise_floor"] == serial[0]["mueggler_noise_floor"]  # a property of the cell


def test_a_failing_cell_is_reported_and_the_others_run():
    ts = tasks(GRID[:1], 32, 24, 3, METHODS[:1]) + [CellTask("cubes", (), 32, 24, 3, METHODS[:1])]
    rows, failures = run_grid(ts, workers=0, progress=False)
    assert len(rows) == 1 and len(failures) == 1
    assert failures[0][0].kind == "cubes" and "unknown cell kind" in str(failures[0][1])


def test_buffer_parameters_reach_the_proposed_detector():
    from evedge.detector.buffer import BufferParams

    cell = GRID[:1]
    paper = run_cell(tasks(cell, 32, 24, 3, [("intra", "intra", None)])[0])
    same = run_cell(tasks(cell, 32, 24, 3, [("intra", "intra", None, BufferParams())])[0])
    longer = run_cell(tasks(cell, 32, 24, 3, [("intra", "intra", None, BufferParams(tau_min_us=50_000))])[0])
    assert _strip_cpu([same]) == _strip_cpu([paper])
    assert longer["intra_noise"] > paper["intra_noise"]  # a longer support window lets more noise through
