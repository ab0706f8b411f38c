"""``indgen budget``: size the protocol an ``evaluate`` command would run before it runs (the arithmetic is
``indgen_vla.app.studies.budget``, imported only when the command runs)."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.evaluate import add_protocol_flags
from indgen_vla.app.config_fields import add_flags
from indgen_vla.app.studies.config import BudgetConfig  # light: no numpy, no scene


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen budget``'s parser: evaluate's protocol flags and the budget's own (``BudgetConfig``'s fields), whose
    --workers (a list here) replaces evaluate's."""
    p = sp.add_parser(
        "budget",
        help="before a run: episodes, adaptive cost, wall time and GPU-hours from a smoke run; --write a plan.lock",
        description="Size the protocol an 'indgen evaluate' command would run (same flags or --config), without "
        "building a scene: episodes per level, power against T0, the adaptive rule's expected episodes, the whole "
        "command's wall time per worker count, and a pre-registered plan.lock.",
    )  # fmt: skip
    add_protocol_flags(p, skip={"workers", "out", "log", "log_project", "preregistered"})
    add_flags(p, BudgetConfig)
    p.add_argument("--json", action="store_true", help="machine-readable output")


def main(args: argparse.Namespace) -> int:
    """Print the budget (``--json``: the dict) and exit 0; bad input exits 2."""
    import json

    from indgen_vla.app.api import budget  # lazy: start-up
    from indgen_vla.app.studies.budget import config_from_budget_args, render  # lazy: start-up

    out = budget(config_from_budget_args(args))
    print(json.dumps(out, indent=2, default=str) if args.json else "\n".join(render(out)))
    return 0
