"""``evedge bench sweep``: grade the compared methods over every sequence of a dataset, on Dask."""

from __future__ import annotations

from pathlib import Path

import click

#: What an earlier sweep output holds: a rerun completes it (dataset verified, grades reused, results rewritten).
_SWEEP_OUTPUT = ("dataset", "grades")


def _check_out(out: Path) -> None:
    """Complete an earlier sweep in ``out`` (announced); refuse a non-empty folder that is not one, or a link."""
    if out.is_symlink():
        raise click.BadParameter(f"{out} is a symbolic link; give the folder it points to", param_hint="'-o'")
    if out.exists() and not out.is_dir():
        raise click.BadParameter(f"{out} is an existing file, not an output folder", param_hint="'-o'")
    if out.is_dir() and any(out.iterdir()):
        if not all((out / name).is_dir() for name in _SWEEP_OUTPUT):
            raise click.BadParameter(f"{out} holds files but is not an earlier sweep output (no dataset/ and "
                                     "grades/): choose another folder", param_hint="'-o'")
        click.echo(f"completing the earlier sweep in {out}: its dataset is verified, grades of unchanged "
                   "sequences reused, results and report rewritten", err=True)


@click.command("sweep")
@click.argument("spec", type=click.Path(path_type=Path))  # a file or a shipped spec's name
@click.option("-o", "--out", "out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Output folder: dataset/, grades/, results.csv, report.md, figures.")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Worker processes of the local Dask cluster (default: the cores).")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run on an existing Dask scheduler (tcp://host:8786); its workers must see OUT at the same path.")
@click.option("--retries", type=click.IntRange(min=0), default=2, show_default=True,
              help="Extra attempts of a task that raised.")
@click.option("--no-progress", is_flag=True, help="Hide progress bars.")
def sweep(spec: Path, out: Path, workers, scheduler, retries: int, no_progress: bool) -> None:
    """Grade the methods over the dataset of SPEC (a dataset spec, sim/DATASETS.md, with an optional
    [sweep] table: methods, warmup_s, canny_settings; or a shipped spec's name, e.g. sweep_stripes),
    making the dataset in OUT/dataset when missing."""
    from evedge.parallel import ClusterError
    from evedge.sim.dataset import dataset_path
    from evedge.sim.scene import SceneError

    from .sweep import load_sweep, run_sweep

    _check_out(out)
    try:
        parsed = load_sweep(dataset_path(spec))
        res = run_sweep(parsed, out, workers=workers, scheduler=scheduler, retries=retries,
                        progress=not no_progress)
    except (SceneError, ClusterError, OSError) as err:
        raise click.ClickException(str(err)) from None
    click.echo(f"{res['graded']} sequences graded ({res['reused']} reused), {res['rows']} result rows: "
               f"{res['results']}")
    click.echo(f"report: {res['report']}")
    for i, why in sorted(res["failed"].items()):
        click.echo(f"  sequence {i} not graded: {why}", err=True)
    if res["failed"]:
        raise SystemExit(1)
