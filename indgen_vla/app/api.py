"""The public Python API (``indgen_vla.evaluate``, ``report``, ...): the CLI's commands for notebooks and training
scripts, with keyword arguments named like the flags and typed results instead of exit codes."""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from indgen_vla.app.certify.certify_config import certify_config
from indgen_vla.app.certify.certify_levels import certify as certify_levels
from indgen_vla.app.engine.config import EvalConfig, PolicyConfig, config_from_values
from indgen_vla.app.engine.run import evaluate as run_evaluation
from indgen_vla.app.engine.trackers import log_runs, tracker_module
from indgen_vla.app.lerobot_bridge.eval_import import ImportConfig
from indgen_vla.app.lerobot_bridge.eval_import import import_lerobot_eval as write_import
from indgen_vla.app.real.design import RealPlanConfig, plan_run
from indgen_vla.app.regimes.demos import DemosConfig, record_demos
from indgen_vla.app.regimes.mimicgen import MimicGenConfig, generate
from indgen_vla.app.regimes.mimicgen_sources import source_scenes
from indgen_vla.app.regimes.train import TrainConfig, train_policy
from indgen_vla.app.regimes.train_eval import eval_hook
from indgen_vla.app.studies.budget import plan_budget
from indgen_vla.app.studies.config import BudgetConfig, SeriesConfig
from indgen_vla.app.studies.series import run_series
from indgen_vla.core.comparison.series_report import write_series
from indgen_vla.core.comparison.two_runs import compare_runs
from indgen_vla.core.errors import ConfigError, EpisodeErrorsWarning, RunDirError
from indgen_vla.core.reporting.certification_view import unavailable_rows
from indgen_vla.core.reporting.report import write_run_report
from indgen_vla.core.runs.records import RunDir
from indgen_vla.core.runs.result import Run
from indgen_vla.core.stats.contrasts import check_margin
from policy_wrappers.objects import describe
from scenes.certificates import cert_path
from scenes.family import Scene, get_scene

PathLike = str | os.PathLike[str]


def family_of(plan: Any) -> Scene:
    """The scene family of a command's plan section (``scene``, ``scene_options()``), configured with its options:
    looked up once here, at the edge, and handed down (a bad option for the family: one ``ConfigError`` line)."""
    return get_scene(plan.scene, plan.scene_options())


def evaluate(
    *,
    policy: Any = None,
    out: PathLike | None = None,
    config: Any = None,
    quiet: bool = False,
    log: str | None = None,
    log_project: str = "indgen",
    **options: Any,
) -> Run:
    """Run (or resume) an evaluation and return its run directory, exactly as ``indgen evaluate`` writes it.

    ``policy`` is a spec string (``--policy``), a ``PolicyConfig``, or a policy already in memory: a LeRobot
    ``(policy, preprocessor, postprocessor)`` or any ``Policy`` (a training loop evaluates its current weights
    without saving them; local backend only; the run records it as ``object:<class>``, or as the ``object:...`` spec
    of an ``EvalConfig`` given as ``config``, e.g. ``object:ACTPolicy@step5000``).

    Keyword arguments are ``indgen evaluate``'s flags with ``_`` for ``-`` (``scene``, ``task``, ``axis``,
    ``levels``, ``episodes``, ``workers``, ``adaptive``, ...); ``axis`` and ``levels`` also take lists. Whole config
    sections are accepted too (``plan=PlanConfig(...)``, ``run=RunConfig(...)``, ``adaptive=AdaptiveConfig(...)``),
    which flat keywords override. ``config`` is a preset name or YAML path (``--config``) whose values the keywords
    override, or an ``EvalConfig``. ``quiet`` hides the live progress display. ``log`` (``trackio`` | ``wandb``) and
    ``log_project`` are ``--log`` and ``--log-project``: the run's rates, k* and verdicts logged at step 0.
    """
    if log is not None:
        tracker_module(log)  # a missing tracker is refused before any episode runs
    obj = None if policy is None or isinstance(policy, str | PolicyConfig) else policy
    # the label: an EvalConfig's own "object:..." spec (a training step's), else the class
    if obj is not None:
        labelled = isinstance(config, EvalConfig) and config.policy.spec.startswith("object:")
        policy = config.policy.spec if labelled else describe(obj)
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
    out_dir = run_evaluation(cfg, family_of(cfg.plan), quiet=quiet, policy=obj)
    if log is not None:
        log_runs(log, [(None, out_dir)], project=log_project, name=out_dir.name)
    run = Run(out_dir)
    _warn_errors(run)
    return run


def _warn_errors(run: Run) -> None:
    """The command's exit 3 in Python: episodes that ended ``error`` (not those their level rules out) are one
    ``EpisodeErrorsWarning`` line with the first cause, instead of rates that silently count fewer episodes."""
    eps = run.episodes()
    bad = eps[(eps["status"] == "error") & ~unavailable_rows(eps)]
    if len(bad):
        first = str(bad["error"].iloc[0]).strip().splitlines()[-1] if "error" in bad else "?"
        warnings.warn(f"{run.path}: {len(bad)} of {len(eps)} episode(s) ended with errors (the 'error' column; the "
                      f"first: {first}); re-run the same call to retry them", EpisodeErrorsWarning, stacklevel=3)  # fmt: skip


def report(
    runs: PathLike | Run | Iterable[PathLike | Run],
    *,
    gamma: float = 0.2,
    ci: str = "wilson",
    margin: float | None = None,
) -> list[Run]:
    """Write summary.json, report.md and plots for each run directory again (as ``indgen report`` does for each)
    and return them; ``gamma``, ``ci`` (wilson | clopper-pearson) and ``margin`` as the flags."""
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
    labels: tuple[str | None, str | None] = (None, None),
    allow_protocol_mismatch: bool = False,
) -> dict[str, Any]:
    """``indgen compare RUN_A RUN_B``: per-level exact tests (paired where the seeds match) with Holm, written to
    compare.json/compare.md (default RUN_A/compare); returns compare.json's content. ``labels``: the two runs'
    names in the tables (default: each run's data regime and policy, else its folder)."""
    if len(labels) != 2:
        raise ConfigError(
            f"labels must be two names (run_a's, run_b's; None for the default), got {labels!r}"
        )
    a, b = (Path(os.fspath(r.path if isinstance(r, Run) else r)) for r in (run_a, run_b))
    return compare_runs(a, b, gamma=gamma, alpha=alpha, test=test, out=out, label_a=labels[0], label_b=labels[1],
                        allow_protocol_mismatch=allow_protocol_mismatch)  # fmt: skip


def certify(config: Any = None, **options: Any) -> dict[str, Any]:
    """``indgen certify`` for one task (default: the scene's first): the privileged oracle on each level until the
    59/59 rule decides it, written where ``evaluate`` looks (or to ``out``/certify.json) and resumed from there;
    returns the certificate (per level: n, successes, lower bound, status certified | failed | insufficient).

    ``config`` is a ``CertifyConfig``; keyword arguments are ``indgen certify``'s flags with ``_`` for ``-``
    (``scene``, ``axis``, ``task``, ``levels``, ``episodes``, ``seed``, ``workers``, ``held_out``, ``split``, ...),
    replacing the config's values."""
    cfg = certify_config(config, **options)
    if cfg.mode != "certify":
        raise ConfigError(f"certify() certifies levels; {cfg.mode.replace('_', '-')} is the command's other mode: "
                          f"run 'indgen certify --{cfg.mode.replace('_', '-')} ...'")  # fmt: skip
    plan = cfg.plan
    scene = family_of(plan)  # configured once (the certificates' folder follows the choice), handed on
    path = (
        Path(cfg.run.out) / "certify.json"
        if cfg.run.out is not None
        else cert_path(scene, plan.task, plan.axis, plan.step, plan.axes_preset)
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
    paths = [sources] if isinstance(sources, str | os.PathLike) else list(sources)
    cfg = ImportConfig(sources=tuple(os.fspath(p) for p in paths), out=os.fspath(out), axis=axis, level=level,
                       seed=seed, policy=policy, data_regime=data_regime)  # fmt: skip
    return report(write_import(cfg, family_of), gamma=gamma)[0]  # each group's family looked up by its name


def budget(config: BudgetConfig) -> dict[str, Any]:
    """``indgen budget``: the size of ``config.protocol`` before it runs (episodes, power, the adaptive rule's
    cost, wall time per worker count; writes the lock with ``write``), as ``indgen budget --json`` prints it."""
    return plan_budget(config, family_of(config.protocol.plan))


def series(config: SeriesConfig, *, after_each: Callable[[list[tuple[int, Path]]], None] | None = None,
           log: str | None = None, log_project: str = "indgen") -> list[tuple[int, Path]]:  # fmt: skip
    """``indgen series``: one run of ``config.protocol`` per checkpoint, into ``config.out``/runs/<step>, and the
    series report (series.md, series.json, plots) rewritten after each (``after_each`` gets the runs too); returns
    (step, run directory) in step order. ``log``/``log_project`` are ``--log``/``--log-project``: each checkpoint's
    run logged once, at its step, into one tracker run named after ``config.out``."""
    out = Path(config.out)
    logged: set[int] = set()
    if log is not None:
        tracker_module(log)  # a missing tracker is refused before any checkpoint runs

    def report(entries: list[tuple[int, Path]]) -> None:
        write_series(entries, out, config.protocol.plan.gamma)
        if log is not None:
            logged.update(log_runs(log, entries, project=log_project, name=out.name, skip=logged))
        if after_each is not None:
            after_each(entries)

    entries = run_series(config, family_of(config.protocol.plan), after_each=report)
    report(entries)  # the checkpoints a re-run skipped too
    return entries


def demos(config: DemosConfig, *, progress: Callable[[str, int, int], None] | None = None,
          notice: Callable[[str], None] | None = None) -> dict[str, Any]:  # fmt: skip
    """``indgen demos``: noisy-oracle demonstrations of ``config.scene`` as a LeRobotDataset at ``config.out``
    (resumed when it holds an unfinished recording of the same config); returns the recording's stats.
    ``progress(cell, kept, attempts)`` follows each cell, ``notice`` gets the resume line."""
    return record_demos(config, get_scene(config.scene), progress=progress, notice=notice)


def mimicgen(config: MimicGenConfig, *, progress: Callable[[str, int, int, int], None] | None = None,
             say: Callable[[str], None] | None = None) -> dict[str, Any]:  # fmt: skip
    """``indgen mimicgen``: MimicGen-style episodes from the demonstrations ``config.source`` into ``config.out``,
    each at its source's level and scene (resumed when unfinished); returns the generation stats.
    ``progress(cell, successes, attempts, total)`` follows each cell, ``say`` gets the resume line."""
    scenes = {name: get_scene(name) for name in source_scenes(config.source)}
    return generate(config, scenes, progress, say=say)


def train(config: TrainConfig, *, progress: Callable[[int, float], None] | None = None,
          say: Callable[[str], None] | None = None) -> Path:  # fmt: skip
    """``indgen train``: a LeRobot policy trained by ``config.recipe`` on ``config.datasets`` into the checkpoint
    ``config.out`` (resumed when unfinished), with ``config.evaluation`` run on the weights in memory every
    ``config.eval_every`` updates; returns the checkpoint directory. ``progress(step, loss)`` follows the loss."""
    family = None if config.evaluation is None else family_of(config.evaluation.plan)
    return train_policy(config, progress=progress, say=say, after_step=eval_hook(config, family))


def real_plan(config: RealPlanConfig) -> Path:
    """``indgen real plan``: a run directory for a real-robot axis and the operator's protocol.md (then ``indgen real
    record``); returns the run directory."""
    return plan_run(config)
