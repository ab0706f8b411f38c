"""``indgen series ROOT``: evaluate's protocol flags over every checkpoint of a training output (the work is
``indgen_vla.app.studies.series``, imported only when the command runs: ``indgen --help`` stays light)."""

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
    from pathlib import Path

    from indgen_vla.app.engine.config import config_from_args
    from indgen_vla.app.studies.series import run_series
    from indgen_vla.core.comparison.series_report import write_series
    from indgen_vla.core.errors import ConfigError

    if args.poll <= 0 or args.idle_stop < 0:
        raise ConfigError("--poll must be > 0 and --idle-stop >= 0 seconds")
    ns = argparse.Namespace(**vars(args))
    ns.policy, ns.out = "series", str(Path(args.out) / "runs" / "_")  # replaced per checkpoint
    base = config_from_args(ns)
    out = Path(args.out)
    logged: set[int] = set()

    def report(entries):
        write_series(entries, out, base.plan.gamma)
        if args.log:
            from indgen_vla.app.engine.trackers import log_runs

            logged.update(log_runs(args.log, entries, project=args.log_project, name=out.name, skip=logged))

    entries = run_series(base, args.roots, out, follow=args.follow, poll_s=args.poll, idle_stop_s=args.idle_stop,
                         after_each=report)  # fmt: skip
    report(entries)
    print(f"series: {len(entries)} checkpoint(s); report: {out / 'series.md'}\njson:   {out / 'series.json'}\n"
          f"plots:  {out / 'plots'}/")  # fmt: skip
    return 0
