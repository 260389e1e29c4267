"""Command line: ``evedge bench ...`` (the paper's experiments) and ``evedge demo`` (the main job)."""

from __future__ import annotations

import os
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import click


def _overwrite(ctx, param, value):
    """Eager, so that the output check in ``_out_dir`` sees it whatever the order on the command line."""
    ctx.meta["evedge_overwrite"] = bool(value)
    return value


#: File in every bench output folder: ``--overwrite`` replaces a folder only when it holds it (or, for
#: outputs written before the marker existed, ``report.html`` and ``results.json``), so a mistyped
#: ``-o`` never wipes a folder of other files.
BENCH_MARKER = ".evedge-bench"


def _is_bench_output(folder: Path) -> bool:
    """A bench, demo or grade output (``grade.json`` for grades written before the marker)."""
    return (folder / BENCH_MARKER).is_file() or ((folder / "report.html").is_file() and (
        (folder / "results.json").is_file() or (folder / "grade.json").is_file()))


def _out_dir(ctx, param, value):
    """Create the output directory up front: an unusable path is a usage error, not a traceback after the run.

    An existing, non-empty output is refused unless --overwrite is given (then announced).
    """
    if value is None:
        return None
    from evedge._output import OutputExistsError, check_output

    if ctx.meta.get("evedge_overwrite", False) and value.is_dir() and not value.is_symlink() \
            and any(value.iterdir()) and not _is_bench_output(value):
        raise click.BadParameter(
            f"{value} holds files but is not an earlier evedge bench output (no {BENCH_MARKER}, no report.html + "
            "results.json): --overwrite replaces only an earlier bench output; choose another folder",
            ctx=ctx, param=param)
    try:
        if check_output(value, overwrite=ctx.meta.get("evedge_overwrite", False)):
            click.echo(f"replacing the earlier output in {value} (swapped in as a whole at the end)", err=True)
    except OutputExistsError as err:
        raise click.BadParameter(str(err), ctx=ctx, param=param) from None
    try:
        value.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise click.BadParameter(f"cannot create directory {str(value)!r}: {err.strerror or err}",
                                 ctx=ctx, param=param) from None
    if not os.access(value, os.W_OK | os.X_OK):
        raise click.BadParameter(f"directory {str(value)!r} is not writable", ctx=ctx, param=param)
    return value


def _scene(ctx, param, value):
    """A shipped scene's name or a TOML file (checked before the simulation starts)."""
    from .exp_similarity import scene_path

    if value is None:
        return None
    try:
        scene_path(value)
    except FileNotFoundError as err:
        raise click.BadParameter(str(err), ctx=ctx, param=param) from None
    return value


_OUT = click.option("-o", "--out", "out", type=click.Path(file_okay=False, path_type=Path), required=True,
                    callback=_out_dir, help="Output directory.")
_QUICK = click.option("--quick", is_flag=True, help="Reduced sizes (as in the demo).")
_OVERWRITE = click.option("--overwrite", is_flag=True, is_eager=True, expose_value=False, callback=_overwrite,
                          help="Replace an existing, non-empty output directory.")
_NOPROG = click.option("--no-progress", is_flag=True, help="Hide progress bars.")
_SEED = click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True, help="Seed of simulations and RANSAC study.")
def _methods(ctx, param, values):
    """Each --method must be a registered estimator or edge detector, or a resolvable module:factory."""
    from evedge.detector.protocols import METHODS

    for v in values:
        try:
            METHODS.get(v, kind=("estimator", "edges"))
        except (LookupError, ValueError) as err:
            raise click.BadParameter(str(err), ctx=ctx, param=param) from None
    return tuple(values)


_METHOD = click.option("--method", "methods_extra", multiple=True, callback=_methods, metavar="NAME",
                       help="Also compare this method (repeatable): a registered method (entry-point group "
                            "evedge.methods) or package.module:factory; shown beside the paper's, never ranked "
                            "in the paper's verdicts.")
_DATA = click.option("--data", "data_dir", type=click.Path(exists=True, file_okay=False, path_type=Path),
                     default=None, help="Folder of the real recordings (default: $EVEDGE_DATA, else "
                                        "../shared/realdata beside the repository).")
_DISPLAY = click.option("--display", "displays", type=click.Choice(["predecessor", "lifetime_only"]), multiple=True,
                        help="Display policy of the lifetime methods (repeatable; default both). predecessor: "
                             "clear the pixel behind each event (primary); lifetime_only: nothing cleared.")


@contextmanager
def _staged(out: Path):
    """Build the run in a temporary folder beside ``out``; swap it in as a whole at the end.

    A run killed at any point leaves the earlier ``out`` intact (plus at most a
    temporary folder the next run removes); see :mod:`evedge._output`. The
    results store figure paths relative to the folder, so none points at the
    temporary one.
    """
    from evedge._output import OutputExistsError, staged_folder

    try:
        with staged_folder(out) as stage:
            (stage / BENCH_MARKER).write_text("an evedge bench output: `evedge bench ... --overwrite` may replace this folder\n")
            yield stage
    except OutputExistsError as err:
        raise click.ClickException(str(err)) from None


class _Group(click.Group):
    """A failed write (a full disk, a vanished folder) is one error line, not a traceback."""

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except OSError as err:
            raise click.ClickException(f"cannot write the output: {err}") from None


@click.group(cls=_Group)
def bench() -> None:
    """The paper's experiments: metrics, figures, tables and an HTML report."""


from .sweep_cli import sweep  # noqa: E402  (its heavy imports happen when it runs)

bench.add_command(sweep)


def _experiment(*, seed: bool = True):
    """``@bench.command()`` with the options every experiment takes: -o/--out, --overwrite, --quick, --no-progress
    (and --seed)."""
    common = (_OUT, _OVERWRITE, _QUICK, _NOPROG, _SEED) if seed else (_OUT, _OVERWRITE, _QUICK, _NOPROG)

    def decorate(f):
        for option in reversed(common):  # the same order as the decorators stacked on top of f
            f = option(f)
        return bench.command()(f)

    return decorate


def _summary(results: dict, t0: float, out: Path) -> None:
    # one line per paper claim (evedge.bench.claims); every detailed check is in the report
    for c in results.get("claims", []):
        counts = f" ({c['n_holds']} of {c['n_checks']} checks hold)" if c["n_checks"] else ""
        click.echo(f"  [{c['status'].upper():11s}] {c['claim']}{counts}")
    for name, why in results.get("skipped", {}).items():
        click.echo(f"  skipped {name}: {why}", err=True)
    for name, err in results.get("errors", {}).items():
        click.echo(f"  experiment {name} FAILED: {err}", err=True)
    click.echo(f"wall time {time.perf_counter() - t0:.1f} s")
    click.echo(f"report: {(out / 'report.html').resolve()}")


@_experiment()
@click.option("--only", "only", multiple=True, type=click.Choice(["ransac", "lifetime", "similarity", "real",
                                                                    "qualitative"]),
              help="Run only these experiments (repeatable; default all).")
@click.option("--scene", default=None, callback=_scene,
              help="Scene of the similarity experiment: a shipped scene's name or a TOML file "
                   "(default shapes_translation).")
@_METHOD
@_DATA
def paper(out: Path, quick: bool, no_progress: bool, seed: int, only: tuple, scene, methods_extra: tuple,
          data_dir) -> None:
    """Run every experiment; write OUT/report.html, OUT/results.json and OUT/results.csv|h5 (the long table)."""
    from .paper import EXPERIMENTS, run_paper

    t0 = time.perf_counter()
    cmd = " ".join(["evedge bench paper"] + (["--quick"] if quick else []) + [f"--only {o}" for o in only]
                   + ([f"--scene {scene}"] if scene else []) + [f"--method {m}" for m in methods_extra])
    with _staged(out) as stage:
        results = run_paper(stage, quick=quick, progress=not no_progress, seed=seed, command=cmd,
                            experiments=tuple(only) or EXPERIMENTS, scene=scene, methods_extra=methods_extra,
                            data_dir=data_dir)
    _summary(results, t0, out)
    if results.get("errors"):
        sys.exit(1)


@_experiment()
@click.option("--repetitions", type=click.IntRange(min=1), default=None, help="Windows per noise level (default 1000, quick 100).")
def ransac(out: Path, quick: bool, no_progress: bool, seed: int, repetitions: int | None) -> None:
    """RANSAC inlier F-measure and lifetime error vs. timestamp noise (paper fig. 7)."""
    from .exp_ransac import RansacStudyParams, run_ransac_study

    params = None
    if repetitions is not None or seed:
        reps = repetitions if repetitions is not None else (100 if quick else 1000)
        params = RansacStudyParams(repetitions=reps, seed=seed)
    with _staged(out) as stage:
        res = run_ransac_study(stage, params=params, quick=quick, progress=not no_progress)
    click.echo("\n".join(str(out / f) for f in res["figures"]))


@_experiment()
@_DATA
@click.option("--scene", default="stripes", show_default=True, callback=_scene,
              help="Scene simulated for the simulated dataset: a shipped scene's name or a TOML file.")
def lifetime(out: Path, quick: bool, no_progress: bool, seed: int, data_dir, scene) -> None:
    """Lifetime histograms and images on real and simulated stripes (paper figs. 4-5)."""
    from .exp_lifetime import run_lifetime

    with _staged(out) as stage:
        res = run_lifetime(stage, quick=quick, progress=not no_progress, seed=seed, data_dir=data_dir, scene=scene)
    click.echo("\n".join(str(out / f) for f in res["figures"]))


@_experiment()
@click.option("--scene", default="shapes_translation", show_default=True, callback=_scene,
              help="A shipped scene's name or a scene TOML file.")
@_DISPLAY
@_METHOD
def similarity(out: Path, quick: bool, no_progress: bool, seed: int, scene: str, displays: tuple,
               methods_extra: tuple) -> None:
    """CDM over time against Canny and exact edges, box plots per section (paper fig. 9).

    Writes figures, similarity_SCENE.csv|json and the long table OUT/results.csv|h5.
    """
    from .exp_similarity import run_similarity
    from .methods import DISPLAYS
    from .results import ResultsTable, cdm_rows

    with _staged(out) as stage:
        res = run_similarity(stage, scene=scene, quick=quick, progress=not no_progress, seed=seed,
                             displays=tuple(displays) or DISPLAYS, methods_extra=methods_extra)
        table = ResultsTable()
        for name, r in res["scenes"].items():
            table.extend(cdm_rows("similarity", name, r["cdm"]), experiment="similarity")
        paths = table.save(stage / "results")
    click.echo("\n".join(str(out / f) for f in res["figures"] + [p.name for p in paths]))


@_experiment(seed=False)
@_DATA
def qualitative(out: Path, quick: bool, no_progress: bool, data_dir) -> None:
    """Grey, Canny, proposed, Mueggler, 1 ms and 30 ms side by side (paper figs. 1, 8), on slider_depth."""
    from .exp_qualitative import run_qualitative

    with _staged(out) as stage:
        res = run_qualitative(stage, quick=quick, progress=not no_progress, data_dir=data_dir)
    click.echo("\n".join(str(out / f) for f in res["figures"]))


@_experiment(seed=False)
@click.option("--path", type=click.Path(exists=True, path_type=Path), default=None,
              help="Recording with frames (default DATA/slider_depth).")
@_DISPLAY
@_METHOD
@_DATA
def real(out: Path, quick: bool, no_progress: bool, path: Path | None, displays: tuple, methods_extra: tuple,
         data_dir) -> None:
    """CDM against Canny at the real frames that fall inside the events."""
    from .exp_real import run_real
    from .methods import DISPLAYS

    from evedge.io import EventFileError

    from .exp_real import NoFramesError

    try:
        with _staged(out) as stage:
            res = run_real(stage, path=path, quick=quick, progress=not no_progress,
                           displays=tuple(displays) or DISPLAYS, methods_extra=methods_extra, data_dir=data_dir)
    except (EventFileError, NoFramesError) as err:  # the recording, not the code, is at fault
        raise click.ClickException(str(err)) from None
    click.echo("\n".join(str(out / f) for f in res["figures"]))


@click.command()
@click.option("-o", "--out", "out", type=click.Path(file_okay=False, path_type=Path), default=Path("demo_out"),
              show_default=True, callback=_out_dir, help="Output directory.")
@_OVERWRITE
@_NOPROG
@_SEED
def demo(out: Path, no_progress: bool, seed: int) -> None:
    """The main job: a reduced but complete run of the paper's experiments, with a report."""
    from .paper import run_paper

    t0 = time.perf_counter()
    click.echo(f"evedge demo: running the paper's experiments (reduced sizes) into {out}/")
    try:
        with _staged(out) as stage:
            results = run_paper(stage, quick=True, progress=not no_progress, seed=seed, command="evedge demo")
    except OSError as err:
        raise click.ClickException(f"cannot write the output: {err}") from None
    _summary(results, t0, out)
    if results.get("errors"):
        sys.exit(1)


@click.command()
@click.argument("dataset", type=click.Path(exists=True, path_type=Path))
@click.option("-d", "--detections", required=True, type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="evedge detect's detection.h5, or a plain layout: .h5/.hdf5/.npz with lifetime_us, vx_px_s, "
                   "vy_px_s, kept (one value per dataset event, in its order) and/or edge_t_us + edge_images, "
                   "or a .csv with those per-event columns.")
@_OUT
@_OVERWRITE
@click.option("--method", "method", default=None,
              help="Name of the method in the results (default: the detection file's method, else its file name).")
@click.option("--canny-settings", type=click.IntRange(1, 3), default=1, show_default=True,
              help="How many Canny settings to grade the edge frames against (the first is MATLAB's 0.3).")
def grade(dataset: Path, detections: Path, out: Path, method: str | None, canny_settings: int) -> None:
    """Grade DETECTIONS of any method against the exact truth of DATASET.

    Figures: lifetime error (median relative, p90, share estimated) per
    section, normal-flow angle and magnitude error, noise-filter precision and
    recall against the noise labels, CDM against the exact edges and Canny at
    the frame times. Writes OUT/grade.csv, OUT/grade.h5 (the long table),
    OUT/grade.json, OUT/grade.png and OUT/report.html, built in a temporary
    folder and swapped in as a whole; an existing OUT is replaced only with
    --overwrite (and only an earlier grade or bench output).
    """
    from .grade import GradeError
    from .grade import grade as run_grade

    cmd = f"evedge grade {dataset} -d {detections} -o {out}"
    try:
        with _staged(out) as stage:
            res = run_grade(dataset, detections, stage, method=method, canny_settings=canny_settings, command=cmd)
    except GradeError as err:
        raise click.ClickException(str(err)) from None
    except OSError as err:
        raise click.ClickException(f"cannot write the output: {err}") from None
    res["files"] = [str(out / Path(f).name) for f in res["files"]]  # they were written in the staged folder
    res["report"] = str(out / Path(res["report"]).name)
    res["figure"] = str(out / Path(res["figure"]).name) if res.get("figure") else None
    table = res["table"]
    for r in table.query(section="all"):
        if r["metric"] in ("median_rel_error", "p90_rel_error", "share_estimated", "median_angle_error_deg",
                           "median_rel_magnitude_error", "noise_precision", "noise_recall", "median_cdm"):
            click.echo(f"  {r['metric']:<28s} {r['reference']:<18s} {r['value']:.4g}")
    click.echo(f"{len(table)} rows -> {res['files'][0]}")
    click.echo(f"report: {Path(res['report']).resolve()}")
