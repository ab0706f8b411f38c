"""Which levels a run's rates rest on a certificate, read back from its manifest's cells for summary.json, report.md
and the caveats: per task, the levels certified, uncertified (no certificate with enough evidence), uncertified
because the scene's oracle has no script for the task (``indgen certify`` cannot help), and failed."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

# a cell's ``evidence`` when the scene's oracle scripts no such task (scenes.planning): no certificate can exist
NO_ORACLE = "no oracle script for this task"
KINDS = ("certified", "uncertified", "no_oracle", "failed")


def certification_entry(manifest: Mapping[str, Any], axis: str) -> dict[str, dict[str, list[int]]]:
    """summary.json's ``certification`` of ``axis``: {task: {kind: [levels]}} for every kind present ({} when the
    manifest predates the record of cells)."""
    out: dict[str, dict[str, list[int]]] = {}
    for c in (manifest.get("resolved") or {}).get("cells", ()):
        if c.get("axis") != axis:
            continue
        kind = str(c.get("certificate", "uncertified"))
        if kind == "uncertified" and c.get("evidence") == NO_ORACLE:
            kind = "no_oracle"
        levels = out.setdefault(str(c["task"]), {}).setdefault(kind, [])
        levels.append(int(c["level"]))
    return {t: {k: sorted(v[k]) for k in KINDS if k in v} for t, v in sorted(out.items())}


def _levels(levels: Sequence[int]) -> str:
    return ", ".join(f"{k:+d}" if k else "0" for k in levels)


def certification_caveats(
    label: str, axis: str, entry: Mapping[str, Mapping[str, Sequence[int]]]
) -> list[str]:
    """report.md's lines on ``axis``'s certificates (none when every level of every task is certified): which
    levels of which task are uncertified, have no oracle at all, or the oracle failed (Assumption 2)."""
    texts = {
        "failed": "the oracle **failed** its certification (an infeasible level: a low rate there is no "
        "generalization failure)",
        "no_oracle": "**uncertified, no oracle** (the scene's oracle has no script for the task, so no certificate "
        "can say the level is solvable; `indgen certify` cannot help)",
        "uncertified": "**uncertified** (no certificate with enough evidence; `indgen certify` can make one)",
    }
    out = []
    for kind, text in texts.items():
        where = [f"{t}: {_levels(v[kind])}" for t, v in entry.items() if v.get(kind)]
        if where:
            out.append(f"**Certification** ({label}, `{axis}`): {text} at {'; '.join(where)}.")
    return out


# how a certified level's certificate was made (``scenes.heldout``; the cell's ``basis``)
BASES = {"held-out": "certified on held-out states", "exhaustive": "certified on every fixed initial state",
         "in-sample (tuned)": "certified in-sample (tuned)"}  # fmt: skip


def basis_entry(manifest: Mapping[str, Any], axis: str) -> dict[str, dict[str, list[int]]]:
    """summary.json's ``certification_basis`` of ``axis``: {task: {"held-out" | "in-sample (tuned)": [levels]}} of
    its certified levels ({} when the manifest predates the record of bases)."""
    out: dict[str, dict[str, list[int]]] = {}
    for c in (manifest.get("resolved") or {}).get("cells", ()):
        if c.get("axis") == axis and c.get("certificate") == "certified" and c.get("basis") in BASES:
            out.setdefault(str(c["task"]), {}).setdefault(str(c["basis"]), []).append(int(c["level"]))
    return {t: {k: sorted(v[k]) for k in BASES if k in v} for t, v in sorted(out.items())}


def basis_lines(label: str, axis: str, entry: Mapping[str, Mapping[str, Sequence[int]]]) -> list[str]:
    """report.md's and evaluate's line on how ``axis``'s certified levels were certified, per task and level:
    on held-out states (a seed block no earlier attempt, replay or tuning used; the 5 % error spent over the
    attempts), on every fixed initial state (LIBERO's 50: exhaustive, the very states evaluate runs) or in-sample
    (tuned) (the oracle was re-tried or tuned on those seeds, or the history is unknown:
    no error guarantee; ``indgen certify --held-out`` re-runs them)."""
    parts = []
    for kind, text in BASES.items():
        where = [f"{t}: {_levels(v[kind])}" for t, v in entry.items() if v.get(kind)]
        if where:
            parts.append(
                f"{'**' + text + '**' if kind == 'in-sample (tuned)' else text} at {'; '.join(where)}"
            )
    if not parts:
        return []
    tail = (" (in-sample: the oracle was tuned or re-tried on those seeds, or their history is unknown, so the 5 % "
            "error is not guaranteed; `indgen certify --held-out` re-runs them on fresh seeds)"
            if any(v.get("in-sample (tuned)") for v in entry.values()) else "")  # fmt: skip
    return [f"**Certificates** ({label}, `{axis}`): {'; '.join(parts)}{tail}."]


def plan_basis_lines(scene: str, axes: Sequence[str], cells: Sequence[Mapping[str, Any]]) -> list[str]:
    """``evaluate``'s lines before its episodes: per axis, how its certified levels were certified."""
    manifest = {"resolved": {"cells": list(cells)}}
    return [line for a in axes for line in basis_lines(scene, a, basis_entry(manifest, a))]


UNAVAILABLE = (
    "EpisodeUnavailableError"  # an error row whose seed rules the level out (placement check, pick window)
)


def unavailable_rows(episodes):
    """Which rows are ruled out by their level: status ``unavailable``, or (runs written before that status) an
    ``error`` row whose message is an ``EpisodeUnavailableError``."""
    legacy = (episodes["status"] == "error") & episodes["error"].fillna("").str.contains(UNAVAILABLE)
    return (episodes["status"] == "unavailable") | legacy


def infeasible_entry(episodes) -> dict[str, dict[str, int]]:
    """summary.json's ``infeasible`` of one axis's episodes: {task: {level: episodes whose initial state cannot hold
    the level}} (a RoboCasa placement check or pick window: infeasible cells, excluded from n like every error)."""
    if not len(episodes) or "error" not in episodes:
        return {}
    bad = episodes[unavailable_rows(episodes)]
    out: dict[str, dict[str, int]] = {}
    for (task, level), n in bad.groupby(["task", "level"]).size().items():
        out.setdefault(str(task), {})[str(int(level))] = int(n)
    return out


def infeasible_caveats(label: str, axis: str, entry: Mapping[str, Mapping[str, int]]) -> list[str]:
    """report.md's line on ``axis``'s infeasible cells: per task and level, how many episodes' kitchens could not
    hold the level (never a policy failure: those episodes are out of n)."""
    where = [f"{t}: " + ", ".join(f"level {k} × {n}" for k, n in sorted(v.items(), key=lambda kv: int(kv[0])))
             for t, v in entry.items() if v]  # fmt: skip
    if not where:
        return []
    return [f"**Infeasible cells** ({label}, `{axis}`): the level could not be placed in these episodes' initial "
            f"states (the scene's placement check or pick window; see the `error` column), so they are excluded "
            f"from n, never counted as policy failures: {'; '.join(where)}."]  # fmt: skip
