"""RoboCasa365's protocol around the runs: the paper presets, what the manifest records of the worker's release."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.axis_ref import AxisRef
from scenes.family import get_scene
from tests.fixtures.levels import level_env
from tests.scenes.robocasa.test_robocasa import needs_venv

PRESETS = {"robocasa_pick": "pick_x", "robocasa_fixture": "fixture_x", "robocasa_horizon": "base_y",
           "robocasa_clutter": "clutter"}  # fmt: skip


def _axes(*names: str) -> list[AxisRef]:
    """The parsed axes of ``names`` (the family's methods take them parsed)."""
    return [AxisRef.parse(n) for n in names]


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_each_paper_preset_runs_its_axis_on_appendix_bs_task_list(name):
    """--task all on the preset's one axis is that axis's list in AXIS_TASKS (appendix B), and its levels are the
    family's whole range of the axis (pick_x: 0..4, region / 5)."""
    from indgen_vla.app.engine.config import load_config_preset
    from indgen_vla.core.protocol.progression import parse_levels
    from scenes.axes import resolve_alias
    from scenes.family import get_scene
    from scenes.robocasa import AXIS_TASKS

    d = load_config_preset(name)
    sc = get_scene("robocasa")
    assert d["scene"] == "robocasa" and d["axes"] == [PRESETS[name]] and d["task"] == "all"
    assert sc.select_tasks(d["task"], _axes(*d["axes"])) == list(AXIS_TASKS[resolve_alias(PRESETS[name])])
    axis = sc.successor(AxisRef.parse(PRESETS[name])).axis
    assert list(parse_levels(d["levels"], axis)) == list(range(axis.max_level + 1))
    assert d["episodes"] == 50


def test_task_all_is_the_axis_list_and_a_task_off_the_list_is_refused():
    from scenes.family import get_scene
    from scenes.robocasa import AXIS_TASKS

    sc = get_scene("robocasa")
    assert sc.select_tasks("all", _axes("fixture_x")) == list(AXIS_TASKS["fixture_x"])
    assert sc.select_tasks(None, _axes("base_y")) == ["PickPlaceFridgeDrawerToShelf"]
    # pick_x and horizon share four tasks, in pick_x's order
    assert sc.select_tasks("all", _axes("pick_x", "horizon")) == [
        "PickPlaceCounterToBlender", "PickPlaceCounterToCabinet", "PickPlaceCounterToDrawer", "PickPlaceCounterToSink"
    ]  # fmt: skip
    with pytest.raises(ConfigError, match="share no task"):
        sc.select_tasks("all", _axes("fixture_x", "clutter"))
    with pytest.raises(ConfigError, match="not on axis horizon's task list"):
        sc.select_tasks("CloseStandMixerHead", _axes("base_y"))
    assert sc.select_tasks("all") == list(sc.tasks)  # no axis given: every task of the family


@needs_venv
def test_the_horizon_preset_resolves_to_appendix_bs_six_tasks(placeholders):
    from indgen_vla.app.engine.config import load_config_preset
    from scenes.planning import resolve_scene_plan
    from scenes.robocasa import AXIS_TASKS

    d = load_config_preset("robocasa_horizon")
    plan = resolve_scene_plan(get_scene(d["scene"]), d["task"], d["axes"], d["levels"])
    assert plan.tasks == AXIS_TASKS["horizon"] and len(plan.cells) == 6 * 4


def test_the_release_is_named_from_the_distribution_that_ships_robocasa():
    """rlinf-robocasa365 1.0.1 is upstream v1.0.1; praxis-robocasa 1.0.0 is v1.0.0 (horizons 1/1.5 as long)."""
    from scenes.robocasa import worker_facts as b

    dists = {"robocasa": ["praxis-robocasa"], "robosuite": ["praxis-robosuite"]}
    dist = b.distribution_of("robocasa", dists, version=lambda d: "1.0.0")
    assert dist == "praxis-robocasa 1.0.0" and "v1.0.0" in b.robocasa_release(dist)
    assert "v1.0.1" in b.robocasa_release("rlinf-robocasa365 1.0.1")
    assert b.robocasa_release("praxis-robocasa 1.0.0, rlinf-robocasa365 1.0.1").startswith("ambiguous")
    assert b.robocasa_release(b.distribution_of("robocasa", {})).startswith("unknown")


@needs_venv
@pytest.mark.slow  # ~3 s (a worker imports RoboCasa): test_the_release_is_named_from_the_distribution_that_ships_robocasa
def test_the_manifest_records_the_workers_versions_and_release(placeholders):
    """What ``SceneLevels.describe`` (the manifest's resolved environment) records, against the venv's own
    dist-info folders (read here, not through the worker)."""
    from scenes.planning import scene_levels
    from scenes.robocasa.environment import find_python
    from scenes.robocasa.worker_facts import RELEASES

    described = scene_levels(get_scene("robocasa"), ["base_y"]).describe()
    env, protocol = described["environment"], described["protocol"]
    assert protocol["regime"] == "black-box" and protocol["assets"]["placeholders"] is True
    assert (
        protocol["assets"]["root"] == str(placeholders.resolve())
        and len(protocol["assets"]["listing_sha256"]) == 64
    )
    site = next(Path(find_python()).parent.parent.glob("lib/python3*/site-packages"))
    installed = dict(
        p.name.removesuffix(".dist-info").lower().rsplit("-", 1) for p in site.glob("*.dist-info")
    )
    name = next(n for n in ("rlinf_robocasa365", "praxis_robocasa", "robocasa") if n in installed)
    assert env["robocasa_dist"] == f"{name.replace('_', '-')} {installed[name]}"
    assert env["robocasa_release"] == RELEASES[name.replace("_", "-")]
    assert env["mujoco"] == installed["mujoco"] and env["numpy"] == installed["numpy"]
    assert env["robosuite_dist"].split(" ")[1] == next(v for k, v in installed.items() if "robosuite" in k)


def _oracle_until(env, seed: int, stop, limit: int) -> int:
    """Step the RoboCasa oracle from ``seed`` until ``stop(env)`` holds after a step (or ``limit`` steps): an
    episode cut short there, the way max_steps cuts one. Returns the steps taken."""
    from scenes.oracles import oracle_for
    from scenes.privileged import with_privileged

    policy = oracle_for(get_scene("robocasa"))
    obs, _ = env.reset(seed=seed)
    policy.reset(env.instruction, seed)
    for _ in range(limit):
        obs, _, terminated, _, _ = env.step(policy.act([with_privileged(obs, env)])[0, 0])
        if terminated or stop(env):
            break
    return env.steps


@needs_venv
@pytest.mark.slow  # ~5 s of oracle steps; test_a_worker_that_dies_mid_episode_... covers the pipe
def test_the_oracle_touching_the_object_then_cut_short_is_no_grasp(placeholders):
    """The worker's facts come from MuJoCo's contacts: the first step whose gripper touches the object (as the
    worker's privileged ``obj_touching`` also says) makes the episode ``no_grasp`` at progress 1, not ``no_contact``.
    The grasp and lift stages: test_the_oracle_lifting_the_object_then_cut_short_is_timeout_holding."""

    env = level_env("robocasa", task="PickPlaceCounterToCabinet", axis="base_y", level=0, cameras=(),
                    max_steps=400)  # fmt: skip
    try:
        assert env.has_progress is False  # nothing known before the first reset
        steps = _oracle_until(env, 3, lambda e: e._facts()["touching"], limit=120)
        assert env.has_progress and steps < 120 and env.privileged_state().pick.touching_gripper
        assert env.failure_mode(False) == "no_grasp" and env.progress(False) == 1
        assert env._facts()["gripper_closed"] is False  # the oracle touches before it closes
    finally:
        env.close()


@needs_venv
@pytest.mark.slow  # ~6 s: ~100 oracle steps; test_a_worker_that_dies_mid_episode_... covers the facts
def test_the_oracle_lifting_the_object_then_cut_short_is_timeout_holding(placeholders):
    env = level_env("robocasa", task="PickPlaceCounterToCabinet", axis="base_y", level=0, cameras=(),
                    max_steps=400)  # fmt: skip
    try:
        start = []

        def lifted(e):
            start.append(e._facts()["bottom"]) if not start else None
            return e._trace.lifted

        _oracle_until(env, 3, lifted, limit=200)
        s = env.privileged_state()
        assert s.pick.touching_gripper and s.pick.bottom > start[0] + 0.02  # really up, really in the fingers
        assert (
            env._trace.grasped and env.failure_mode(False) == "timeout_holding" and env.progress(False) == 3
        )
    finally:
        env.close()


@needs_venv
@pytest.mark.slow  # ~5 s (a build and reset): test_a_worker_that_dies_mid_episode_... checks the facts by default
def test_a_pick_task_sends_its_contact_facts_over_the_pipe(placeholders):
    """One still step of PickPlaceCounterToCabinet: the worker's facts are there (the gripper is away from the
    object, which rests where T0 put it: the privileged state's bottom), so the episode is honestly
    ``no_contact`` at progress 0; the gripper command is read at RoboCasa's index 6, not the last entry."""
    import numpy as np

    env = level_env("robocasa", task="PickPlaceCounterToCabinet", axis="base_y", level=0, cameras=(),
                    max_steps=5)  # fmt: skip
    try:
        env.reset(seed=3)
        action = np.zeros(12)
        action[6], action[11] = 1.0, -1.0  # close the gripper, arm mode (the last entry < 0)
        env.step(action)
        f = env._facts()
        assert env.has_progress and f["touching"] is False and f["placed"] is False and f["gripper_closed"]
        assert f["bottom"] == pytest.approx(env.privileged_state().pick.bottom, abs=1e-9)
        assert env.failure_mode(False) == "no_contact" and env.progress(False) == 0
    finally:
        env.close()


@needs_venv
@pytest.mark.slow  # ~5 s (a second task's build); test_the_oracle_closes_the_stand_mixer_head checks the same
def test_a_fixture_task_has_no_contact_facts_so_its_failure_is_unknown(placeholders):
    """CloseStandMixerHead has no pick object: the worker sends no facts; the failure reads ``unknown`` and the
    progress is missing (None), never a made-up ``no_contact`` / 0."""
    import numpy as np

    env = level_env("robocasa", task="CloseStandMixerHead", axis="fixture_x", level=0, cameras=(),
                    max_steps=2)  # fmt: skip
    try:
        env.reset(seed=1)
        action = np.zeros(12)
        action[11] = -1.0  # arm mode, no motion
        for _ in range(2):
            *_, truncated, _ = env.step(action)
        assert truncated and env.failure_mode(False) == "unknown" and env.progress(False) is None
        assert env.failure_mode(True) == "none"
    finally:
        env.close()


def test_canonical_kitchens_expand_and_reach_the_worker_config():
    """``Task@5x5`` is the task in each of RoboCasa's 25 canonical kitchens (minus those its class excludes);
    ``Task@L-S`` pins one, passed to the worker as RoboCasa's own layout_ids / style_ids; anything else is one line."""
    from scenes.axes import get_successor
    from scenes.family import get_scene
    from scenes.robocasa import AXIS_TASKS, KITCHEN_SETS

    sc = get_scene("robocasa")
    tasks = sc.select_tasks("PickPlaceCounterToCabinet@5x5", _axes("base_y"))
    assert tasks == [f"PickPlaceCounterToCabinet@{lay}-{sty}" for lay, sty in KITCHEN_SETS["5x5"]]
    horizon = sc.select_tasks("all@5x1", _axes("base_y"))
    assert (
        len(horizon) == 5 * len(AXIS_TASKS["horizon"]) - 1
    )  # PickPlaceFridgeDrawerToShelf excludes layout 18
    assert (
        "PickPlaceFridgeDrawerToShelf@18-34" not in horizon
        and "PickPlaceFridgeDrawerToShelf@11-34" in horizon
    )
    cfg = sc.level_config(
        "PickPlaceCounterToCabinet@40-46", get_successor(AxisRef.parse("horizon")), 1, (), (64, 64)
    )
    assert (cfg["task"], cfg["layout_ids"], cfg["style_ids"]) == ("PickPlaceCounterToCabinet", [40], [46])
    assert (
        sc.level_config(
            "PickPlaceCounterToCabinet", get_successor(AxisRef.parse("horizon")), 1, (), (64, 64)
        )["layout_ids"]
        is None
    )
    for bad, match in (("PickPlaceCounterToCabinet@7-3", "not one of RoboCasa's canonical kitchens"),
                       ("PickPlaceFridgeDrawerToShelf@18-14", "excludes layout 18"),
                       ("CloseStandMixerHead@11-34", "not on axis horizon's task list")):  # fmt: skip
        with pytest.raises(ConfigError, match=match):
            sc.select_tasks(bad, _axes("base_y"))


@needs_venv
@pytest.mark.slow  # ~5 s (imports RoboCasa); test_canonical_kitchens_expand_and_reach_the_worker_config uses them
def test_kitchen_sets_and_exclusions_are_robocasas_own():
    """KITCHEN_SETS against robocasa/utils/env_utils.py (KITCHEN_SCENES_5X5, KITCHEN_SCENES_5X1) and
    EXCLUDED_KITCHENS against each appendix-B task class's EXCLUDE_LAYOUTS / EXCLUDE_STYLES, read by RoboCasa's
    own interpreter (its venv)."""
    import json
    import subprocess

    from scenes.robocasa import AXIS_TASKS, EXCLUDED_KITCHENS, KITCHEN_SETS
    from scenes.robocasa.environment import find_python

    tasks = sorted({t for ts in AXIS_TASKS.values() for t in ts})
    code = (
        "import json, sys, robocasa; from robocasa.utils import env_utils as E; "
        "from robosuite.environments.base import REGISTERED_ENVS as R; "
        "print(json.dumps([E.KITCHEN_SCENES_5X5, E.KITCHEN_SCENES_5X1, "
        "{t: [R[t].EXCLUDE_LAYOUTS, R[t].EXCLUDE_STYLES] for t in sys.argv[1:]}]))"
    )
    out = subprocess.run([str(find_python()), "-c", code, *tasks], capture_output=True, text=True, timeout=120,
                         env={"PATH": os.environ["PATH"], "MUJOCO_GL": "egl", "PYTHONNOUSERSITE": "1"},
                         cwd="/")  # fmt: skip
    five, one, excl = json.loads(out.stdout.strip().splitlines()[-1])
    assert [tuple(p) for p in five] == list(KITCHEN_SETS["5x5"]) and [tuple(p) for p in one] == list(
        KITCHEN_SETS["5x1"]
    )
    got = {}
    for t, (layouts, styles) in excl.items():
        hit = {lay for lay, sty in KITCHEN_SETS["5x5"] if lay in layouts or sty in styles}
        if hit:
            got[t] = frozenset(hit)
    assert got == EXCLUDED_KITCHENS


def test_robocasa_runs_in_the_black_box_regime():
    """The family's protocol names the regime the report reads (indgen_vla.core.reporting.levels.run_regime)."""
    from indgen_vla.core.reporting.levels import BLACK_BOX, run_regime
    from scenes.robocasa import BLACK_BOX as FAMILY

    assert FAMILY == BLACK_BOX
    assert run_regime({"resolved": {"environment": {"protocol": {"regime": FAMILY}}}}) == BLACK_BOX
