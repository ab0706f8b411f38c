"""The outcome store of a real run: an append-only, fsync'd JSON-lines journal that is the source of truth.

Every verdict the operator gives is one line of ``journal.jsonl``, written with a single ``write`` and
``fsync``'d before the session moves on; ``episodes.parquet`` is then rebuilt from the journal (atomic rename),
so a process killed anywhere (even SIGKILL) loses nothing that was confirmed, and a torn last line (killed
mid-write) is dropped and overwritten by the next entry. Lines are never edited: an undo is a new line.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from indgen_vla.core.errors import ConfigError, RunDirError
from indgen_vla.core.protocol.interface import FAILURE_MODES
from indgen_vla.core.runs.records import EpisodeRecord, RunDir

JOURNAL = "journal.jsonl"
LOCK = ".record.lock"
KINDS = ("success", "failure", "void", "undo")
OPERATOR_FAILURES = tuple(m for m in FAILURE_MODES if m not in ("none", "error", "unknown", "unavailable"))
FAILURE_HELP = {
    "no_contact": "the gripper never touched the object",
    "no_grasp": "touched the object but never lifted it",
    "dropped": "lifted the object, then it slipped out of the gripper",
    "misplaced": "released the object where the task does not count (missed, toppled the stack)",
    "timeout_holding": "time ran out while still holding the object",
}
assert set(FAILURE_HELP) == set(OPERATOR_FAILURES)


@dataclass(frozen=True)
class Entry:
    """One journal line: a verdict on one attempt of an episode, or an undo of an earlier line."""

    seq: int
    kind: str  # success | failure | void | undo
    axis: str = ""
    level: int = 0
    episode: int = 0
    failure: str = ""  # failure mode for kind == failure
    reason: str = ""  # why, for kind == void
    note: str = ""
    video: str = ""
    operator: str = ""
    time: str = ""
    wall_s: float = 0.0  # seconds from the episode being shown to its verdict (set-up + run + judging)
    undo: int = 0  # for kind == undo: the seq it cancels
    trigger: dict = field(default_factory=dict)  # what --episode-command / --check-policy did (real.trigger)

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ConfigError(f"journal entry kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if self.kind == "failure" and self.failure not in (*OPERATOR_FAILURES, ""):  # "": not classified
            raise ConfigError(
                f"unknown failure mode {self.failure!r}; choose one of {', '.join(OPERATOR_FAILURES)}"
            )
        if self.kind == "void" and not self.reason.strip():
            raise ConfigError("a void needs a reason (e.g. void:robot e-stop), so the run log explains it")


def now() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def read_journal(run_path: Path) -> list[Entry]:
    """Every complete journal line in order; a torn last line (no newline: killed mid-write) is ignored."""
    p = Path(run_path) / JOURNAL
    if not p.exists():
        return []
    data = p.read_bytes()
    lines = data.split(b"\n")
    complete = lines[:-1]  # the piece after the last newline is empty, or a torn write
    out = []
    for i, raw in enumerate(complete, 1):
        if not raw.strip():
            continue
        try:
            d = json.loads(raw)
            out.append(Entry(**d))
        except (ValueError, TypeError, ConfigError) as e:
            raise RunDirError(
                f"{p} line {i} is corrupt ({type(e).__name__}); restore it from a backup or delete that line"
            ) from None
    return out


def append_entry(run_path: Path, entry: Entry) -> None:
    """Append one line and fsync it (dropping a torn tail left by a killed writer first)."""
    p = Path(run_path) / JOURNAL
    new = not p.exists()
    fd = os.open(p, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        size = os.fstat(fd).st_size
        if size and os.pread(fd, 1, size - 1) != b"\n":  # a torn line: cut back to the last complete one
            os.ftruncate(fd, _last_line_end(fd, size))
        os.lseek(fd, 0, os.SEEK_END)
        line = (json.dumps(asdict(entry), ensure_ascii=False) + "\n").encode()
        os.write(fd, line)
        os.fsync(fd)
    finally:
        os.close(fd)
    if new:
        dfd = os.open(p.parent, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)


def _last_line_end(fd: int, size: int) -> int:
    """The offset just past the journal's last newline (0 if none), read back in 64 KiB steps: a torn line may
    be longer than one step, and cutting at 0 on a miss would drop every complete line before it."""
    end = size
    while end > 0:
        start = max(0, end - (1 << 16))
        cut = os.pread(fd, end - start, start).rfind(b"\n")
        if cut >= 0:
            return start + cut + 1
        end = start
    return 0


@contextmanager
def recording_lock(run_path: Path) -> Iterator[None]:
    """One recording session per run at a time (the lock dies with its process, even on SIGKILL)."""
    import fcntl

    fd = os.open(Path(run_path) / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise RunDirError(
                f"{run_path} is being recorded by another 'indgen real record' session; finish that one first"
            ) from None
        yield
    finally:
        os.close(fd)


@dataclass(frozen=True)
class State:
    """What the journal says after undos: the counted verdict per episode, and the voids."""

    counted: dict[tuple[int, int], Entry]  # (level, episode) -> success/failure entry
    voids: dict[
        tuple[int, int], list[Entry]
    ]  # (level, episode) -> void entries (still re-queued if not counted)
    live: list[Entry]  # success/failure/void entries not undone, in order
    last: Entry | None  # the latest live entry (what the next undo cancels)


def undone_lines(entries: list[Entry]) -> set[int]:
    """The journal lines an undo line cancels."""
    return {e.undo for e in entries if e.kind == "undo"}


def replay(entries: list[Entry], axis: str) -> State:
    """Apply the journal in order (an undo cancels its target) and keep the entries of ``axis``."""
    undone = undone_lines(entries)
    live = [e for e in entries if e.kind != "undo" and e.seq not in undone and e.axis == axis]
    counted: dict[tuple[int, int], Entry] = {}
    voids: dict[tuple[int, int], list[Entry]] = {}
    for e in live:
        key = (e.level, e.episode)
        if e.kind == "void":
            voids.setdefault(key, []).append(e)
        else:
            if key in counted:
                raise RunDirError(
                    f"the journal records level {key[0]} episode {key[1]} twice (lines "
                    f"{counted[key].seq} and {e.seq}); undo one of them: 'indgen real record RUN --undo LINE'"
                )
            counted[key] = e
    return State(counted, voids, live, live[-1] if live else None)


def records(state: State, manifest: dict[str, Any], seeds: dict[int, int], params: dict[int, float]) -> list:
    """The ``EpisodeRecord`` rows of the counted episodes (voids are journal-only: they never count)."""
    plan = manifest["plan"]
    axis, task = plan["axes"][0], plan["tasks"][0]
    return [
        EpisodeRecord(
            run_id=manifest["run_id"],
            policy=manifest.get("policy", ""),
            data_regime=manifest.get("data_regime", ""),
            scene=manifest["scene"],
            task=task,
            axis=axis,
            level=k,
            param=params[k],
            episode=i,
            seed=seeds[i],
            success=e.kind == "success",
            steps=0,
            status="ok",
            error="",
            wall_s=e.wall_s,
            video=e.video,
            failure="none" if e.kind == "success" else e.failure,
        )  # fmt: skip
        for (k, i), e in sorted(state.counted.items())
    ]


def rebuild(run: RunDir, rows: list) -> None:
    """Rewrite ``episodes.parquet`` from the journal's rows (atomic)."""
    run.rewrite(rows)
