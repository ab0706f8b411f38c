"""``indgen import lerobot-eval DIR... --out RUN``: its parser; the handler writes the run directory
(``indgen_vla.app.lerobot_bridge.eval_import``) and its report."""

from __future__ import annotations

import argparse

from indgen_vla.core.runs.records import EPISODES, REPORT, RunDir

HARNESSES = ("lerobot-eval",)


def add_parser(sp: argparse._SubParsersAction) -> None:
    """The import subcommand: the harness, its output directories, the run directory to write."""
    p = sp.add_parser(
        "import",
        help="turn another harness' rollouts (lerobot-eval's eval_info.json) into a run directory for report, "
        "compare, gate",
        description="Read the per-episode successes of one or more lerobot-eval output directories and write a run "
        "directory (episodes.parquet, summary.json, report.md, a manifest naming the sources and what they do not "
        "record). A task group written by --env.type=indgen names its own level and episodes (they pair with "
        "indgen evaluate's); any other env's run is the level --axis A --level K. Re-running rewrites --out.",
    )
    p.add_argument("harness", choices=HARNESSES, help="whose output: lerobot-eval")
    p.add_argument(
        "sources", nargs="+", metavar="DIR", help="lerobot-eval --output_dir(s) (or eval_info.json files)"
    )
    p.add_argument("--out", required=True, help="the run directory to write (new, or an earlier import)")
    p.add_argument("--axis", help="the axis of a run that is not --env.type=indgen's (with --level)")
    p.add_argument("--level", type=int, help="its level (with --axis)")
    p.add_argument("--seed", type=int, help="lerobot-eval's --seed, for files that record no seeds (lerobot 0.6; "
                   "default: its default 1000)")  # fmt: skip
    p.add_argument("--policy", help="a label for the policy (eval_info.json does not name it)")
    p.add_argument("--data-regime", default="", help="the data_regime label the rows carry")
    p.add_argument("--gamma", type=float, default=0.2, help="break threshold of the report (default 0.2)")


def main(args: argparse.Namespace) -> int:
    """Import, write the report, print the tables and where things are."""
    from indgen_vla.app.api import import_lerobot_eval  # lazy: start-up (the API loads the engine on use)
    from indgen_vla.core.reporting.report import print_tables, run_label  # lazy: start-up (numpy)
    from indgen_vla.core.reporting.summary import summarize  # lazy: start-up (numpy)

    out = import_lerobot_eval(args.sources, out=args.out, axis=args.axis, level=args.level, seed=args.seed,
                              policy=args.policy, data_regime=args.data_regime, gamma=args.gamma).path  # fmt: skip
    run = RunDir.open(out)
    print_tables([(run_label(run), summarize(run.episodes(), run.manifest, args.gamma))])
    for line in run.manifest["imported"]["unknown"]:
        print(f"not in eval_info.json: {line}")
    print(f"report: {out / REPORT}\nepisodes: {out / EPISODES}")
    return 0
