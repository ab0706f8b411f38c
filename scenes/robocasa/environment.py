"""Where RoboCasa365 lives: its own venv (pinned, made by ``indgen setup robocasa``) and its kitchen asset tree.

RoboCasa 1.0 needs robosuite 1.5, mujoco 3.3.1 and numpy 2.2.5; our venv has LIBERO's robosuite 1.4, so RoboCasa runs
in a second venv and ``scenes.external`` drives it over a pipe. Importing this is cheap (no subprocess, no RoboCasa).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

from indgen_vla.core.errors import ConfigError, SceneError
from scenes.robocasa.placeholder_tree import VERSION

PYTHON_ENV = "INDGEN_ROBOCASA_PYTHON"  # an interpreter of a ready RoboCasa venv
VENV_ENV = "INDGEN_ROBOCASA_VENV"  # where ``indgen setup robocasa`` makes it
ASSETS_ENV = "INDGEN_ROBOCASA_ASSETS"  # preferred; rlinf-robocasa365's ROBOCASA_ASSETS_PATH is accepted too
# Installed with --no-deps: rlinf-robocasa365 declares PyPI's robosuite (1.5.2 fails at reset, pins numpy<2).
NO_DEPS = ("rlinf-robocasa365==1.0.1", "praxis-robosuite==1.5.2.post1")
# Their run-time dependencies, pinned exactly (checked on PyPI 2026-11-24) so every set-up is the same.
PINNED = (
    "mujoco==3.3.1", "numpy==2.2.5", "scipy==1.15.3", "numba==0.61.2", "llvmlite==0.44.0", "pillow==13.0.0",
    "opencv-python==5.0.0.93", "termcolor==3.3.0", "tqdm==4.70.1", "gymnasium==1.4.0", "h5py==3.16.0",
    "imageio==2.38.1", "lxml==6.1.3", "PyYAML==6.0.4", "glfw==2.11.0", "PyOpenGL==3.1.10", "absl-py==2.5.1",
    "etils==1.15.0", "fsspec==2026.9.0", "typing_extensions==4.16.0", "zipp==4.1.2", "cloudpickle==3.1.3",
    "Farama-Notifications==0.0.6",
)  # fmt: skip
STAMP = ".indgen-robocasa-installed"  # written last: a venv without it is incomplete


def cache_dir() -> Path:
    return Path(os.environ.get("INDGEN_CACHE", "~/.cache/indgen")).expanduser()


def venv_dir() -> Path:
    return Path(os.environ.get(VENV_ENV) or cache_dir() / "robocasa-venv").expanduser()


def stamp_text() -> str:
    return "\n".join((*NO_DEPS, *PINNED)) + "\n"


def find_python(required: bool = True) -> Path | None:
    """The RoboCasa venv's interpreter: $INDGEN_ROBOCASA_PYTHON, else the set-up venv (complete only)."""
    explicit = os.environ.get(PYTHON_ENV)
    if explicit:
        p = Path(explicit).expanduser()
        if p.is_file():
            return p
        if required:
            raise SceneError(
                f"${PYTHON_ENV}={explicit} is not an interpreter; run 'indgen setup robocasa' and unset it"
            )
        return None
    v = venv_dir()
    if (v / STAMP).is_file() and (v / STAMP).read_text() == stamp_text():
        return v / "bin" / "python"
    if required:
        state = "is out of date" if (v / STAMP).is_file() else "is missing"
        raise SceneError(
            f"the RoboCasa venv {v} {state}; run 'indgen setup robocasa' (about a minute: robosuite 1.5, "
            f"mujoco 3.3.1 from PyPI) or set {PYTHON_ENV} to an interpreter with rlinf-robocasa365 installed"
        )
    return None


PROBE_312 = "import sys; assert sys.version_info[:2] == (3, 12); print(sys._base_executable)"


def python312_candidates() -> list[str]:
    """Where a Python 3.12 may be, in the Makefile's order (``scripts/find_python312.sh``)."""
    out = []
    if shutil.which("pyenv"):
        r = subprocess.run(["pyenv", "which", "python3.12"], capture_output=True, text=True)
        out.append(r.stdout.strip() if r.returncode == 0 else "")
    out.append(shutil.which("python3.12") or "")
    for root in (os.environ.get("PYENV_ROOT"), "~/.pyenv"):
        if root:
            found = Path(root).expanduser().glob("versions/3.12*/bin/python3.12")
            out += [str(p) for p in sorted(found, key=lambda p: [int(x) for x in re.findall(r"\d+", p.parts[-3])],
                                           reverse=True)]  # fmt: skip
    return [*out, "/usr/local/bin/python3.12", "/usr/bin/python3.12", sys.executable]


def find_python312() -> str:
    """A Python 3.12 interpreter that runs: each candidate is tried, so a pyenv shim whose global version is not
    3.12 is passed over, and the real executable (not a shim or a venv's link) is returned."""
    for cand in python312_candidates():
        if not cand or not Path(cand).is_file():
            continue
        r = subprocess.run([cand, "-c", PROBE_312], capture_output=True, text=True)
        if r.returncode == 0 and r.stdout.strip():
            return r.stdout.strip()
    raise ConfigError(
        "Python 3.12 not found; install it (e.g. 'pyenv install 3.12') and re-run 'indgen setup robocasa'"
    )


def setup_venv(target: Path | None = None, force: bool = False, log=print) -> Path:
    """Create the pinned RoboCasa venv at ``target`` (idempotent: a complete one is left alone)."""
    v = (target or venv_dir()).expanduser()
    if not force and (v / STAMP).is_file() and (v / STAMP).read_text() == stamp_text():
        log(f"RoboCasa venv ready: {v}")
        return v / "bin" / "python"
    t0 = time.perf_counter()
    if v.exists():
        shutil.rmtree(v)
    v.parent.mkdir(parents=True, exist_ok=True)
    py = find_python312()
    log(
        f"creating the RoboCasa venv {v} with {py} (robosuite 1.5, mujoco 3.3.1, numpy 2.2.5; about a minute)"
    )
    steps = (
        [py, "-m", "venv", str(v)],
        [str(v / "bin" / "python"), "-m", "pip", "install", "-q", "--no-deps", *NO_DEPS],
        [str(v / "bin" / "python"), "-m", "pip", "install", "-q", *PINNED],
    )
    for cmd in steps:
        r = _run_group(cmd)
        if r.returncode != 0:
            tail = (r.stderr or r.stdout).strip().splitlines()
            raise SceneError(
                f"RoboCasa venv set-up failed at '{' '.join(cmd[2:5])}': {tail[-1] if tail else r.returncode}; "
                "check that PyPI is reachable and re-run 'indgen setup robocasa'"
            )
    (v / STAMP).write_text(stamp_text())
    log(f"RoboCasa venv ready: {v} ({time.perf_counter() - t0:.0f} s)")
    return v / "bin" / "python"


def _run_group(cmd: list[str]) -> subprocess.CompletedProcess:
    """``cmd`` in a process group of its own, killed whole if this process stops first (Ctrl-C, SIGTERM): ``venv``
    runs ensurepip, which runs pip, and killing ``venv`` alone (``subprocess.run``) left them installing into the
    folder that the re-run removes and makes again."""
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )
    try:
        out, err = proc.communicate()
    except BaseException:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        raise
    return subprocess.CompletedProcess(cmd, proc.returncode, out, err)


# ---- assets -------------------------------------------------------------------------------------------------
PLACEHOLDER_MARKER = "INDGEN_PLACEHOLDER_TREE"  # written by placeholder_tree at the tree's root


def default_assets() -> Path:
    return cache_dir() / "robocasa-assets"


def venv_assets() -> Path:
    """Where RoboCasa's own download script writes (``robocasa/scripts/download_kitchen_assets.py``: under
    ``robocasa.__path__[0]/models/assets``), in the venv ``indgen setup robocasa`` makes (Python 3.12)."""
    return venv_dir() / "lib" / "python3.12" / "site-packages" / "robocasa" / "models" / "assets"


def has_objects(path: Path) -> bool:
    """At least one object model under ``objects/<registry>/<category>/<model>/`` (the wheel's bundled asset folder,
    3.5 MB of fixtures and layouts, has none: every task would fail at its first object)."""
    return next((path / "objects").glob("*/*/*/model.xml"), None) is not None


def is_asset_tree(path: Path) -> bool:
    return (
        (path / "fixtures" / "fixture_registry").is_dir()
        and (path / "scenes" / "kitchen_layouts").is_dir()
        and has_objects(path)
    )


def is_placeholder(path: Path) -> bool:
    return (path / PLACEHOLDER_MARKER).is_file()


def stale_placeholders(path: Path) -> str | None:
    """One line when ``path`` is a placeholder tree an older generator wrote (its geometry is not what the oracle
    and the docs' numbers assume, and its listing hash names other certificates); None otherwise."""
    if not is_placeholder(path):
        return None
    first = (path / PLACEHOLDER_MARKER).read_text().partition("\n")[0]
    if first == f"version {VERSION}":
        return None
    return (
        f"{path} holds RoboCasa placeholders of an older generator ({first or 'no version'}; current: version "
        f"{VERSION}); rewrite them with 'indgen setup robocasa --placeholders {path}'"
    )


def _usable(p: Path, required: bool) -> bool:
    """``p`` is an asset tree and not a stale placeholder tree (refused in one line when ``required``)."""
    if not is_asset_tree(p):
        return False
    stale = stale_placeholders(p)
    if stale and required:
        raise SceneError(stale)
    return stale is None


def find_assets(required: bool = True) -> Path | None:
    """The kitchen asset tree: $INDGEN_ROBOCASA_ASSETS, $ROBOCASA_ASSETS_PATH, then the default cache path (a
    placeholder tree of an older generator is refused)."""
    for var in (ASSETS_ENV, "ROBOCASA_ASSETS_PATH"):
        if os.environ.get(var):
            p = Path(os.environ[var]).expanduser()
            if _usable(p, required):
                return p.resolve()
            if required:
                raise SceneError(f"${var}={p} is not a RoboCasa asset tree ({_missing(p)}); {_hint()}")
            return None
    for p in (default_assets(), venv_assets()):  # the documented place, then where RoboCasa's download writes
        if _usable(p, required):
            return p.resolve()
    if required:
        raise SceneError(
            f"RoboCasa's kitchen assets are missing (looked in {default_assets()} and {venv_assets()}: "
            f"{_missing(venv_assets())}); {_hint()}"
        )
    return None


def _missing(p: Path) -> str:
    """What ``p`` lacks of an asset tree, in words."""
    if not (p / "fixtures" / "fixture_registry").is_dir():
        return "no fixtures/fixture_registry"
    if not (p / "scenes" / "kitchen_layouts").is_dir():
        return "no scenes/kitchen_layouts"
    return "no object models under objects/ (RoboCasa's bundled assets only: run the download)"


def _hint() -> str:
    return (
        f"for smoke runs write placeholders with 'indgen setup robocasa --placeholders {default_assets()}'; for "
        f"the real kitchens run 'indgen setup robocasa' and then RoboCasa's own download in that venv ('"
        f"{venv_dir() / 'bin' / 'python'} -m robocasa.scripts.download_kitchen_assets'; it writes into "
        f"{venv_assets()}, where indgen finds them), or set {ASSETS_ENV}=DIR for a tree elsewhere"
    )
