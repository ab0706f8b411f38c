"""``indgen merge RUN... --out DIR``: its parser; the handler merges the shards (``studies.merge.merge``) and prints
the tables and what is left to run."""

from __future__ import annotations

import argparse

from indgen_vla.core.runs.records import EPISODES, REPORT


def add_parser(sp: argparse._SubParsersAction) -> None:
    """The merge subcommand: the shards and the merged run directory."""
    p = sp.add_parser(
        "merge",
        help="merge the shards of one protocol (evaluate runs split by --task or --axis) into one run directory",
        description="Shards of one evaluate command split over a cluster (one job per task or axis) as one ordinary "
        "run directory: the union of their plans and every finished episode, for report, compare, reference and a "
        "resume. Refuses shards that are not parts of one protocol (plan, fingerprint, outcomes); never writes into "
        "a shard.",
    )
    p.add_argument(
        "runs",
        nargs="+",
        metavar="RUN_DIR",
        help="the shards' run directories (written by 'indgen evaluate')",
    )
    p.add_argument("--out", required=True, help="the merged run directory (new, or an empty directory)")


def main(args: argparse.Namespace) -> int:
    """Merge the shards into ``--out``, print its tables, the merge's notes and where the report is."""
    import shlex

    from indgen_vla.app.api import family_of  # lazy: start-up (numpy)
    from indgen_vla.app.studies.merge import merge  # lazy: start-up (numpy)
    from indgen_vla.core.reporting.report import print_tables, run_label  # lazy: start-up (numpy)

    command = " ".join(["indgen", "merge", *map(shlex.quote, args.runs), "--out", shlex.quote(args.out)])
    run, summary, lines = merge(
        args.runs, args.out, family_of, command
    )  # the shards' config names the family
    print_tables([(run_label(run), summary)])
    for line in lines:
        print(line)
    print(f"report: {run.path / REPORT}\nplots:  {run.path / 'plots'}/\nepisodes: {run.path / EPISODES}")
    return 0
