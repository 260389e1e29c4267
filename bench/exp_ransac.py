"""Experiment 1: RANSAC inlier decision and lifetime error on synthetic windows (paper fig. 7).

One straight edge crosses a 5 x 5 window of the Surface of Active Events. The
current event sits at the centre (local coordinates (0, 0), time ``t_e``); the
edge moves along its unit normal ``n = (cos theta, sin theta)`` (theta uniform
in [0, 2 pi)) at ``1 / tau`` px per microsecond, so pixel ``p`` (offset from
the centre) fired at ``t_e + tau (n . p)``. Pixels ahead of the edge
(``n . p > 0``) have not fired yet: NaN ("never fired").

Noise, standard deviation ``sigma = s * tau`` (``s`` = noise level, in pixels
of edge travel, the x-axis of the figures):

* ``global`` (fig. 7a): Gaussian noise on every fired past pixel;
* ``scattered`` (fig. 7b): Gaussian noise on ``n_scattered`` (3) fired past
  pixels drawn at random.

The current event is exact (it defines the plane's anchor). A noisy timestamp
is clipped to ``t_e``: in an SAE no past event is newer than the current one.

Truth of the inlier decision: a fired past pixel is a *true inlier* when its
timestamp is within ``truth_tol_px * tau`` of the true plane (default 0.25 px
of edge travel, i.e. the edge passed within a quarter pixel of where the
timestamp puts it), otherwise a true outlier. The predicted inliers are
RANSAC's final inlier set (points dropped by the 2-means split count as
outliers). F-measure (paper eq. 5) over the fired past pixels, the centre
excluded; averaged over the repetitions. A fit that fails (``ok`` False)
predicts no inliers.

Lifetime error: ``|tau_est - tau| / tau`` over the repetitions whose fit
succeeded (mean and median reported), plus the success rate.

Methods: without intra-pixel-area events (``use_intra=False``) and with them
for each ``delta`` in ``deltas``. All methods see the same windows and the same
RANSAC seeds (paired comparison).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from ._files import relative_figures, save_figure, write_csv_atomic, write_json_atomic
from ._plot import pyplot
from .stats import f_measure

NOISE_KINDS = ("global", "scattered")


@dataclass(frozen=True)
class RansacStudyParams:
    """Parameters of the RANSAC study (see the module docstring).

    Attributes
    ----------
    window_px : int
        Window size N (paper: 5).
    lifetime_us : float
        True lifetime tau of the edge (5 ms: 200 px/s).
    noise_levels_px : tuple of float
        Noise standard deviations in units of tau (pixels of edge travel).
    deltas_px : tuple of float
        Intra-pixel half-sizes delta compared (paper: 0, 0.1, 0.25, 0.4, 0.5).
    repetitions : int
        Windows per noise level (paper: 1000).
    n_scattered : int
        Pixels perturbed in the scattered-noise case.
    truth_tol_px : float
        Tolerance (units of tau) within which a perturbed pixel is still a true inlier.
    seed : int
    """

    window_px: int = 5
    lifetime_us: float = 5000.0
    noise_levels_px: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.75, 1.0)
    deltas_px: tuple[float, ...] = (0.0, 0.1, 0.25, 0.4, 0.5)
    repetitions: int = 1000
    n_scattered: int = 3
    truth_tol_px: float = 0.25
    seed: int = 0

    def __post_init__(self) -> None:
        if self.window_px < 3 or self.window_px % 2 == 0:
            raise ValueError(f"RansacStudyParams.window_px must be odd and >= 3, got {self.window_px}")
        if not self.lifetime_us > 0:
            raise ValueError(f"RansacStudyParams.lifetime_us must be > 0, got {self.lifetime_us}")
        if len(self.noise_levels_px) == 0 or min(self.noise_levels_px) < 0:
            raise ValueError("RansacStudyParams.noise_levels_px must be non-empty and >= 0")
        if len(self.deltas_px) == 0 or min(self.deltas_px) < 0 or max(self.deltas_px) > 0.5:
            raise ValueError("RansacStudyParams.deltas_px must be non-empty, within [0, 0.5]")
        if self.repetitions < 1:
            raise ValueError(f"RansacStudyParams.repetitions must be >= 1, got {self.repetitions}")
        if self.n_scattered < 1:
            raise ValueError(f"RansacStudyParams.n_scattered must be >= 1, got {self.n_scattered}")
        if not self.truth_tol_px >= 0:
            raise ValueError(f"RansacStudyParams.truth_tol_px must be >= 0, got {self.truth_tol_px}")
        object.__setattr__(self, "noise_levels_px", tuple(float(v) for v in self.noise_levels_px))
        object.__setattr__(self, "deltas_px", tuple(float(v) for v in self.deltas_px))


@dataclass
class SyntheticWindow:
    """One synthetic window: noisy timestamps and the truth."""

    t_us: np.ndarray          # (N, N) float, NaN = never fired
    true_inlier: np.ndarray   # (N, N) bool over fired past pixels (centre False)
    fired_past: np.ndarray    # (N, N) bool: fired and not the centre
    deviation_us: np.ndarray  # (N, N) |t - t_true| (0 where not fired)
    theta: float = field(default=0.0)


def make_window(rng: np.random.Generator, params: RansacStudyParams, noise_px: float, kind: str,
                t_e_us: float = 1_000_000.0) -> SyntheticWindow:
    """Draw one synthetic window (see the module docstring)."""
    if kind not in NOISE_KINDS:
        raise ValueError(f"make_window: kind must be one of {NOISE_KINDS}, got {kind!r}")
    n = params.window_px
    r = n // 2
    theta = float(rng.uniform(0.0, 2.0 * np.pi))
    ys, xs = np.mgrid[-r:r + 1, -r:r + 1]
    along = np.cos(theta) * xs + np.sin(theta) * ys
    tau = params.lifetime_us
    t_true = t_e_us + tau * along
    fired = along <= 1e-12
    centre = (ys == 0) & (xs == 0)
    fired_past = fired & ~centre
    noise = np.zeros((n, n))
    sigma = noise_px * tau
    if kind == "global":
        noise[fired_past] = rng.normal(0.0, sigma, size=int(fired_past.sum())) if sigma > 0 else 0.0
    else:
        cand = np.flatnonzero(fired_past.ravel())
        k = min(params.n_scattered, cand.size)
        pick = rng.choice(cand, size=k, replace=False)
        if sigma > 0:
            noise.flat[pick] = rng.normal(0.0, sigma, size=k)
    t = np.where(fired, np.minimum(t_true + noise, t_e_us), np.nan)
    t[centre] = t_e_us
    deviation = np.where(fired, np.abs(t - t_true), 0.0)
    true_inlier = fired_past & (deviation <= params.truth_tol_px * tau)
    return SyntheticWindow(t_us=t, true_inlier=true_inlier, fired_past=fired_past, deviation_us=deviation,
                           theta=theta)


def kept_cluster(window_t_us: np.ndarray, *, min_points: int = 5, fallback_all_points: bool = True) -> np.ndarray:
    """Cells of the window that the detector hands to RANSAC (the centre excluded).

    A plain-Python restatement of the documented rule of
    :mod:`evedge.detector.intra`: 1-D 2-means of the fired pixels' timestamps
    relative to the current event, initial centroids the window minimum and the
    current time, ties join the current event's cluster, all timestamps equal ->
    one cluster; the current event's cluster is kept. With
    ``fallback_all_points`` (the detector's default), a degenerate cluster
    (fewer than ``min_points`` points with the current event, or all its points
    on one line through the current event) is replaced by all fired pixels. A
    test checks that the detector's inliers always lie inside this set.
    """
    w = np.asarray(window_t_us, dtype=np.float64)
    side = w.shape[0]
    c = side // 2
    mask = np.isfinite(w)
    mask[c, c] = False
    dt = (w - w[c, c])[mask]
    out = np.zeros(w.shape, dtype=bool)
    if dt.size == 0:
        return out
    c0, c1 = min(0.0, float(dt.min())), 0.0
    if c0 == c1:
        out[mask] = True
        return out
    label = np.full(dt.size, -1)
    cur = -1
    for _ in range(100):
        lc = 1 if abs(0.0 - c1) <= abs(0.0 - c0) else 0
        new = np.where(np.abs(dt - c1) <= np.abs(dt - c0), 1, 0)
        changed = lc != cur or bool(np.any(new != label))
        cur, label = lc, new
        if not changed:
            break
        s0 = dt[label == 0].sum()
        n0 = int(np.sum(label == 0)) + (0 if lc == 1 else 1)
        s1 = dt[label == 1].sum()
        n1 = int(np.sum(label == 1)) + (1 if lc == 1 else 0)
        if n0 > 0:
            c0 = s0 / n0
        if n1 > 0:
            c1 = s1 / n1
    out[mask] = label == cur
    if fallback_all_points:
        ys, xs = np.nonzero(out)
        dx, dy = xs - c, ys - c
        n = dx.size
        degenerate = n < 2 or n + 1 < min_points
        if not degenerate:
            det = dx[:, None] * dy[None, :] - dx[None, :] * dy[:, None]
            degenerate = not np.any(det != 0)
        if degenerate:
            out = mask.copy()
    return out


def _methods(params: RansacStudyParams) -> list[tuple[str, bool, float]]:
    """(label, use_intra, delta) for every compared method."""
    out = [("no_intra", False, 0.0)]
    out += [(f"intra_delta_{d:g}", True, d) for d in params.deltas_px]
    return out


def _fit_batch(windows: np.ndarray, use_intra: bool, delta: float, seed: int):
    """The detector's 2-means + RANSAC on a stack of windows (default parameters but delta)."""
    from evedge.detector.intra import IntraParams, fit_windows

    return fit_windows(windows, IntraParams(delta_px=delta), use_intra=use_intra, seed=seed)


def _detector_defaults():
    from evedge.detector.intra import IntraParams

    return IntraParams()


#: Extra truth tolerances (units of tau) whose F-measures are reported to show
#: how much the F-measure verdicts depend on the definition of a true inlier.
_SENSITIVITY_TOLS_PX = (0.1, 0.5)


def run_ransac_study(out_dir, *, params: RansacStudyParams | None = None, quick: bool = False,
                     progress: bool = True) -> dict:
    """Run the study, write figures and tables to ``out_dir``, return the numbers.

    Parameters
    ----------
    out_dir : path
        Directory for ``ransac_study.csv``, ``ransac_study.json`` and the PNG figures.
    params : RansacStudyParams, optional
    quick : bool
        Fewer repetitions (100) for the demo and tests, unless ``params`` is given.
    progress : bool
        Show a progress bar.

    Returns
    -------
    dict
        ``{"params": ..., "fmeasure": {kind: {method: {"noise_px": [...],
        "f_measure": [...], "lifetime_rel_error_mean": [...],
        "lifetime_rel_error_median": [...], "ok_rate": [...]}}}, "figures": [...]}``
    """
    if params is None:
        params = RansacStudyParams(repetitions=100) if quick else RansacStudyParams()
    out_dir = Path(out_dir)
    methods = _methods(params)
    levels = params.noise_levels_px
    n_rep = params.repetitions
    shape = (len(NOISE_KINDS), len(methods), len(levels), n_rep)
    tols = (params.truth_tol_px,) + tuple(t for t in _SENSITIVITY_TOLS_PX if t != params.truth_tol_px)
    fm = np.full((len(tols),) + shape, np.nan)
    fm_all = np.full(shape, np.nan)
    err = np.full(shape, np.nan)
    ok = np.zeros(shape, dtype=bool)
    total = len(NOISE_KINDS) * len(levels) * len(methods)
    bar = tqdm(total=total, desc="RANSAC study", unit="batch", disable=not progress, leave=False)
    for ki, kind in enumerate(NOISE_KINDS):
        for li, level in enumerate(levels):
            rng = np.random.default_rng([params.seed, ki, li])
            wins = [make_window(rng, params, level, kind) for _ in range(n_rep)]
            stack = np.stack([w.t_us for w in wins])
            fired_past = np.stack([w.fired_past for w in wins])
            deviation = np.stack([w.deviation_us for w in wins])
            cluster = np.stack([kept_cluster(w.t_us, min_points=_detector_defaults().min_points,
                                             fallback_all_points=_detector_defaults().fallback_all_points)
                                for w in wins])
            fit_seed = int(rng.integers(0, 2**31 - 1))
            for mi, (_, use_intra, delta) in enumerate(methods):
                a, b, good, inl = _fit_batch(stack, use_intra, delta, fit_seed)
                ok[ki, mi, li] = good
                tau_est = np.hypot(a, b)
                err[ki, mi, li] = np.where(good, np.abs(tau_est - params.lifetime_us) / params.lifetime_us, np.nan)
                for ti, tol in enumerate(tols):
                    truth = fired_past & (deviation <= tol * params.lifetime_us)
                    for rep in range(n_rep):
                        pred = inl[rep] & fired_past[rep] & good[rep]
                        m = cluster[rep]
                        fm[ti, ki, mi, li, rep] = f_measure(pred[m], truth[rep][m])
                        if ti == 0:
                            m = fired_past[rep]
                            fm_all[ki, mi, li, rep] = f_measure(pred[m], truth[rep][m])
                bar.update(1)
    bar.close()
    sensitivity = {}
    for ti, tol in enumerate(tols[1:], start=1):
        sensitivity[f"truth_tol_{tol:g}px"] = {
            kind: {label: np.nanmean(fm[ti, ki, mi], axis=1) for mi, (label, _, _) in enumerate(methods)}
            for ki, kind in enumerate(NOISE_KINDS)}
    fm = fm[0]

    results: dict = {}
    rows = []
    for ki, kind in enumerate(NOISE_KINDS):
        results[kind] = {}
        for mi, (label, use_intra, delta) in enumerate(methods):
            with np.errstate(all="ignore"):
                f_mean = np.nanmean(fm[ki, mi], axis=1)
                f_all = np.nanmean(fm_all[ki, mi], axis=1)
                e_mean = np.array([np.nanmean(e) if np.isfinite(e).any() else np.nan for e in err[ki, mi]])
                e_med = np.array([np.nanmedian(e) if np.isfinite(e).any() else np.nan for e in err[ki, mi]])
            ok_rate = ok[ki, mi].mean(axis=1)
            results[kind][label] = {
                "use_intra": use_intra, "delta_px": delta, "noise_px": list(levels),
                "f_measure": f_mean, "f_measure_all_fired": f_all, "lifetime_rel_error_mean": e_mean,
                "lifetime_rel_error_median": e_med, "ok_rate": ok_rate,
            }
            for li, level in enumerate(levels):
                rows.append([kind, label, use_intra, delta, level, f_mean[li], f_all[li], e_mean[li], e_med[li],
                             ok_rate[li], n_rep])
    write_csv_atomic(out_dir / "ransac_study.csv",
                     ["noise_kind", "method", "use_intra", "delta_px", "noise_px", "f_measure", "f_measure_all_fired",
                      "lifetime_rel_error_mean", "lifetime_rel_error_median", "ok_rate", "repetitions"], rows)
    figures = _plot(out_dir, results, params)
    out = {"params": asdict(params), "fmeasure": results, "figures": relative_figures(out_dir, figures),
           "truth_tolerance_sensitivity": sensitivity,
           "definitions": {
               "noise_px": "Gaussian timestamp noise std in units of the true lifetime (pixels of edge travel)",
               "true_inlier": f"fired past pixel within {params.truth_tol_px} * tau of the true plane",
               "f_measure": "mean over repetitions of F1 of RANSAC's final inliers vs. true inliers, "
                            "over the points RANSAC is given (the 2-means cluster of the current event, "
                            "centre excluded; failed fit = no inliers)",
               "f_measure_all_fired": "the same over all fired past pixels (2-means + RANSAC together)",
               "lifetime_rel_error": "|tau_est - tau| / tau over successful fits",
           }}
    write_json_atomic(out_dir / "ransac_study.json", out)
    return out


def _legend(res: dict) -> str:
    """Legend text of a study variant (the registry's name of the detector, and its delta)."""
    from evedge.detector.protocols import METHODS

    name = METHODS.get("intra").display_name
    if not res["use_intra"]:
        return f"{name}'s RANSAC without intra-pixel area"
    return f"{name}, delta {res['delta_px']:g} px" + (" (plain RANSAC)" if res["delta_px"] == 0 else "")


def _plot(out_dir: Path, results: dict, params: RansacStudyParams) -> list[Path]:
    plt = pyplot()
    paths = []
    cmap = plt.get_cmap("viridis")
    for kind in NOISE_KINDS:
        fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
        for label, res in results[kind].items():
            if res["use_intra"]:
                colour = cmap(res["delta_px"] / 0.5 * 0.85)
                style = "-"
            else:
                colour, style = "k", "--"
            text = _legend(res)
            axes[0].plot(res["noise_px"], res["f_measure"], style, marker="o", ms=3, color=colour, label=text)
            axes[1].plot(res["noise_px"], res["lifetime_rel_error_mean"], style, marker="o", ms=3,
                         color=colour, label=text)
        axes[0].set_xlabel("timestamp noise std (units of lifetime)")
        axes[0].set_ylabel("F-measure of inlier decision")
        axes[1].set_xlabel("timestamp noise std (units of lifetime)")
        axes[1].set_ylabel("mean relative lifetime error")
        axes[1].set_ylim(bottom=0)
        axes[0].legend(fontsize=7)
        fig.suptitle(f"RANSAC study, {kind} noise ({params.repetitions} windows per point)")
        paths.append(save_figure(fig, out_dir / f"ransac_{kind}.png"))

    # The paper's second view: the metrics against delta (mean over the noisy levels).
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for kind, style in zip(NOISE_KINDS, ("-", "--")):
        rows = sorted((r["delta_px"], r) for r in results[kind].values() if r["use_intra"])
        lv = np.asarray(rows[0][1]["noise_px"]) if rows else np.zeros(0)
        noisy = lv > 0
        if not noisy.any():
            continue
        d = [x for x, _ in rows]
        f = [np.nanmean(np.asarray(r["f_measure"], float)[noisy]) for _, r in rows]
        e = [np.nanmean(np.asarray(r["lifetime_rel_error_mean"], float)[noisy]) for _, r in rows]
        axes[0].plot(d, f, style, marker="o", label=f"{kind} noise")
        axes[1].plot(d, e, style, marker="o", label=f"{kind} noise")
    axes[0].set_xlabel("intra-pixel half-size delta (px)")
    axes[0].set_ylabel("F-measure (mean over noise > 0)")
    axes[1].set_xlabel("intra-pixel half-size delta (px)")
    axes[1].set_ylabel("rel. lifetime error (mean over noise > 0)")
    axes[0].legend(fontsize=8)
    fig.suptitle("RANSAC study: effect of delta")
    paths.append(save_figure(fig, out_dir / "ransac_vs_delta.png"))
    return paths
