"""The ``evedge`` command: one CLI, subcommands loaded on first use.

Each subcommand lives beside the code it drives (``evedge.io`` for ``info``,
``evedge.sim`` for ``simulate``, ...) and is imported only when called, so
``evedge info`` does not pay for numba or pyrender.
"""

from __future__ import annotations

import importlib

import click

from . import __version__

# name -> "module:attribute" of a click command
_SUBCOMMANDS = {
    "info": "evedge.io.cli:info",
    "convert": "evedge.io.cli:convert",
    "render": "evedge.video_cli:render",
    "simulate": "evedge.sim.cli:simulate",
    "dataset": "evedge.sim.dataset_cli:dataset",
    "detect": "evedge.detector.cli:detect",
    "bench": "evedge.bench.cli:bench",
    "demo": "evedge.bench.cli:demo",
    "grade": "evedge.bench.cli:grade",
}


class _LazyGroup(click.Group):
    def list_commands(self, ctx):
        return sorted(_SUBCOMMANDS)

    def get_command(self, ctx, name):
        target = _SUBCOMMANDS.get(name)
        if target is None:
            return None
        module, attr = target.split(":")
        return getattr(importlib.import_module(module), attr)


@click.group(cls=_LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="evedge")
def main() -> None:
    """evedge: edge detection for event cameras by lifetime estimation, and its testbench."""


if __name__ == "__main__":
    main()
