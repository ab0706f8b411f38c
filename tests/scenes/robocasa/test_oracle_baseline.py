"""The RoboCasa oracle's per-task baseline (``oracle_baseline.json``, written by scripts/robocasa_oracle_baseline.py):
every scripted task has one, made by the current oracle version on the current placeholder tree (default suite),
and the oracle still reaches each level's recorded successes on those episodes (slow: ~40 episodes)."""

from __future__ import annotations

from pathlib import Path

import pytest

from scenes.family import get_scene
from tests.scenes.robocasa.test_robocasa import needs_venv

BASELINE = Path(__file__).with_name("oracle_baseline.json")


def _baseline() -> dict:
    from indgen_vla.app.certify.baseline import load_baseline

    return load_baseline(BASELINE)


def test_every_scripted_task_has_a_baseline_of_the_current_oracle_and_tree():
    """An oracle change bumps its version (and a tree change the tree's): the file must then be measured again, so
    a lowered count shows in the commit's diff of it."""
    from scenes.oracles import oracle_identity
    from scenes.robocasa import AXIS_TASKS
    from scenes.robocasa.oracle import RoboCasaOracle
    from scenes.robocasa.placeholder_tree import VERSION
    from scenes.robocasa.splits import DEFAULT_SPLIT

    b = _baseline()
    now = oracle_identity(
        get_scene("robocasa")
    )  # its code hash moves with any edit (comments too): the version decides
    assert b["oracle"] == {"name": now["name"], "version": now["version"]}, (
        "re-measure: scripts/robocasa_oracle_baseline.py"
    )
    assert b["tree_version"] == VERSION, "re-measure on the current placeholder tree"
    assert (b["scene"], b["split"], b["seed"]) == ("robocasa", DEFAULT_SPLIT, 0)
    assert set(b["tasks"]) == set(RoboCasaOracle.tasks)
    for task, row in b["tasks"].items():
        axis = "horizon" if row["axis"] == "base_y" else row["axis"]
        assert task in AXIS_TASKS[axis], (task, row["axis"])
        for level in row["levels"].values():
            assert 0 <= level["successes"] <= level["episodes"] - level["unavailable"]
            assert len(level["steps"]) == level["episodes"]


def test_a_level_below_its_recorded_successes_is_named_in_one_line():
    from indgen_vla.app.certify.baseline import level_entry, shortfall

    recorded = level_entry([(True, 281), (True, 282)])
    assert recorded == {"episodes": 2, "successes": 2, "unavailable": 0, "steps": [281, 282]}
    assert shortfall("T", "base_y", 0, recorded, [(True, 290), (True, 300)]) == ""
    line = shortfall("T", "base_y", 0, recorded, [(True, 290), (False, 750)])
    assert "T base_y level 0: 1/2 oracle successes, the baseline records 2/2" in line and "\n" not in line
    assert level_entry([(None, 0), (True, 10)])["unavailable"] == 1  # ruled out by the placement check


def _rows():
    return [(task, row["axis"]) for task, row in sorted(_baseline()["tasks"].items())]


@needs_venv
@pytest.mark.slow  # 1-6 oracle episodes a task, ~20-90 s each on a 2-core machine
@pytest.mark.parametrize(("task", "axis"), _rows())
def test_the_oracle_keeps_its_baseline(placeholders, task, axis):
    from indgen_vla.app.certify.baseline import baseline_episodes, shortfall

    b = _baseline()
    lines = []
    for level, recorded in b["tasks"][task]["levels"].items():
        results = baseline_episodes(
            get_scene("robocasa"),
            task,
            axis,
            int(level),
            recorded["episodes"],
            b["seed"],
            {"split": b["split"]},
        )
        lines.append(shortfall(task, axis, int(level), recorded, results))
    assert not any(lines), "\n".join(line for line in lines if line)
