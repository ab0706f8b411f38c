"""``indgen train --eval-every N --eval "EVALUATE FLAGS"``: evaluate the weights in memory every N updates, one run
per step in ``--eval-out`` (default ``OUT_evals``), and keep that directory's series report (``indgen_vla.core.comparison.series_report``)
current. The runs are the training loop recipe of docs/loop.md: same plan and seeds at every step (paired), and the
training itself is not changed by them (the checkpoint equals one trained without ``--eval-every``). The protocol is
an ``EvalConfig`` (``TrainConfig.evaluation``; the CLI parses ``--eval``'s flags into it); this module takes it."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.app.engine.run import evaluate
from indgen_vla.app.regimes.train import TrainConfig
from indgen_vla.core.comparison.series_report import write_series
from scenes.family import Scene


def make_hook(
    base: EvalConfig, family: Scene, root: Path, every: int, last: int | None = None,
    say: Callable[[str], None] = print,
):  # fmt: skip
    """``after_step(step, model)``: at every ``every``-th step (and ``last``) evaluate ``model`` in memory on
    ``family`` (``base``'s scene, looked up by the API) into ``root/runs/<step>`` and rewrite ``root``'s series
    report."""
    done: list[tuple[int, Path]] = sorted(
        (int(p.name), p) for p in (root / "runs").glob("*") if p.name.isdigit()
    )

    def after_step(step: int, model) -> None:
        if step % every and step != last:
            return
        cfg = base.override(policy=f"object:indgen-train@step{step}", out=str(root / "runs" / f"{step:09d}"))
        say(f"train: evaluating step {step} in memory into {cfg.run.out}")
        run = evaluate(cfg, family, quiet=True, policy=(model.policy, model.pre, model.post))
        done[:] = sorted({**dict(done), step: run}.items())
        write_series(done, root, base.plan.gamma)

    return after_step


def eval_hook(cfg: TrainConfig, family: Scene | None, say: Callable[[str], None] = print):
    """The ``after_step`` of ``cfg``'s ``--eval-every`` on ``family`` (its evaluation's scene; None without it)."""
    if cfg.evaluation is None or family is None:
        return None
    return make_hook(cfg.evaluation, family, cfg.eval_root, cfg.eval_every, last=cfg.recipe.steps, say=say)
