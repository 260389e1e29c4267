"""The README's figures of the paper's experiments, at demo size.

Run: ``.venv/bin/python docs/make_readme_figures.py`` (about as long as ``evedge demo``).

Runs every experiment at the demo's reduced size (:func:`evedge.bench.paper.run_paper`
with ``quick=True``, in a temporary directory) -- or, with ``--from-run DIR``,
reuses the output of an earlier ``evedge demo -o DIR`` / ``evedge bench paper -o DIR``
-- and writes into ``docs/img/``:

``qualitative.png``
    The qualitative panel (paper figs. 1, 8), lifetime methods under the primary display policy.
``lifetime_hist_stripes_real.png``, ``lifetime_image_stripes_real.png``
    Lifetime histogram and accumulated lifetime images of both methods on the
    real stripes recording (paper figs. 5, 4).
``cdm_boxplots.png``
    CDM box plots per section of the slow-then-fast sequence (paper fig. 9):
    the lifetime methods under the primary display policy (predecessor
    display, plain boxes) beside the lifetime-only display (hatched, "no clear").
``ransac_fmeasure.png``
    RANSAC study, F-measure of the inlier decision against timestamp noise,
    global and scattered noise (paper fig. 7).

The experiments' PNGs are resampled to about 100 dpi and a 256-colour
palette to keep the repository small; every file is written atomically. Missing inputs (e.g. the real
recordings absent) are reported and the other figures still written; the exit
status is then 1.
"""

from __future__ import annotations

import argparse
import io
import json
import sys
import tempfile
from pathlib import Path

#: Resolution of the README figures.
README_DPI = 100

#: README figure -> the experiment output it comes from (relative to a run's directory; globs allowed).
COPIED = {
    "qualitative.png": "qualitative/qualitative.png",
    "lifetime_hist_stripes_real.png": "lifetime/lifetime_hist_stripes_real.png",
    "lifetime_image_stripes_real.png": "lifetime/lifetime_image_stripes_real.png",
    "cdm_boxplots.png": "similarity/similarity_shapes_translation_boxplots.png",
}

#: Everything this script writes (``ransac_fmeasure.png`` is drawn from ``results.json``).
OUTPUTS = tuple(COPIED) + ("ransac_fmeasure.png",)


def resample_png(src, dst: Path, *, dpi: int = README_DPI) -> Path:
    """Copy a PNG (path or bytes) to ``dst`` atomically, resampled from its own dpi to ``dpi``
    (never enlarged), flattened on white and stored with a 256-colour palette."""
    from PIL import Image

    from evedge.bench._files import write_bytes_atomic

    with Image.open(io.BytesIO(src) if isinstance(src, bytes) else src) as im:
        src_dpi = float((im.info.get("dpi") or (dpi, dpi))[0]) or dpi
        scale = min(1.0, dpi / src_dpi)
        rgba = im.convert("RGBA")
    # matplotlib's figures are opaque in practice: flatten on white, then resample
    flat = Image.new("RGB", rgba.size, (255, 255, 255))
    flat.paste(rgba, mask=rgba.getchannel("A"))
    if scale < 1.0:
        size = (max(1, round(flat.width * scale)), max(1, round(flat.height * scale)))
        flat = flat.resize(size, Image.Resampling.LANCZOS)
    # a 256-colour palette: plots have few colours, a third of the bytes of RGB
    pal = flat.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    buf = io.BytesIO()
    pal.save(buf, format="PNG", optimize=True, dpi=(dpi, dpi))
    return write_bytes_atomic(dst, buf.getvalue())


def plot_ransac_fmeasure(fmeasure: dict, dst: Path, *, dpi: int = README_DPI) -> Path:
    """Paper fig. 7: F-measure of RANSAC's inlier decision vs timestamp noise, one panel per noise kind.

    Parameters
    ----------
    fmeasure : dict
        ``results.json["fmeasure"]``: kind -> label -> ``{"noise_px", "f_measure", "use_intra", "delta_px"}``.
    dst : path
    """
    from evedge.bench._plot import pyplot

    if not fmeasure:
        raise ValueError("plot_ransac_fmeasure: fmeasure is empty (RANSAC study not run)")
    plt = pyplot()
    kinds = list(fmeasure)
    fig, axes = plt.subplots(1, len(kinds), figsize=(4.6 * len(kinds), 3.4), squeeze=False, sharey=True)
    cmap = plt.get_cmap("viridis")
    for ax, kind in zip(axes[0], kinds):
        for label, res in fmeasure[kind].items():
            if res.get("use_intra"):
                colour, style = cmap(float(res["delta_px"]) / 0.5 * 0.85), "-"
                name = f"intra, delta {float(res['delta_px']):g} px"
            else:  # on top: it coincides with delta 0 (a zero-size area adds nothing)
                colour, style, name = "k", "--", "plain RANSAC (no intra)"
            f = [float("nan") if v is None else v for v in res["f_measure"]]
            ax.plot(res["noise_px"], f, style, marker="o", ms=3, color=colour, label=name,
                    zorder=3 if not res.get("use_intra") else 2)
        ax.set_title(f"{kind} noise", fontsize=10)
        ax.set_xlabel("timestamp noise std (units of lifetime)")
    axes[0][0].set_ylabel("F-measure of the inlier decision")
    axes[0][0].legend(fontsize=7)
    fig.suptitle("RANSAC with and without intra-pixel-area events (paper fig. 7)", fontsize=10, y=1.02)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return resample_png(buf.getvalue(), dst, dpi=dpi)


def build_figures(run_dir: Path, out_dir: Path) -> tuple[list[Path], dict[str, str]]:
    """Write the README figures from one run's output directory.

    Returns
    -------
    written : list of Path
    missing : dict
        README figure -> why it could not be written.
    """
    run_dir, out_dir = Path(run_dir), Path(out_dir)
    written, missing = [], {}
    for name, rel in COPIED.items():
        hits = sorted(run_dir.glob(rel))
        if not hits:
            missing[name] = f"{run_dir / rel} not found"
            continue
        written.append(resample_png(hits[0], out_dir / name))
    results_path = run_dir / "results.json"
    try:
        fm = json.loads(results_path.read_text()).get("fmeasure") if results_path.exists() else None
        if not fm:
            raise ValueError(f"no RANSAC results in {results_path}")
        written.append(plot_ransac_fmeasure(fm, out_dir / "ransac_fmeasure.png"))
    except ValueError as exc:
        missing["ransac_fmeasure.png"] = str(exc)
    return written, missing


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--from-run", type=Path, default=None,
                        help="Reuse the output directory of an earlier 'evedge demo' or 'evedge bench paper'.")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "img",
                        help="Where to write the PNGs (default docs/img).")
    parser.add_argument("--seed", type=int, default=0, help="Seed of the simulations and the RANSAC study.")
    parser.add_argument("--no-progress", action="store_true", help="Hide progress bars.")
    args = parser.parse_args(argv)
    if args.from_run is not None:
        if not (args.from_run / "results.json").exists():
            parser.error(f"--from-run: no results.json in {args.from_run}")
        written, missing = build_figures(args.from_run, args.out)
    else:
        from evedge.bench.paper import run_paper

        with tempfile.TemporaryDirectory(prefix="evedge_readme_") as tmp:
            res = run_paper(tmp, quick=True, progress=not args.no_progress, seed=args.seed,
                            command="docs/make_readme_figures.py")
            for name, why in {**res.get("errors", {}), **res.get("skipped", {})}.items():
                print(f"make_readme_figures: experiment {name}: {why}", file=sys.stderr)
            written, missing = build_figures(Path(tmp), args.out)
    for p in written:
        print(f"{p} ({p.stat().st_size // 1024} KiB)")
    for name, why in missing.items():
        print(f"make_readme_figures: {name} not written: {why}", file=sys.stderr)
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
