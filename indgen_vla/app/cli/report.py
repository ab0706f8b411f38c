"""``indgen report RUN...``: its parser; the handler writes the reports (``core.reporting.report.write_reports``)
and prints what it wrote and the tables."""

from __future__ import annotations

import argparse

from indgen_vla.core.protocol.plan_lock import run_status
from indgen_vla.core.runs.records import REPORT, SUMMARY, RunDir


def add_parser(sp: argparse._SubParsersAction) -> None:
    """The report subcommand: run directories, γ, the interval, the equivalence margin and the overlay folder."""
    p = sp.add_parser("report", help="summary.json, report.md and plots for one or more run directories")
    p.add_argument("runs", nargs="+", metavar="RUN_DIR", help="run directories written by 'indgen evaluate'")
    p.add_argument("--gamma", type=float, default=0.2, help="break threshold (paper: 0.2)")
    p.add_argument(
        "--ci",
        choices=["wilson", "clopper-pearson"],
        default="wilson",
        help="95%% interval of each level's success rate (default wilson; clopper-pearson is exact, wider)",
    )
    p.add_argument(
        "--margin", type=float, default=None, metavar="M",
        help="also test, per level, whether the change from level 0 lies within ±M (paired equivalence test, e.g. "
        "0.1 for ±10 points): the only way the report says \"no change\"",
    )  # fmt: skip
    p.add_argument(
        "--out", default=None, help="where to put the multi-run overlay (default: FIRST_RUN/overlay)"
    )
    p.add_argument(
        "--lock-published", default=None, metavar="WHERE",
        help="where the plan.lock's hash was published before the run (a URL, a commit); printed beside the hash",
    )  # fmt: skip


def main(args: argparse.Namespace) -> int:
    """Write each run's report (and the overlay of several), then print the files and the tables."""
    # lazy: start-up (numpy)
    from indgen_vla.core.reporting.report import (
        overlay_dir,
        print_tables,
        write_reports,
    )

    results = write_reports(args.runs, gamma=args.gamma, ci=args.ci, out=args.out, margin=args.margin)
    for path in args.runs:
        run = RunDir(path)
        print(f"{run.path}: wrote {SUMMARY}, {REPORT}, report.html, plots/")
        # "locked, hash H, followed (published WHERE)" or its deviations (docs/budget.md)
        published = args.lock_published
        if line := run_status(run.manifest, len(run.episodes()), published, gamma=args.gamma, ci=args.ci):
            print(f"{run.path}: {line}")
    if len(args.runs) > 1:
        out = overlay_dir(args.runs[0], args.out)
        print(f"overlay: {out / REPORT}, {out / 'report.html'}, {out / 'plots'}/")
    print_tables(results)
    return 0
