"""Experiment 2: lifetimes on the stripes sequence (paper figs. 4-5).

Stripes pass the camera at constant speed (two regions, two speeds), so the
lifetime histogram should show two sharp peaks and the accumulated lifetime
image should be uniform within each region. Compared: Mueggler et al. 2015
(raw events) and the proposed method (event buffer, then intra-pixel-area
RANSAC). Datasets:

* ``stripes_real``: Mueggler's DVS128 recording ``stripes.mat`` (no truth);
* ``stripes_sim``: the simulated ``stripes`` scene, whose per-event truth
  gives the median relative lifetime error (events with a valid estimate,
  ``is_signal`` and a finite true lifetime) and the true histogram.

Per method and dataset: the share of its input events with an estimate
(``share_estimated``; the proposed method's input is the event buffer's
output), on simulated data the median relative error against the truth.

Sharpness, three views (all kept in ``results.json``):

* global histogram peaks: :func:`evedge.bench.stats.histogram_peaks` on log10
  lifetime (the two most prominent local maxima; location, basin median and
  MAD, FWHM in decades) -- blind to a peak that is only a shoulder;
* shoulder-aware global peaks: :func:`evedge.bench.stats.shoulder_peaks`
  (maxima of the negative curvature of the log histogram);
* per speed region (``regions``): the rows of each speed band, found without
  any estimator (:mod:`evedge.bench.regions`: from the model-free neighbour
  delay on real data, from the truth on simulated data), and per region and
  method :func:`evedge.bench.stats.log_spread` (MAD of log10 lifetime,
  IQR / median, share within +-20 % of the region's mode; on simulated data
  also the median relative error and the share within +-20 % of the truth).

Sensitivity (``regions_core``): the same spreads without the 4 rows at each
end of each band, so that a verdict resting on where a band ends shows.

Diagnostic (``mueggler.on_buffered_events``, never in a verdict): Mueggler's
region spreads on the proposed method's input (the event buffer's output), to
separate the estimator from the buffer.

Accumulated lifetime image: per pixel, the median of the valid lifetimes of
its events over the whole sequence.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._files import relative_figures, save_figure, write_csv_atomic, write_json_atomic
from ._plot import pyplot
from .exp_real import default_realdata_dir
from .exp_similarity import simulate_scene
from .methods import colour as method_colour, label as method_label, mueggler_lifetimes, proposed_lifetimes
from .regions import NoRegionsError, regions_from_delays, regions_from_truth, row_agreement
from .stats import histogram_peaks, log_spread, relative_errors, shoulder_peaks

LIFETIME_METHODS = ("proposed", "mueggler")


def lifetime_image(events: np.ndarray, lifetimes: np.ndarray, shape) -> np.ndarray:
    """Per-pixel median of the valid lifetimes (us); NaN where a pixel has none."""
    ok = np.asarray(lifetimes["valid"], bool) & np.isfinite(lifetimes["lifetime_us"])
    h, w = shape
    img = np.full(h * w, np.nan)
    if not ok.any():
        return img.reshape(h, w)
    flat = events["y"][ok].astype(np.int64) * w + events["x"][ok].astype(np.int64)
    vals = lifetimes["lifetime_us"][ok]
    order = np.lexsort((vals, flat))
    flat, vals = flat[order], vals[order]
    starts = np.flatnonzero(np.r_[True, flat[1:] != flat[:-1]])
    ends = np.r_[starts[1:], flat.size]
    for s, e in zip(starts, ends):
        img[flat[s]] = np.median(vals[s:e])
    return img.reshape(h, w)


def _truth_lifetimes(rec) -> np.ndarray | None:
    if rec.truth is None or "lifetime_us" not in (rec.truth.dtype.names or ()):
        return None
    t = np.asarray(rec.truth["lifetime_us"], dtype=np.float64).copy()
    if "is_signal" in rec.truth.dtype.names:
        t[~np.asarray(rec.truth["is_signal"], bool)] = np.nan
    return t


def analyse_dataset(name: str, rec, *, progress: bool = False) -> dict:
    """Lifetimes of both methods on one recording, with peaks, images and errors."""
    from tqdm.auto import tqdm

    truth = _truth_lifetimes(rec)
    regions = _regions(rec, truth)
    out = {"info": {"n_events": int(rec.events.size), "sensor": [rec.sensor_size.width, rec.sensor_size.height],
                    "has_truth": truth is not None,
                    "source": str(rec.metadata.get("source", rec.metadata.get("scene", name))),
                    "regions": regions},
           "methods": {}}
    arrays = {}
    kept = None
    for m in tqdm(LIFETIME_METHODS, desc=f"lifetimes {name}", unit="method", disable=not progress, leave=False):
        run = proposed_lifetimes(rec.events, rec.sensor_size) if m == "proposed" else \
            mueggler_lifetimes(rec.events, rec.sensor_size)
        lt = run.lifetimes
        valid = np.asarray(lt["valid"], bool) & np.isfinite(lt["lifetime_us"])
        vals = lt["lifetime_us"][valid]
        res = {"n_input_events": int(run.events.size), "n_valid": int(valid.sum()),
               "share_estimated": float(valid.sum() / max(1, run.events.size)),
               "valid_fraction_of_all_events": float(valid.sum() / max(1, rec.events.size)),
               "median_lifetime_us": float(np.median(vals)) if vals.size else float("nan"),
               "peaks": histogram_peaks(vals), "shoulder_peaks": shoulder_peaks(vals)}
        tr = None
        if truth is not None:
            tr = truth if run.kept is None else truth[run.kept]
            est = np.where(valid, lt["lifetime_us"], np.nan)
            err = relative_errors(est, tr)
            res["median_rel_error"] = float(np.median(err)) if err.size else float("nan")
            res["mean_rel_error"] = float(np.mean(err)) if err.size else float("nan")
            res["n_with_truth"] = int(err.size)
            sig = np.isfinite(tr) & (tr > 0)
            res["share_estimated_signal"] = float((valid & sig).sum() / max(1, sig.sum()))
        if regions is not None:
            res["regions"] = region_spreads(run.events, lt, regions, truth=tr)
            # sensitivity to where the bands end: the same without CORE_MARGIN_ROWS rows at each end
            res["regions_core"] = region_spreads(run.events, lt, core_regions(regions), truth=tr)
        if m == "proposed":
            kept = run.kept
        elif m == "mueggler" and regions is not None and kept is not None:
            # diagnostic: Mueggler on the proposed method's input (after the event buffer), so that
            # the region spreads can be compared on the same events; never used in a verdict
            sub = mueggler_lifetimes(rec.events[kept], rec.sensor_size)
            sub_valid = np.asarray(sub.lifetimes["valid"], bool) & np.isfinite(sub.lifetimes["lifetime_us"])
            res["on_buffered_events"] = {
                "share_estimated": float(sub_valid.sum() / max(1, sub.events.size)),
                "regions": region_spreads(sub.events, sub.lifetimes, regions,
                                          truth=None if truth is None else truth[kept])}
        out["methods"][m] = res
        by_region = {}
        if regions is not None:
            y = run.events["y"].astype(np.int64)
            by_region = {k: lt["lifetime_us"][valid & np.isin(y, np.asarray(r, dtype=np.int64))]
                         for k, r in regions["rows"].items()}
        arrays[m] = (vals, lifetime_image(run.events, lt, rec.sensor_size.shape), by_region)
    if truth is not None:
        tv = truth[np.isfinite(truth) & (truth > 0)]
        out["truth"] = {"median_lifetime_us": float(np.median(tv)) if tv.size else float("nan"),
                        "peaks": histogram_peaks(tv), "n": int(tv.size)}
        arrays["truth"] = (tv, lifetime_image(rec.events, _as_lifetimes(truth), rec.sensor_size.shape), {})
    return out, arrays


#: Rows dropped at each end of a band for the boundary-sensitivity check (``regions_core``).
CORE_MARGIN_ROWS = 4


def core_regions(regions: dict, margin: int = CORE_MARGIN_ROWS) -> dict:
    """The regions without ``margin`` rows at each end of each band (a band too thin keeps its middle row)."""
    rows = {}
    for k, r in regions["rows"].items():
        r = list(r)
        rows[k] = r[margin:len(r) - margin] if len(r) > 2 * margin else r[len(r) // 2:len(r) // 2 + 1]
    return {"method": f"{regions.get('method', '')}; without {margin} rows at each end", "rows": rows}


def _regions(rec, truth) -> dict | None:
    """Speed regions: from the truth when there is one (with the data-driven split's agreement), else data."""
    # only "no speed bands in these data" means no regions; any other error is a bug and must surface
    try:
        found = regions_from_delays(rec.events, rec.sensor_size)
    except NoRegionsError:
        found = None
    if truth is None:
        return found
    try:
        known = regions_from_truth(rec.events, truth, rec.sensor_size)
    except NoRegionsError:  # the truth has no bands of rows: no regions, whatever the data-driven split says
        return None
    if found is not None:
        known["data_driven_rows"] = found["rows"]
        known["data_driven_row_agreement"] = row_agreement(known, found)
    return known


def region_spreads(events: np.ndarray, lifetimes: np.ndarray, regions: dict, *, truth=None,
                   within: float = 0.2) -> dict:
    """Per speed region, the spread of one method's valid lifetimes (:func:`log_spread`).

    Parameters
    ----------
    events, lifetimes : numpy.ndarray
        Aligned (the method's input events and its estimates).
    regions : dict
        ``{"rows": {name: [row, ...]}, ...}`` (:mod:`evedge.bench.regions`).
    truth : array_like, optional
        Per-event true lifetime aligned with ``events`` (NaN for noise): adds
        ``median_rel_error`` (per event, vs its own truth), ``frac_within_truth``
        (share within +-``within`` of it) and ``share_estimated_signal``.
    within : float
        Half-width of the band around the mode (and the truth), relative.

    Returns
    -------
    dict
        region -> :func:`log_spread` fields plus ``n_events`` (the method's
        input events in those rows) and ``share_estimated`` (share of them
        with a valid estimate), ``frac_of_events_within`` (share of *all* those
        events with an estimate within +-``within`` of the mode: a missing
        estimate counts as a miss); with truth also ``frac_of_signal_within_truth``
        (the same against each event's truth, over all signal events).
    """
    valid = np.asarray(lifetimes["valid"], bool) & np.isfinite(lifetimes["lifetime_us"])
    y = events["y"].astype(np.int64)
    out = {}
    for name, rows in regions["rows"].items():
        inside = np.isin(y, np.asarray(rows, dtype=np.int64))
        sel = inside & valid
        r = log_spread(lifetimes["lifetime_us"][sel], within=within)
        r["n_events"] = int(inside.sum())
        r["share_estimated"] = float(sel.sum() / max(1, inside.sum()))
        # coverage-aware: an event without an estimate counts as a miss
        r["frac_of_events_within"] = (float(r["frac_within"] * sel.sum() / inside.sum())
                                      if inside.any() and r["n"] else float("nan"))
        if truth is not None:
            tr = np.asarray(truth, dtype=np.float64)
            sig = inside & np.isfinite(tr) & (tr > 0)
            err = relative_errors(np.where(sel, lifetimes["lifetime_us"], np.nan)[sig], tr[sig])
            r["median_rel_error"] = float(np.median(err)) if err.size else float("nan")
            r["frac_within_truth"] = float(np.mean(err <= within)) if err.size else float("nan")
            r["frac_of_signal_within_truth"] = float(np.sum(err <= within) / max(1, sig.sum()))
            r["share_estimated_signal"] = float((sel & sig).sum() / max(1, sig.sum()))
            r["truth_lifetime_us"] = float(np.median(tr[sig])) if sig.any() else float("nan")
        out[name] = r
    return out


def _as_lifetimes(t: np.ndarray) -> np.ndarray:
    from evedge.detector.result import empty_lifetimes

    lt = empty_lifetimes(t.size)
    ok = np.isfinite(t) & (t > 0)
    lt["lifetime_us"][ok] = t[ok]
    lt["valid"] = ok
    return lt


def run_lifetime(out_dir, *, quick: bool = False, progress: bool = True, seed: int = 0,
                 real_path=None, sim_duration_s: float | None = None, datasets=("stripes_real", "stripes_sim"),
                 recordings: dict | None = None, data_dir=None, scene="stripes") -> dict:
    """Lifetime histograms, accumulated lifetime images and errors on the stripes data.

    Parameters
    ----------
    out_dir : path
    quick : bool
        Unused (the whole sequences are cheap); kept for a uniform signature.
    progress : bool
    seed : int
        Simulator seed.
    real_path : path, optional
        ``stripes.mat`` (default ``../shared/realdata/rpg_event_lifetime/stripes.mat``).
    sim_duration_s : float, optional
    datasets : sequence of str
        Which of ``stripes_real`` and ``stripes_sim`` to run.
    recordings : dict, optional
        Precomputed recordings by dataset name (skips reading/simulating).
    data_dir : path, optional
        Folder of the real recordings (default ``$EVEDGE_DATA``, else ``../shared/realdata``).
    scene : str or path
        Scene simulated for ``stripes_sim``: a shipped scene's name (default ``stripes``) or a TOML file.

    Returns
    -------
    dict
        ``{"lifetime": {dataset: {"methods": {method: {"median_rel_error", "peaks", ...}},
        "truth": {...}}}, "figures": [...]}``
    """
    out_dir = Path(out_dir)
    if real_path is None and data_dir is not None:
        real_path = default_realdata_dir(data_dir) / "rpg_event_lifetime" / "stripes.mat"
    recordings = dict(recordings or {})
    results, figures, rows, region_rows, skipped = {}, [], [], [], {}
    for name in datasets:
        rec = recordings.get(name)
        if rec is None:
            try:
                rec = _load(name, quick=quick, progress=progress, seed=seed, real_path=real_path, scene=scene,
                            sim_duration_s=sim_duration_s)
            except FileNotFoundError as exc:  # real data absent: run the rest, say so
                skipped[name] = str(exc)
                continue
        res, arrays = analyse_dataset(name, rec, progress=progress)
        results[name] = res
        figures += _plot(out_dir, name, res, arrays)
        for m, r in res["methods"].items():
            for k, p in enumerate(r["peaks"]):
                rows.append([name, m, k, p["mode"], p["median"], p["mad"], p["fwhm_log10"], p["fraction"],
                             r.get("median_rel_error")])
            for k, p in enumerate(r["shoulder_peaks"]):
                rows.append([name, m, f"curvature {k} ({p['kind']})", p["mode"], p["median"], None,
                             p["fwhm_log10"], p["fraction"], r.get("median_rel_error")])
            for reg, q in (r.get("regions") or {}).items():
                region_rows.append([name, reg, m, q["n_events"], q["share_estimated"], q["mode"], q["median"],
                                    q["mad_log10"], q["iqr_over_median"], q["frac_within"],
                                    q.get("median_rel_error"), q.get("frac_within_truth")])
        if "truth" in res:
            for k, p in enumerate(res["truth"]["peaks"]):
                rows.append([name, "truth", k, p["mode"], p["median"], p["mad"], p["fwhm_log10"], p["fraction"], None])
    write_csv_atomic(out_dir / "lifetime_peaks.csv",
                     ["dataset", "method", "peak", "mode_us", "median_us", "mad_us", "fwhm_log10", "fraction",
                      "median_rel_error"], rows)
    write_csv_atomic(out_dir / "lifetime_regions.csv",
                     ["dataset", "region", "method", "n_events", "share_estimated", "mode_us", "median_us",
                      "mad_log10", "iqr_over_median", "frac_within_20pct_of_mode", "median_rel_error",
                      "frac_within_20pct_of_truth"], region_rows)
    # results.json layout: lifetime[dataset][method] (the truth as a pseudo-method)
    flat = {name: dict(res["methods"], **({"truth": res["truth"]} if "truth" in res else {}))
            for name, res in results.items()}
    out = {"lifetime": flat, "datasets": {name: res["info"] for name, res in results.items()},
           "skipped": skipped, "figures": relative_figures(out_dir, figures)}
    write_json_atomic(out_dir / "lifetime.json", out)
    return out


def _load(name: str, *, quick: bool, progress: bool, seed: int, real_path, sim_duration_s, scene="stripes"):
    if name == "stripes_real":
        from evedge.io import read_events

        path = Path(real_path) if real_path else default_realdata_dir() / "rpg_event_lifetime" / "stripes.mat"
        if not path.exists():
            raise FileNotFoundError(f"run_lifetime: stripes recording not found: {path}")
        return read_events(path)
    if name == "stripes_sim":
        return simulate_scene(scene, seed=seed, duration_s=sim_duration_s, progress=progress)
    raise ValueError(f"run_lifetime: unknown dataset {name!r} (stripes_real or stripes_sim)")


def _log_ms_axis(ax) -> None:
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    ax.set_xscale("log")
    ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v / 1e3:g}"))
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("lifetime (ms)")


def plot_histogram(ax, name: str, res: dict, arrays: dict) -> None:
    """Fig. 5: lifetime histograms of the methods on one axis; global peaks dotted, shoulders dash-dot."""
    keys = list(arrays)
    all_vals = np.concatenate([arrays[k][0] for k in keys if arrays[k][0].size]) if keys else np.zeros(0)
    all_vals = all_vals[all_vals > 0]
    if all_vals.size:
        lo, hi = np.quantile(np.log10(all_vals), [0.002, 0.998])
        bins = np.logspace(lo, hi, 100)
        for k in keys:
            vals = arrays[k][0]
            colour = method_colour(k)
            if k == "truth":
                # the true lifetimes are a few exact values: mark them, a histogram
                # spike would flatten the estimators' curves
                for j, p in enumerate(res["truth"]["peaks"]):
                    ax.axvline(p["median"], color="k", lw=1.5, ls="--",
                               label="true lifetimes" if j == 0 else None)
                continue
            ax.hist(vals, bins=bins, histtype="step", lw=1.5, color=colour, label=method_label(k),
                    density=True)
            for p in res["methods"][k]["peaks"]:
                ax.axvline(p["mode"], color=colour, lw=0.8, ls=":")
            for p in res["methods"][k].get("shoulder_peaks", []):
                if p["kind"] == "shoulder":
                    ax.axvline(p["mode"], color=colour, lw=0.8, ls="-.")
        _log_ms_axis(ax)
    ax.set_ylabel("density")
    ax.legend(fontsize=8)
    ax.set_title(f"{name}: lifetime histogram (dotted: peaks, dash-dot: shoulders)", fontsize=9)


def plot_images(fig, axes, name: str, arrays: dict, regions: dict | None = None) -> None:
    """Fig. 4: accumulated lifetime images, one per method (and the truth), one colour scale."""
    from matplotlib.colors import LogNorm

    keys = list(arrays)
    finite = np.concatenate([arrays[k][1][np.isfinite(arrays[k][1])] for k in keys])
    finite = finite[finite > 0]
    vmin, vmax = (np.quantile(finite, [0.02, 0.95]) / 1e3) if finite.size else (0.1, 1.0)
    vmax = max(vmax, vmin * 1.01)
    im = None
    for ax, k in zip(axes, keys):
        im = ax.imshow(arrays[k][1] / 1e3, cmap="jet", norm=LogNorm(vmin=vmin, vmax=vmax))
        ax.set_title((method_label(k) if k != "truth" else "ground truth"), fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
        if regions is not None:  # the speed regions' rows, as a strip left of the image
            for reg, rows in regions["rows"].items():
                c = "k" if reg == "slow" else "0.6"
                ax.scatter(np.full(len(rows), -2.5), rows, s=1, marker="s", c=c, clip_on=False)
    if im is not None:
        fig.colorbar(im, ax=list(axes), label="median lifetime (ms)", shrink=0.8)


def plot_regions(axes, name: str, res: dict, arrays: dict) -> None:
    """Per speed region, the methods' lifetime histograms with each one's region mode (dotted)."""
    regions = res["info"].get("regions") or {}
    for ax, reg in zip(axes, regions.get("rows", {})):
        vals = [arrays[k][2].get(reg, np.zeros(0)) for k in arrays if k != "truth"]
        allv = np.concatenate(vals) if vals else np.zeros(0)
        allv = allv[allv > 0]
        if allv.size:
            lo, hi = np.quantile(np.log10(allv), [0.005, 0.995])
            bins = np.logspace(lo, hi, 80)
            for k in arrays:
                if k == "truth":
                    continue
                q = res["methods"][k]["regions"][reg]
                colour = method_colour(k)
                ax.hist(arrays[k][2][reg], bins=bins, histtype="step", lw=1.5, color=colour, density=True,
                        label=f"{method_label(k)}: MAD {q['mad_log10']:.3f} dec, "
                              f"{100 * q['frac_within']:.0f}% in +-20%")
                ax.axvline(q["mode"], color=colour, lw=0.8, ls=":")
            tl = (regions.get("truth_lifetime_us") or {}).get(reg)
            if tl:
                ax.axvline(tl, color="k", lw=1.5, ls="--", label="true lifetime")
            _log_ms_axis(ax)
            ax.set_ylabel("density (per lifetime)")
        n_rows = len(regions["rows"][reg])
        ax.set_title(f"{name}, {reg} region ({n_rows} rows)", fontsize=9)
        ax.legend(fontsize=7)


def _plot(out_dir: Path, name: str, res: dict, arrays: dict, *, dpi: int = 110) -> list[Path]:
    plt = pyplot()
    paths = []
    fig, ax = plt.subplots(figsize=(7, 3.6))
    plot_histogram(ax, name, res, arrays)
    paths.append(save_figure(fig, out_dir / f"lifetime_hist_{name}.png", dpi=dpi))

    keys = list(arrays)
    fig, axes = plt.subplots(1, len(keys), figsize=(3.6 * len(keys), 3.4), squeeze=False)
    plot_images(fig, axes[0], name, arrays, res["info"].get("regions"))
    fig.suptitle(f"{name}: accumulated lifetime image (left strip: rows of the slow/fast region, black/grey)",
                 fontsize=9)
    paths.append(save_figure(fig, out_dir / f"lifetime_image_{name}.png", dpi=dpi))

    if res["info"].get("regions"):
        n = len(res["info"]["regions"]["rows"])
        fig, axes = plt.subplots(1, n, figsize=(5.2 * n, 3.4), squeeze=False)
        plot_regions(axes[0], name, res, arrays)
        paths.append(save_figure(fig, out_dir / f"lifetime_regions_{name}.png", dpi=dpi))
    return paths
