"""``indgen train --eval-every N --eval "EVALUATE FLAGS"``: evaluate the weights in memory every N updates, one run
per step in ``--eval-out`` (default ``OUT_evals``), and keep that directory's series report (``indgen_vla.core.reporting.series_report``)
current. The runs are the training loop recipe of docs/loop.md: same plan and seeds at every step (paired), and the
training itself is not changed by them (the checkpoint equals one trained without ``--eval-every``)."""

from __future__ import annotations

import argparse
import shlex
from collections.abc import Callable
from pathlib import Path
from typing import Any

from indgen_vla.core.errors import ConfigError


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
    if every is None or flags is None:
        raise ConfigError("--eval-every N and --eval 'FLAGS' go together, e.g. --eval-every 500 --eval='--scene "
                          "pick_place --axis pick_y --levels -2:2 --episodes 10'")  # fmt: skip
    if every < 1:
        raise ConfigError(f"--eval-every must be >= 1 update, got {every}")
    root = Path(args.eval_out) if args.eval_out else out.parent / f"{out.name}_evals"
    base = eval_config(flags, root)
    steps = getattr(args, "steps", None)
    return make_hook(base, root, every, last=steps)


def make_hook(base, root: Path, every: int, last: int | None = None, say: Callable[[str], None] = print):
    """``after_step(step, model)``: at every ``every``-th step (and ``last``) evaluate ``model`` in memory into
    ``root/runs/<step>`` and rewrite ``root``'s series report."""
    from indgen_vla.app.engine.run import evaluate
    from indgen_vla.core.reporting.series_report import write_series

    done: list[tuple[int, Path]] = sorted(
        (int(p.name), p) for p in (root / "runs").glob("*") if p.name.isdigit()
    )

    def after_step(step: int, model) -> None:
        if step % every and step != last:
            return
        cfg = base.override(policy=f"object:indgen-train@step{step}", out=str(root / "runs" / f"{step:09d}"))
        say(f"train: evaluating step {step} in memory into {cfg.run.out}")
        run = evaluate(cfg, quiet=True, policy=(model.policy, model.pre, model.post))
        done[:] = sorted({**dict(done), step: run}.items())
        write_series(done, root, base.plan.gamma)

    return after_step
