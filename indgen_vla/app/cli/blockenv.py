"""``indgen blockenv sample|train|eval|reproduce|ablate``: a passthrough subcommand; its sub-parsers and their
handlers are the BlockEnv study's own CLI (``indgen_vla.app.blockenv.cli``)."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.options import add_passthrough


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen blockenv`` parses its own arguments (``main``)."""
    add_passthrough(sp, "blockenv", "the toy BlockEnv benchmark: sample | train | eval | reproduce | ablate")


def main(args: argparse.Namespace) -> int:
    """Parse ``args.rest`` with the blockenv sub-parsers and run the one named."""
    from indgen_vla.app.blockenv.cli import run

    return run(args.rest)
