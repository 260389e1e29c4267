"""``evedge info``: what is in an event file."""

from __future__ import annotations

import json

import click

from .._cli_options import sensor_option
from ..events import SensorSize


@click.command()
@click.argument("file", type=click.Path(path_type=str))
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@sensor_option()
@click.option("--format", "fmt", type=click.Choice(["ecd", "mat", "hdf5", "aedat4"]),
              help="Skip format detection.")
@click.option("--sort", is_flag=True, help="Sort events by time (stable) if the file is unsorted.")
def info(file: str, as_json: bool, sensor: SensorSize | None, fmt: str | None, sort: bool) -> None:
    """Summarise an event FILE: count, duration, sensor, rates, polarity, frames, truth.

    FILE is an Event Camera Dataset folder or events.txt, a .mat (DVS128
    lifetime data), an evedge .h5, or an .aedat4 file.
    """
    from .read import read_events
    from .summary import format_summary, summarize

    try:
        recording = read_events(file, sensor_size=sensor, format=fmt, sort=sort)
    except (ValueError, TypeError, OSError) as err:
        raise click.ClickException(str(err)) from err
    summary = summarize(recording)
    click.echo(json.dumps(summary, indent=2) if as_json else format_summary(summary))
