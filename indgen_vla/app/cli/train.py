"""``indgen train``: its parser (over the passthrough arguments, made from ``TrainConfig``'s fields); the handler
trains (``indgen_vla.app.api.train``) and prints where the checkpoint is."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from indgen_vla.app.cli import build_parser as indgen_parser
from indgen_vla.app.cli.options import IndgenParser, add_passthrough
from indgen_vla.app.config_fields import add_flags, from_args
from indgen_vla.app.engine.config import EvalConfig, config_from_args
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.training_support import cells_from_json, support_text


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen train`` parses its own arguments (``main``)."""
    add_passthrough(sp, "train", "train a small LeRobot policy (ACT/Diffusion) on one or more datasets")


def build_parser() -> argparse.ArgumentParser:
    """``indgen train``'s own parser: DATASETS, then ``TrainConfig``'s fields and --eval."""
    p = IndgenParser(prog="indgen train", description="train a small lerobot policy on indgen datasets")
    p.add_argument(
        "datasets", nargs="+", help="LeRobotDataset root directories (e.g. human and MimicGen demos)"
    )
    add_eval_options(p)
    return p


def main(args: argparse.Namespace) -> int:
    """The handler: its own parser over ``args.rest``, then the library call."""
    import json

    from indgen_vla.app.api import train  # lazy: start-up
    from indgen_vla.app.regimes.train import INFO_FILE, TrainConfig, eval_root  # lazy: start-up

    a = build_parser().parse_args(getattr(args, "rest", args))
    evaluation = None
    if a.eval is not None:
        evaluation = eval_config(a.eval, eval_root(a.out, a.eval_out))
    cfg = from_args(TrainConfig, a, command="train", datasets=tuple(a.datasets), evaluation=evaluation)
    done = (Path(cfg.out) / INFO_FILE).is_file()
    steps = cfg.recipe.steps
    out = train(
        cfg, say=print, progress=lambda s, loss: print(f"  step {s}/{steps} loss {loss:.4f}", flush=True)
    )
    if done:
        return 0
    info = json.loads((out / INFO_FILE).read_text())
    print(f"trained {cfg.recipe.policy} for {steps} steps in {info['train_s']:.0f} s; checkpoint in {out}")
    if info["levels"]:
        print(
            f"training levels (train_info.json, read by evaluate): {support_text(cells_from_json(info['levels']))}"
        )
    return 0


def add_eval_options(p: argparse.ArgumentParser) -> None:
    """``indgen train``'s flags after DATASETS (``TrainConfig``'s fields), with the command's own --eval among them."""
    from indgen_vla.app.regimes.train import (  # lazy: start-up
        FLAGS_AFTER_EVAL,
        FLAGS_BEFORE_EVAL,
        TrainConfig,
    )

    add_flags(p, TrainConfig, FLAGS_BEFORE_EVAL)
    p.add_argument("--eval", default=None, metavar="FLAGS",
                   help="evaluate's protocol flags for --eval-every, quoted after =, e.g. --eval='--scene pick_place --axis pick_y "
                   "--levels -2:2 --episodes 10' (or --config PRESET)")  # fmt: skip
    add_flags(p, TrainConfig, FLAGS_AFTER_EVAL)


def eval_config(flags: str, out: Path) -> EvalConfig:
    """The ``EvalConfig`` of ``--eval FLAGS`` (evaluate's own parser and config resolution; ``--policy`` and
    ``--out`` are set per step)."""
    words = shlex.split(flags)
    bad = [w for w in words if w.split("=")[0] in ("--policy", "--out", "--backend")]
    if bad:
        raise ConfigError(f"--eval {bad[0]}: the trained policy and the run directories are set per step (local "
                          "backend); leave it out")  # fmt: skip
    try:
        ns = indgen_parser().parse_args(["evaluate", *words])
    except SystemExit:
        raise ConfigError(
            f"--eval {flags!r}: not valid evaluate flags (see 'indgen evaluate --help')"
        ) from None
    ns.policy, ns.out = "object:indgen-train", str(out / "_")
    return config_from_args(ns)
