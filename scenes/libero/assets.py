"""Where LIBERO's files live: its BDDL/init-state files (in the hf-libero wheel) and its assets (a Hub download).

Nothing here imports ``libero``: ``import_libero`` first writes the ``config.yaml`` LIBERO would otherwise ask
for on stdin, then imports it and points its asset lookup at the resolved asset tree.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
from pathlib import Path

from indgen_vla.core.errors import SceneError

ASSETS_ENV = "INDGEN_LIBERO_ASSETS"  # preferred; LIBERO_ASSETS is accepted too
HUB_REPO = "lerobot/libero-assets"  # what hf-libero's own downloader fetches (repo_type=dataset)
HUB_CACHE = Path("~/.cache/libero/assets")  # where hf-libero's downloader puts them
REQUIRED = ("scenes", "stable_hope_objects", "stable_scanned_objects")
# LIBERO-Object's grocery items (assets/stable_hope_objects/<name>/); the pool distractors are drawn from, in order
HOPE_OBJECTS = (
    "alphabet_soup", "bbq_sauce", "butter", "chocolate_pudding", "cream_cheese", "ketchup", "milk", "orange_juice",
    "salad_dressing", "tomato_sauce",
)  # fmt: skip


# a file at the top of a tree whose files are not all LIBERO's (the miniature tree, an overlay that filled gaps):
# an image policy's success there is not a measurement (``LiberoEnvironment.placeholder_assets``)
PLACEHOLDER_MARK = "INDGEN_PLACEHOLDER_ASSETS.txt"


def mark_placeholder(root: Path, why: str) -> None:
    """Say in ``root`` that its pictures are not LIBERO's (``why``: what made them)."""
    (Path(root) / PLACEHOLDER_MARK).write_text(
        f"{why}\nindgen refuses an image policy on this tree unless --smoke (the manifest then says 'not a measurement').\n"
    )


def is_placeholder_tree(root: Path) -> bool:
    """Whether ``root`` carries ``PLACEHOLDER_MARK``."""
    return (Path(root) / PLACEHOLDER_MARK).is_file()


def libero_root() -> Path:
    """The installed ``libero/libero`` package directory (BDDL files, init files), found without importing it."""
    spec = importlib.util.find_spec("libero")
    if spec is None or not spec.submodule_search_locations:
        raise SceneError("LIBERO is not installed; install it with: pip install 'lerobot[libero]==0.6.1'")
    root = Path(next(iter(spec.submodule_search_locations))) / "libero"
    if not (root / "bddl_files").is_dir():
        raise SceneError(f"the installed LIBERO package at {root} has no bddl_files/; reinstall hf-libero")
    return root


def is_asset_tree(path: Path) -> bool:
    """Does ``path`` look like LIBERO's ``assets/`` folder (scenes/ and the object folders)?"""
    return all((path / sub).is_dir() for sub in REQUIRED)


def candidate_dirs() -> list[Path]:
    """Asset folders tried in order: $INDGEN_LIBERO_ASSETS, $LIBERO_ASSETS, the package's assets/, hf-libero's cache."""
    out = [Path(os.environ[v]).expanduser() for v in (ASSETS_ENV, "LIBERO_ASSETS") if os.environ.get(v)]
    try:
        out.append(libero_root() / "assets")
    except SceneError:
        pass
    out.append(HUB_CACHE.expanduser())
    return out


def missing_assets_message() -> str:
    """The one line ``evaluate`` prints when no asset tree is found."""
    return (
        f"LIBERO's assets are missing (looked in {', '.join(str(p) for p in candidate_dirs())}); run 'indgen "
        "setup libero' (or 'make libero': LIBERO's complete tree from the package registry, ~355 MB, about a "
        f"minute), or set {ASSETS_ENV}=DIR to a folder holding scenes/, stable_hope_objects/, "
        f"stable_scanned_objects/ and textures/ (e.g. 'hf download {HUB_REPO} --repo-type dataset' elsewhere)"
    )


def find_assets(required: bool = True) -> Path | None:
    """The first candidate folder that holds LIBERO's asset tree; ``SceneError`` (one line) when none does."""
    explicit = [Path(os.environ[v]).expanduser() for v in (ASSETS_ENV, "LIBERO_ASSETS") if os.environ.get(v)]
    for p in explicit:
        if not is_asset_tree(p):
            if required:
                raise SceneError(
                    f"{p} (from ${ASSETS_ENV}/$LIBERO_ASSETS) is not a LIBERO asset folder: it needs "
                    f"{', '.join(s + '/' for s in REQUIRED)}; {missing_assets_message()}"
                )
            return None
    for p in candidate_dirs():
        if is_asset_tree(p):
            return p.resolve()
    if required:
        raise SceneError(missing_assets_message())
    return None


@functools.cache
def tree_identity(root: Path) -> str:
    """SHA-256 over every file's relative path and size under ``root``: tells two asset trees apart (the real
    download, a miniature or placeholder tree, an overlay) without reading gigabytes of meshes."""
    h = hashlib.sha256()
    for dirpath, dirnames, filenames in os.walk(root, followlinks=True):
        dirnames.sort()
        for name in sorted(filenames):
            p = Path(dirpath, name)
            h.update(f"{p.relative_to(root)}\0{p.stat().st_size}\n".encode())
    return h.hexdigest()


def config_dir() -> Path:
    """Where indgen writes LIBERO's config.yaml: $INDGEN_CACHE/libero, else ~/.cache/indgen/libero."""
    base = Path(os.environ.get("INDGEN_CACHE", "~/.cache/indgen")).expanduser()
    return base / "libero"


def ensure_config(assets: Path) -> Path:
    """Point $LIBERO_CONFIG_PATH at a config.yaml naming the wheel's BDDL/init files and ``assets`` (no prompt).

    A user's own $LIBERO_CONFIG_PATH with a config.yaml is left alone.
    """
    import yaml

    user = os.environ.get("LIBERO_CONFIG_PATH")
    if user and (Path(user) / "config.yaml").is_file():
        return Path(user) / "config.yaml"
    root = libero_root()
    cfg = {
        "benchmark_root": str(root),
        "bddl_files": str(root / "bddl_files"),
        "init_states": str(root / "init_files"),
        "datasets": str(root.parent / "datasets"),
        "assets": str(assets),
    }
    d = config_dir()
    path = d / "config.yaml"
    try:
        d.mkdir(parents=True, exist_ok=True)
        if not path.is_file() or yaml.safe_load(path.read_text()) != cfg:
            tmp = path.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(yaml.safe_dump(cfg))
            tmp.replace(path)
    except OSError as e:
        raise SceneError(
            f"cannot write LIBERO's config at {path}: {e.strerror}; set INDGEN_CACHE to a writable folder"
        ) from None
    os.environ["LIBERO_CONFIG_PATH"] = str(d)
    return path


def import_libero(assets: Path | None = None):
    """Import ``libero.libero`` without its stdin prompt and make its asset lookup return ``assets``."""
    assets = assets or find_assets()
    os.environ.setdefault("MUJOCO_GL", "egl")
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    ensure_config(assets)
    import libero.libero as ll

    # lazy: optional robosuite (LIBERO's import needs it; scenes.sim imports it with its macro warning silenced)
    import scenes.sim  # noqa: F401

    ll._assets_path_cache = str(assets)  # get_assets_path() returns this while it exists
    return ll
