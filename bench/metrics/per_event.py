"""Per-event metrics: lifetime error, normal-flow error, noise-filter precision/recall.

Each is registered in :data:`evedge.bench.metrics.METRICS` and tested against
hand-computed answers (``tests/bench/test_metrics.py``).
"""

from __future__ import annotations

import numpy as np

from . import METRICS, GradeInput, section_masks


def _signal_truth(inp: GradeInput, field: str) -> np.ndarray | None:
    if inp.truth is None or field not in (inp.truth.dtype.names or ()):
        return None
    value = np.asarray(inp.truth[field], dtype=np.float64)
    if "is_signal" in inp.truth.dtype.names:
        value = np.where(inp.truth["is_signal"], value, np.nan)
    return value


#: Bands of true normal speed (px/s, ``1e6 / lifetime``) the lifetime error is also given in.
SPEED_BANDS_PX_S = (0.0, 50.0, 100.0, 200.0, 400.0, 800.0, float("inf"))


def _speed_bands(truth_lifetime_us: np.ndarray) -> dict[str, np.ndarray]:
    speed = 1e6 / truth_lifetime_us
    out = {}
    for lo, hi in zip(SPEED_BANDS_PX_S[:-1], SPEED_BANDS_PX_S[1:]):
        sel = (speed >= lo) & (speed < hi)
        if sel.any():
            out[f"speed {lo:g}-{hi:g} px/s"] = sel
    return out


def lifetime_error(inp: GradeInput) -> list[dict]:
    """Relative lifetime error on the signal events with a finite true lifetime, per section and speed band.

    ``median_rel_error`` and ``p90_rel_error`` of ``|est / truth - 1|`` over the
    events with an estimate; ``share_estimated``: events with an estimate over
    all such events; ``n_events``: how many such events. Sections: the scene's
    time sections (``slow``, ``fast``, ``all``) and bands of the true normal
    speed ``1e6 / lifetime`` (:data:`SPEED_BANDS_PX_S`, e.g. ``speed 50-100 px/s``).

    Examples
    --------
    Truth 10 ms for four events; estimates 11, 9, 20 ms and none: errors 0.1,
    0.1, 1.0, median 0.1, 3 of 4 estimated.
    """
    truth = _signal_truth(inp, "lifetime_us")
    if truth is None or inp.lifetime_us is None:
        return []
    est = np.asarray(inp.lifetime_us, dtype=np.float64)
    usable = np.isfinite(truth) & (truth > 0)
    rows = []
    groups = dict(section_masks(inp.events["t"], inp.sections))
    with np.errstate(divide="ignore", invalid="ignore"):
        groups.update(_speed_bands(np.where(usable, truth, np.nan)))
    for name, sel in groups.items():
        base = sel & usable
        n = int(base.sum())
        ok = base & np.isfinite(est) & (est > 0)
        err = np.abs(est[ok] / truth[ok] - 1.0)
        for metric, value in (("median_rel_error", np.median(err) if err.size else np.nan),
                              ("p90_rel_error", np.quantile(err, 0.9) if err.size else np.nan),
                              ("share_estimated", ok.sum() / n if n else np.nan),
                              ("n_events", n)):
            rows.append({"reference": "truth", "section": name, "metric": metric, "value": float(value)})
    return rows


def normal_flow_error(inp: GradeInput) -> list[dict]:
    """Angle (degrees) and relative magnitude error of the estimated normal flow, per section.

    The true normal flow is the flow's component along the brightness
    gradient, ``(v . n) n``; the estimate is ``(vx_px_s, vy_px_s)``. Over the
    signal events with a non-zero true normal flow and a finite estimate:
    ``median_angle_error_deg`` (the angle between the two vectors, 0..180),
    ``median_rel_magnitude_error`` (``| |est| / |true| - 1 |``) and
    ``share_estimated``.
    """
    if inp.vx_px_s is None or inp.vy_px_s is None:
        return []
    vx, vy, nx, ny = (_signal_truth(inp, f) for f in ("vx_px_s", "vy_px_s", "nx", "ny"))
    if any(a is None for a in (vx, vy, nx, ny)):
        return []
    dot = vx * nx + vy * ny
    tx, ty = dot * nx, dot * ny
    tmag = np.hypot(tx, ty)
    ex, ey = np.asarray(inp.vx_px_s, np.float64), np.asarray(inp.vy_px_s, np.float64)
    emag = np.hypot(ex, ey)
    usable = np.isfinite(tmag) & (tmag > 0)
    rows = []
    for name, sel in section_masks(inp.events["t"], inp.sections).items():
        base = sel & usable
        n = int(base.sum())
        ok = base & np.isfinite(emag) & (emag > 0)
        cos = np.clip((ex[ok] * tx[ok] + ey[ok] * ty[ok]) / (emag[ok] * tmag[ok]), -1.0, 1.0)
        angle = np.degrees(np.arccos(cos))
        mag = np.abs(emag[ok] / tmag[ok] - 1.0)
        for metric, value in (("median_angle_error_deg", np.median(angle) if angle.size else np.nan),
                              ("median_rel_magnitude_error", np.median(mag) if mag.size else np.nan),
                              ("share_estimated", ok.sum() / n if n else np.nan)):
            rows.append({"reference": "truth_flow", "section": name, "metric": metric, "value": float(value)})
    return rows


def noise_filter(inp: GradeInput) -> list[dict]:
    """The filter's removed events against the simulator's noise labels, per section.

    Noise is the positive class: ``noise_precision`` = removed noise / removed,
    ``noise_recall`` = removed noise / noise, ``signal_kept`` = kept signal / signal.
    """
    if inp.kept is None or inp.truth is None or "is_signal" not in (inp.truth.dtype.names or ()):
        return []
    kept = np.asarray(inp.kept, dtype=bool)
    signal = np.asarray(inp.truth["is_signal"], dtype=bool)
    rows = []
    for name, sel in section_masks(inp.events["t"], inp.sections).items():
        removed = sel & ~kept
        noise = sel & ~signal
        sig = sel & signal
        tp = int((removed & noise).sum())
        for metric, num, den in (("noise_precision", tp, int(removed.sum())), ("noise_recall", tp, int(noise.sum())),
                                 ("signal_kept", int((kept & sig).sum()), int(sig.sum()))):
            rows.append({"reference": "noise_labels", "section": name, "metric": metric,
                         "value": num / den if den else np.nan})
    return rows


METRICS.register("lifetime_error", lifetime_error, kind="per_event", display_name="lifetime error")
METRICS.register("normal_flow_error", normal_flow_error, kind="per_event", display_name="normal-flow error")
METRICS.register("noise_filter", noise_filter, kind="per_event", display_name="noise filter vs noise labels")
