"""The oracle on a run's own initial states (``indgen certify --evaluation-states``, ``oracle_states.json`` in the run
directory): summary.json's ``oracle_states`` and report.md's line that splits the policy's failures into those on
states the oracle solved (policy failures) and those on states it did not (possibly unsolvable states: a different
finding, never silently a policy failure)."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

ORACLE_STATES = "oracle_states.json"


def load_states(run_path: str | Path) -> dict[tuple[str, str, int, int], bool | None] | None:
    """{(task, axis, level, episode): solved (None: the state could not hold the level)}, or None without a file."""
    path = Path(run_path) / ORACLE_STATES
    if not path.is_file():
        return None
    data = json.loads(path.read_text())
    return {
        (s["task"], s["axis"], int(s["level"]), int(s["episode"])): s["solved"]
        for s in data.get("states", [])
    }


def states_entry(
    states: Mapping[tuple, bool | None], episodes, axis: str
) -> dict[str, dict[str, dict[str, Any]]]:
    """{task: {level: {"states", "oracle_solved", "oracle_unsolved", "policy_failed_solved",
    "policy_failed_unsolved", "unsolved_episodes"}}} over ``axis``'s policy episodes whose state the oracle played
    (a shared T0 row looks up its owner axis's state)."""
    out: dict[str, dict[str, dict[str, Any]]] = {}
    rows = episodes[(episodes["axis"] == axis) & (episodes["status"] == "ok")]
    shared = rows["shared_from"].fillna("") if "shared_from" in rows else None
    for i, r in enumerate(rows.itertuples()):
        owner = (shared.iloc[i] if shared is not None else "") or axis
        key = (r.task, owner, int(r.level), int(r.episode))
        if key not in states or states[key] is None:
            continue
        e = out.setdefault(str(r.task), {}).setdefault(str(int(r.level)), {
            "states": 0, "oracle_solved": 0, "oracle_unsolved": 0, "policy_failed_solved": 0,
            "policy_failed_unsolved": 0, "unsolved_episodes": []})  # fmt: skip
        solved = bool(states[key])
        e["states"] += 1
        e["oracle_solved" if solved else "oracle_unsolved"] += 1
        if not solved:
            e["unsolved_episodes"].append(int(r.episode))
        if not bool(r.success):
            e["policy_failed_solved" if solved else "policy_failed_unsolved"] += 1
    return {t: dict(sorted(v.items(), key=lambda kv: int(kv[0]))) for t, v in sorted(out.items())}


def attach_oracle_states(summary: dict, run_path: str | Path, episodes) -> None:
    """Add each axis's ``oracle_states`` to ``summary`` when the run directory has ``oracle_states.json``."""
    states = load_states(run_path)
    if states is None:
        return
    for axis, a in summary.get("axes", {}).items():
        a["oracle_states"] = states_entry(states, episodes, axis)


def states_lines(label: str, axis: str, entry: Mapping[str, Mapping[str, Mapping[str, Any]]]) -> list[str]:
    """report.md's line: per task and level, the policy's failures on states the oracle solved and on states it
    did not (n = the states the oracle played)."""
    if not entry:
        return []
    cells, total = [], [0, 0, 0, 0]  # states, unsolved, failures on solved, failures on unsolved
    for task, levels in entry.items():
        for level, e in levels.items():
            total[0] += e["states"]
            total[1] += e["oracle_unsolved"]
            total[2] += e["policy_failed_solved"]
            total[3] += e["policy_failed_unsolved"]
            if e["oracle_unsolved"] or e["policy_failed_solved"]:
                cells.append(f"{task} level {int(level):+d}: {e['policy_failed_solved']} of {e['oracle_solved']} "
                              f"solved states failed by the policy, {e['policy_failed_unsolved']} of "
                              f"{e['oracle_unsolved']} unsolved ones (episodes {e['unsolved_episodes']})")  # fmt: skip
    head = (f"**Oracle on the evaluated states** ({label}, `{axis}`): the oracle played {total[0]} of the run's "
            f"initial states and did not solve {total[1]}; of the policy's failures, {total[2]} were on states the "
            f"oracle solved (policy failures) and {total[3]} on states it did not (a state the oracle cannot solve "
            f"may be unsolvable: a different finding from a policy failure)")  # fmt: skip
    return [head + (": " + "; ".join(cells) if cells else "") + "."]
