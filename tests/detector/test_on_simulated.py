"""Lifetime accuracy on simulated data with per-event ground truth (``evedge.sim``).

The simulated ``stripes`` (scenes/stripes.toml: 50 and 125 px/s, true lifetimes
20 ms and 8 ms) make about three events per pixel and edge passage
(log(0.75 / 0.25) = 1.1 for a contrast threshold of 0.3). Measured on the first
0.3 s (2026-11-23): the intra-pixel method (with the event buffer) gives a
median relative error of 2.1 % with an estimate for 97.3 % of the signal
events; with the paper's SAE (``burst_lifetimes = 0``) 22.5 % (97.4 %); the
Mueggler baseline 5.7 % (53.4 %).
"""

from pathlib import Path

import numpy as np
import pytest

from evedge.detector.intra import IntraParams
from evedge.detector.mueggler import estimate_lifetimes_mueggler
from evedge.detector.pipeline import detect

SCENES = Path(__file__).resolve().parents[2] / "scenes"


@pytest.fixture(scope="module")
def stripes():
    from evedge.sim import load_scene, simulate

    path = SCENES / "stripes.toml"
    if not path.exists():
        pytest.skip(f"scene file absent: {path}")
    return simulate(load_scene(path), duration_s=0.3, frame_rate_hz=0, progress=False)


def _error(lifetimes, truth):
    """(median |relative error|, share with an estimate) over the signal events."""
    sig = truth["is_signal"] & np.isfinite(truth["lifetime_us"]) & (truth["lifetime_us"] > 0)
    ok = lifetimes["valid"] & sig
    rel = np.abs(lifetimes["lifetime_us"][ok] / truth["lifetime_us"][ok] - 1.0)
    return float(np.median(rel)), ok.sum() / sig.sum()


def test_stripes_intra_beats_mueggler(stripes):
    ev, truth, size = stripes.events, stripes.truth, stripes.sensor_size
    assert ev.size > 50_000 and truth["is_signal"].mean() > 0.95
    intra_err, intra_share = _error(detect(ev, size).lifetimes, truth)
    mueg_err, mueg_share = _error(estimate_lifetimes_mueggler(ev, size), truth)
    assert intra_err < 0.05
    assert intra_err < mueg_err
    assert intra_share > 0.95
    assert mueg_share > 0.3  # the baseline gives estimates too (53 % measured): a fair comparison
    # the flow points along +x, as the stripes move
    lt = detect(ev, size).lifetimes
    v = lt["valid"] & truth["is_signal"]
    assert np.mean(np.abs(lt["vy_px_s"][v]) < 0.2 * lt["vx_px_s"][v]) > 0.9


def test_stripes_bursts_need_grouping(stripes):
    # the paper's SAE (newest event per pixel) underestimates multi-event edges
    ev, truth, size = stripes.events, stripes.truth, stripes.sensor_size
    lt0 = detect(ev, size, params=IntraParams(burst_lifetimes=0.0)).lifetimes
    err0, share0 = _error(lt0, truth)
    ok = lt0["valid"] & truth["is_signal"]
    assert err0 > 0.1 and share0 > 0.95
    assert np.median(lt0["lifetime_us"][ok] / truth["lifetime_us"][ok]) < 0.9  # too short, not noisy
