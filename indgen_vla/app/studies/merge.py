"""``indgen merge SHARD... --out DIR``: the shards of one protocol (a SLURM array of ``evaluate`` runs, one per task or
axis) as one ordinary run directory, so ``report``, ``compare``, ``reference`` and a resume read it like any run.

The checks and unions are ``indgen_vla.core.runs.shards`` (core). Here: the one ``evaluate`` command that plans the union (the
shards' flags with ``--task`` one task or ``all`` and ``--axis`` every axis), checked by resolving it as ``evaluate``
would (``build_plan``), so ``evaluate --out DIR`` with it finishes the episodes no shard finished; then the directory
is written whole under a temporary name and renamed into place (the shards are only read).
"""

from __future__ import annotations

import glob
import json
import os
import shlex
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from indgen_vla.app.engine.config import FLAG_FIELDS, FLAT_DEFAULTS, EvalConfig, PlanConfig
from indgen_vla.app.engine.run import build_plan
from indgen_vla.core.errors import IndgenError, RunDirError
from indgen_vla.core.reporting.report import write_run_report
from indgen_vla.core.runs.records import FINISHED, MANIFEST, EpisodeRecord, RunDir, atomic_write_json
from indgen_vla.core.runs.shards import (
    Shard,
    check_protocol,
    merged_cells,
    merged_manifest,
    merged_plan,
    merged_rows,
    numerics_notes,
    open_shards,
    sharing_setting,
)
from scenes.family import Scene

FamilyOf = Callable[[PlanConfig], Scene]  # the edge's look-up: a plan section's scene family, configured

# the evaluate flags a resume command repeats where the shards' config differs from the default: what the plan, the
# protocol and the report depend on (not workers, backend or patience: the user picks those on the machine)
RESUME_FLAGS = ("policy", "scene", "task", "axes", "levels", "step", "axes_preset", "episodes", "seed", "max_steps",
                "replan_steps", "warmup_steps", "image_size", "video", "video_per_level", "data_regime", "gamma",
                "allow_infeasible", "smoke", "trust_remote_code", "device", "precision", "compile", "adaptive",
                "adaptive_delta", "adaptive_alpha", "round_size", "share_t0", "split", "obj_registries")  # fmt: skip


def resume_command(cfg: EvalConfig) -> str:
    """``cfg`` as the ``indgen evaluate`` command line that runs (or resumes) it."""
    parts, values = ["indgen", "evaluate"], cfg.flat()
    for name in RESUME_FLAGS:
        value = values[name]
        if name not in ("policy", "scene", "axes") and (value is None or value == FLAT_DEFAULTS[name]):
            continue
        flag = "--axis" if name == "axes" else "--" + name.replace("_", "-")
        if name == "share_t0":  # the one flag whose non-default is False
            parts.append("--no-share-t0")
        elif isinstance(value, bool):
            parts.append(flag)
        else:
            parts += [flag, shlex.quote(",".join(value) if name == "axes" else str(value))]
    return " ".join([*parts, "--out", shlex.quote(cfg.run.out)])


def resume_plan(
    shards: Sequence[Shard],
    plan: dict[str, Any],
    out: Path,
    family_of: FamilyOf,
    share_t0: bool | None = None,
) -> tuple[dict[str, Any], dict[str, Any]]:
    """The merged plan in the task order ``evaluate`` gives it, and how to resume the merge: ``{"config", "command"}``
    when one evaluate command plans exactly the union (resolved here as ``evaluate`` resolves it), else ``{"config",
    "note"}`` saying why none does (the shards' tasks are neither one task nor all, their --levels differ by axis...).
    ``family_of``: the edge's look-up of the shards' scene family (their config names it); ``share_t0``: the shards'
    T0 sharing as last run (``shards.sharing_setting``), over their first config's."""
    tasks = plan["tasks"]
    config = {k: v for k, v in (shards[0].manifest.get("config") or {}).items() if k in FLAG_FIELDS}
    config.update(task=tasks[0] if len(tasks) == 1 else "all", axes=tuple(plan["axes"]), out=str(out))
    if share_t0 is not None:
        config["share_t0"] = share_t0
    try:
        cfg = EvalConfig.from_flat(**config)
        resolved = build_plan(cfg, family_of(cfg.plan))
    except (IndgenError, ImportError, OSError) as e:  # e.g. LIBERO's assets missing on this machine
        why = str(e).splitlines()[0] if str(e) else type(e).__name__
        note = f"the shards' command does not resolve on this machine ({why}); merge where the shards ran"
        return plan, {"config": config, "note": note}
    want = cfg.plan_dict(list(resolved.tasks), {a: list(v) for a, v in resolved.levels.items()}, cfg.plan.max_steps,
                         resolved.scene_plan.task_steps)  # fmt: skip
    if set(want["tasks"]) == set(tasks):  # evaluate's order: --task all lists the scene's tasks in its order
        plan = {**plan, "tasks": want["tasks"]}
    diff = [k for k in dict.fromkeys([*want, *plan]) if want.get(k) != plan.get(k)]
    config = cfg.flat()
    if not diff:
        return plan, {"config": config, "command": resume_command(cfg)}
    why = (f"tasks {', '.join(tasks)} are neither one task nor all of the scene's ('--task' takes one or 'all')"
           if diff[0] == "tasks" else f"'{resume_command(cfg)}' plans another {diff[0]}")  # fmt: skip
    return plan, {"config": config, "note": why}


def _check_out(out: Path, shards: Sequence[Shard]) -> None:
    """--out must be new (or an empty directory) and outside every shard: a merge never adds to a run."""
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise RunDirError(f"--out {out} exists and is not empty; merge into a new directory (a merge never adds to a "
                          "run)")  # fmt: skip
    for s in shards:
        if out.resolve().is_relative_to(s.path.resolve()):
            raise RunDirError(f"--out {out} lies inside shard {s.path}, and a merge never writes into a shard; choose "
                              "a directory outside it")  # fmt: skip


def write_merged(
    out: Path, manifest: dict[str, Any], rows: list[dict[str, Any]], shards: Sequence[Shard]
) -> int:
    """Write the merged run under a temporary name beside ``out`` (manifest, episodes, the shards' videos of its
    episodes) and rename it into place, so ``out`` appears whole or not at all; returns the videos not found."""
    tmp = out.parent / f".{out.name}.merging-{os.getpid()}"
    _remove_dead_merges(out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp.mkdir()
    except OSError as e:
        raise RunDirError(f"cannot write to --out {out}: {e.strerror}; choose another directory") from None
    try:
        atomic_write_json(tmp / MANIFEST, manifest)
        RunDir(tmp).rewrite(EpisodeRecord(**row) for row in rows)
        missing = _copy_videos(tmp, rows, shards)
        try:  # over an empty directory too; a non-empty one (another merge just now) refuses
            os.rename(tmp, out)
        except OSError as e:
            raise RunDirError(
                f"cannot create --out {out}: {e.strerror}; merge into a new directory"
            ) from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return missing


def _remove_dead_merges(out: Path) -> None:
    """Temporary trees of earlier merges into ``out`` whose process is gone (killed before its rename) are removed;
    a live one (another merge running now) is left alone."""
    for stale in out.parent.glob(f".{glob.escape(out.name)}.merging-*"):
        pid = stale.name.rpartition("-")[2]
        if pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)):
            shutil.rmtree(stale, ignore_errors=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def _copy_videos(dest: Path, rows: list[dict[str, Any]], shards: Sequence[Shard]) -> int:
    """Each kept episode's video (``videos/NAME``, relative to its run) from the shard that holds it; returns how
    many of the rows' videos no shard has."""
    missing = 0
    for row in rows:
        if not row.get("video"):
            continue
        src = next((s.path / row["video"] for s in shards if (s.path / row["video"]).is_file()), None)
        if src is None:
            missing += 1
            continue
        (dest / row["video"]).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, dest / row["video"])
    return missing


def merge(
    paths: Sequence[str], out: str | os.PathLike[str], family_of: FamilyOf, command: str = ""
) -> tuple[RunDir, dict, list[str]]:
    """Merge the shard run directories ``paths`` into a new run directory ``out`` and write its report; returns the
    run, its summary and the lines that say what the merge did (duplicates, episodes still to run and how).
    ``family_of``: the edge's (CLI's) look-up of the scene family the shards' config names."""
    out = Path(out)
    shards = open_shards(paths)
    run = _merged_already(out, shards)
    if run is not None:  # the same merge again, e.g. after one stopped between its rename and its report
        manifest, rows = run.manifest, run.rows()
        counts = manifest["merged_from"]
        missing = sum(bool(r.get("video")) and not (out / r["video"]).is_file() for r in rows)
    else:
        _check_out(out, shards)
        plan = merged_plan(shards)
        merged_cells(shards, plan)  # refuses other parameters or a (task, axis) in no shard, before resolving
        check_protocol(shards)
        rows, counts, kept = merged_rows(shards)
        plan, resume = resume_plan(shards, plan, out, family_of, sharing_setting(shards))
        manifest = merged_manifest(shards, plan, counts, kept, resume, command)
        missing = write_merged(out, manifest, rows, shards)
        run = RunDir.open(out)
    summary = write_run_report(run, float(manifest["config"].get("gamma", 0.2)))
    return run, summary, [*numerics_notes(shards), *_lines(manifest, rows, counts, missing)]


def _merged_already(out: Path, shards: Sequence[Shard]) -> RunDir | None:
    """``out`` when it is the merge of exactly these shards as they are now (their paths, run ids and row counts),
    so that a second merge only rewrites its report: a merge stopped after its rename, before its report was
    whole, is finished by running it again. None for anything else (``_check_out`` refuses a non-empty ``out``)."""
    try:
        listed = json.loads((out / MANIFEST).read_text())["merged_from"]["shards"]
        was = [(e["path"], e["run_id"], e["episodes"]) for e in listed]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    now = [(str(s.path.resolve()), s.manifest.get("run_id"), len(s.rows)) for s in shards]
    return RunDir.open(out) if was == now else None


def _lines(
    manifest: dict[str, Any], rows: list[dict[str, Any]], counts: dict[str, int], missing: int
) -> list[str]:
    merged, plan = manifest["merged_from"], manifest["plan"]
    # an unavailable episode is its seed's: finished, never run again
    finished = sum(r["status"] in FINISHED for r in rows)
    unavailable, errors = sum(r["status"] == "unavailable" for r in rows), len(rows) - finished
    planned = manifest["resolved"]["episodes"]
    lines = [f"merged {len(merged['shards'])} shards: {finished} finished episodes"
             + (f" ({unavailable} of them unavailable: ruled out by their level)" if unavailable else "")
             + (f" and {errors} error rows" if errors else "")
             + f" of {planned} planned; tasks {', '.join(plan['tasks'])}; axes {', '.join(plan['axes'])}"]  # fmt: skip
    lines += [
        f"  {s['path']}: {s['kept']} of its {s['episodes']} rows (run {s['run_id']})"
        for s in merged["shards"]
    ]
    if counts["identical_duplicates"]:
        lines.append(f"kept one copy of {counts['identical_duplicates']} episode(s) found in two shards with the same "
                     "outcome")  # fmt: skip
    if counts["retried_errors"]:
        lines.append(
            f"{counts['retried_errors']} error row(s) had a copy in another shard (an ok copy is kept)"
        )
    if missing:
        lines.append(
            f"{missing} episode video(s) named in the shards' rows are in no shard (their rows keep them)"
        )
    todo = planned - finished if not plan.get("adaptive") else None
    if todo == 0:
        return lines
    # an adaptive run's plan caps its episodes: only its rule knows whether the shards' ladders are settled
    what = (
        f"{todo} planned episode(s) are not finished" if todo else "an adaptive rule may want more episodes"
    )
    if merged["resume"]:
        return [*lines, f"{what}; to run them: {merged['resume']}"]
    return [*lines, f"{what}, and no single evaluate command resumes this merge ({merged['resume_note']}): finish the "
                    "shards and merge them again"]  # fmt: skip
