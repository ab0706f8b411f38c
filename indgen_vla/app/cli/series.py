"""``indgen series ROOT``'s parser: evaluate's protocol flags over every checkpoint of a training output. Its handler is
``indgen_vla.app.engine.series:series_main`` (this module imports nothing of the engine: ``indgen --help`` stays light,
and the modules that build on the parser do not depend on scenes or policies)."""

from __future__ import annotations

import argparse
import copy

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
    evaluate = sp.choices["evaluate"]  # its option definitions, shared (argparse actions are descriptions)
    for action in evaluate._actions:
        if action.dest not in SKIP:
            p._add_action(copy.copy(action))
