"""Files shipped with the package (presets, committed certificates), found the same way from a checkout or a wheel."""

from __future__ import annotations

import importlib.util
from importlib.resources import files
from pathlib import Path

CONFIG_KINDS = ("paper", "axes", "real")  # evaluate --config; --axes-preset step/range; indgen real --setup


def config_dir(kind: str) -> Path:
    """The shipped preset folder ``configs/<kind>``: top-level ``configs/`` beside the package in a checkout
    (editable install included), ``indgen_vla/configs/`` in an installed wheel (pyproject maps it there)."""
    if kind not in CONFIG_KINDS:
        raise ValueError(f"unknown config kind {kind!r}; expected one of {', '.join(CONFIG_KINDS)}")
    package = Path(str(files("indgen_vla")))
    wheel, checkout = package / "configs" / kind, package.parent / "configs" / kind
    return checkout if not wheel.is_dir() and checkout.is_dir() else wheel


def certification_dir() -> Path:
    """The committed certificates of the built-in scenes (``scenes/certification``, package data of ``scenes``);
    every lookup of them goes through this function. Found without importing ``scenes`` (core must not)."""
    spec = importlib.util.find_spec("scenes")
    if spec is None or not spec.submodule_search_locations:
        raise ModuleNotFoundError("the scenes package is not installed; reinstall indgen-vla")
    return Path(next(iter(spec.submodule_search_locations))) / "certification"
