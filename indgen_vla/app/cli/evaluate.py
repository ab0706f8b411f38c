"""``indgen evaluate``: its flags; the handler turns them into an ``EvalConfig``, runs it
(``indgen_vla.app.engine.run.evaluate``) and prints the tables."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.options import add_level_options


def _workers(text: str) -> int | str:
    """``--workers``: a number, or ``auto`` (the Ray backend follows its cluster's CPUs)."""
    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or auto, got {text!r}") from None


def add_parser(sp: argparse._SubParsersAction) -> None:
    """The evaluate subcommand and its flags (a help line each)."""
    p = sp.add_parser("evaluate", help="run a policy along one or more axes and write a run directory")
    p.add_argument("--policy", help="policy spec, e.g. lerobot:HUB_ID, openpi:ws://HOST:PORT, standin:oracle")
    p.add_argument("--scene", help="scene name (see 'indgen scenes')")
    p.add_argument(
        "--task", default=None, help="task of the scene, or 'all' (default: the scene's first task)"
    )
    p.add_argument("--axis", help="axis or comma list of axes (see 'indgen axes')")
    add_level_options(p)
    p.add_argument(
        "--episodes", type=int, default=None, help="episodes per level (default 50; the cap with --adaptive)"
    )
    p.add_argument(
        "--adaptive",
        choices=["kstar", "curve", "until-failure"],
        default=None,
        help="run episodes in rounds and stop a level once a sequential test decides it (kstar: also skip levels "
        "past a decided break; curve: decide every level); until-failure: the paper's real-robot design, "
        "--episodes per level, levels in order until the first observed rate < γ (no test); docs/adaptive.md",
    )
    p.add_argument(
        "--adaptive-delta", type=float, default=None, help="indifference half-width around γ (default 0.1)"
    )
    p.add_argument(
        "--adaptive-alpha", type=float, default=None, help="error rate of each verdict, α = β (default 0.025)"
    )
    p.add_argument("--round-size", type=int, default=None, help="episodes between two looks (default 5)")
    p.add_argument("--workers", type=_workers, default=None,
                   help="worker processes (default: number of cores); with --backend ray the simulator actors, "
                   "or auto: as many as the cluster's CPUs hold, following nodes that join or leave")  # fmt: skip
    p.add_argument(
        "--device", default=None, help="where in-process policies run: cpu, cuda, cuda:N (default cpu)"
    )
    p.add_argument(
        "--precision",
        choices=["fp32", "bf16"],
        default=None,
        help="bf16: autocast forward (lerobot: policies)",
    )
    p.add_argument(
        "--compile",
        choices=["off", "default", "reduce-overhead", "max-autotune"],
        default=None,
        help="torch.compile the policy's per-call forward (lerobot: policies; reduce-overhead = CUDA graphs, "
        "needs --device cuda); the first call compiles, ~/.cache/indgen/inductor keeps it for the next run",
    )
    p.add_argument(
        "--pipeline",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="two environments per worker: one steps while the policy computes the other's chunk (default off)",
    )
    p.add_argument(
        "--share-t0",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="run level 0 once per task for the axes whose level 0 is the same environment; each such axis reports "
        "those episodes as its own (episodes.parquet shared_from; default on, --adaptive too)",
    )
    p.add_argument(
        "--backend",
        choices=["local", "ray"],
        default=None,
        help="local worker processes or Ray (default local)",
    )
    p.add_argument("--seed", type=int, default=None, help="run seed (default 0)")
    p.add_argument("--max-steps", type=int, default=None, help="override the scene's episode length")
    p.add_argument(
        "--replan-steps", type=int, default=None, help="actions executed per chunk (default: the policy's)"
    )
    p.add_argument(
        "--image-size", type=int, default=None, help="rendered image side in pixels (default: the policy's)"
    )
    p.add_argument("--video", action="store_true", help="write mp4 videos of episodes")
    p.add_argument(
        "--video-per-level", type=int, default=None, help="videos per level when --video (default 1)"
    )
    p.add_argument(
        "--data-regime", default=None, help="label of the training data regime, e.g. h-only or h+mg"
    )
    p.add_argument("--gamma", type=float, default=None, help="break threshold for the report (default 0.2)")
    p.add_argument(
        "--allow-infeasible", action="store_true", help="evaluate levels the oracle did not certify"
    )
    p.add_argument(
        "--smoke",
        action="store_true",
        help="run an image policy on placeholder assets (RoboCasa's boxes) anyway; recorded as not a measurement",
    )
    p.add_argument(
        "--trust-remote-code", action="store_true", help="allow checkpoints that ship their own code"
    )
    p.add_argument(
        "--allow-protocol-mismatch",
        action="store_true",
        help="resume a run although its protocol fingerprint changed in a field that changes outcomes "
        "(simulator versions, assets, horizon, cameras, render backend, policy conventions); the manifest lists it",
    )
    p.add_argument(
        "--server-patience",
        type=float,
        default=None,
        help="seconds to keep reconnecting to an unreachable policy server before stopping (default 600)",
    )
    p.add_argument(
        "--config",
        default=None,
        help="shipped preset name (configs/paper) or YAML path; flags override it",
    )
    p.add_argument(
        "--preregistered", default=None, metavar="LOCK",
        help="a plan.lock written by 'indgen budget --write': refuse to run anything that deviates from it",
    )  # fmt: skip
    p.add_argument("--out", help="run directory (re-run the same command to resume)")
    p.add_argument("--log", choices=["trackio", "wandb"], default=None,
                   help="also log rates with CIs, k*, verdicts, failure modes, config, fingerprint and videos to this "
                   "tracker (optional extras; trackio is local, wandb honours WANDB_MODE=offline)")  # fmt: skip
    p.add_argument("--log-project", default="indgen", help="the tracker's project name (default indgen)")


def main(args: argparse.Namespace) -> int:
    """Exit 0 only when every planned episode finished ``ok``, EXIT_EPISODE_ERRORS (3) when some ended ``error``
    (re-run to retry them); a run that stopped early raises (ServerUnreachableError -> EXIT_STOPPED (4), Ctrl-C ->
    130), bad input ConfigError -> 2."""
    import json
    import sys

    from indgen_vla.app.engine.config import config_from_args
    from indgen_vla.app.engine.run import evaluate
    from indgen_vla.core.errors import EXIT_EPISODE_ERRORS
    from indgen_vla.core.reporting.report import print_tables, run_label
    from indgen_vla.core.runs.records import SUMMARY, RunDir

    cfg = config_from_args(args)
    out = evaluate(cfg)
    run = RunDir.open(out)
    if args.log:
        from indgen_vla.app.engine.trackers import log_runs

        log_runs(args.log, [(None, out)], project=args.log_project, name=out.name)
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
