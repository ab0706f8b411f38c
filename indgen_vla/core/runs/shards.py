"""Shards of one protocol as one run: the checks and unions behind ``indgen merge``.

A protocol split over a cluster (a SLURM array of ``indgen evaluate ... --task T --out runs/T``, one job per task or
per axis) leaves one run directory per shard. Merged, they make one ordinary run directory: the union of their plans
and every finished episode, so ``report``, ``compare`` and ``reference`` read it like any run. Shards must be parts of
one protocol: the same plan apart from its tasks and axes (policy, seed, episodes, levels of each axis, steps,
horizon...), together every task on every axis, the same protocol fingerprint in each field that changes outcomes
(never overridden: a merged run claims one protocol, and every later report would hide the difference), and the same
outcome wherever two shards hold the same episode. Pure: reads the shards, writes nothing (``studies/merge.py`` does).
"""

from __future__ import annotations

import datetime as _dt
import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from indgen_vla.core.errors import ConfigError, RunDirError
from indgen_vla.core.protocol.fingerprint import (
    NUMERICS,
    differences,
    numerics_warning,
    short,
    show_difference,
)
from indgen_vla.core.protocol.interface import declared_reads
from indgen_vla.core.protocol.plan import SHARING_OFF, jobs_sha256, plan_jobs, shared_t0_of, sharing_summary
from indgen_vla.core.runs.records import KEY, RunDir

# the plan entries a merge unions; every other one must be equal in every shard
UNION_KEYS = ("tasks", "axes", "levels", "task_steps")
# what two copies of one episode in two shards must agree on
OUTCOME = ("seed", "param", "success", "steps", "status", "failure", "progress")
# manifest entries beside the plan and the fingerprint that must be equal: a smoke run never pools with a measurement
EQUAL_MANIFEST = ("measurement",)


@dataclass(frozen=True)
class Shard:
    """One shard: its run directory, manifest and recorded episodes (rows of ``records.COLUMNS``)."""

    path: Path
    manifest: dict[str, Any]
    rows: tuple[dict[str, Any], ...]

    def entry(self, kept: int) -> dict[str, Any]:
        """The shard as the merged manifest's ``merged_from.shards`` lists it (``kept``: its rows in the merge)."""
        m, ok = self.manifest, sum(r["status"] == "ok" for r in self.rows)
        return {"path": str(self.path.resolve()), "run_id": m.get("run_id"), "episodes": len(self.rows), "ok": ok,
                "errors": len(self.rows) - ok, "kept": kept, "tasks": m["plan"]["tasks"], "axes": m["plan"]["axes"],
                "created": m.get("created"), "git_sha": m.get("git_sha"), "command": m.get("command"),
                "numerics": (m.get("fingerprint") or {}).get(NUMERICS)}  # fmt: skip


def open_shards(paths: Sequence[str]) -> list[Shard]:
    """The shards' run directories, read once; refuses fewer than two, one given twice and real-robot runs."""
    if len(paths) < 2:
        raise ConfigError(
            "give two or more shard run directories to merge (indgen merge RUN RUN... --out DIR)"
        )
    shards: list[Shard] = []
    seen: dict[Path, str] = {}
    for p in paths:
        run = RunDir.open(p)
        where = run.path.resolve()
        if where in seen:
            raise ConfigError(
                f"{p} is the same run directory as {seen[where]}: each shard counts once, drop the repeat"
            )
        seen[where] = str(p)
        m = run.manifest
        if "real" in m:
            raise RunDirError(f"{p} is a real-robot run (indgen real): its journal.jsonl is the source of truth, so it "
                              "is not merged; report it on its own")  # fmt: skip
        cells = (m.get("resolved") or {}).get("cells")
        if not isinstance(m.get("plan"), dict) or not isinstance(cells, list):
            raise RunDirError(f"{p}'s manifest has no plan or resolved cells (made by an older indgen); re-run that "
                              "shard into a new --out to merge it")  # fmt: skip
        shards.append(Shard(run.path, m, tuple(run.rows())))
    return shards


def _refuse(a: Shard, b: Shard, what: str) -> RunDirError:
    return RunDirError(f"{a.path} and {b.path} are not shards of one protocol: {what}; merge only the shards of one "
                       "evaluate command split by --task or --axis ('indgen report A B' shows different runs side by "
                       "side)")  # fmt: skip


def merged_plan(shards: Sequence[Shard]) -> dict[str, Any]:
    """The union of the shards' plans: their tasks and axes in first-seen order, each axis's levels (equal in every
    shard that plans it); every other entry (policy, seed, episodes, step, horizon, ...) must be equal."""
    first, p0 = shards[0], shards[0].manifest["plan"]
    for s in shards[1:]:
        p = s.manifest["plan"]
        for key in dict.fromkeys([*p0, *p]):
            if key not in UNION_KEYS and p0.get(key) != p.get(key):
                raise _refuse(first, s, f"plan {key} is {short(p0.get(key))} vs {short(p.get(key))}")
    levels: dict[str, tuple[list[int], Shard]] = {}
    task_steps: dict[str, dict[str, Any]] = {}
    for s in shards:
        p = s.manifest["plan"]
        for axis, ks in p["levels"].items():
            seen, by = levels.setdefault(axis, (ks, s))
            if seen != ks:
                raise _refuse(by, s, f"axis {axis} has levels {short(seen)} vs {short(ks)} (a run plans one set of "
                                     "levels per axis)")  # fmt: skip
        for axis, by_task in (p.get("task_steps") or {}).items():
            for task, steps in by_task.items():
                if task_steps.setdefault(axis, {}).setdefault(task, steps) != steps:
                    raise _refuse(first, s, f"task {task} has {axis} steps {short(task_steps[axis][task])} vs "
                                            f"{short(steps)}")  # fmt: skip
    axes = list(dict.fromkeys(a for s in shards for a in s.manifest["plan"]["axes"]))
    plan = {**p0, "tasks": list(dict.fromkeys(t for s in shards for t in s.manifest["plan"]["tasks"])),
            "axes": axes, "levels": {a: levels[a][0] for a in axes}}  # fmt: skip
    if task_steps:
        plan["task_steps"] = task_steps
    return plan


def merged_cells(shards: Sequence[Shard], plan: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Every (task, axis, level) of ``plan`` with its parameter and certificate, in the order ``evaluate`` records
    them; refuses a cell two shards give different parameters and a (task, axis) no shard planned."""
    cells: dict[tuple[str, str, int], tuple[dict[str, Any], Shard]] = {}
    for s in shards:
        for c in s.manifest["resolved"]["cells"]:
            seen, by = cells.setdefault((c["task"], c["axis"], int(c["level"])), (c, s))
            if seen["param"] != c["param"]:
                raise _refuse(by, s, f"{c['task']}/{c['axis']} level {c['level']} has parameter {seen['param']} vs "
                                     f"{c['param']}")  # fmt: skip
    for axis in plan["axes"]:
        for task in plan["tasks"]:
            if (task, axis, plan["levels"][axis][0]) not in cells:
                raise RunDirError(f"no shard plans task {task} on axis {axis}, so the shards do not cover every task on "
                                  f"every axis as one run does: evaluate it (--task {task} --axis {axis}, the shards' "
                                  "other flags) and merge again, or merge the shards of that axis alone")  # fmt: skip
    return [cells[(t, a, k)][0] for a in plan["axes"] for t in plan["tasks"] for k in plan["levels"][a]]


def numerics_notes(shards: Sequence[Shard]) -> list[str]:
    """A line per shard that ran on other numerics than the first (``fingerprint.numerics_warning``): informational,
    as a merge of such shards is allowed; each shard's numerics stay in the merged manifest's ``merged_from``."""
    first = (shards[0].manifest.get("fingerprint") or {}).get(NUMERICS)
    lines = []
    for s in shards[1:]:
        w = numerics_warning(first, (s.manifest.get("fingerprint") or {}).get(NUMERICS), f"{s.path} ran")
        if w:
            lines.append(f"warning: {w}")
    return lines


def check_protocol(shards: Sequence[Shard]) -> None:
    """Refuse shards whose protocols differ: a fingerprint field that changes outcomes (never overridden), an axis's
    spec, the scene environment, or a smoke run beside a measurement; a shard with finished episodes but no
    fingerprint (made before they were recorded) cannot be checked and is refused too."""
    prints = []
    for s in shards:
        fp = s.manifest.get("fingerprint")
        if fp is None and any(r["status"] == "ok" for r in s.rows):
            raise RunDirError(f"{s.path} has finished episodes but no protocol fingerprint (made before they were "
                              "recorded), so merge cannot check that it ran the others' protocol; re-run it into a "
                              "new --out")  # fmt: skip
        if fp is not None:
            prints.append((s, fp))
    for s, fp in prints[1:]:
        bad = [d for d in differences(prints[0][1], fp) if d[3]]
        if bad:
            field, a, b, _ = bad[0]
            sa, sb = show_difference(field, a, b, width=60)
            more = f" (and {len(bad) - 1} more field(s))" if len(bad) > 1 else ""
            raise _refuse(prints[0][0], s, f"their protocols differ in {field}: {sa} vs {sb}{more}")
    first = shards[0]
    for s in shards[1:]:
        for key in EQUAL_MANIFEST:
            if first.manifest.get(key) != s.manifest.get(key):
                raise _refuse(
                    first, s, f"{key} is {short(first.manifest.get(key))} vs {short(s.manifest.get(key))}"
                )
        for axis in set(first.manifest.get("axes") or {}) & set(s.manifest.get("axes") or {}):
            if first.manifest["axes"][axis] != s.manifest["axes"][axis]:
                raise _refuse(first, s, f"axis {axis} is defined differently ({short(first.manifest['axes'][axis])} "
                                        f"vs {short(s.manifest['axes'][axis])})")  # fmt: skip
        ea, eb = _environment(first), _environment(s)
        for key in dict.fromkeys([*ea, *eb]):
            if key != "successors" and ea.get(key) != eb.get(key):
                raise _refuse(first, s, f"their scene environments differ in {key}: {short(ea.get(key))} vs "
                                        f"{short(eb.get(key))}")  # fmt: skip
        for axis in set(ea.get("successors") or {}) & set(eb.get("successors") or {}):
            if ea["successors"][axis] != eb["successors"][axis]:
                raise _refuse(first, s, f"axis {axis} moves by another successor ({short(ea['successors'][axis])} vs "
                                        f"{short(eb['successors'][axis])})")  # fmt: skip


def sharing_setting(shards: Sequence[Shard]) -> bool | None:
    """Whether the shards share T0 across axes (their manifests' ``t0_sharing.enabled``, as last run): the merged
    run records, and its resume uses, that one setting; None when no shard says (made before T0 sharing). Refuses
    shards that disagree, in one line."""
    said = [(s, s.manifest["t0_sharing"]) for s in shards if isinstance(s.manifest.get("t0_sharing"), dict)]
    a, first = said[0] if said else (None, {})
    for b, entry in said[1:]:
        if bool(entry.get("enabled")) != bool(first.get("enabled")):
            (on, _), (off, why) = sorted([(a, first), (b, entry)], key=lambda se: not se[1].get("enabled"))
            raise RunDirError(f"{on.path} shares level 0 across axes (manifest t0_sharing) and {off.path} does not "
                              f"({why.get('reason') or 'off'}), and a merged run records one setting: resume one "
                              "of them with the other's (--share-t0 or --no-share-t0; its episodes are kept) and merge "
                              "again")  # fmt: skip
    return bool(first.get("enabled")) if said else None


def merged_sharing(
    plan: Mapping[str, Any], cells: Sequence[Mapping[str, Any]], jobs, enabled: bool
) -> dict[str, Any]:
    """The merged manifest's ``t0_sharing``: what ``evaluate`` records for the union plan under the shards' setting
    (``share.sharing_entry``), from the cells' level-0 ``env_key``, so a resume of the merge keeps it as it is."""
    keys = {(c["task"], c["axis"]): c.get("env_key", "") for c in cells if int(c["level"]) == 0}
    shared = shared_t0_of(plan["tasks"], plan["axes"], keys) if enabled else {}
    return sharing_summary(plan["tasks"], plan["axes"], shared, jobs, enabled, "" if enabled else SHARING_OFF)


def _environment(s: Shard) -> dict[str, Any]:
    return dict(s.manifest["resolved"].get("environment") or {})


def merged_rows(shards: Sequence[Shard]) -> tuple[list[dict[str, Any]], dict[str, int], list[int]]:
    """Every shard's episodes once: of two copies of one episode (same task, axis, level, episode) an ``ok`` row
    replaces an ``error`` row (a retry), two ``ok`` rows must agree on the outcome (one is kept, and counted in
    ``identical_duplicates``), and any disagreement is refused. Returns the rows, those counts and the rows kept
    from each shard."""
    kept: dict[tuple, tuple[dict[str, Any], int]] = {}
    counts = {"identical_duplicates": 0, "retried_errors": 0}
    for i, s in enumerate(shards):
        for row in s.rows:
            key = tuple(row[k] for k in KEY)
            if key not in kept:
                kept[key] = (row, i)
                continue
            old, by = kept[key]
            if old["status"] != row["status"]:  # an error row is a retry's placeholder: the finished row wins
                counts["retried_errors"] += 1
                if row["status"] != "error":
                    kept[key] = (row, i)
            elif old["status"] == "error":
                counts["retried_errors"] += 1
            elif diff := [f for f in OUTCOME if old[f] != row[f]]:
                f = diff[0]
                raise _refuse(shards[by], s, f"both hold episode {row['episode']} of {row['task']}/{row['axis']} level "
                                     f"{row['level']} with different outcomes ({f} {old[f]!r} vs {row[f]!r})")  # fmt: skip
            else:
                counts["identical_duplicates"] += 1
    per_shard = [0] * len(shards)
    for _, i in kept.values():
        per_shard[i] += 1
    return [row for row, _ in kept.values()], counts, per_shard


def merged_manifest(
    shards: Sequence[Shard], plan: dict[str, Any], counts: Mapping[str, int], kept: Sequence[int],
    resume: Mapping[str, Any], command: str,
) -> dict[str, Any]:  # fmt: skip
    """The merged run's manifest.json: an ordinary run's fields for the union plan (``resolved`` with every cell and
    the union's jobs hash, the fingerprint with every certificate, ``t0_sharing`` under the shards' setting, which
    ``resume``'s config carries) plus ``merged_from``: the shards (path, run id,
    episodes, how many were kept: ``kept``), the duplicate counts (``merged_rows``) and how to resume (``resume``: the
    merged ``config``, and its ``command`` or a ``note`` saying why none resumes it); ``command``: the merge's own."""
    first = shards[0].manifest
    cells = merged_cells(shards, plan)
    config = dict(resume.get("config") or {})
    params = {(c["task"], c["axis"], int(c["level"])): c["param"] for c in cells}
    jobs = plan_jobs(plan["scene"], plan["tasks"], plan["levels"], params, plan["episodes"], plan["seed"],
                     bool(config.get("video")), int(config.get("video_per_level", 1)))  # fmt: skip
    digest = jobs_sha256(jobs)
    ids = " ".join(sorted(str(s.manifest.get("run_id")) for s in shards))
    manifest = {
        "run_id": hashlib.sha256(ids.encode()).hexdigest()[:12],  # the same shards, the same merged run id
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        **{k: first.get(k) for k in ("policy", "data_regime", "scene", "seed")},
        "plan": plan,
        "axes": {a: _axis_spec(shards, a) for a in plan["axes"]},
        "resolved": {
            "environment": _merged_environment(shards),
            "cells": cells,
            "episodes": len(jobs),
            "jobs_sha256": digest,
        },
        "t0_sharing": merged_sharing(plan, cells, jobs, bool(config.get("share_t0", True))),
        "config": config,
        "versions": _common(s.manifest.get("versions") or {} for s in shards),
        "git_sha": _common({"sha": s.manifest.get("git_sha")} for s in shards).get("sha", ""),
        "command": command,
        "merged_from": {
            "shards": [s.entry(n) for s, n in zip(shards, kept, strict=True)],
            **counts,
            "resume": resume.get("command"),
            **({"resume_note": resume["note"]} if resume.get("note") else {}),
        },
    }
    prints = [s.manifest["fingerprint"] for s in shards if s.manifest.get("fingerprint")]
    if prints:
        certificates = {f"{c['task']}/{c['axis']}/{c['level']}": c["certificate"] for c in cells}
        manifest["fingerprint"] = {**prints[0], "certificates": certificates, "plan_sha256": digest}
    changes = [{**c, "shard": str(s.path)} for s in shards for c in s.manifest.get("protocol_changes", [])]
    if changes:
        manifest["protocol_changes"] = changes
    for key in EQUAL_MANIFEST:
        if key in first:
            manifest[key] = first[key]
    # the policy's declaration (interface.PolicySpec), absent where no shard recorded one
    reads = declared_reads(s.manifest.get("reads_observations") for s in shards)
    if reads is not None:
        manifest["reads_observations"] = reads
    return manifest


def _axis_spec(shards: Sequence[Shard], axis: str) -> dict[str, Any]:
    return next(s.manifest["axes"][axis] for s in shards if axis in (s.manifest.get("axes") or {}))


def _merged_environment(shards: Sequence[Shard]) -> dict[str, Any]:
    """The shards' common environment with every axis's successor."""
    env = _environment(shards[0])
    successors = {}
    for s in shards:
        successors.update(_environment(s).get("successors") or {})
    return {**env, "successors": successors} if successors else env


def _common(dicts) -> dict[str, Any]:
    """The entries every dict has with the same value (versions and commits the shards share)."""
    dicts = list(dicts)
    return {k: v for k, v in dicts[0].items() if all(d.get(k) == v for d in dicts[1:])}
