"""Click options shared by the ``evedge`` subcommands (one home for the parsing)."""

from __future__ import annotations

import click

from .events import SensorSize

SENSOR_HELP = "Sensor size (e.g. 240x180, dvs128) when the file does not say."


def parse_sensor(ctx, param, value):
    """Click callback: ``--sensor WxH`` (or a preset name) to a :class:`SensorSize`.

    ``None`` passes through (option not given); a bad value becomes a
    :class:`click.BadParameter` naming the option, not a traceback.
    """
    if value is None:
        return None
    try:
        return SensorSize.parse(value)
    except (ValueError, TypeError) as err:
        raise click.BadParameter(str(err), ctx=ctx, param=param) from None


def sensor_option(help: str = SENSOR_HELP):
    """The ``--sensor WxH`` option, parsed to a :class:`SensorSize` (``None`` when absent)."""
    return click.option("--sensor", callback=parse_sensor, metavar="WxH", help=help)
