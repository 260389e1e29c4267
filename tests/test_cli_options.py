"""The shared ``--sensor WxH`` option: one parser, used by ``evedge info`` and ``evedge detect``."""

import click
import pytest
from click.testing import CliRunner

from evedge._cli_options import sensor_option
from evedge.detector.cli import detect
from evedge.events import SensorSize
from evedge.io.cli import info


@click.command()
@sensor_option()
def _echo(sensor):
    click.echo(repr(sensor))


@pytest.mark.parametrize("args, shown", [
    (["--sensor", "240x180"], repr(SensorSize(240, 180))),
    (["--sensor", "dvs128"], repr(SensorSize(128, 128))),
    ([], "None"),
])
def test_sensor_option_parses(args, shown):
    result = CliRunner().invoke(_echo, args)
    assert result.exit_code == 0, result.output
    assert result.output.strip() == shown


@pytest.mark.parametrize("command", [_echo, info, detect], ids=["option", "info", "detect"])
def test_bad_sensor_is_a_usage_error_naming_the_option(tmp_path, command):
    src = tmp_path / "events.txt"
    src.write_text("0.1 1 2 0\n")
    args = [] if command is _echo else [str(src)]
    args += ["-o", str(tmp_path / "out")] if command is detect else []
    result = CliRunner().invoke(command, [*args, "--sensor", "240by180"])
    assert result.exit_code == 2, result.output
    assert "--sensor" in result.output and "expected WIDTHxHEIGHT" in result.output
    assert "Traceback" not in result.output
