"""``indgen budget``: size the protocol an ``evaluate`` command would run before it runs (the arithmetic is
``indgen_vla.app.studies.budget``, imported only when the command runs)."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.options import add_evaluate_protocol
from indgen_vla.app.studies.budget import DEFAULT_DROP, DEFAULT_STARTUP_S  # light: no numpy, no scene


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen budget``'s parser: evaluate's protocol options (its own definitions) and the budget's, whose
    --workers (a list here) replaces evaluate's."""
    p = sp.add_parser(
        "budget", conflict_handler="resolve",
        help="before a run: episodes, adaptive cost, wall time and GPU-hours from a smoke run; --write a plan.lock",
        description="Size the protocol an 'indgen evaluate' command would run (same flags or --config), without "
        "building a scene: episodes per level, power against T0, the adaptive rule's expected episodes, the whole "
        "command's wall time per worker count, and a pre-registered plan.lock.",
    )  # fmt: skip
    add_evaluate_protocol(sp, p, {"workers", "out", "log", "log_project", "preregistered"})
    p.add_argument("--workers", default=None, metavar="W[,W...]",
                   help="worker counts to project, e.g. 8,16 (default: the number of cores)")  # fmt: skip
    p.add_argument("--timing", default=None, metavar="RUN",
                   help="a smoke run's directory made on the target box: its manifest's timing and its episodes")  # fmt: skip
    p.add_argument("--steps-per-s", type=float, default=None,
                   help="without a smoke run: control steps per second of one worker, policy included")  # fmt: skip
    p.add_argument("--startup-s", type=float, default=None,
                   help=f"with --steps-per-s: start-up, report and exit seconds (default {DEFAULT_STARTUP_S:g})")  # fmt: skip
    p.add_argument("--assume", default=None, metavar="S0,S1,...",
                   help="assumed success rate per |level| 0, 1, 2, ... (every axis and task), e.g. 0.95,0.9,0.5,0.1")  # fmt: skip
    p.add_argument("--pilot", default=None, metavar="RUN",
                   help="a pilot run of the protocol: its per-level counts, with their uncertainty, as the curve")  # fmt: skip
    p.add_argument("--drop", type=float, default=DEFAULT_DROP,
                   help=f"the drop from T0 the paired test should see (default {DEFAULT_DROP:g})")  # fmt: skip
    p.add_argument("--ci", choices=["wilson", "clopper-pearson"], default="wilson",
                   help="the per-level interval report will use (default wilson)")  # fmt: skip
    p.add_argument("--replicates", type=int, default=120,
                   help="simulated tasks per curve draw for the adaptive rule (default 120)")  # fmt: skip
    p.add_argument("--gpus", type=int, default=None,
                   help="GPUs the run holds, for GPU-hours (default 1 with --device cuda, else 0)")  # fmt: skip
    p.add_argument(
        "--write", default=None, metavar="LOCK", help="write the pre-registered design to this file"
    )
    p.add_argument("--json", action="store_true", help="machine-readable output")


def main(args: argparse.Namespace) -> int:
    """Print the budget (``--json``: the dict) and exit 0; bad input exits 2."""
    import json

    from indgen_vla.app.studies.budget import plan_budget, render, request_from_args

    out = plan_budget(request_from_args(args))
    print(json.dumps(out, indent=2, default=str) if args.json else "\n".join(render(out)))
    return 0
