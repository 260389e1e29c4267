"""``evedge info`` (what is in an event file) and ``evedge convert`` (from one format to another)."""

from __future__ import annotations

import json

import click

from .._cli_options import sensor_option
from ..events import SensorSize
from .registry import formats


def _readable() -> list[str]:
    return sorted(n for n, f in formats().items() if f.read is not None)


def _writable() -> list[str]:
    return sorted(n for n, f in formats().items() if f.write is not None)


@click.command()
@click.argument("file", type=click.Path(path_type=str))
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@sensor_option()
@click.option("--format", "fmt", type=click.Choice(_readable()), help="Skip format detection.")
@click.option("--sort", is_flag=True, help="Sort events by time (stable) if the file is unsorted.")
def info(file: str, as_json: bool, sensor: SensorSize | None, fmt: str | None, sort: bool) -> None:
    """Summarise an event FILE: count, duration, sensor, rates, polarity, frames, truth.

    FILE is any readable format: an Event Camera Dataset folder or
    events.txt, .mat, evedge .h5, .aedat4, .aedat (2.0/3.1), Prophesee .raw
    (EVT 2/3) or .dat, or .es.
    """
    from .read import read_events
    from .summary import format_summary, summarize

    try:
        recording = read_events(file, sensor_size=sensor, format=fmt, sort=sort)
    except (ValueError, TypeError, OSError) as err:
        raise click.ClickException(str(err)) from err
    summary = summarize(recording)
    click.echo(json.dumps(summary, indent=2) if as_json else format_summary(summary))


@click.command()
@click.argument("source", type=click.Path(path_type=str))
@click.argument("target", type=click.Path(path_type=str))
@click.option("--format", "fmt", type=click.Choice(_writable()),
              help="Output format (default: from TARGET's extension; .raw writes EVT 3, no extension an ECD folder).")
@click.option("--from", "src_fmt", type=click.Choice(_readable()), help="Input format (default: detected).")
@sensor_option()
@click.option("--sort", is_flag=True, help="Sort events by time (stable) if SOURCE is unsorted.")
def convert(source: str, target: str, fmt: str | None, src_fmt: str | None, sensor: SensorSize | None,
            sort: bool) -> None:
    """Convert the event file SOURCE to TARGET (any readable format to any writable one).

    The write is atomic: TARGET is complete or untouched. What the output
    format cannot hold (frames, truth, edge maps) is named on stderr.
    """
    from .read import read_events
    from .registry import get_format, output_format
    from .write import write_events

    try:
        recording = read_events(source, sensor_size=sensor, format=src_fmt, sort=sort)
        name = fmt or output_format(target)
        written = write_events(target, recording, format=name)
    except (ValueError, TypeError, OSError) as err:
        raise click.ClickException(str(err)) from err
    holds = get_format(name).holds
    dropped = [k for k in ("frames", "truth", "edges") if getattr(recording, k) is not None and k not in holds]
    if dropped:
        click.echo(f"note: {name} holds events only here; not written: {', '.join(dropped)}", err=True)
    click.echo(f"{written}: {recording.events.size} events, {recording.sensor_size.width}x"
               f"{recording.sensor_size.height}, {name}")
