"""A LeRobotDataset that a killed recording resumes: lerobot 0.6's writer keeps its Parquet files open until
``finalize`` (their footers, hence every episode since the last ``finalize``, are unreadable after a kill) and
rewrites ``meta/info.json``/``stats.json`` per episode, so a kill leaves counts of episodes lerobot cannot read.

Here every episode is staged first (one pickle, renamed into place), then saved through lerobot's own API; every
``every`` episodes the dataset is finalized and checkpointed (lerobot's mutable meta files copied, its other files
listed: after ``LeRobotDataset.resume`` lerobot only adds files). A rerun rolls the dataset back to its last
checkpoint and saves the staged episodes again, so it writes the very files an uninterrupted run writes.
"""

from __future__ import annotations

import json
import logging
import pickle
import shutil
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.runs.records import atomic_write_bytes, atomic_write_json

# per-episode sidecar beside lerobot's own metadata: episode seed and per-frame object poses (MimicGen's source)
EPISODES_SIDECAR = "meta/indgen_episodes.jsonl"
JOURNAL = ".indgen_journal"  # staged episodes and the last checkpoint; removed once the dataset is complete
MUTABLE = (
    "meta/info.json",
    "meta/stats.json",
    "meta/tasks.parquet",
)  # the lerobot files a saved episode rewrites
CHECKPOINT_EVERY = (
    20  # episodes between two checkpoints: the most a rerun saves again (and at most that many staged)
)


def append_episode_sidecar(root: Path, record: dict) -> None:
    """Append one episode's record (seed, task, per-frame object poses) to the dataset's sidecar."""
    path = Path(root) / EPISODES_SIDECAR
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("a") as f:
        f.write(json.dumps(record, separators=(",", ":")) + "\n")


def read_episode_sidecar(root: Path) -> list[dict]:
    """The sidecar records of a dataset written by ``indgen demos`` or ``indgen mimicgen`` ([] if absent)."""
    path = Path(root) / EPISODES_SIDECAR
    if not path.is_file():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def read_record(out: Path, record: str) -> dict | None:
    """The arguments record at ``out/record`` (None if absent)."""
    path = out / record
    return json.loads(path.read_text()) if path.is_file() else None


def drop_journal(out: Path) -> None:
    """Remove the journal of a complete dataset (there only when a run was killed between its last two steps)."""
    shutil.rmtree(out / JOURNAL, ignore_errors=True)


@dataclass
class JournaledDataset:
    """The dataset at ``out`` while it is recorded: ``add`` stages and saves one episode, ``complete`` ends it.

    Attributes:
        out: dataset root.
        repo_id: lerobot repo id stored in it.
        record: path (under ``out``) of the caller's arguments record, e.g. ``meta/indgen_demos.json``.
        write: saves one staged payload as the next episode of a ``LeRobotDataset``; returns its sidecar record.
        every: episodes between two checkpoints (the file layout depends on it: keep it fixed per dataset).
    """

    out: Path
    repo_id: str
    record: str
    write: Callable[[Any, Any], dict]
    every: int = CHECKPOINT_EVERY
    episodes: int = 0
    _ds: Any = None

    @property
    def journal(self) -> Path:
        return self.out / JOURNAL

    @classmethod
    def create(cls, out: Path, args: dict, lerobot_kwargs: dict, **kw) -> JournaledDataset:
        """A new dataset at ``out`` (absent or empty): made beside it and renamed into place with its record and
        first checkpoint, so ``out`` is never a dataset without them."""
        from lerobot.datasets.lerobot_dataset import LeRobotDataset

        tmp = out.parent / f".{out.name}.indgen-new"
        shutil.rmtree(tmp, ignore_errors=True)  # a creation killed before its rename
        out.parent.mkdir(parents=True, exist_ok=True)
        LeRobotDataset.create(root=tmp, **lerobot_kwargs).finalize()
        atomic_write_json(tmp / kw["record"], {**args, "complete": False})
        made = cls(tmp, **kw)
        made._checkpoint()
        if out.exists():
            out.rmdir()
        tmp.rename(out)
        made.out = out
        return made

    @classmethod
    def reopen(cls, out: Path, **kw) -> JournaledDataset:
        """The dataset at ``out`` as its last run left it: rolled back to its last checkpoint, then the episodes
        staged since saved again."""
        made = cls(out, **kw)
        made.episodes = made._rollback()
        staged = made._staged()
        for path in staged:
            with path.open("rb") as f:
                made._save(pickle.load(f))
        return made

    def add(self, payload: Any) -> None:
        """Stage ``payload`` (a kill after this keeps it), save it as the next episode, checkpoint when due."""
        path = self.journal / f"ep-{self.episodes:06d}.pkl"
        atomic_write_bytes(path, pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL))
        self._save(payload)

    def complete(self, extra: dict) -> None:
        """Finalize, mark the record complete (with ``extra``) and drop the journal."""
        if self._ds is not None:
            self._checkpoint()
        path = self.out / self.record
        atomic_write_json(path, {**json.loads(path.read_text()), **extra, "complete": True})
        drop_journal(self.out)

    @contextmanager
    def recording(self) -> Iterator[JournaledDataset]:
        """The dataset while episodes are added: an interruption (Ctrl-C, an error) abandons it and goes on."""
        try:
            yield self
        except BaseException:
            try:
                self.abandon()
            # closing must not mask the run's own outcome; a rerun rolls the session back anyway
            except Exception:
                logging.getLogger(__name__).debug("finalizing an interrupted dataset failed", exc_info=True)
            raise

    def abandon(self) -> None:
        """Finalize the open lerobot session without a checkpoint (an interrupted run; a rerun rolls it back and
        saves its episodes again from the journal), so that no finalizer of it writes into ``out`` later."""
        if self._ds is not None:
            ds, self._ds = self._ds, None
            ds.finalize()

    def _save(self, payload: Any) -> None:
        if self._ds is None:
            from lerobot.datasets.lerobot_dataset import LeRobotDataset

            self._ds = LeRobotDataset.resume(self.repo_id, root=self.out, video_backend="pyav")
        record = self.write(self._ds, payload)
        assert record["episode_index"] == self.episodes, (record["episode_index"], self.episodes)
        append_episode_sidecar(self.out, record)
        self.episodes += 1
        if self.episodes % self.every == 0:
            self._checkpoint()

    def _lerobot_files(self) -> dict[str, int]:
        """lerobot's files under ``out`` (relative path -> size): all but the journal, the record and the sidecar."""
        ours = {self.record, EPISODES_SIDECAR}
        files = {}
        for path in self.out.rglob("*"):
            rel = path.relative_to(self.out).as_posix()
            if path.is_file() and rel not in ours and not rel.startswith(JOURNAL + "/"):
                files[rel] = path.stat().st_size
        return files

    def _checkpoint(self) -> None:
        """Finalize lerobot's writers and record what the dataset holds now, as the point a rerun returns to."""
        if self._ds is not None:
            self._ds.finalize()
            self._ds = None
        tmp = self.journal / "checkpoint.tmp"
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir(parents=True)
        files = self._lerobot_files()
        for rel in MUTABLE:
            if rel in files:
                shutil.copy2(self.out / rel, tmp / Path(rel).name)
        immutable = {k: v for k, v in files.items() if k not in MUTABLE}
        atomic_write_json(tmp / "manifest.json", {"episodes": self.episodes, "files": immutable})
        done = self.journal / f"checkpoint-{self.episodes:06d}"
        shutil.rmtree(done, ignore_errors=True)
        tmp.rename(done)  # the commit: a rerun returns here
        for old in self.journal.iterdir():
            if old.name.startswith("checkpoint-") and old != done:
                shutil.rmtree(old)
            elif old.name.startswith("ep-") and old.suffix == ".pkl" and int(old.stem[3:]) < self.episodes:
                old.unlink()

    def _rollback(self) -> int:
        """Return ``out`` to its last checkpoint (drop lerobot's files made since, restore its mutable ones, cut
        the sidecar to the checkpoint's episodes); return that episode count."""
        done = sorted(self.journal.glob("checkpoint-*"))
        if not done:
            raise ConfigError(f"--out {self.out} has no checkpoint in {JOURNAL}/ (it was not written by this "
                              "version of indgen); choose a new directory")  # fmt: skip
        ckpt = done[-1]
        manifest = json.loads((ckpt / "manifest.json").read_text())
        keep, files = manifest["files"], self._lerobot_files()
        for rel, size in files.items():
            if rel in MUTABLE or rel not in keep:
                (self.out / rel).unlink()
            elif size != keep[rel]:
                raise ConfigError(f"--out {self.out}: {rel} changed since the last checkpoint (something other "
                                  "than indgen wrote into the dataset); choose a new directory")  # fmt: skip
        missing = sorted(set(keep) - set(files))  # what was deleted above was not in keep
        if missing:
            raise ConfigError(
                f"--out {self.out}: {missing[0]} is missing (deleted by hand?); choose a new directory"
            )
        for rel in MUTABLE:
            if (ckpt / Path(rel).name).is_file():
                shutil.copy2(ckpt / Path(rel).name, self.out / rel)
        _remove_empty_dirs(self.out)
        episodes = int(manifest["episodes"])
        sidecar = self.out / EPISODES_SIDECAR
        if sidecar.is_file():  # a line per saved episode, the last maybe cut short
            sidecar.write_text("".join(sidecar.read_text().splitlines(keepends=True)[:episodes]))
        shutil.rmtree(self.journal / "checkpoint.tmp", ignore_errors=True)
        return episodes

    def _staged(self) -> list[Path]:
        """The episodes staged since the checkpoint, in order (a partly written one dropped)."""
        for tmp in self.journal.glob(".ep-*.pkl.*"):  # atomic_write_bytes's temp file of a killed write
            tmp.unlink()
        staged = sorted(self.journal.glob("ep-*.pkl"))
        first = self.episodes
        run = [p for p in staged if int(p.stem[3:]) >= first]
        assert [int(p.stem[3:]) for p in run] == list(range(first, first + len(run))), run
        return run


def _remove_empty_dirs(root: Path) -> None:
    """Remove the empty directories under ``root`` (lerobot's staging folders of an unsaved episode)."""
    for path in sorted((p for p in root.rglob("*") if p.is_dir()), key=lambda p: len(p.parts), reverse=True):
        if not any(path.iterdir()):
            path.rmdir()
