"""An oracle's baseline: its successes on fixed ``evaluate`` episodes per (task, axis, level), kept in a data file
that a slow test runs again, so an oracle (or asset) change that lowers a task's count shows in the file's diff.

Episode i of a level starts from ``evaluation_seed(seed, scene, task, i)``, the state ``indgen evaluate --seed
seed`` gives it at every level, so a baseline row is reproduced by ``indgen evaluate --policy standin:oracle``
with the same split, levels and ``--episodes``.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from indgen_vla.app.certify.certify_levels import run_oracle_episode
from indgen_vla.core.errors import EpisodeUnavailableError
from indgen_vla.core.protocol.seeding import evaluation_seed
from scenes.family import Scene
from scenes.oracles import oracle_for
from scenes.planning import resolve_scene_plan


def baseline_episodes(
    scene: Scene, task: str, axis: str, level: int, episodes: int, seed: int = 0,
    options: Mapping[str, Any] | None = None,
) -> list[tuple[bool | None, int]]:  # fmt: skip
    """The oracle's (success, steps) on ``evaluate``'s episodes 0..episodes-1 of one level (None: the level's
    placement check ruled the episode's initial state out, as ``evaluate`` counts it unavailable)."""
    plan = resolve_scene_plan(scene, task, (axis,), [level], certificates=False, options=options)
    env = plan.builder.make_env(task, axis, level, cameras=(), image_size=(128, 128), max_steps=None)
    policy = oracle_for(plan.builder.family)
    out: list[tuple[bool | None, int]] = []
    try:
        for i in range(episodes):
            try:
                out.append(run_oracle_episode(env, policy, evaluation_seed(seed, scene.name, task, i), i))
            except EpisodeUnavailableError:
                out.append((None, 0))
    finally:
        env.close()
    return out


def level_entry(results: list[tuple[bool | None, int]]) -> dict:
    """A level's row of the data file: episodes run, successes, unavailable ones, each episode's steps."""
    return {
        "episodes": len(results),
        "successes": sum(ok is True for ok, _ in results),
        "unavailable": sum(ok is None for ok, _ in results),
        "steps": [steps for _, steps in results],
    }


def load_baseline(path: Path) -> dict:
    """The data file (``scene``, ``split``, ``oracle``, ``tree_version``, ``seed``, ``tasks``: task -> ``axis``
    and ``levels``: level -> ``level_entry``)."""
    return json.loads(Path(path).read_text())


def shortfall(task: str, axis: str, level: int, recorded: Mapping, results: list) -> str:
    """One line naming a level whose successes fell below the recorded ones, or "" where they did not."""
    got = level_entry(results)
    if got["successes"] >= recorded["successes"]:
        return ""
    return (
        f"{task} {axis} level {level}: {got['successes']}/{got['episodes']} oracle successes, the baseline records "
        f"{recorded['successes']}/{recorded['episodes']} (episode steps {got['steps']}, recorded "
        f"{recorded['steps']}); an oracle change that lowers a baseline says so in its commit and re-records it"
    )
