"""``evedge dataset``: make (or complete) a dataset from a spec, on Dask."""

from __future__ import annotations

from pathlib import Path

import click


@click.command()
@click.argument("spec", type=click.Path(path_type=Path))  # a file or a shipped spec's name
@click.option("-o", "--output", "output", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Dataset folder (created; a rerun completes and verifies it).")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Worker processes of the local Dask cluster (default: the cores).")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run on an existing Dask scheduler (tcp://host:8786) instead of a local cluster; "
                   "its workers must see OUTPUT at the same path.")
@click.option("--layout", "layouts", multiple=True, type=click.Choice(["evedge", "dsec"]),
              help="File layout(s) of each sequence, repeatable (default: evedge). dsec: "
                   "dsec/<seq>/events/left/events.h5 as DSEC's loaders read it.")
@click.option("--retries", type=click.IntRange(min=0), default=2, show_default=True,
              help="Extra attempts of a sequence whose task raised.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
def dataset(spec: Path, output: Path, workers, scheduler, layouts, retries: int, quiet: bool) -> None:
    """Make the dataset of SPEC (TOML, see sim/DATASETS.md; or a shipped spec's name, e.g. small) in OUTPUT.

    Sequences whose files exist and match the manifest's sha256 are kept;
    missing, corrupt or failed ones are made again. Exits with status 1 when
    a sequence failed (the others are made; the manifest says why).
    """
    from evedge.parallel import ClusterError

    from .dataset import dataset_path, load_dataset
    from .dataset_run import generate_dataset
    from .scene import SceneError

    if output.is_symlink():
        raise click.ClickException(f"{output} is a symbolic link; give the folder it points to")
    if output.is_dir() and any(output.iterdir()):
        if not (output / "dataset.json").is_file():
            raise click.ClickException(f"{output} is not empty and holds no dataset.json: it is not a dataset "
                                       f"folder and is not written into; choose another output folder")
        # the same spec's dataset is completed and verified, never replaced (another spec's is refused)
        click.echo(f"completing the existing dataset in {output} (verified sequences are kept)", err=True)
    try:
        parsed = load_dataset(dataset_path(spec))
        run = generate_dataset(parsed, output, layouts=layouts or ("evedge",), workers=workers,
                               scheduler=scheduler, retries=retries, progress=not quiet)
    except (SceneError, ClusterError, OSError) as err:
        raise click.ClickException(str(err)) from None
    ok = [r for r in run.rows.values() if r["status"] == "ok"]
    click.echo(f"{output}: {len(ok)}/{parsed.count} sequences ok ({run.made} made, {run.skipped} verified and "
               f"kept, {run.failed} failed), {sum(r['n_events'] for r in ok)} events; see {output / 'README.md'}")
    if run.failed:
        for r in sorted(run.rows.values(), key=lambda r: r["index"]):
            if r["status"] != "ok":
                click.echo(f"  {r['name']}: {r['error']}", err=True)
        raise SystemExit(1)
