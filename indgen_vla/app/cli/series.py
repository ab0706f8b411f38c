"""``indgen series ROOT``: evaluate's protocol flags over every checkpoint of a training output (the work is
``indgen_vla.app.engine.series``, imported only when the command runs: ``indgen --help`` stays light)."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.options import add_evaluate_protocol

SKIP = {"policy", "out", "help"}  # evaluate's options that a series sets per checkpoint (or has its own of)
# (evaluate's --log/--log-project come along: a series logs each checkpoint at its training step)


def add_parser(sp: argparse._SubParsersAction) -> None:
    """Register ``indgen series``: evaluate's own protocol options (the same definitions: ``sp`` must hold evaluate's
    parser already), ROOT, --out, --follow."""
    p = sp.add_parser(
        "series",
        help="evaluate every checkpoint of a training output (LeRobot's ROOT/checkpoints/<step>) and plot success "
        "and k* against the training step",
        description="One evaluate run per checkpoint (same protocol and seeds, so checkpoints are paired), skipping "
        "finished ones; series.md, series.json, plots of success per level and k* per direction against the step, a "
        "trend test over the steps and paired tests between consecutive checkpoints.",
    )
    p.add_argument("roots", nargs="+", metavar="ROOT", help="a LeRobot training output (ROOT/checkpoints/<step>/"
                   "pretrained_model) or checkpoint directories in training order")  # fmt: skip
    p.add_argument(
        "--out", required=True, help="the series directory (runs/<step>, series.md, series.json, plots)"
    )
    p.add_argument(
        "--follow", action="store_true", help="keep polling ROOT for new checkpoints while training runs"
    )
    p.add_argument(
        "--poll", type=float, default=60.0, help="seconds between two looks with --follow (default 60)"
    )
    p.add_argument("--idle-stop", type=float, default=3600.0,
                   help="with --follow: stop after this many seconds without a new checkpoint (default 3600)")  # fmt: skip
    add_evaluate_protocol(sp, p, SKIP)


def main(args: argparse.Namespace) -> int:
    """Run the series, write its report, print where it is."""
    from indgen_vla.app.engine.series import series_main

    return series_main(args)
