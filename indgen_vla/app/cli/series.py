"""``indgen series ROOT``: evaluate's protocol flags over every checkpoint of a training output (the work is
``indgen_vla.app.studies.series``, imported only when the command runs: ``indgen --help`` stays light)."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.evaluate import add_protocol_flags
from indgen_vla.app.config_fields import add_flags, from_args
from indgen_vla.app.engine.config import config_from_args
from indgen_vla.app.studies.config import SeriesConfig  # light: no numpy, no scene

SKIP = {"policy", "out"}  # evaluate's options that a series sets per checkpoint (or has its own of)
# (evaluate's --log/--log-project come along: a series logs each checkpoint at its training step)


def add_parser(sp: argparse._SubParsersAction) -> None:
    """Register ``indgen series``: ROOT, its own options (``SeriesConfig``'s fields: --out, --follow...), then
    evaluate's protocol flags."""
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
    add_flags(p, SeriesConfig)
    add_protocol_flags(p, skip=SKIP)


def main(args: argparse.Namespace) -> int:
    """Run the series, write its report, print where it is."""
    from pathlib import Path

    from indgen_vla.app.api import series  # lazy: start-up

    ns = argparse.Namespace(**vars(args))
    ns.policy, ns.out = "series", str(Path(args.out) / "runs" / "_")  # replaced per checkpoint
    cfg = from_args(
        SeriesConfig, args, command="series", protocol=config_from_args(ns), roots=tuple(args.roots)
    )
    out = Path(cfg.out)
    entries = series(cfg, log=args.log, log_project=args.log_project)
    print(f"series: {len(entries)} checkpoint(s); report: {out / 'series.md'}\njson:   {out / 'series.json'}\n"
          f"plots:  {out / 'plots'}/")  # fmt: skip
    return 0
