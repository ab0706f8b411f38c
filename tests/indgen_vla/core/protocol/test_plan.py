"""The resolved plan (core): episode order and seeds, the jobs' hash, and the manifest record."""

import dataclasses
import json
import pickle

import pytest

from indgen_vla.core.protocol.plan import (
    CERTIFIED,
    UNCERTIFIED,
    Cell,
    EvalPlan,
    ScenePlan,
    plan_jobs,
    shared_t0,
    sharing_record,
)
from indgen_vla.core.protocol.progression import AxisSpec
from indgen_vla.core.protocol.seeding import episode_seed


class Builder:
    """A minimal LevelBuilder: the plan only stores it and asks for its description."""

    scene = "toy"
    preload = ()

    def make_env(self, task, axis, level, *, cameras, image_size, max_steps):
        raise AssertionError("the plan never builds envs itself")

    def describe(self):
        return {"scene": "toy", "family": "Builder"}


def toy_plan(episodes=2, seed=0, param_at_1=0.1) -> EvalPlan:
    axis = AxisSpec("pick_y", "move", "pick.y", 0.1, "m", True, 1)
    cells = tuple(
        Cell(t, "pick_y", k, param_at_1 * k, CERTIFIED if k == 0 else UNCERTIFIED)
        for t in ("a", "b")
        for k in (0, 1, -1)
    )
    sp = ScenePlan("toy", ("a", "b"), {"pick_y": axis}, {"pick_y": (-1, 0, 1)}, cells, Builder())
    return EvalPlan(sp, plan_jobs("toy", sp.tasks, sp.levels, sp.params(), episodes, seed))


def test_jobs_run_axis_task_level_by_distance_then_episode_with_level_free_seeds():
    jobs = toy_plan().jobs
    assert [(j.task, j.level, j.episode) for j in jobs[:6]] == [
        ("a", 0, 0), ("a", 0, 1), ("a", -1, 0), ("a", -1, 1), ("a", 1, 0), ("a", 1, 1),
    ]  # fmt: skip
    # episode i of task t has the same seed at every level (common random numbers), from (seed, scene, task, i)
    assert {j.seed for j in jobs if j.task == "b" and j.episode == 1} == {episode_seed(0, "toy", "b", 1)}
    assert [j.param for j in jobs if j.task == "a" and j.episode == 0] == [0.0, -0.1, 0.1]


def test_the_jobs_hash_changes_with_any_planned_fact_and_only_then():
    base = toy_plan().jobs_hash()
    assert toy_plan().jobs_hash() == base
    assert toy_plan(seed=1).jobs_hash() != base
    assert toy_plan(episodes=3).jobs_hash() != base
    assert toy_plan(param_at_1=0.2).jobs_hash() != base


def test_the_record_is_json_and_names_every_cell_and_certificate():
    plan = toy_plan()
    rec = json.loads(json.dumps(plan.record()))
    assert rec["environment"] == {"scene": "toy", "family": "Builder"}
    assert rec["episodes"] == len(plan.jobs) == 12 and len(rec["jobs_sha256"]) == 64
    assert {(c["task"], c["level"], c["certificate"]) for c in rec["cells"]} == {
        (t, k, CERTIFIED if k == 0 else UNCERTIFIED) for t in ("a", "b") for k in (-1, 0, 1)
    }
    assert plan.scene_plan.cell("b", "pick_y", -1).param == pytest.approx(-0.1)


def test_a_plan_travels_to_workers_by_pickle():
    sp = toy_plan().scene_plan
    sp.cell("a", "pick_y", 0)  # fills the lookup cache, which must pickle too
    back = pickle.loads(pickle.dumps(sp))
    assert back.cells == sp.cells and back.cell("a", "pick_y", 0) == sp.cell("a", "pick_y", 0)


def shared_plan(keys: dict[str, str], levels=(0, 1)) -> EvalPlan:
    """Axes named by ``keys`` (axis -> its level-0 ``env_key``) on tasks a and b, one episode per level."""
    axes = {a: AxisSpec(a, "move", a, 0.1, "m", False, 1) for a in keys}
    cells = tuple(Cell(t, a, k, 0.1 * k, CERTIFIED, "", keys[a] if k == 0 else "")
                  for a in keys for t in ("a", "b") for k in levels)  # fmt: skip
    sp = ScenePlan("toy", ("a", "b"), axes, {a: levels for a in keys}, cells, Builder())
    plan = EvalPlan(sp, plan_jobs("toy", sp.tasks, sp.levels, sp.params(), 1, 0))
    return dataclasses.replace(plan, shared=shared_t0(sp))


def test_axes_share_t0_only_where_the_scene_layer_calls_level_0_one_environment():
    plan = shared_plan({"x": "k1", "y": "k2", "z": "k1", "w": "", "v": "k2"})
    # z shares x's T0 and v shares y's (the first axis of that key owns it); w's level 0 is unknown: not shared
    assert plan.shared == {("a", "z"): "x", ("a", "v"): "y", ("b", "z"): "x", ("b", "v"): "y"}
    assert plan.sharers("a", "x") == ("z",) and plan.sharers("a", "z") == ()
    run = {j.key for j in plan.rollouts()}
    assert len(plan.jobs) == 20 and len(run) == 16 and ("a", "z", 0, 0) not in run and ("a", "z", 1, 0) in run
    rec = sharing_record(plan, True)
    assert rec["groups"] == {"a": [["x", "z"], ["y", "v"]], "b": [["x", "z"], ["y", "v"]]}
    assert (rec["rollouts"], rec["saved"]) == (16, 4)
    assert (
        plan.jobs_hash() == dataclasses.replace(plan, shared={}).jobs_hash()
    )  # the planned episodes are the same


def test_no_level_0_no_sharing():
    assert shared_plan({"x": "k", "y": "k"}, levels=(1,)).shared == {}
