"""The run logic of ``indgen evaluate`` as a library: resolve the plan, check feasibility, write the manifest,
run every remaining episode resumably, then write the report. The CLI (``indgen_vla/app/cli/evaluate.py``) only parses and prints."""

from __future__ import annotations

import dataclasses
import datetime as _dt
import subprocess
import sys
import uuid
from collections import defaultdict
from pathlib import Path
from typing import Any

from indgen_vla.app.engine import timing
from indgen_vla.app.engine.adaptive import next_round, run_adaptive
from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.app.engine.local import Handoff, LocalOptions, run_local, worker_processes
from indgen_vla.app.engine.policy_source import PolicySource, check_object_run, runner_config
from indgen_vla.app.engine.preregister import check_preregistered
from indgen_vla.app.engine.rollout import RunMeta
from indgen_vla.app.engine.share import (
    copies,
    fill_copies,
    record_sharing,
    sharing_entry,
    taken_keys,
    with_sharing,
)
from indgen_vla.core.errors import ConfigError, InfeasibleLevelError, ServerUnreachableError
from indgen_vla.core.protocol.deviations import protocol_deviations
from indgen_vla.core.protocol.fingerprint import (
    NUMERICS,
    ProtocolMismatchError,
    build_fingerprint,
    differences,
    numeric_builds,
    numerics_warning,
    policy_conventions,
    show_difference,
    workers_warning,
)
from indgen_vla.core.protocol.plan import FAILED, UNCERTIFIED, EvalPlan, plan_jobs
from indgen_vla.core.protocol.training_support import cells_to_json
from indgen_vla.core.reporting.certification_view import NO_ORACLE, plan_basis_lines
from indgen_vla.core.reporting.live import level_info, level_label, progress_columns
from indgen_vla.core.reporting.report import write_run_report
from indgen_vla.core.runs.records import RunDir, episodes_frame
from scenes.family import Scene
from scenes.planning import resolve_scene_plan

VERSIONED = ("indgen-vla", "lerobot", "torch", "transformers", "robosuite", "mujoco", "numpy", "hf-libero")


def package_versions() -> dict[str, str]:
    """Installed versions of the packages that can change the numbers, recorded in the manifest."""
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for name in VERSIONED:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            pass
    return out


def git_sha() -> str:
    """The toolkit's commit, so a run names the code that made it ("" outside a git checkout)."""
    try:
        here = Path(__file__).resolve().parent
        r = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, timeout=5)
        return r.stdout.strip() if r.returncode == 0 else ""
    except (OSError, subprocess.SubprocessError):
        return ""


def build_plan(cfg: EvalConfig, family: Scene) -> EvalPlan:
    """Resolve ``cfg`` once on ``family`` (the scene family its edge looked up, configured with ``cfg``'s scene
    options): the scene layer's answer (tasks, successors, parameters, certificates) plus every planned episode.
    The only call from the engine into ``scenes`` for a run; everything after reads the plan."""
    p = cfg.plan
    sp = resolve_scene_plan(family, p.task, p.axes, p.levels, p.step, p.axes_preset)
    jobs = plan_jobs(sp.scene, sp.tasks, sp.levels, sp.params(), p.episodes, p.seed, cfg.run.video,
                     cfg.run.video_per_level)  # fmt: skip
    return with_sharing(cfg, EvalPlan(sp, jobs))


def _levels_text(levels: list[int]) -> str:
    return ", ".join(f"{k:+d}" if k else "0" for k in levels)


def check_feasible(cfg: EvalConfig, plan: EvalPlan) -> list[str]:
    """Refuse levels where the oracle failed (Assumption 2) unless --allow-infeasible; return one warning
    line per axis naming the requested levels no certificate covers (missing, or too few episodes)."""
    warnings = []
    for name, spec in plan.axes.items():
        want = list(plan.levels[name])
        failed: dict[str, list[int]] = {}
        missing: dict[str, list[int]] = {}
        no_oracle: dict[str, list[int]] = {}
        for task in plan.tasks:
            cells = [plan.scene_plan.cell(task, name, k) for k in want]
            bad = sorted(c.level for c in cells if c.certificate == FAILED)
            short = [c.level for c in cells if c.certificate == UNCERTIFIED and c.evidence != NO_ORACLE]
            if unscripted := [
                c.level for c in cells if c.certificate == UNCERTIFIED and c.evidence == NO_ORACLE
            ]:
                no_oracle[task] = unscripted
            if bad:
                failed[task] = bad
            if short:
                missing[task] = short
        if failed and not cfg.plan.allow_infeasible:
            where = "; ".join(f"task {t}: levels {_levels_text(b)}" for t, b in failed.items())
            raise InfeasibleLevelError(
                f"{cfg.plan.scene}/{name}: the oracle failed its certification at {where}; drop them from --levels "
                "or pass --allow-infeasible"
            )
        if failed:
            where = "; ".join(f"task {t}: {_levels_text(b)}" for t, b in failed.items())
            warnings.append(f"evaluating levels of {name} the oracle failed (--allow-infeasible): {where}")
        if no_oracle:
            where = "; ".join(f"task {t}: levels {_levels_text(v)}" for t, v in no_oracle.items())
            warnings.append(
                f"axis {name} is uncertified at {where}: the scene's oracle has no script for "
                f"{'these tasks' if len(no_oracle) > 1 else 'this task'}, so no certificate can say those levels "
                "are solvable (indgen certify refuses it); report.md and summary.json name them"
            )
        if missing:
            if all(v == want for v in missing.values()) and len(missing) == len(plan.tasks):
                where = f"all requested levels of {'every task' if len(plan.tasks) > 1 else 'task ' + plan.tasks[0]}"
            else:
                where = "; ".join(f"task {t}: levels {_levels_text(v)}" for t, v in missing.items())
            own = name in plan.scene_plan.task_steps  # a family's step per task (RoboCasa365's pick_x)
            step = "each task's own step" if own else f"step {spec.step:g} {spec.unit}"
            warnings.append(
                f"axis {name} ({step}) is uncertified at {where} (no oracle certificate "
                f"with enough evidence); run 'indgen certify --scene {cfg.plan.scene} --axis {name} --task "
                f"{'all' if len(plan.tasks) > 1 else plan.tasks[0]}"
                f"{f' --step {cfg.plan.step:g}' if cfg.plan.step else ''}"
                f"{f' --axes-preset {cfg.plan.axes_preset}' if cfg.plan.axes_preset else ''}'"
            )
    return warnings


def build_manifest(cfg: EvalConfig, plan: EvalPlan, run_id: str) -> dict[str, Any]:
    """manifest.json: the plan a resume must match, the resolved plan (environment, every level's parameter and
    certificate, the episodes' hash), plus provenance (config, versions, commit, command)."""
    return {
        "run_id": run_id,
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "policy": cfg.policy.spec,
        "data_regime": cfg.plan.data_regime,
        "scene": cfg.plan.scene,
        "seed": cfg.plan.seed,
        "plan": cfg.plan_dict(
            list(plan.tasks),
            {a: list(v) for a, v in plan.levels.items()},
            cfg.plan.max_steps,
            plan.scene_plan.task_steps,
        ),
        "axes": {n: dataclasses.asdict(s) for n, s in plan.axes.items()},
        "resolved": (resolved := plan.record()),
        "deviations": protocol_deviations(cfg.plan.max_steps, resolved["environment"].get("protocol", {})),
        "t0_sharing": sharing_entry(cfg, plan),
        "config": cfg.flat(),  # flat, as runs have always recorded it
        "versions": package_versions(),
        "git_sha": git_sha(),
        "command": " ".join(["indgen", *sys.argv[1:]]) if sys.argv and "indgen" in sys.argv[0] else "",
        **(
            {
                "measurement": "not a measurement (--smoke: a smoke run, e.g. an image policy on placeholder assets)"
            }
            if cfg.run.smoke
            else {}
        ),  # fmt: skip
        # boxes and flat textures in place of the benchmark's meshes: the report says so before any rate
        **({"placeholder_assets": True} if getattr(plan.builder, "placeholder_assets", False) else {}),
    }


def evaluate(cfg: EvalConfig, family: Scene, quiet: bool = False, *, policy: object | None = None) -> Path:
    """Run (or resume) an evaluation of ``cfg`` on ``family`` (its scene configured with its scene options, looked up
    once by the caller: the CLI, the API) and write its report; returns the run directory.

    ``policy``: a policy already in memory, run instead of loading ``cfg.policy.spec`` (then only the run's label):
    ``(policy, preprocessor, postprocessor)`` of LeRobot or any ``indgen_vla.core.protocol.interface.Policy``
    (``policy_wrappers.objects``; the local backend only)."""
    from rich.console import Console

    clock = timing.start_session()
    console = Console(stderr=True, quiet=quiet)
    plan, preregistered = prepare(cfg, family, console, given=policy)
    out, source, probe = Path(cfg.run.out), PolicySource(cfg, plan, policy), None
    run_id = existing_run_id(out) or uuid.uuid4().hex[:12]
    try:
        if not (
            out / "manifest.json"
        ).exists():  # a new run: refuse a policy that does not fit before writing
            probe = source.checked(_first_round(cfg, plan))
        run = open_run(cfg, plan, run_id, preregistered)
        todo = plan_todo(cfg, plan, run)
        if todo:
            if probe is None:
                probe = source.checked(todo)
            _run_todo(cfg, plan, run, run_id, todo, source, probe, console)
        elif probe is not None:
            probe.close()
    finally:
        source.close_unused()
    finish(cfg, plan, run, todo, probe, clock, console)
    return out


def prepare(
    cfg: EvalConfig, family: Scene, console, given: object | None = None
) -> tuple[EvalPlan, dict | None]:
    """The plan, checked before anything loads or is written: an object policy's run, the assets building needs,
    a pre-registered lock (one line on a deviation), infeasible levels; prints the feasibility warnings and each
    level's certification basis. Returns the plan and the lock's record (None without ``--preregistered``)."""
    if given is not None:
        check_object_run(cfg)
    if cfg.run.backend == "ray":  # its environment knobs, before a run directory is opened
        from indgen_vla.app.engine.ray_backend import ray_knobs  # lazy: optional ray

        ray_knobs()
    plan = build_plan(cfg, family)
    plan.builder.check_ready()  # what building an env needs (LIBERO's assets), after the names and levels
    preregistered = None
    if cfg.plan.preregistered:
        preregistered = check_preregistered(cfg, plan, package_versions())
    for w in check_feasible(cfg, plan):
        console.print(f"[yellow]warning:[/] {w}")
    cells = [dataclasses.asdict(c) for c in plan.scene_plan.cells]
    for line in plan_basis_lines(plan.scene_plan.scene, list(plan.axes), cells):
        console.print(line.replace("**", "").replace("`", ""), markup=False, highlight=False)
    return plan, preregistered


def existing_run_id(out: Path) -> str | None:
    """The run id of the run in ``out`` a resume continues (None for a new run)."""
    return RunDir(out).manifest.get("run_id") if (out / "manifest.json").exists() else None


def open_run(cfg: EvalConfig, plan: EvalPlan, run_id: str, preregistered: dict | None) -> RunDir:
    """The run directory, new or resumed (a different plan refused), with its T0 sharing, lock and the shared T0
    copies a kill cut off."""
    run = RunDir.create_or_resume(Path(cfg.run.out), build_manifest(cfg, plan, run_id))
    record_sharing(run, sharing_entry(cfg, plan))
    if cfg.plan.preregistered:
        run.update_manifest(preregistered=preregistered)
    fill_copies(plan, run)
    return run


def plan_todo(cfg: EvalConfig, plan: EvalPlan, run: RunDir) -> list:
    """The rollouts still to run: those not finished, or under ``--adaptive`` only what the sequential rule still
    needs (levels past a decided break never run)."""
    if cfg.adaptive.mode:
        return next_round(plan, run.episodes(), cfg)
    done = run.done_keys()
    return [j for j in plan.rollouts() if j.key not in done]


def finish(cfg: EvalConfig, plan: EvalPlan, run: RunDir, todo: list, probe, clock, console) -> None:
    """Write the run's report, and what this session's clocks saw (``indgen budget --timing`` reads it back)."""
    if not todo:
        done_text = (
            "the decisions of every level the adaptive rule needs are"
            if cfg.adaptive.mode
            else f"all {len(plan.jobs)} planned episodes are"
        )
        console.print(f"{done_text} already in {Path(cfg.run.out)}; writing the report")
    write_run_report(run, cfg.plan.gamma)
    if clock.episodes:
        spec = probe.spec if probe is not None else None
        run.update_manifest(timing=clock.record(
            workers=cfg.run.workers, processes=worker_processes(len(todo), cfg.run.workers, cfg.run.pipeline),
            pipeline=cfg.run.pipeline, batched=spec.batched if spec else None, device=cfg.policy.device,
            backend=cfg.run.backend,
            replan=(cfg.policy.replan_steps or spec.replan_steps) if spec else cfg.policy.replan_steps))  # fmt: skip


def _first_round(cfg: EvalConfig, plan: EvalPlan) -> list:
    """The jobs a new run starts with: the whole plan, or the adaptive rule's first round (its workers prepare
    the scenes of those, not of levels the rule may never reach)."""
    if not cfg.adaptive.mode:
        return plan.rollouts()

    return next_round(plan, episodes_frame([]), cfg)


@dataclasses.dataclass(frozen=True)
class Rollouts:
    """How this session's episodes roll out: the workers' config, the records' run fields, actions per chunk."""

    runner_cfg: Any  # rollout.RunnerConfig
    meta: Any  # rollout.RunMeta
    replan: int


def _run_todo(
    cfg: EvalConfig,
    plan: EvalPlan,
    run: RunDir,
    run_id: str,
    todo: list,
    source: PolicySource,
    probe,
    console,
):
    """Run the episodes still to do with the loaded ``probe`` (more policies from ``source``, and the workers it
    started while the policy loaded), after fixing (or checking, on a resume) the run's protocol fingerprint."""
    spec = probe.spec
    replan = cfg.policy.replan_steps or spec.replan_steps
    if replan > spec.chunk_size:
        raise ConfigError(f"--replan-steps {replan} exceeds the policy's chunk size {spec.chunk_size}")
    runner_cfg = runner_config(cfg, plan, spec)
    manifest = run.manifest
    resolved = manifest.get("resolved") or plan.record()  # a run made before "resolved" existed
    if "fingerprint" in manifest:  # a resume weighs today's scene facts (assets, worker, initial states)
        resolved = plan.record()
    fingerprint = _fingerprint(cfg, plan, resolved, runner_cfg, probe)
    if "fingerprint" not in manifest:  # what fixes the outcomes, once the policy's conventions are known
        # and the levels its training data covered, where the policy declares them (report marks them "trained")
        trained = {"training_levels": cells_to_json(spec.training)} if spec.training else {}
        run.update_manifest(fingerprint=fingerprint, reads_observations=spec.reads_observations, **trained)
    else:  # a resume: the episodes still to run must be made under the protocol of those on disk
        began = (manifest.get("config") or {}).get("workers")
        workers = workers_warning(began, cfg.run.workers, spec.batched)
        for line in [*_check_resumed_protocol(run, fingerprint, cfg.run.allow_protocol_mismatch), workers]:
            if line:
                console.print(f"[yellow]warning:[/] {line}")
        if "reads_observations" not in manifest:  # a run started before policies declared it: the same policy
            run.update_manifest(reads_observations=spec.reads_observations)
        # say what it keeps and what it runs (an adaptive round's todo is not "the rest")
        if not cfg.adaptive.mode:
            left = len(plan.jobs) - len(run.done_keys() & {j.key for j in plan.jobs})
            why = f" ({len(todo)} rollouts: level 0 runs once for the axes sharing it)"
            shared = "" if left == len(todo) else why
            console.print(f"resuming {run.path}: {len(plan.jobs) - left} of {len(plan.jobs)} planned episodes "
                          f"already recorded; running the other {left}{shared}", soft_wrap=True)  # fmt: skip
    meta = RunMeta(
        run_id=run_id, policy=cfg.policy.spec, data_regime=cfg.plan.data_regime, scene=cfg.plan.scene
    )
    try:
        _run_with_progress(cfg, run, plan, todo, Rollouts(runner_cfg, meta, replan), source, probe, console)
    except ServerUnreachableError as e:
        raise ServerUnreachableError(f"{e} (run directory {run.path})") from None


def _check_resumed_protocol(run: RunDir, now: dict[str, Any], allow: bool) -> list[str]:
    """Refuse, in one line naming the field, to resume a run whose outcome-changing protocol differs from the one
    its episodes on disk were made under (an upgraded simulator, other assets, a new GL renderer); with ``allow``,
    go on and record the differences in the manifest (``protocol_changes``), returning the lines to print."""
    was_numerics = run.manifest["fingerprint"].get(NUMERICS)
    warning = numerics_warning(was_numerics, now.get(NUMERICS), "resumed")
    notes = []
    if warning:  # informational: recorded, so the report of a mixed run can say so
        changes = run.manifest.get("numerics_changes", [])
        if not changes or changes[-1].get("now") != now.get(NUMERICS):
            run.update_manifest(numerics_changes=[*changes, {"was": was_numerics, "now": now.get(NUMERICS)}])
        notes.append(warning)
    bad = [d for d in differences(run.manifest["fingerprint"], now) if d[3]]
    if not bad:
        return notes
    field, was, is_now, _ = bad[0]
    if not allow:
        more = f" (and {len(bad) - 1} more field(s))" if len(bad) > 1 else ""
        was_text, now_text = show_difference(field, was, is_now, width=60)
        raise ProtocolMismatchError(
            f"{run.path} was started under another protocol: {field} was {was_text}, now {now_text}{more}; "
            "resume it where it was started, use a new --out, or pass --allow-protocol-mismatch (the manifest then "
            "records the change)"
        )
    changes = [{"field": f, "was": a, "now": b} for f, a, b, _ in bad]
    run.update_manifest(protocol_changes=[*run.manifest.get("protocol_changes", []), *changes])
    lines = notes
    for f, a, b, _ in bad:
        was_text, now_text = show_difference(f, a, b)
        lines.append(f"resumed under another protocol: {f} was {was_text}, now {now_text}")
    return lines


def _fingerprint(cfg: EvalConfig, plan: EvalPlan, resolved: dict, runner_cfg, policy) -> dict[str, Any]:
    """The run's protocol fingerprint (``indgen_vla.core.protocol.fingerprint``); the render backend is probed only when a
    camera is read."""
    cams = tuple(runner_cfg.cameras)
    versions = package_versions()
    fp = build_fingerprint(
        resolved, versions, max_steps=cfg.plan.max_steps, warmup_steps=cfg.policy.warmup_steps,
        cameras=cams, image_size=runner_cfg.image_size, render_backend=plan.builder.render_backend() if cams else "",
        policy=policy_conventions(policy.spec, policy),
    )  # fmt: skip
    return {**fp, NUMERICS: numeric_builds(versions)}


def _run_with_progress(
    cfg: EvalConfig, run: RunDir, plan: EvalPlan, todo: list, rollouts: Rollouts, source: PolicySource, probe,
    console,
):  # fmt: skip
    """Run the remaining episodes under a live display: one row per (axis, level) with its success so
    far, and a total row with the ETA. ``source.early`` (``local.EarlyWorkers``) serves the first round's workers,
    ``source.load`` makes more policies than ``probe``."""
    runner_cfg, meta, replan, early = rollouts.runner_cfg, rollouts.meta, rollouts.replan, source.early
    from rich.progress import Progress

    planned: dict[tuple[str, int], int] = defaultdict(int)
    for j in plan.jobs:
        planned[(j.axis, j.level)] += 1
    stats: dict[tuple[str, int], list[int]] = defaultdict(lambda: [0, 0, 0])  # successes, ok, errors
    # earlier error rows are re-run now; ok and unavailable ones are done
    for r in run.episodes().itertuples():
        if r.status == "ok":
            stats[(r.axis, int(r.level))][0] += int(r.success)
            stats[(r.axis, int(r.level))][1] += 1
        elif r.status == "unavailable":  # counted as on_record counts it when it is recorded
            stats[(r.axis, int(r.level))][2] += 1
    rollouts = {j.key for j in plan.rollouts()}  # the total and its ETA count rollouts, not shared copies
    taken = taken_keys(plan, run)
    with Progress(*progress_columns(), console=console, transient=False) as progress:
        done = len(run.done_keys() & rollouts)  # what finished: an adaptive run skips planned episodes
        label = "all episodes" if len(rollouts) == len(plan.jobs) else "rollouts (T0 shared)"
        total = progress.add_task(label, total=len(rollouts), completed=done, info="")
        rows = {}
        for key in sorted(planned, key=lambda k: (cfg.plan.axes.index(k[0]), k[1])):
            s = stats[key]
            rows[key] = progress.add_task(level_label(*key), total=planned[key], completed=s[1] + s[2],
                                          info=level_info(*s))  # fmt: skip

        def on_record(rec) -> None:
            # one append: the copies are journalled with their rollout
            recs = [rec, *copies(plan, rec, taken)]
            run.append(recs)
            for r in recs:
                s = stats[(r.axis, r.level)]
                if r.status == "ok":
                    s[0] += int(r.success)
                    s[1] += 1
                else:
                    s[2] += 1
                progress.update(rows[(r.axis, r.level)], advance=1, info=level_info(*s))
            progress.update(total, advance=1)

        made, handed = [probe], [0]

        def policy_factory():  # hand out the loaded policies again in every round; load more only when needed
            if handed[0] == len(made):
                made.append(source.load())
            handed[0] += 1
            return made[handed[0] - 1]

        kept: list = []  # the local backend's workers between adaptive rounds, with the scenes they hold

        def run_jobs(batch: list) -> None:
            handed[0] = 0
            timing.CLOCK.rollout(started=True)
            if cfg.run.backend == "ray":
                from indgen_vla.app.engine.ray_backend import run_ray  # lazy: optional ray

                run_ray(batch, runner_cfg, cfg, meta, on_record, replan)
            else:
                # the first round gets the workers started while the policy loaded, a later one the last round's
                nonlocal early
                workers = early.take(runner_cfg) if early is not None else list(kept)
                early = None
                kept.clear()
                options = LocalOptions(workers=cfg.run.workers, replan_steps=replan, max_retries=cfg.run.max_retries,
                                       server_patience_s=cfg.policy.server_patience, pipeline=cfg.run.pipeline,
                                       close_policies=False)  # fmt: skip
                run_local(batch, runner_cfg, policy_factory, meta, on_record, options,
                          on_wait=lambda text: progress.update(total, info=text), handoff=Handoff(workers, kept))  # fmt: skip

        try:
            if cfg.adaptive.mode:  # rounds until the sequential rule settles every level (docs/adaptive.md)
                run_adaptive(plan, run.episodes, run_jobs, cfg)
            else:
                run_jobs(todo)
            timing.CLOCK.rollout(started=False)
        finally:
            run.flush()  # the rows a long run's append deferred (records.FLUSH_SHARE)
            for w in kept:
                w.close()
            for p in made:  # the ray backend loads its own policies in its actors
                p.close()
