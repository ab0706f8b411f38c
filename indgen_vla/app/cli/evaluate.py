"""``indgen evaluate``: its flags; the handler turns them into an ``EvalConfig``, runs it
(``indgen_vla.app.engine.run.evaluate``) and prints the tables."""

from __future__ import annotations

import argparse
from collections.abc import Iterable

from indgen_vla.app.cli.options import add_config_flags
from indgen_vla.app.engine.config import OPTIONS, config_from_args
from indgen_vla.core.errors import EXIT_EPISODE_ERRORS, EXIT_UNAVAILABLE
from indgen_vla.core.reporting.certification_view import unavailable_rows
from indgen_vla.core.runs.records import SUMMARY, RunDir

# evaluate's config options (flat names, engine/config.py) in --help's order around the command's own --config,
# --log and --log-project; an option listed in neither tuple is added at the end of the first (before --config)
FLAGS_BEFORE_CONFIG = ("policy", "scene", "task", "axes", "levels", "step", "axes_preset", "episodes", "adaptive",
                       "adaptive_delta", "adaptive_alpha", "round_size", "workers", "device", "precision", "compile",
                       "pipeline", "share_t0", "backend", "seed", "max_steps", "replan_steps", "image_size", "video",
                       "video_per_level", "data_regime", "gamma", "allow_infeasible", "smoke", "trust_remote_code",
                       "allow_protocol_mismatch", "server_patience", "split", "obj_registries")  # fmt: skip
FLAGS_AFTER_CONFIG = ("preregistered", "out")


def add_parser(sp: argparse._SubParsersAction) -> None:
    """The evaluate subcommand: a flag per config option with a help line (made from the config's fields), and
    the command's own --config, --log and --log-project."""
    p = sp.add_parser("evaluate", help="run a policy along one or more axes and write a run directory")
    add_protocol_flags(p)


def add_protocol_flags(p: argparse.ArgumentParser, skip: Iterable[str] = ()) -> None:
    """evaluate's flags in its --help order, all but ``skip``'s dests: one per ``EvalConfig`` option with a help
    line (made from the config's fields), and --config, --log, --log-project. ``indgen budget`` and ``indgen
    series`` take a protocol exactly as evaluate does, with these."""
    skip = set(skip)
    listed = {*FLAGS_BEFORE_CONFIG, *FLAGS_AFTER_CONFIG}
    before = [*FLAGS_BEFORE_CONFIG, *(n for n, o in OPTIONS.items() if o.flag and n not in listed)]
    add_config_flags(p, [n for n in before if OPTIONS[n].flag not in skip])
    if "config" not in skip:
        p.add_argument("--config", default=None,
                       help="shipped preset name (configs/paper) or YAML path; flags override it")  # fmt: skip
    add_config_flags(p, [n for n in FLAGS_AFTER_CONFIG if OPTIONS[n].flag not in skip])
    if "log" not in skip:
        p.add_argument("--log", choices=["trackio", "wandb"], default=None,
                       help="also log rates with CIs, k*, verdicts, failure modes, config, fingerprint and videos to "
                       "this tracker (optional extras; trackio is local, wandb honours WANDB_MODE=offline)")  # fmt: skip
    if "log_project" not in skip:
        p.add_argument("--log-project", default="indgen", help="the tracker's project name (default indgen)")


def main(args: argparse.Namespace) -> int:
    """Exit 0 only when every planned episode finished ``ok``, EXIT_EPISODE_ERRORS (3) when some ended ``error``
    (re-run to retry them), EXIT_UNAVAILABLE (6) when the only others are ``unavailable`` (ruled out by their level:
    nothing to retry); a run that stopped early raises (ServerUnreachableError -> EXIT_STOPPED (4), Ctrl-C -> 130),
    bad input ConfigError -> 2."""
    import json
    import sys

    from indgen_vla.app.api import family_of  # lazy: start-up (numpy)
    from indgen_vla.app.engine.run import evaluate  # lazy: start-up (numpy)
    from indgen_vla.core.reporting.report import print_tables, run_label  # lazy: start-up (numpy)

    cfg = config_from_args(args)
    if args.log:
        from indgen_vla.app.engine.trackers import tracker_module  # lazy: start-up (numpy)

        tracker_module(args.log)  # a missing tracker is refused before any episode runs
    out = evaluate(cfg, family_of(cfg.plan))  # the family looked up once, here at the edge
    run = RunDir.open(out)
    if args.log:
        from indgen_vla.app.engine.trackers import log_runs  # lazy: start-up (numpy)

        log_runs(args.log, [(None, out)], project=args.log_project, name=out.name)
    print_tables([(run_label(run), json.loads((out / SUMMARY).read_text()))])
    print(f"report: {out / 'report.md'} (in a browser: {out / 'report.html'})\nplots:  {out / 'plots'}/ (success "
          f"curves; 'indgen report {out}' draws every plot)\nepisodes: {out / 'episodes.parquet'}")  # fmt: skip
    eps = run.episodes()
    ruled_out = unavailable_rows(eps)  # an empty run's frame has the columns too
    # an unavailable episode is its seed's (a RoboCasa kitchen too narrow for pick_x, a LIBERO state that does not
    # hold a moved object): a re-run repeats it, so it is no error to retry
    unavailable, errors = int(ruled_out.sum()), int(((eps["status"] == "error") & ~ruled_out).sum())
    if unavailable:
        print(f"note: {unavailable} episode(s) are unavailable: their initial state cannot hold the level (out of "
              "n, named in report.md's infeasible cells); nothing to retry", file=sys.stderr)  # fmt: skip
    if errors:
        print(f"warning: {errors} episode(s) ended with errors (see the 'error' column); re-run the same command to "
              "retry them", file=sys.stderr)  # fmt: skip
        return EXIT_EPISODE_ERRORS
    return EXIT_UNAVAILABLE if unavailable else 0
