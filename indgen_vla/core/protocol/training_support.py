"""The levels a policy was trained on (its training support), so a report can tell them from generalization steps.

``indgen demos --axis A --levels 0:2`` records each episode's (scene, task, axis, level, axis parameter) in the
dataset's per-episode sidecar; ``indgen train`` aggregates them into its checkpoint's ``train_info.json``
(``levels``); the ``lerobot:`` adapter declares them in ``PolicySpec.training``; ``evaluate`` copies them into the
manifest (``training_levels``); ``report`` marks the levels they cover ("trained", a shaded band). Core code.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

from indgen_vla.core.errors import ConfigError

TRAINED_NOTE = (
    "\"trained\": a level the policy's training data covered (its checkpoint's train_info.json, recorded in "
    "the manifest's training_levels): inside the training support, not a step of generalization."
)


@dataclass(frozen=True)
class TrainedCell:
    """One (scene, task, axis, level) of a policy's training data.

    Attributes:
        scene, task: where the demonstrations were recorded.
        level: the level along ``axis``.
        axis: the axis the level lies on; None for T0 recorded without ``--axis``. Level 0 is T0 on every axis.
        param: the axis parameter at that level (None without ``--axis``); a level evaluated at another
            parameter (another ``--step``) is not the trained one.
        episodes: demonstrations of the cell in the training data.
    """

    scene: str
    task: str
    level: int
    axis: str | None = None
    param: float | None = None
    episodes: int = 0

    def __post_init__(self) -> None:
        if self.axis is None and self.level != 0:
            raise ConfigError(f"training level {self.level} of {self.scene}/{self.task} names no axis")

    def covers(self, scene: str, task: str, axis: str, level: int, param: float | None) -> bool:
        """Whether evaluating (scene, task) at ``level`` of ``axis`` (parameter ``param``) is inside this cell."""
        if (scene, task, level) != (self.scene, self.task, self.level):
            return False
        if level == 0:  # T0: the same scene on every axis (as plan.plan_jobs' paired design has it)
            return True
        return self.axis == axis and (self.param is None or param is None or _close(self.param, param))


def _close(a: float, b: float) -> bool:
    return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)


def cells_from_records(records: Iterable[Mapping[str, Any]]) -> list[TrainedCell]:
    """The cells of ``indgen demos``/``mimicgen`` sidecar records (one per episode), with episode counts."""
    counts: Counter = Counter()
    for r in records:
        param = r.get("param")
        counts[(r["scene"], r["task"], int(r.get("level", 0)), r.get("axis"),
                None if param is None else float(param))] += 1  # fmt: skip
    return [TrainedCell(s, t, k, a, p, n) for (s, t, k, a, p), n in counts.items()]


def cells_from_json(entries: Sequence[Mapping[str, Any]] | None) -> tuple[TrainedCell, ...]:
    """``TrainedCell``s from their JSON form (``train_info.json`` ``levels``, the manifest's ``training_levels``)."""
    if not entries:
        return ()
    try:
        return tuple(
            TrainedCell(str(e["scene"]), str(e["task"]), int(e["level"]), e.get("axis"),
                        None if e.get("param") is None else float(e["param"]), int(e.get("episodes", 0)))
            for e in entries
        )  # fmt: skip
    except (KeyError, TypeError, ValueError) as e:
        raise ConfigError(
            f"training levels {list(entries)[:1]} ... are malformed ({e!r}); re-run `indgen train`"
        ) from None


def cells_to_json(cells: Iterable[TrainedCell]) -> list[dict[str, Any]]:
    return [asdict(c) for c in cells]


def trained_levels(
    cells: Sequence[TrainedCell],
    scene: str,
    axis: str,
    task_levels: Mapping[str, Sequence[Mapping[str, Any]]],
) -> list[dict[str, Any]]:
    """Levels of ``axis`` inside the training support: ``[{"level": k, "tasks": [...]}]``, in level order.

    Args:
        cells: the policy's training cells.
        task_levels: each evaluated task's level rows (``level`` and ``param``, as in summary.json).
    """
    found: dict[int, list[str]] = {}
    for task in sorted(task_levels):
        for row in task_levels[task]:
            k, param = int(row["level"]), row.get("param")
            if any(c.covers(scene, task, axis, k, param) for c in cells):
                found.setdefault(k, []).append(task)
    return [{"level": k, "tasks": found[k]} for k in sorted(found)]


def support_text(cells: Sequence[TrainedCell]) -> str:
    """One line naming the training support, e.g. "pick_place pick_y levels 0, 1, 2 (tasks milk)"."""
    groups: dict[tuple[str, str | None], tuple[set[int], set[str]]] = {}
    for c in cells:
        levels, tasks = groups.setdefault((c.scene, c.axis), (set(), set()))
        levels.add(c.level)
        tasks.add(c.task)
    parts = []
    for (scene, axis), (levels, tasks) in sorted(groups.items(), key=lambda kv: (kv[0][0], kv[0][1] or "")):
        where = "T0" if axis is None else f"{axis} levels {', '.join(map(str, sorted(levels)))}"
        parts.append(f"{scene} {where} (tasks {', '.join(sorted(tasks))})")
    return "; ".join(parts)


def trained_text(axis_summary: Mapping[str, Any], level: int) -> str:
    """A report cell's mark for ``level``: " · trained", " · trained (m/n tasks)" or ""."""
    entry = next((e for e in axis_summary.get("trained") or () if e["level"] == level), None)
    if entry is None:
        return ""
    n = len(axis_summary.get("pooled_tasks") or entry["tasks"])
    return " · trained" if len(entry["tasks"]) >= n else f" · trained ({len(entry['tasks'])}/{n} tasks)"


def fully_trained(axis_summary: Mapping[str, Any]) -> list[int]:
    """Levels every pooled task of ``axis_summary`` was trained on (a plot's shaded band)."""
    n = len(axis_summary.get("pooled_tasks") or ())
    return [e["level"] for e in axis_summary.get("trained") or () if len(e["tasks"]) >= max(n, 1)]
