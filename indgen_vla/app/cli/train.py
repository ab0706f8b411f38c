"""``indgen train``: its parser (over the passthrough arguments); the handler trains
(``indgen_vla.app.regimes.train.train_policy``) and prints where the checkpoint is."""

from __future__ import annotations

import argparse
import shlex
from collections.abc import Callable
from pathlib import Path
from typing import Any

from indgen_vla.app.cli.options import IndgenParser, add_passthrough


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen train`` parses its own arguments (``main``)."""
    add_passthrough(sp, "train", "train a small LeRobot policy (ACT/Diffusion) on one or more datasets")


def main(args: argparse.Namespace) -> int:
    """The handler: its own parser over ``args.rest``, then the library call."""
    import json

    from indgen_vla.app.regimes.train import (
        DEFAULT_REPO_ID,
        INFO_FILE,
        POLICIES,
        TrainConfig,
        train_policy,
    )
    from indgen_vla.core.protocol.training_support import cells_from_json, support_text

    p = IndgenParser(prog="indgen train", description="train a small lerobot policy on indgen datasets")
    p.add_argument(
        "datasets", nargs="+", help="LeRobotDataset root directories (e.g. human and MimicGen demos)"
    )
    p.add_argument("--out", required=True,
                   help="checkpoint directory: new, or an unfinished one to resume with the same arguments")  # fmt: skip
    p.add_argument("--policy", default="act", choices=POLICIES, help="lerobot policy type to train")
    p.add_argument("--steps", type=int, default=TrainConfig.steps, help="optimiser updates")
    p.add_argument("--batch-size", type=int, default=TrainConfig.batch_size, help="frames per update")
    p.add_argument("--lr", type=float, default=TrainConfig.lr, help="learning rate")
    p.add_argument("--seed", type=int, default=0, help="training seed (init and batch order)")
    p.add_argument("--cameras", default="", help="comma-separated cameras to read; empty = state-only")
    p.add_argument(
        "--objects", action="store_true", help="also read the recorded object poses (low-dim; no cameras)"
    )
    p.add_argument(
        "--chunk-size", type=int, default=TrainConfig.chunk_size, help="actions predicted per chunk"
    )
    p.add_argument(
        "--n-action-steps", type=int, default=TrainConfig.n_action_steps, help="actions executed per chunk"
    )
    p.add_argument(
        "--data-regime", default="", help="label stored with the checkpoint (e.g. human, human+mimicgen)"
    )
    p.add_argument("--repo-id", default=DEFAULT_REPO_ID, help="repo id stored in the checkpoint config")
    p.add_argument("--save-every", type=int, default=None,
                   help="steps between resumable states in OUT/resume (default: every 10%% of --steps)")  # fmt: skip
    add_eval_options(p)
    a = p.parse_args(getattr(args, "rest", args))
    cameras = tuple(c for c in a.cameras.split(",") if c)
    cfg = TrainConfig(policy=a.policy, steps=a.steps, batch_size=a.batch_size, lr=a.lr, seed=a.seed,
                      cameras=cameras, objects=a.objects, chunk_size=a.chunk_size, n_action_steps=a.n_action_steps,
                      save_every=a.save_every)  # fmt: skip
    done = (Path(a.out) / INFO_FILE).is_file()
    hook = eval_hook(a, Path(a.out))
    out = train_policy(a.datasets, a.out, cfg, repo_id=a.repo_id, data_regime=a.data_regime, say=print,
                       progress=lambda s, loss: print(f"  step {s}/{cfg.steps} loss {loss:.4f}", flush=True),
                       after_step=hook)  # fmt: skip
    if done:
        return 0
    info = json.loads((out / INFO_FILE).read_text())
    print(f"trained {a.policy} for {cfg.steps} steps in {info['train_s']:.0f} s; checkpoint in {out}")
    if info["levels"]:
        print(
            f"training levels (train_info.json, read by evaluate): {support_text(cells_from_json(info['levels']))}"
        )
    return 0


def add_eval_options(p: argparse.ArgumentParser) -> None:
    """--eval-every, --eval and --eval-out of ``indgen train``."""
    p.add_argument("--eval-every", type=int, default=None, metavar="N",
                   help="evaluate the weights in memory every N updates (and after the last), with --eval's flags")  # fmt: skip
    p.add_argument("--eval", default=None, metavar="FLAGS",
                   help="evaluate's protocol flags for --eval-every, quoted after =, e.g. --eval='--scene pick_place --axis pick_y "
                   "--levels -2:2 --episodes 10' (or --config PRESET)")  # fmt: skip
    p.add_argument("--eval-out", default=None, help="where the runs and series.md go (default: OUT_evals)")


def eval_config(flags: str, out: Path):
    """The ``EvalConfig`` of ``--eval FLAGS`` (evaluate's own parser and config resolution; ``--policy`` and
    ``--out`` are set per step)."""
    from indgen_vla.app.cli import build_parser
    from indgen_vla.app.engine.config import config_from_args
    from indgen_vla.core.errors import ConfigError

    words = shlex.split(flags)
    bad = [w for w in words if w.split("=")[0] in ("--policy", "--out", "--backend")]
    if bad:
        raise ConfigError(f"--eval {bad[0]}: the trained policy and the run directories are set per step (local "
                          "backend); leave it out")  # fmt: skip
    try:
        ns = build_parser().parse_args(["evaluate", *words])
    except SystemExit:
        raise ConfigError(
            f"--eval {flags!r}: not valid evaluate flags (see 'indgen evaluate --help')"
        ) from None
    ns.policy, ns.out = "object:indgen-train", str(out / "_")
    return config_from_args(ns)


def eval_hook(args: argparse.Namespace, out: Path) -> Callable[[int, Any], None] | None:
    """The ``after_step`` of ``train_policy`` for ``--eval-every``/``--eval`` (None without them)."""
    every, flags = getattr(args, "eval_every", None), getattr(args, "eval", None)
    if every is None and flags is None:
        return None
    from indgen_vla.app.regimes.train_eval import make_hook
    from indgen_vla.core.errors import ConfigError

    if every is None or flags is None:
        raise ConfigError("--eval-every N and --eval 'FLAGS' go together, e.g. --eval-every 500 --eval='--scene "
                          "pick_place --axis pick_y --levels -2:2 --episodes 10'")  # fmt: skip
    if every < 1:
        raise ConfigError(f"--eval-every must be >= 1 update, got {every}")
    root = Path(args.eval_out) if args.eval_out else out.parent / f"{out.name}_evals"
    base = eval_config(flags, root)
    steps = getattr(args, "steps", None)
    return make_hook(base, root, every, last=steps)
