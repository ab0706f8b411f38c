"""Per-episode files (videos) of a Ray run reach the run directory: a simulator actor writes them into a scratch
directory of its own node and sends them back with the episode's record, or, when ``--out`` is on a file system
every node mounts (``INDGEN_RAY_SHARED_OUT=1``, checked), writes them there directly."""

from __future__ import annotations

import os
import secrets
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.runs.records import atomic_write_bytes

SHARED_ENV = "INDGEN_RAY_SHARED_OUT"
PROBE = ".indgen-shared-probe"


@dataclass(frozen=True)
class FileRoute:
    """How a simulator actor's episode files reach the run directory ``run_dir`` (absolute): ``shared`` (written
    there directly) or shipped back with each record."""

    run_dir: str
    shared: bool = False

    def __post_init__(self) -> None:
        if not Path(self.run_dir).is_absolute():
            raise ConfigError(f"run directory {self.run_dir!r} must be absolute on a Ray cluster")

    def manifest(self) -> dict:
        """What the manifest records (``ray.files``): where the files went."""
        return {"files": "shared", "shared_path": self.run_dir} if self.shared else {"files": "shipped"}


def shared_out(environ=os.environ) -> bool:
    """``INDGEN_RAY_SHARED_OUT`` checked (unset or 0: False; 1: True), whether or not the run writes files."""
    raw = environ.get(SHARED_ENV, "").strip()
    if raw not in ("", "0", "1"):
        raise ConfigError(
            f"{SHARED_ENV}={raw!r}: must be 1 (--out is on a file system every node mounts) or 0"
        )
    return raw == "1"


def route(out: str | os.PathLike[str], environ=os.environ) -> FileRoute:
    """The run's route from ``INDGEN_RAY_SHARED_OUT`` (unset or 0: shipped; 1: shared, checked on every node)."""
    return FileRoute(str(Path(out).resolve()), shared=shared_out(environ))


def write_probe(run_dir: str) -> str:
    """Leave a token in the run directory for the simulator actors to read back (``sees``); returns it."""
    token = secrets.token_hex(8)
    Path(run_dir, PROBE).write_text(token)
    return token


def sees(run_dir: str, token: str) -> bool:
    """Whether this node sees the driver's run directory: the probe there holds the driver's token."""
    try:
        return Path(run_dir, PROBE).read_text() == token
    except OSError:
        return False


def not_shared(run_dir: str, node: str) -> ConfigError:
    """The one line refusing a shared route that one node does not see."""
    return ConfigError(f"{SHARED_ENV}=1 but node {node} does not see {run_dir} (its {PROBE} is missing or "
                       f"different): mount --out on every node at the same path, or unset {SHARED_ENV} so each "
                       "episode's files travel back with its record")  # fmt: skip


class Scratch:
    """A simulator actor's node-local stand-in for the run directory: the runner writes under it, and after every
    episode ``collect`` hands back what was written (paths relative to the run directory) and empties it."""

    def __init__(self) -> None:
        self.root = Path(tempfile.mkdtemp(prefix="indgen-ray-"))

    def video_dir(self, video_dir: str) -> str:
        """Where the runner writes videos: the same place relative to the scratch as to the run directory."""
        return str(self.root / Path(video_dir).name)

    def collect(self) -> dict[str, bytes]:
        files = {}
        for p in sorted(self.root.rglob("*")):
            if p.is_file() and not p.name.startswith(
                "."
            ):  # a hidden partial is an encode that did not finish
                files[p.relative_to(self.root).as_posix()] = p.read_bytes()
        for p in self.root.iterdir():
            shutil.rmtree(p) if p.is_dir() else p.unlink()
        return files

    def close(self) -> None:
        shutil.rmtree(self.root, ignore_errors=True)


def deliver(run_dir: str, files: dict[str, bytes]) -> None:
    """Write an episode's files into the run directory (atomically each, before its record is appended: a record
    never names a file that is not there)."""
    root = Path(run_dir).resolve()
    for rel, data in files.items():
        path = (root / rel).resolve()
        if root not in path.parents:
            raise ConfigError(f"an episode file {rel!r} points outside the run directory")
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(path, data)
