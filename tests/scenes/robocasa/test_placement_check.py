"""A fixture_x or base_y move that lands in an obstacle is an infeasible cell for that episode, never a silent policy
failure (issue 41): the worker's placement check (``scenes/robocasa/placement_check.py``) after RoboCasa's settle."""

from __future__ import annotations

import re

import pytest

from indgen_vla.core.errors import EpisodeUnavailableError
from tests.scenes.robocasa.test_robocasa import needs_venv


def _worker_resets(task: str, levels: list[tuple[dict, int]]) -> list:
    """One RoboCasa worker built for ``task`` with each level's ``edits`` (what ``level_config`` sends) and reset
    from its seed: the reset's reply, or the ``EpisodeUnavailableError`` it raised."""
    from scenes.family import get_scene
    from scenes.runtime import WorkerProcess

    worker, out = WorkerProcess(get_scene("robocasa").runtime), []
    try:
        for edits, seed in levels:
            worker.request("build", {"task": task, "cameras": [], "image_size": (64, 64), "edits": edits})
            try:
                out.append(worker.request("reset", seed))
            except EpisodeUnavailableError as e:
                out.append(e)
        return out
    finally:  # killed, not asked to close: a loaded machine's slow exit is no part of this test
        worker.proc.kill()
        worker.proc.wait()
        worker.close()


@needs_venv  # ~8 s of CPU: one worker, two builds and resets
@pytest.mark.slow  # ~9 s: two RoboCasa builds; the check's unit tests stay in the default suite
def test_a_base_moved_into_the_counter_is_infeasible_and_back_from_it_is_not(placeholders):
    """0.6 m toward the counter (a base_y move the other way) puts the base's feet into the cabinets below it;
    0.375 m back (base_y level 3) is clear in the same kitchen."""
    into, back = _worker_resets(
        "PickPlaceCounterToCabinet", [({"base_back": -0.6}, 0), ({"base_back": 0.375}, 0)]
    )
    assert isinstance(into, EpisodeUnavailableError)
    assert re.search(r"base_y moved the robot base .* cm into .*placement check", str(into))
    assert isinstance(back, dict) and back["state"] is not None


@needs_venv
@pytest.mark.slow  # ~15 s of CPU: three TurnOnBlender builds; the base_y test above covers the worker's reply
def test_an_appliance_slid_into_a_wall_or_off_its_counter_is_infeasible(placeholders):
    """TurnOnBlender slid 0.5 m the other way: seed 1's blender ends in the wall beside its counter, seed 2's off
    its island; 0.375 m (fixture_x level 3) leaves seed 1's on its counter and clear."""
    wall, island, level3 = _worker_resets(
        "TurnOnBlender", [({"fixture_x": -0.5}, 1), ({"fixture_x": -0.5}, 2), ({"fixture_x": 0.375}, 1)]
    )
    assert isinstance(wall, EpisodeUnavailableError) and isinstance(island, EpisodeUnavailableError)
    assert re.search(r"fixture_x moved blender.* cm into wall.*placement check", str(wall))
    assert "off its support: 4 of its footprint's corners" in str(island)
    assert isinstance(level3, dict) and level3["state"] is not None
