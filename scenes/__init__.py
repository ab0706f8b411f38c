"""Scenes: frozen specs, inductive axes (successors), the registered scene families, the oracle and certification.

A scene family is one ``scenes.registry.Scene`` subclass registered with ``@register_scene`` (the built-ins in
``scenes.catalog``, the LIBERO suites in ``scenes.libero``); the functions here look it up by name.
Importing this package is cheap: robosuite and MuJoCo load only when ``make_env`` builds an env.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import TYPE_CHECKING

from indgen_vla.core.protocol.interface import CAMERAS
from indgen_vla.core.protocol.progression import AxisSpec
from scenes import catalog, libero, robocasa  # noqa: F401  (registers the built-ins, the LIBERO suites, RoboCasa365)
from scenes.axes import get_axis as _get_axis
from scenes.axes import get_successor
from scenes.registry import get_scene, registered_scenes

if TYPE_CHECKING:
    from scenes.env import BaseSceneEnv


class _DropMacroWarning(logging.Filter):
    """robosuite 1.4 warns about a missing private macro file on every import; it is irrelevant here."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "macro" not in record.getMessage()


# here, so that it is in place before any module of this package imports robosuite (the ones above never do):
# scenes.sim, scenes.objects (the layouts), LIBERO; certify, demos, mimicgen and the workers all stay quiet
logging.getLogger("robosuite_logs").addFilter(_DropMacroWarning())

__all__ = [
    "make_env", "scene_names", "tasks", "select_tasks", "axes_for", "get_axis", "level_param", "check_ready",
    "check_axis_progression",
]  # fmt: skip


def scene_names() -> list[str]:
    """Registered scene names: the built-in families, then the LIBERO suites."""
    return [s.name for s in registered_scenes()]


def check_ready(scene: str) -> None:
    """Fail fast, in one line, when a scene's external install or assets are missing (LIBERO's Hub download)."""
    get_scene(scene).check_ready()


def tasks(scene: str) -> list[str]:
    """Tasks of ``scene`` (the first is the default)."""
    return list(get_scene(scene).tasks)


def select_tasks(scene: str, task: str | None) -> list[str]:
    """The tasks a run covers: ``[default]`` for None/"", every task for "all", else ``[task]`` (checked)."""
    return get_scene(scene).select_tasks(task)


def axes_for(scene: str) -> list[str]:
    """Single axes ``scene`` supports (any '+'-composition of them works too)."""
    return list(get_scene(scene).axes)


def get_axis(name: str, step: float | None = None, preset: str | None = None) -> AxisSpec:
    """The ``AxisSpec`` of an axis or composition such as ``pick_y+distractor``; ``step`` overrides its step,
    ``preset`` (a configs/axes name or YAML path) sets steps and ranges, components' included."""
    return _get_axis(name, step, preset)


def successor_for(
    axis: str, step: float | None = None, preset: str | None = None, scene: str | None = None,
    task: str | None = None,
):  # fmt: skip
    """The successor of ``axis`` with the --step / --axes-preset overrides applied (over ``scene``'s own steps
    and ranges when a scene is named, for ``task`` where the family's steps differ by task)."""
    from scenes.axes import load_preset

    overrides = load_preset(preset) if preset else None
    if scene is not None:
        return get_scene(scene).successor(axis, step, overrides, task)
    return get_successor(axis, step, overrides)


def level_param(
    scene: str, task: str | None, axis: str, level: int, step: float | None = None, preset: str | None = None
) -> float:
    """The axis parameter at ``level`` exactly as the built env reports it (``env.axis_param``), without
    building the simulator: e.g. 1.2 for ``scale`` at level 3, or the pick object's y in metres."""
    from scenes.axes import axis_param, spec_at_level

    sc = get_scene(scene)
    task = sc.resolve_task(task)
    successor = successor_for(axis, step, preset, scene, task)
    spec = spec_at_level(sc.base(task), successor, level)
    return axis_param(spec, successor, level)


def check_axis_progression(
    scene: str, task: str | None, axis: str, step: float | None = None, preset: str | None = None
) -> None:
    """Condition 2 (strictly harder levels) before any episode runs: raises ProgressionError (a ConfigError).

    Built-in scenes are checked from their frozen specs (each component of a composition on its own);
    LIBERO suites against their fixed initial states, which needs level 0 built (physics only, ~10 s), so
    up front only when --step / --axes-preset changed a step; the env repeats the check when it is built.
    """
    sc = get_scene(scene)
    sc.check_axis(axis)
    task = sc.resolve_task(task)
    successor = successor_for(axis, step, preset, scene, task)
    sc.check_progression(task, successor, step is not None or preset is not None)


def make_env(
    scene: str,
    *,
    task: str | None = None,
    axis: str | None = None,
    level: int = 0,
    step: float | None = None,
    cameras: Sequence[str] = CAMERAS,
    image_size: tuple[int, int] = (128, 128),
    max_steps: int | None = None,
    preset: str | None = None,
) -> BaseSceneEnv:
    """Build one level of one task: the scene's T0 moved ``level`` atomic steps along ``axis`` (default: the
    scene's first axis)."""
    sc = get_scene(scene)
    task = sc.resolve_task(task)
    axis = axis or sc.default_axis
    sc.check_axis(axis)
    successor = successor_for(axis, step, preset, scene, task)
    return sc.make_env(task, successor, level, cameras=cameras, image_size=image_size, max_steps=max_steps)
