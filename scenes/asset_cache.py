"""MuJoCo's asset cache, filled once in the workers' fork server (a ``preload`` module of the robosuite families).

MuJoCo (≥ 3.2) keeps the meshes and textures it decodes while compiling a model in a process-wide cache, so a
process's second scene build compiles in a fraction of its first (here 0.13-0.2 CPU-s against ≈ 1.1). Every
worker used to pay that first, cold compile. When the engine starts the fork server it names the first cell its
workers will build (``indgen_vla.core.protocol.plan.WARM_CELL_ENV``: scene and task, JSON); importing this module in the fork server builds and resets
that task's level 0 without cameras, so every worker forked from it inherits the decoded assets (copy on write;
pick_place: ≈ 90 MB). Without the variable, e.g. anywhere but the fork server, importing it does nothing.
"""

from __future__ import annotations

import json
import os
import warnings

from indgen_vla.core.protocol.plan import WARM_CELL_ENV
from scenes.family import Scene, registered_scenes
from scenes.planning import scene_levels


def warm(scene: Scene, task: str) -> None:
    """Build and reset ``task``'s level 0 of ``scene`` (along its first axis: level 0 is T0 on every axis), no
    cameras (no GL context in the fork server), and close it: what is left is MuJoCo's asset cache."""
    axis = scene.default_axis
    env = scene_levels(scene, [axis]).make_env(task, axis, 0, cameras=(), image_size=(64, 64), max_steps=1)
    try:
        env.reset(seed=0)
    finally:
        env.close()


if cell := os.environ.get(WARM_CELL_ENV):
    try:  # an optimisation: a failure here must not stop the fork server (each worker then compiles cold)
        named = json.loads(cell)
        # the families this fork server knows; one a user's script registers is not among them: nothing to warm
        known = {s.name: s for s in registered_scenes()}
        if named["scene"] in known:
            warm(known[named["scene"]], named["task"])
    except Exception as e:
        warnings.warn(
            f"MuJoCo's asset cache not filled in the fork server ({type(e).__name__}: {e})", stacklevel=1
        )
