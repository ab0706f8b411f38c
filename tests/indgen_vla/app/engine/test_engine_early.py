"""Start-up (issue 28): workers start and build their first scenes while the policy loads (``local.EarlyWorkers``,
from the policy's ``ScenePreview``). The records are those of a run that builds its scenes after the load, and
workers that the loaded policy does not take are closed."""

from __future__ import annotations

import dataclasses
import multiprocessing as mp
from pathlib import Path

import pandas as pd
import pytest

from indgen_vla.app.engine.config import EvalConfig, plan_episodes
from indgen_vla.app.engine.local import EarlyWorkers, Handoff, LocalOptions, run_local
from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig
from policy_wrappers.specs import load_policy, preview_policy
from scenes.family import get_scene
from scenes.planning import scene_levels
from tests.fixtures.resolved import evaluate

pytestmark = pytest.mark.filterwarnings("ignore")


def _outcomes(records) -> dict:
    return {(r.task, r.level, r.episode): (r.seed, r.success, r.steps, r.status, r.failure) for r in records}


def _jobs_and_config():
    import scenes

    c = EvalConfig.from_flat(
        policy="standin:random", scene="pick_place", axes=("pick_y",), levels="0:1", episodes=2, out="unused"
    )
    tasks = list(scenes.get_scene("pick_place").tasks)[:1]
    jobs = plan_episodes(c, tasks, {"pick_y": [0, 1]}, {(t, "pick_y", k): 0.0 for t in tasks for k in (0, 1)})
    rc = RunnerConfig(levels=scene_levels(get_scene("pick_place"), ["pick_y"]), cameras=(), image_size=(64, 64),
                      max_steps=6, privileged=False)  # fmt: skip
    return jobs, rc


def _run(jobs, rc, early=None) -> dict:
    records: list = []
    policy = load_policy("standin:random")
    run_local(
        jobs,
        rc,
        lambda: policy,
        RunMeta("r", "standin:random", "", "pick_place"),
        records.append,
        LocalOptions(workers=1, replan_steps=3),
        handoff=Handoff(early=early),
    )
    return _outcomes(records)


def test_early_workers_give_the_records_of_a_scene_built_after_the_load():
    jobs, rc = _jobs_and_config()
    before = set(mp.active_children())
    pool = EarlyWorkers(rc, jobs, 1).take(rc)
    assert pool is not None and len(pool) == 1 and pool[0].proc.is_alive()
    early = _run(jobs, rc, pool)
    assert not pool[0].proc.is_alive()  # run_local owns the workers it was handed, and closed them
    assert early == _run(jobs, rc) and len(early) == 4
    assert set(mp.active_children()) <= before


def test_workers_for_other_scenes_are_closed_not_used():
    """The loaded policy asks for another image size than the preview said: the early workers are closed."""
    jobs, rc = _jobs_and_config()
    before = set(mp.active_children())
    early = EarlyWorkers(rc, jobs, 2)
    assert early.take(dataclasses.replace(rc, image_size=(32, 32))) is None
    assert set(mp.active_children()) <= before
    early.close()  # again: nothing left to close


@pytest.mark.slow  # ~9 s: an overlap of two slow starts, timed
def test_evaluate_builds_the_first_scene_while_the_policy_loads(tmp_path, monkeypatch):
    """A LeRobot checkpoint's cameras are read from its config before it loads; the run takes the early worker
    and its episodes equal those of the same run without a preview (scene built in-process after the load)."""
    pytest.importorskip("lerobot")
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

    ckpt = build_tiny_checkpoint("act", tmp_path / "act", cameras=("image", "image2"), size=32)
    taken: list[bool] = []
    take = EarlyWorkers.take

    def spy(self, runner_cfg):
        pool = take(self, runner_cfg)
        taken.append(pool is not None)
        return pool

    monkeypatch.setattr(EarlyWorkers, "take", spy)

    def run(name: str) -> dict:
        cfg = EvalConfig.from_flat(policy=f"lerobot:{ckpt}", scene="pick_place", axes=("pick_y",), levels="0",
                         episodes=2, max_steps=6, workers=1, out=str(tmp_path / name))  # fmt: skip
        out = evaluate(cfg, quiet=True)
        return _outcomes(pd.read_parquet(Path(out) / "episodes.parquet").itertuples())

    early = run("early")
    assert taken == [True]
    monkeypatch.setattr("policy_wrappers.specs.preview_policy", lambda *a, **k: None)
    late = run("late")
    assert taken == [True]  # no preview: no early workers
    assert early == late and len(early) == 2


def test_a_policy_refused_after_its_preview_leaves_no_workers_and_no_run(tmp_path):
    """The checkpoint's cameras preview fine but its 12-d actions do not fit the tabletop: the load's one-line
    error, the early workers closed, nothing written."""
    pytest.importorskip("lerobot")
    from indgen_vla.core.errors import PolicyError
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

    ckpt = build_tiny_checkpoint(
        "act", tmp_path / "act12", cameras=("image", "image2"), size=16, action_dim=12
    )
    assert preview_policy(f"lerobot:{ckpt}") is not None  # so workers start during the load
    before = set(mp.active_children())
    cfg = EvalConfig.from_flat(policy=f"lerobot:{ckpt}", scene="pick_place", axes=("pick_y",), levels="0", episodes=1,
                     max_steps=2, out=str(tmp_path / "run"))  # fmt: skip
    with pytest.raises(PolicyError, match=r"actions of shape \(12,\)"):
        evaluate(cfg, quiet=True)
    assert set(mp.active_children()) <= before
    assert not (tmp_path / "run" / "manifest.json").exists()


def test_workers_take_the_callers_environment_as_of_their_start(tmp_path, monkeypatch):
    """The fork server keeps the environment of its own start; workers take the caller's current one, so an
    asset path set after an earlier run reaches the scene build (a RoboCasa placeholder path set by a test fixture
    after another test had started the fork server once did not)."""
    import scenes
    from indgen_vla.app.engine.local import start_forkserver

    builder = scene_levels(get_scene("libero_object"), ["pick_y"])
    start_forkserver(builder)  # a no-op when an earlier test started it: either way it predates the next line
    nowhere = tmp_path / "nowhere"
    monkeypatch.setenv("INDGEN_LIBERO_ASSETS", str(nowhere))
    c = EvalConfig.from_flat(policy="standin:random", scene="libero_object", axes=("pick_y",), levels="0", episodes=2,
                   out="unused")  # fmt: skip
    task = list(scenes.get_scene("libero_object").tasks)[:1]
    jobs = plan_episodes(c, task, {"pick_y": [0]}, {(task[0], "pick_y", 0): 0.0})
    rc = RunnerConfig(levels=builder, cameras=(), image_size=(64, 64), max_steps=2, privileged=False)
    records: list = []
    policy = load_policy("standin:random")
    run_local(
        jobs,
        rc,
        lambda: policy,
        RunMeta("r", "standin:random", "", "libero_object"),
        records.append,
        LocalOptions(workers=2, max_retries=0),
    )
    assert len(records) == 2 and all(r.status == "error" and str(nowhere) in r.error for r in records), [
        r.error for r in records
    ]


def test_without_a_fork_server_the_run_starts_as_without_a_preview(monkeypatch):
    """A platform without the forkserver start method (Windows): no early workers, and ``take`` says so; the run
    then steps its one environment in-process as before."""
    import indgen_vla.app.engine.local as local

    def no_forkserver(levels, task=None):
        raise ValueError("cannot find context for 'forkserver'")

    monkeypatch.setattr(local, "_context", no_forkserver)
    jobs, rc = _jobs_and_config()
    early = EarlyWorkers(rc, jobs, 1)
    assert early.take(rc) is None and early.pool == []
    early.close()
