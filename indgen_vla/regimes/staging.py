"""A resumable dataset writer: every finished attempt of a generator is one journal entry under ``<out>/resume``,
written atomically (its frames first, then its record), and the LeRobotDataset is written from the entries once
they are all in. A killed run resumes after its last saved attempt and ends with the dataset an uninterrupted run
writes; a kill while the dataset is written only repeats that write.

lerobot's own writer cannot be resumed after a kill: it keeps a data file's Parquet footer and up to ten episodes'
metadata in memory until ``finalize()``, so a killed recording leaves an unreadable file and metadata that
disagree. ``indgen mimicgen`` stages here; ``indgen demos`` could too (``FrameCapture`` takes ``save_episode``'s
frames, its kept and discarded attempts become entries, and ``write_dataset`` replaces its direct writes).
"""

from __future__ import annotations

import io
import json
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from indgen_vla.records import atomic_write_bytes, atomic_write_json

ENTRIES_DIR = "episodes"  # under resume/: NNNNNN.json per attempt, NNNNNN.npz with the frames of a kept one
BUILD_DIR = "dataset"  # under resume/: the LeRobotDataset being written, moved into --out when whole
DATASET_PARTS = (
    "data",
    "videos",
    "images",
    "meta",
)  # what lerobot writes under a root; meta (info.json) last


class FrameCapture:
    """Takes the frames a recorder hands a LeRobotDataset (``add_frame``, ``save_episode``), to stage them."""

    def __init__(self):
        self.frames: list[dict] = []

    def add_frame(self, frame: dict) -> None:
        self.frames.append(dict(frame))

    def save_episode(self) -> None:
        """Nothing to flush: the frames are staged by ``Stage.add``."""


class Stage:
    """The journal of attempts under ``root`` (``<out>/resume``); entries are numbered from 0 in attempt order."""

    def __init__(self, root: Path):
        self.dir = Path(root) / ENTRIES_DIR
        self.dir.mkdir(parents=True, exist_ok=True)
        self.entries: list[dict] = self._load()

    def _load(self) -> list[dict]:
        """The committed entries; whatever a kill left half-written (temp files, frames without a record) goes."""
        entries = []
        while (p := self.dir / f"{len(entries):06d}.json").is_file():
            entries.append(json.loads(p.read_text()))
        keep = {f"{i:06d}.{ext}" for i in range(len(entries)) for ext in ("json", "npz")}
        for p in self.dir.iterdir():
            if p.name not in keep:
                p.unlink()
        return entries

    def add(self, record: dict, frames: list[dict] | None = None) -> None:
        """Commit one attempt: ``record`` (JSON) and, for a kept episode, its lerobot frames."""
        stem = self.dir / f"{len(self.entries):06d}"
        if frames is not None:
            buf = io.BytesIO()
            np.savez_compressed(buf, **_columns(frames))
            atomic_write_bytes(stem.with_suffix(".npz"), buf.getvalue())
        atomic_write_json(stem.with_suffix(".json"), record)
        self.entries.append(record)

    def frames(self, i: int) -> Iterator[dict]:
        """Entry ``i``'s frames, exactly as they were added (dtypes, shapes, strings)."""
        with np.load(self.dir / f"{i:06d}.npz", allow_pickle=False) as z:
            cols = {k: z[k] for k in z.files}
        n = len(cols["task"])
        for t in range(n):
            yield {k: (str(v[t]) if v.dtype.kind == "U" else v[t]) for k, v in cols.items()}

    def write_dataset(self, out: Path, create: Callable[[Path], object],
                      sidecar: Callable[[Path, int, dict], None], kept: Callable[[dict], bool]) -> int:  # fmt: skip
        """Write every kept entry, in order, into a LeRobotDataset made by ``create(root)`` (``sidecar(root,
        episode index, record)`` beside each episode), then move it into ``out``; return the number of episodes."""
        build = self.dir.parent / BUILD_DIR
        shutil.rmtree(build, ignore_errors=True)
        for part in DATASET_PARTS:  # a move a kill interrupted: written again from the entries
            shutil.rmtree(out / part, ignore_errors=True)
        ds = create(build)
        n = 0
        try:
            for i, record in enumerate(self.entries):
                if kept(record):
                    for frame in self.frames(i):
                        ds.add_frame(frame)
                    ds.save_episode()
                    sidecar(build, n, record)
                    n += 1
        finally:
            ds.finalize()
        for part in DATASET_PARTS:
            if (build / part).exists():
                (build / part).rename(out / part)
        shutil.rmtree(build)
        return n


def _columns(frames: list[dict]) -> dict[str, np.ndarray]:
    """Frames as one array per key (strings as a unicode array: no pickles in the journal)."""
    return {k: np.stack([np.asarray(f[k]) for f in frames]) for k in frames[0]}
