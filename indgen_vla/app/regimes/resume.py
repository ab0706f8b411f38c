"""What ``indgen train``, ``indgen mimicgen`` (and ``indgen demos``'s argument check) share to resume a killed run:
the ``--out`` states (fresh, unfinished, finished, someone else's), the one-line refusal of a rerun with other
arguments, and a state directory replaced atomically (the previous state survives a kill mid-save)."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Literal

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.runs.records import atomic_write_json

RESUME_DIR = "resume"  # an unfinished run's state inside --out; removed once the run is complete
RUN_FILE = "run.json"  # in RESUME_DIR: the arguments that decide the output, compared on every rerun
LAST_FILE = "last.json"  # in RESUME_DIR: the name of the newest complete state directory

OutState = Literal["fresh", "unfinished", "finished"]


def out_state(
    out: Path, done_file: str, command: str, run_file: str = f"{RESUME_DIR}/{RUN_FILE}"
) -> OutState:
    """Whether ``out`` is new (absent or empty), an unfinished run of ``command`` (it has ``run_file``) or a
    finished one (``done_file`` is written last); anything else is refused, as it was before runs could resume."""
    if not out.exists():
        return "fresh"
    if not out.is_dir():
        raise ConfigError(f"{command}: --out {out} is a file; choose a directory")
    names = set(os.listdir(out))
    if not names:  # made empty beforehand (mkdir -p): as good as absent
        return "fresh"
    if done_file in names:
        return "finished"
    if (out / run_file).is_file():
        return "unfinished"
    # killed before its first state was written: nothing to keep (a run whose state lives elsewhere keeps it)
    if names == {RESUME_DIR} and run_file.startswith(f"{RESUME_DIR}/"):
        shutil.rmtree(out / RESUME_DIR, ignore_errors=True)
        return "fresh"
    raise ConfigError(
        f"{command}: --out {out} already exists and is not empty (not an unfinished '{command}' output); "
        "choose a new directory"
    )


def start_run(out: Path, run: Mapping) -> Path:
    """Create ``out``/resume with the run's arguments (atomically: a kill leaves it absent or whole)."""
    state = out / RESUME_DIR
    state.mkdir(parents=True, exist_ok=True)
    atomic_write_json(state / RUN_FILE, dict(run))
    return state


INPUTS = "inputs"  # a run's key for {input path: its size}: an input that changed is named as such


def flatten(run: Mapping) -> dict:
    """``{"config": {"n": 3}}`` -> ``{"n": 3}``: nested keys by their last name (the option they came from)."""
    out: dict = {}
    for k, v in run.items():
        if k == INPUTS:
            continue
        if isinstance(v, Mapping):
            out.update(flatten(v))
        else:
            out[k] = list(v) if isinstance(v, tuple) else v
    return out


def check_same_run(out: Path, saved: Mapping, now: Mapping, command: str, flags: Iterable[str],
                   finished: bool) -> None:  # fmt: skip
    """Refuse, in one line naming the first differing option, a rerun whose arguments differ from the run that made
    ``out`` (``flags``: the keys that are CLI options, shown as ``--key``; others as ``key=value``), or whose
    inputs (``run["inputs"]``: path -> size) changed since."""
    old, new = flatten(saved), flatten(now)
    for key in [*new, *(k for k in old if k not in new)]:
        if old.get(key) != new.get(key):
            what = "a finished" if finished else "an unfinished"
            fix = "" if finished else " to resume it"
            raise ConfigError(
                f"{command}: --out {out} holds {what} run made with {_shown(key, old.get(key), flags)}, not "
                f"{_shown(key, new.get(key), flags)}; rerun with {_shown(key, old.get(key), flags)}{fix}, or "
                "choose a new --out"
            )
    was = saved.get(INPUTS, {})
    for path, size in now.get(INPUTS, {}).items():
        if was.get(path) != size:
            raise ConfigError(f"{command}: {path} changed since --out {out} was made ({was.get(path)} then, {size} "
                              "now); choose a new --out")  # fmt: skip


def dataset_size(root: Path) -> str:
    """A LeRobotDataset's size as its info.json states it: a dataset changed since a run started is refused."""
    info = json.loads((Path(root) / "meta" / "info.json").read_text())
    return f"{info.get('total_episodes')} episodes, {info.get('total_frames')} frames"


def _shown(key: str, value, flags: Iterable[str]) -> str:
    if key not in set(flags):
        return f"{key}={value!r}"
    flag = "--" + key.replace("_", "-")
    if value is None or isinstance(value, bool):
        return flag if value else f"no {flag}"
    if isinstance(value, list):
        return f"{flag} {','.join(map(str, value))}" if value else f"no {flag}"
    return f"{flag} {value}"


# ---- a state directory replaced atomically ------------------------------------------------------------------
def save_state(root: Path, name: str, write: Callable[[Path], None]) -> Path:
    """Write a new state with ``write(dir)`` into a fresh directory, fsync it, point ``root``/last.json at it
    (atomic rename) and only then delete the older ones: a kill at any moment leaves a complete last state."""
    tmp = Path(tempfile.mkdtemp(prefix=f".{name}.", dir=root))
    write(tmp)
    _fsync_tree(tmp)
    final = root / name
    if final.exists():
        shutil.rmtree(final)
    tmp.rename(final)
    atomic_write_json(root / LAST_FILE, {"state": name})
    _drop_others(root, keep=name)
    return final


def last_state(root: Path) -> Path | None:
    """The newest complete state directory under ``root`` (None before the first save); leftovers of a save that
    a kill interrupted are deleted."""
    try:
        name = json.loads((root / LAST_FILE).read_text())["state"]
    except (OSError, ValueError, KeyError):
        name = None
    _drop_others(root, keep=name)
    return root / name if name else None


def _drop_others(root: Path, keep: str | None) -> None:
    for p in root.iterdir():
        if p.is_dir() and p.name != keep:
            shutil.rmtree(p, ignore_errors=True)


def _fsync_tree(path: Path) -> None:
    for p in sorted(path.rglob("*"), reverse=True) + [path]:
        fd = os.open(p, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
