"""The ``indgen`` command line: one module per subcommand (``indgen_vla/app/cli/<command>.py``), each holding its
``add_parser(subparsers)`` and its handler ``main(args) -> int``, which turns the flags into keyword arguments of a
library call and prints the result.

Handlers are ``"package.module:function"`` strings, imported only when their subcommand runs, and parser modules
import nothing heavy, so ``indgen --help`` never imports torch, robosuite or lerobot.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import sys
from collections.abc import Sequence

from indgen_vla import __version__
from indgen_vla.app.cli.options import IndgenParser
from indgen_vla.app.interrupts import by_sigterm, interrupted_message, sigterm_raises
from indgen_vla.core.errors import EXIT_SIGTERM, IndgenError

# subcommand -> "package.module:function" handler taking the parsed Namespace, imported only when that subcommand runs
HANDLERS: dict[str, str] = {
    "evaluate": "indgen_vla.app.cli.evaluate:main",
    "certify": "indgen_vla.app.cli.certify:main",
    "preview": "indgen_vla.app.cli.preview:main",
    "report": "indgen_vla.app.cli.report:main",
    "merge": "indgen_vla.app.cli.merge:main",
    "compare": "indgen_vla.app.cli.compare:main",
    "reference": "indgen_vla.app.cli.reference:main",
    "serve": "indgen_vla.app.cli.serve:main",
    "scenes": "indgen_vla.app.cli.catalog:main",
    "axes": "indgen_vla.app.cli.catalog:main",
    "policies": "indgen_vla.app.cli.catalog:main",
    "setup": "indgen_vla.app.cli.setup:main",
    "blockenv": "indgen_vla.app.cli.blockenv:main",
    "demos": "indgen_vla.app.cli.demos:main",
    "mimicgen": "indgen_vla.app.cli.mimicgen:main",
    "train": "indgen_vla.app.cli.train:main",
    "real": "indgen_vla.app.cli.real:main",
    "budget": "indgen_vla.app.cli.budget:main",
    "gate": "indgen_vla.app.cli.gate:main",
    "import": "indgen_vla.app.cli.import_runs:main",
    "series": "indgen_vla.app.cli.series:main",
    "view": "indgen_vla.app.cli.view:main",
}

# the modules whose ``add_parser(subparsers)`` build ``indgen --help``, in its order; each imports nothing heavy at
# module level (its handler imports what it runs)
PARSERS: tuple[str, ...] = tuple(
    f"indgen_vla.app.cli.{name}"
    for name in ("evaluate", "certify", "preview", "report", "merge", "compare", "reference", "gate", "import_runs",
                 "series", "serve", "catalog", "setup", "blockenv", "demos", "mimicgen", "train", "real", "budget", "view")
)  # fmt: skip

PASSTHROUGH = {"blockenv", "demos", "mimicgen", "train", "real"}  # subcommands that parse their own arguments


def build_parser() -> argparse.ArgumentParser:
    parser = IndgenParser(
        prog="indgen",
        description="Measure inductive generalization of robot policies: move a task one atomic step at a "
        "time along one axis, run the policy, report success per level and the break level k*.",
    )
    parser.add_argument("--version", action="version", version=f"indgen-vla {__version__}")
    sp = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=IndgenParser)
    for module in PARSERS:
        importlib.import_module(module).add_parser(sp)
    return parser


def _resolve(command: str):
    importlib.import_module("indgen_vla.app.engine")  # registers the scene-side stand-ins (standin:oracle)
    module, _, func = HANDLERS[command].partition(":")
    return getattr(importlib.import_module(module), func)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``indgen`` console script. Exit codes (docs/cli.md "Exit codes"): 0 success, 1 an
    unexpected crash, 2 bad input (``IndgenError``), 3 ``evaluate`` finished with ``error`` episodes, 4 it
    stopped early because the policy server stayed unreachable, 130 Ctrl-C, 143 SIGTERM."""
    try:
        return _main(argv)
    finally:
        if argv is None:  # the console script: the interpreter exits next
            # its shutdown would garbage-collect every object torch/lerobot/transformers made, several times
            # (seconds after a LeRobot policy, docs/results/benchmarks/startup.md). Frozen, they are left to the OS;
            # atexit handlers still run, and every file of the run is closed by now.
            gc.freeze()


PIPED_COLUMNS = 240  # the table width when stdout is not a terminal and $COLUMNS is unset


def _main(argv: Sequence[str] | None) -> int:
    os.environ.setdefault("MUJOCO_GL", "egl")
    # piped or logged: rich would cut tables (task names, readiness notes) to 80 columns
    if not sys.stdout.isatty():
        os.environ.setdefault("COLUMNS", str(PIPED_COLUMNS))
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if args.command in PASSTHROUGH:
        args.rest = extra
    elif extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    if not args.command:
        parser.print_help()
        return 2
    try:
        with sigterm_raises():
            return int(_resolve(args.command)(args) or 0)
    except IndgenError as e:
        print(f"error: {e}", file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt as e:  # Ctrl-C, or SIGTERM (``Terminated``, or what a library made of it)
        if by_sigterm(e):
            print(
                interrupted_message(args).replace("interrupted:", "terminated (SIGTERM):", 1), file=sys.stderr
            )
            return EXIT_SIGTERM
        print(interrupted_message(args), file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `indgen axes | head`: the reader left; not an error of ours
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
