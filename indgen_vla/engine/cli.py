"""``indgen evaluate``: turn the parsed flags into an ``EvalConfig``, run it (``engine/run.py``), print the tables."""

from __future__ import annotations

import argparse
import json
import sys

from indgen_vla.engine.config import config_from_args
from indgen_vla.engine.run import evaluate
from indgen_vla.errors import EXIT_EPISODE_ERRORS
from indgen_vla.records import SUMMARY, RunDir


def evaluate_main(args: argparse.Namespace) -> int:
    """CLI handler for ``indgen evaluate``: exit 0 only when every planned episode finished ``ok``,
    EXIT_EPISODE_ERRORS (3) when some ended ``error`` (re-run to retry them); a run that stopped early raises
    (ServerUnreachableError -> EXIT_STOPPED (4), Ctrl-C -> 130), bad input ConfigError -> 2."""
    cfg = config_from_args(args)
    out = evaluate(cfg)
    from indgen_vla.report import print_tables, run_label

    run = RunDir.open(out)
    print_tables([(run_label(run), json.loads((out / SUMMARY).read_text()))])
    print(f"report: {out / 'report.md'} (in a browser: {out / 'report.html'})\nplots:  {out / 'plots'}/\n"
          f"episodes: {out / 'episodes.parquet'}")  # fmt: skip
    errors = run.episodes().query("status == 'error'")["error"]
    if len(errors):
        # an EpisodeUnavailableError is the seed's (e.g. a RoboCasa kitchen too narrow for pick_x): a re-run repeats it
        fixed = int(errors.str.contains("EpisodeUnavailableError", regex=False).sum())
        why = f", {fixed} of them unavailable at every try (their seed rules the level out)" if fixed else ""
        retry = f"; re-run to retry {'the others' if fixed else 'them'}" if fixed < len(errors) else ""
        print(f"warning: {len(errors)} episode(s) ended with errors (see the 'error' column){why}{retry}",
              file=sys.stderr)  # fmt: skip
        return EXIT_EPISODE_ERRORS
    return 0
