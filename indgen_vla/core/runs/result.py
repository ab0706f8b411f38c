"""What the Python API hands back for a run directory: its summary, k* per axis and direction, its episodes."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

from indgen_vla.core.errors import RunDirError
from indgen_vla.core.runs.records import REPORT, SUMMARY, RunDir

if TYPE_CHECKING:
    import pandas as pd


@dataclass(frozen=True)
class KStar:
    """The break level of one axis (pooled over its tasks, or of one task), as summary.json states it.

    ``pos``/``neg`` are the first level with S < γ on each side (an int), None when no evaluated level on that
    side broke, or ``"undetermined"`` when a level without usable data comes first; ``neg`` is None for a
    one-sided axis (``signed`` False). ``determined`` and ``verdict`` carry the CI-based decision report.md prints.
    """

    axis: str
    task: str | None
    signed: bool
    pos: int | str | None
    neg: int | str | None
    determined: dict[str, bool] = field(default_factory=dict)  # per direction: is k* decided?
    verdict: dict[str, str] = field(default_factory=dict)  # per direction: the sentence report.md prints

    def __str__(self) -> str:
        where = f"{self.axis}" + (f" ({self.task})" if self.task else "")
        sides = [f"{'+' if d == 'pos' else '−'}: {v}" for d, v in self.verdict.items()]
        return f"k* of {where}: " + "; ".join(sides)


def _level(value: Any) -> int | str | None:
    """summary.json writes a level as an int (or its text); keep statuses as text."""
    if value is None or isinstance(value, int):
        return value
    try:
        return int(value)
    except (TypeError, ValueError):
        return str(value)


@dataclass(frozen=True)
class Run:
    """A finished (or stopped) run directory, read through its own files; ``evaluate`` returns one."""

    path: Path

    def __post_init__(self) -> None:
        object.__setattr__(self, "path", Path(os.fspath(self.path)))
        if not (self.path / "manifest.json").is_file():
            raise RunDirError(
                f"{self.path} is not a run directory (no manifest.json); run 'indgen evaluate' first"
            )

    @cached_property
    def _dir(self) -> RunDir:
        return RunDir.open(self.path)

    @property
    def manifest(self) -> dict[str, Any]:
        return self._dir.manifest

    @property
    def report_md(self) -> Path:
        return self.path / REPORT

    @cached_property
    def summary(self) -> dict[str, Any]:
        """summary.json as written by ``evaluate``/``report`` (rates with CIs, k*, verdicts per axis)."""
        p = self.path / SUMMARY
        if not p.is_file():
            raise RunDirError(f"{p} is missing; write it with 'indgen report {self.path}'")
        return json.loads(p.read_text())

    @property
    def axes(self) -> list[str]:
        return list(self.summary["axes"])

    def episodes(self) -> pd.DataFrame:
        """Every recorded episode (one row per episode of episodes.parquet)."""
        return self._dir.episodes()

    def kstar(self, axis: str, task: str | None = None) -> KStar:
        """k* of ``axis``, pooled over the run's tasks, or of one ``task``."""
        axes = self.summary["axes"]
        if axis not in axes:
            raise RunDirError(f"{self.path} has no axis {axis!r}; its axes: {', '.join(axes) or 'none'}")
        entry = axes[axis]
        if task is not None:
            tasks = entry.get("tasks") or {}
            if task not in tasks:
                raise RunDirError(
                    f"{self.path}: axis {axis!r} has no task {task!r}; tasks: {', '.join(tasks)}"
                )
            entry = tasks[task]
        bl, status = entry.get("break_level") or {}, entry.get("kstar_status") or {}
        return KStar(
            axis=axis,
            task=task,
            signed="neg" in bl,
            pos=_level(bl.get("pos")),
            neg=_level(bl.get("neg")) if "neg" in bl else None,
            determined={d: bool(s.get("determined")) for d, s in status.items()},
            verdict=dict(entry.get("verdict") or {}),
        )

    def __str__(self) -> str:
        return str(self.path)
