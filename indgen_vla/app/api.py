"""The public Python API (``indgen_vla.evaluate``, ``report``, ...): the CLI's commands for notebooks and training
scripts, with keyword arguments named like the flags and typed results instead of exit codes."""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.runs.result import Run

PathLike = str | os.PathLike[str]


def evaluate(
    *,
    policy: Any = None,
    out: PathLike | None = None,
    config: Any = None,
    quiet: bool = False,
    **options: Any,
) -> Run:
    """Run (or resume) an evaluation and return its run directory, exactly as ``indgen evaluate`` writes it.

    ``policy`` is a spec string (``--policy``), a ``PolicyConfig``, or a policy already in memory: a LeRobot
    ``(policy, preprocessor, postprocessor)`` or any ``Policy`` (a training loop evaluates its current weights
    without saving them; local backend only; the run records it as ``object:<class>``).

    Keyword arguments are ``indgen evaluate``'s flags with ``_`` for ``-`` (``scene``, ``task``, ``axis``,
    ``levels``, ``episodes``, ``workers``, ``adaptive``, ...); ``axis`` and ``levels`` also take lists. Whole config
    sections are accepted too (``plan=PlanConfig(...)``, ``run=RunConfig(...)``, ``adaptive=AdaptiveConfig(...)``),
    which flat keywords override. ``config`` is a preset name or YAML path (``--config``) whose values the keywords
    override, or an ``EvalConfig``. ``quiet`` hides the live progress display.
    """
    from indgen_vla.app.engine.config import EvalConfig, PolicyConfig, config_from_values
    from indgen_vla.app.engine.run import evaluate as run_evaluation

    obj = None if policy is None or isinstance(policy, str | PolicyConfig) else policy
    if obj is not None:
        from policy_wrappers.objects import describe

        policy = describe(obj)
    given = {
        **options,
        **({"policy": policy} if policy is not None else {}),
        **({"out": out} if out is not None else {}),
    }
    if config is None or isinstance(config, EvalConfig | str | os.PathLike):
        preset = os.fspath(config) if isinstance(config, str | os.PathLike) else config
        cfg = config_from_values(given, preset, strict=True)
    else:
        raise ConfigError(
            f"config must be a preset name, a YAML path or an EvalConfig, got {type(config).__name__}"
        )
    return Run(run_evaluation(cfg, quiet=quiet, policy=obj))


def report(
    runs: PathLike | Run | Iterable[PathLike | Run],
    *,
    gamma: float = 0.2,
    ci: str = "wilson",
    margin: float | None = None,
) -> list[Run]:
    """Write summary.json, report.md and plots for each run directory again (as ``indgen report`` does for each)
    and return them; ``gamma``, ``ci`` (wilson | clopper-pearson) and ``margin`` as the flags."""
    from indgen_vla.core.errors import RunDirError
    from indgen_vla.core.reporting.report import write_run_report
    from indgen_vla.core.runs.records import RunDir
    from indgen_vla.core.stats.contrasts import check_margin

    if not 0 < gamma <= 1:
        raise ConfigError(f"gamma must be in (0, 1], got {gamma}")
    check_margin(margin)
    paths = [runs] if isinstance(runs, str | os.PathLike | Run) else list(runs)
    done = []
    for p in paths:
        run = RunDir.open(Path(os.fspath(p.path if isinstance(p, Run) else p)))
        episodes = run.episodes()
        if len(episodes) == 0:
            raise RunDirError(
                f"{run.path} has no finished episodes yet; run or resume 'indgen evaluate' first"
            )
        write_run_report(run, gamma, ci, episodes, margin, plots=True)
        done.append(Run(run.path))
    return done


def compare(
    run_a: PathLike | Run,
    run_b: PathLike | Run,
    *,
    gamma: float = 0.2,
    alpha: float = 0.05,
    test: str = "auto",
    out: PathLike | None = None,
    label_a: str | None = None,
    label_b: str | None = None,
    allow_protocol_mismatch: bool = False,
) -> dict[str, Any]:
    """``indgen compare RUN_A RUN_B``: per-level exact tests (paired where the seeds match) with Holm, written to
    compare.json/compare.md (default RUN_A/compare); returns compare.json's content."""
    from indgen_vla.core.comparison.two_runs import compare_runs

    a, b = (Path(os.fspath(r.path if isinstance(r, Run) else r)) for r in (run_a, run_b))
    return compare_runs(a, b, gamma=gamma, alpha=alpha, test=test, out=out, label_a=label_a, label_b=label_b,
                        allow_protocol_mismatch=allow_protocol_mismatch)  # fmt: skip


def certify(config: Any = None, **options: Any) -> dict[str, Any]:
    """``indgen certify`` for one task (default: the scene's first): the privileged oracle on each level until the
    59/59 rule decides it, written where ``evaluate`` looks (or to ``out``/certify.json) and resumed from there;
    returns the certificate (per level: n, successes, lower bound, status certified | failed | insufficient).

    ``config`` is a ``CertifyConfig``; keyword arguments are ``indgen certify``'s flags with ``_`` for ``-``
    (``scene``, ``axis``, ``task``, ``levels``, ``episodes``, ``seed``, ``workers``, ``held_out``, ``split``, ...),
    replacing the config's values."""
    from indgen_vla.app.certify.certify_config import certify_config  # lazy: start-up (import indgen_vla)
    from indgen_vla.app.certify.certify_levels import certify as certify_levels
    from scenes.certificates import cert_path
    from scenes.registry import configure_scene

    cfg = certify_config(config, **options)
    if cfg.mode != "certify":
        raise ConfigError(f"certify() certifies levels; {cfg.mode.replace('_', '-')} is the command's other mode: "
                          f"run 'indgen certify --{cfg.mode.replace('_', '-')} ...'")  # fmt: skip
    plan = cfg.plan
    with configure_scene(
        plan.scene, plan.scene_options()
    ) as scene:  # the certificates' folder follows the choice
        path = (
            Path(cfg.run.out) / "certify.json"
            if cfg.run.out is not None
            else cert_path(scene.name, plan.task, plan.axis, plan.step, plan.axes_preset)
        )
        return certify_levels(scene, cfg, path)


def import_lerobot_eval(
    sources: PathLike | Iterable[PathLike],
    *,
    out: PathLike,
    axis: str | None = None,
    level: int | None = None,
    seed: int | None = None,
    policy: str | None = None,
    data_regime: str = "",
    gamma: float = 0.2,
) -> Run:
    """``indgen import lerobot-eval DIR... --out RUN``: lerobot-eval output directories as one run directory, its
    report written (docs/lerobot.md); ``axis``/``level`` place another env's run, ``seed`` is lerobot-eval's --seed
    where eval_info.json records none (default 1000)."""
    from indgen_vla.app.lerobot_bridge.eval_import import ImportConfig
    from indgen_vla.app.lerobot_bridge.eval_import import import_lerobot_eval as write_import

    paths = [sources] if isinstance(sources, str | os.PathLike) else list(sources)
    cfg = ImportConfig(sources=tuple(os.fspath(p) for p in paths), out=os.fspath(out), axis=axis, level=level,
                       seed=seed, policy=policy, data_regime=data_regime)  # fmt: skip
    return report(write_import(cfg), gamma=gamma)[0]
