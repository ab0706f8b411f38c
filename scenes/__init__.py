"""Scenes: frozen specs, inductive axes (successors), the registered scene families, the oracle and certification.

A scene family is one ``scenes.family.Scene`` subclass registered with ``@register_scene`` (the built-ins in
``scenes.tabletop``, the LIBERO suites in ``scenes.libero``); ``get_scene`` looks one up by name at the edges. Environments are
built through a level builder (``scenes.planning``: ``resolve_scene_plan(...).builder`` or ``scene_levels``), the one
road ``evaluate``, ``certify``, ``demos`` and ``mimicgen`` take. Importing this package is cheap: robosuite and MuJoCo
load only when a builder builds an env.
"""

from __future__ import annotations

import logging

from scenes import tabletop  # noqa: F401  (registers the built-ins first: they lead the listings)

# isort: split
from scenes import libero, robocasa  # noqa: F401  (then the LIBERO suites, RoboCasa365)
from scenes.family import get_scene, registered_scenes


class _DropMacroWarning(logging.Filter):
    """robosuite 1.4 warns about a missing private macro file on every import; it is irrelevant here."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "macro" not in record.getMessage()


# here, so that it is in place before any module of this package imports robosuite (the ones above never do):
# scenes.sim, scenes.tabletop.mjcf (the layouts), LIBERO; certify, demos, mimicgen and the workers all stay quiet
logging.getLogger("robosuite_logs").addFilter(_DropMacroWarning())

__all__ = ["get_scene", "scene_names"]


def scene_names() -> list[str]:
    """Registered scene names: the built-in families, then the LIBERO suites."""
    return [s.name for s in registered_scenes()]
