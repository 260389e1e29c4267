"""The top-level ``evedge`` command: subcommands are listed and load lazily."""

from click.testing import CliRunner

from evedge import __version__
from evedge.cli import _SUBCOMMANDS, main


def test_help_lists_every_subcommand():
    result = CliRunner().invoke(main, ["--help"])
    assert result.exit_code == 0, result.output
    for name in ("info", "simulate", "detect", "bench", "demo"):
        assert name in result.output


def test_version():
    result = CliRunner().invoke(main, ["--version"])
    assert result.exit_code == 0
    assert __version__ in result.output


def test_every_subcommand_resolves_and_has_help():
    for name in _SUBCOMMANDS:
        result = CliRunner().invoke(main, [name, "--help"])
        assert result.exit_code == 0, f"evedge {name} --help failed: {result.output}"
        assert "Usage" in result.output


def test_unknown_subcommand_is_an_error():
    result = CliRunner().invoke(main, ["no-such-command"])
    assert result.exit_code != 0
    assert "no-such-command" in result.output
