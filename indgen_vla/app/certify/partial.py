"""A level's finished episodes on disk while it runs, so a killed ``indgen certify`` resumes mid-level.

Beside ``certify.json``, ``certify.partial.L<level>.jsonl`` holds a header line (what must match for reuse: steps,
seed, rule, episode length) and one line per finished episode, appended and fsynced. Episode i always has the same
seed, so the episodes read back are exactly those a fresh run would have made; the file goes once the level's row
is in ``certify.json``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path


def partial_path(cert_json: Path, level: int) -> Path:
    return Path(cert_json).with_name(f"certify.partial.L{level}.jsonl")


class EpisodeLog:
    """The finished episodes of one level: ``results`` [(success, steps)] and ``unavailable`` seeds, in order."""

    def __init__(self, path: Path | None, key: str):
        self.path, self.key = path, key
        self.results: list[tuple[bool, int]] = []
        self.unavailable = 0
        if path is None:
            return
        lines = path.read_text().splitlines() if path.is_file() else []
        rows = []
        for line in lines:
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:  # a line cut by a kill: the episodes before it stand
                break
        if not rows or rows[0].get("key") != key:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps({"key": key}) + "\n")
            return
        for r in rows[1:]:
            if r.get("unavailable"):
                self.unavailable += 1
            else:
                self.results.append((bool(r["success"]), int(r["steps"])))

    def add(self, success: bool | None, steps: int = 0) -> None:
        """Record one episode (``success`` None: its seed could not hold the level)."""
        if success is None:
            self.unavailable += 1
            row = {"unavailable": True}
        else:
            self.results.append((bool(success), int(steps)))
            row = {"success": bool(success), "steps": int(steps)}
        if self.path is not None:
            with self.path.open("a") as f:
                f.write(json.dumps(row) + "\n")
                f.flush()
                os.fsync(f.fileno())

    def discard(self) -> None:
        if self.path is not None:
            self.path.unlink(missing_ok=True)
