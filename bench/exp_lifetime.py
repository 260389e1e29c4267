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

Histogram peaks: :func:`evedge.bench.stats.histogram_peaks` on log10 lifetime
(the two most prominent peaks; location, basin median and MAD, FWHM in
decades). Accumulated lifetime image: per pixel, the median of the valid
lifetimes of its events over the whole sequence.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._files import save_figure, write_csv_atomic, write_json_atomic
from ._plot import METHOD_COLOURS, pyplot
from .exp_real import default_realdata_dir
from .exp_similarity import simulate_scene
from .methods import METHOD_LABELS, mueggler_lifetimes, proposed_lifetimes
from .stats import histogram_peaks, relative_errors

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
    out = {"info": {"n_events": int(rec.events.size), "sensor": [rec.sensor_size.width, rec.sensor_size.height],
                    "has_truth": truth is not None,
                    "source": str(rec.metadata.get("source", rec.metadata.get("scene", name)))},
           "methods": {}}
    arrays = {}
    for m in tqdm(LIFETIME_METHODS, desc=f"lifetimes {name}", unit="method", disable=not progress, leave=False):
        run = proposed_lifetimes(rec.events, rec.sensor_size) if m == "proposed" else \
            mueggler_lifetimes(rec.events, rec.sensor_size)
        lt = run.lifetimes
        valid = np.asarray(lt["valid"], bool) & np.isfinite(lt["lifetime_us"])
        vals = lt["lifetime_us"][valid]
        res = {"n_input_events": int(run.events.size), "n_valid": int(valid.sum()),
               "valid_fraction_of_all_events": float(valid.sum() / max(1, rec.events.size)),
               "median_lifetime_us": float(np.median(vals)) if vals.size else float("nan"),
               "peaks": histogram_peaks(vals)}
        if truth is not None:
            tr = truth if run.kept is None else truth[run.kept]
            est = np.where(valid, lt["lifetime_us"], np.nan)
            err = relative_errors(est, tr)
            res["median_rel_error"] = float(np.median(err)) if err.size else float("nan")
            res["mean_rel_error"] = float(np.mean(err)) if err.size else float("nan")
            res["n_with_truth"] = int(err.size)
        out["methods"][m] = res
        arrays[m] = (vals, lifetime_image(run.events, lt, rec.sensor_size.shape))
    if truth is not None:
        tv = truth[np.isfinite(truth) & (truth > 0)]
        out["truth"] = {"median_lifetime_us": float(np.median(tv)) if tv.size else float("nan"),
                        "peaks": histogram_peaks(tv), "n": int(tv.size)}
        arrays["truth"] = (tv, lifetime_image(rec.events, _as_lifetimes(truth), rec.sensor_size.shape))
    return out, arrays


def _as_lifetimes(t: np.ndarray) -> np.ndarray:
    from evedge.detector.result import empty_lifetimes

    lt = empty_lifetimes(t.size)
    ok = np.isfinite(t) & (t > 0)
    lt["lifetime_us"][ok] = t[ok]
    lt["valid"] = ok
    return lt


def run_lifetime(out_dir, *, quick: bool = False, progress: bool = True, seed: int = 0,
                 real_path=None, sim_duration_s: float | None = None, datasets=("stripes_real", "stripes_sim"),
                 recordings: dict | None = None) -> dict:
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

    Returns
    -------
    dict
        ``{"lifetime": {dataset: {"methods": {method: {"median_rel_error", "peaks", ...}},
        "truth": {...}}}, "figures": [...]}``
    """
    out_dir = Path(out_dir)
    recordings = dict(recordings or {})
    results, figures, rows, skipped = {}, [], [], {}
    for name in datasets:
        rec = recordings.get(name)
        if rec is None:
            try:
                rec = _load(name, quick=quick, progress=progress, seed=seed, real_path=real_path,
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
        if "truth" in res:
            for k, p in enumerate(res["truth"]["peaks"]):
                rows.append([name, "truth", k, p["mode"], p["median"], p["mad"], p["fwhm_log10"], p["fraction"], None])
    write_csv_atomic(out_dir / "lifetime_peaks.csv",
                     ["dataset", "method", "peak", "mode_us", "median_us", "mad_us", "fwhm_log10", "fraction",
                      "median_rel_error"], rows)
    # results.json layout: lifetime[dataset][method] (the truth as a pseudo-method)
    flat = {name: dict(res["methods"], **({"truth": res["truth"]} if "truth" in res else {}))
            for name, res in results.items()}
    out = {"lifetime": flat, "datasets": {name: res["info"] for name, res in results.items()},
           "skipped": skipped, "figures": [str(p) for p in figures]}
    write_json_atomic(out_dir / "lifetime.json", out)
    return out


def _load(name: str, *, quick: bool, progress: bool, seed: int, real_path, sim_duration_s):
    if name == "stripes_real":
        from evedge.io import read_events

        path = Path(real_path) if real_path else default_realdata_dir() / "rpg_event_lifetime" / "stripes.mat"
        if not path.exists():
            raise FileNotFoundError(f"run_lifetime: stripes recording not found: {path}")
        return read_events(path)
    if name == "stripes_sim":
        return simulate_scene("stripes", seed=seed, duration_s=sim_duration_s, progress=progress)
    raise ValueError(f"run_lifetime: unknown dataset {name!r} (stripes_real or stripes_sim)")


def _plot(out_dir: Path, name: str, res: dict, arrays: dict) -> list[Path]:
    plt = pyplot()
    keys = list(arrays)
    all_vals = np.concatenate([arrays[k][0] for k in keys if arrays[k][0].size]) if keys else np.zeros(0)
    all_vals = all_vals[all_vals > 0]
    paths = []
    fig, ax = plt.subplots(figsize=(7, 3.6))
    if all_vals.size:
        lo, hi = np.quantile(np.log10(all_vals), [0.002, 0.998])
        bins = np.logspace(lo, hi, 100)
        for k in keys:
            vals = arrays[k][0]
            colour = METHOD_COLOURS.get(k, "k")
            if k == "truth":
                # the true lifetimes are a few exact values: mark them, a histogram
                # spike would flatten the estimators' curves
                for j, p in enumerate(res["truth"]["peaks"]):
                    ax.axvline(p["median"], color="k", lw=1.5, ls="--",
                               label="true lifetimes" if j == 0 else None)
                continue
            ax.hist(vals, bins=bins, histtype="step", lw=1.5, color=colour, label=METHOD_LABELS.get(k, k),
                    density=True)
            for p in res["methods"][k]["peaks"]:
                ax.axvline(p["mode"], color=colour, lw=0.8, ls=":")
        ax.set_xscale("log")
        from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

        ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v / 1e3:g}"))
        ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("lifetime (ms)")
    ax.set_ylabel("density")
    ax.legend(fontsize=8)
    ax.set_title(f"{name}: lifetime histogram (dotted: peaks found)")
    paths.append(save_figure(fig, out_dir / f"lifetime_hist_{name}.png"))

    fig, axes = plt.subplots(1, len(keys), figsize=(3.6 * len(keys), 3.4), squeeze=False)
    from matplotlib.colors import LogNorm

    finite = np.concatenate([arrays[k][1][np.isfinite(arrays[k][1])] for k in keys])
    finite = finite[finite > 0]
    vmin, vmax = (np.quantile(finite, [0.02, 0.95]) / 1e3) if finite.size else (0.1, 1.0)
    vmax = max(vmax, vmin * 1.01)
    for ax, k in zip(axes[0], keys):
        im = ax.imshow(arrays[k][1] / 1e3, cmap="jet", norm=LogNorm(vmin=vmin, vmax=vmax))
        ax.set_title(METHOD_LABELS.get(k, "ground truth"), fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.colorbar(im, ax=axes[0].tolist(), label="median lifetime (ms)", shrink=0.8)
    fig.suptitle(f"{name}: accumulated lifetime image")
    paths.append(save_figure(fig, out_dir / f"lifetime_image_{name}.png"))
    return paths
