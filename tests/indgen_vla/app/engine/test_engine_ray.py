"""The Ray backend (simulator actors + one shared, batching policy actor) equals the local backend."""

import importlib.util
import re
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from indgen_vla.app.engine.config import EvalConfig, plan_episodes
from indgen_vla.app.engine.ray_backend import Batcher, ray_knobs
from indgen_vla.core.errors import ConfigError, PolicyError
from indgen_vla.core.protocol.interface import Observation
from scenes.family import get_scene
from scenes.planning import scene_levels
from tests.fixtures.feedback import feedback_policy_class

pytestmark = pytest.mark.filterwarnings("ignore")


def _obs(k: int, instruction: str = "go") -> Observation:
    return Observation({}, np.linspace(-1, 1, 8).astype(np.float32) * (k + 1), instruction)


def test_batcher_coalesces_and_matches_single_calls():
    policy = feedback_policy_class()()
    batcher = Batcher(policy, "test:feedback", max_batch=4, max_wait_s=0.3)
    results: dict[int, np.ndarray] = {}
    threads = [
        threading.Thread(target=lambda k=k: results.__setitem__(k, batcher.act(_obs(k)))) for k in range(6)
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=30)
    try:
        assert sorted(results) == list(range(6))
        for k, chunk in results.items():  # each caller gets its own row, equal to an unbatched call
            np.testing.assert_array_equal(chunk, policy.act([_obs(k)])[0])
        assert sum(batcher.batch_sizes) == 6 and max(batcher.batch_sizes) <= 4
        assert len(batcher.batch_sizes) < 6  # requests within the wait were coalesced
        with pytest.raises(PolicyError, match="refuses"):  # a failing batch fails each of its requests
            batcher.act(_obs(0, "fail"))
        np.testing.assert_array_equal(batcher.act(_obs(1)), results[1])  # and the batcher keeps serving
    finally:
        batcher.close()


class _Sizes:
    """A batched policy that records the number of rows of every call (padding is visible)."""

    def __init__(self):
        self.inner, self.sizes = feedback_policy_class()(), []
        self.spec = self.inner.spec

    def act(self, observations):
        self.sizes.append(len(observations))
        return self.inner.act(observations)


def test_batcher_pads_every_call_to_its_client_count():
    """Which requests coalesce depends on timing; the policy must still see one batch size, always."""
    policy = _Sizes()
    batcher = Batcher(policy, "test:feedback", max_batch=8, max_wait_s=0.0, pad_to=3)
    try:
        for k in range(4):  # one request at a time: each call would be a batch of 1 unpadded
            np.testing.assert_array_equal(batcher.act(_obs(k)), policy.inner.act([_obs(k)])[0])
        assert policy.sizes == [3, 3, 3, 3] and batcher.batch_sizes == [1, 1, 1, 1]
    finally:
        batcher.close()
    assert Batcher(policy, "p", max_batch=2, max_wait_s=0.0, pad_to=5).pad_to == 2  # never above max_batch


def test_batcher_serves_a_full_house_without_waiting():
    """Once it knows its simulators (``pad``), a batch holding one request of each goes at once, not after the wait."""
    policy = _Sizes()
    batcher = Batcher(policy, "test:feedback", max_batch=8, max_wait_s=5.0)
    batcher.pad(1)
    try:
        t0 = time.perf_counter()
        for k in range(3):
            np.testing.assert_array_equal(batcher.act(_obs(k)), policy.inner.act([_obs(k)])[0])
        assert time.perf_counter() - t0 < 4.0 and batcher.batch_sizes == [1, 1, 1]  # 3 waits would be 15 s
    finally:
        batcher.close()


def test_policy_actor_replies_errors_as_the_local_engine_describes_them():
    """The policy actor's logic without Ray: per-client instances of a per-episode policy, and a policy error
    comes back as a value that still names where it was raised after pickling (error rows equal local ones)."""
    import pickle

    from indgen_vla.app.engine.ray_backend import _PolicyActor
    from indgen_vla.app.engine.rollout import _describe
    from scenes.tabletop.oracle import OraclePolicy

    made = []
    actor = _PolicyActor(lambda: made.append(OraclePolicy()) or made[-1], max_batch=4, max_wait_s=0.01)
    assert actor.reset(0, "go", 1) is None and actor.reset(1, "go", 2) is None
    assert len(made) == 2 and made[0].seed == 1 and made[1].seed == 2  # one instance per simulator
    err = actor.act(0, _obs(0))  # the oracle needs privileged state: a PolicyError, returned, not raised
    assert isinstance(err, PolicyError)
    local = _describe(err)
    assert local.startswith("PolicyError: standin:oracle needs") and " at privileged.py:" in local
    assert _describe(pickle.loads(pickle.dumps(err))) == local  # what the simulator actor records
    actor.close()


def test_ray_knobs_are_checked():
    assert ray_knobs({})["INDGEN_RAY_MAX_BATCH"] == 32
    assert ray_knobs({"INDGEN_RAY_GPUS_PER_POLICY": "0.5"})["INDGEN_RAY_GPUS_PER_POLICY"] == 0.5
    with pytest.raises(ConfigError, match="INDGEN_RAY_MAX_BATCH='lots'.*positive"):
        ray_knobs({"INDGEN_RAY_MAX_BATCH": "lots"})
    with pytest.raises(ConfigError, match="INDGEN_RAY_CPUS_PER_SIM"):
        ray_knobs({"INDGEN_RAY_CPUS_PER_SIM": "0"})
    assert (
        ray_knobs({})["INDGEN_RAY_SOCKET"] == 1
        and ray_knobs({"INDGEN_RAY_SOCKET": "0"})["INDGEN_RAY_SOCKET"] == 0
    )
    for bad in ("2", "yes"):
        with pytest.raises(ConfigError, match=f"INDGEN_RAY_SOCKET='{bad}'.*0 or 1"):
            ray_knobs({"INDGEN_RAY_SOCKET": bad})


def test_every_documented_ray_knob_is_checked_even_when_the_run_writes_no_files():
    """INDGEN_RAY_SHARED_OUT=yes was checked only on a --video run (route), so a run without videos took it
    silently; and INDGEN_RAY_MAX_BATCH=1.5 was told to be 'a positive number'. docs/cluster.md: a bad value of any
    knob in its table is one error line naming the variable."""
    with pytest.raises(ConfigError, match="^INDGEN_RAY_SHARED_OUT='yes': must be 1"):
        ray_knobs({"INDGEN_RAY_SHARED_OUT": "yes"})
    with pytest.raises(ConfigError, match="INDGEN_RAY_MAX_BATCH='1.5'.*a positive whole number"):
        ray_knobs({"INDGEN_RAY_MAX_BATCH": "1.5"})
    table = (
        (Path(__file__).parents[4] / "docs" / "cluster.md")
        .read_text()
        .split("| variable |")[1]
        .split("\n\n")[0]
    )
    documented = set(re.findall(r"^\| `(INDGEN_RAY_\w+)`", table, re.M))
    assert len(documented) == 7
    for name in documented:  # each documented knob is read and refused when bad
        with pytest.raises(ConfigError, match=f"^{name}='-2'"):
            ray_knobs({name: "-2"})


def test_simulator_actors_carry_the_drivers_robocasa_split(monkeypatch):
    """What the plan resolved (the driver's variable, or --split over it), not a node's own environment: the
    manifest records the driver's split."""
    from indgen_vla.app.engine.ray_backend import sim_options
    from scenes.planning import scene_levels

    monkeypatch.setenv("INDGEN_ROBOCASA_SPLIT", "all")
    monkeypatch.delenv("INDGEN_ROBOCASA_OBJ_REGISTRIES", raising=False)
    env = sim_options(scene_levels(get_scene("robocasa"), ["base_y"]))["runtime_env"]["env_vars"]
    assert env == {"INDGEN_ROBOCASA_SPLIT": "all", "INDGEN_ROBOCASA_OBJ_REGISTRIES": "objaverse,lightwheel"}
    flagged = scene_levels(
        get_scene("robocasa", {"split": "target", "obj_registries": "lightwheel"}), ["base_y"]
    )
    assert sim_options(flagged)["runtime_env"]["env_vars"] == {
        "INDGEN_ROBOCASA_SPLIT": "target", "INDGEN_ROBOCASA_OBJ_REGISTRIES": "lightwheel"
    }  # fmt: skip
    monkeypatch.delenv("INDGEN_ROBOCASA_SPLIT")
    default = sim_options(scene_levels(get_scene("robocasa"), ["base_y"]))["runtime_env"]["env_vars"]
    assert default["INDGEN_ROBOCASA_SPLIT"] == "pretrain"
    assert (
        sim_options(scene_levels(get_scene("pick_place"), ["pick_y"])) == {}
    )  # a scene that reads no such choice


ROW = ("task", "axis", "level", "episode", "seed", "success", "steps", "status", "failure")


def _rows(records):
    return sorted(tuple(getattr(r, k) for k in ROW) for r in records)


needs_ray = pytest.mark.skipif(
    importlib.util.find_spec("ray") is None, reason="the 'ray' extra is not installed"
)


@pytest.fixture
def ray_session():
    ray = pytest.importorskip("ray")
    ray.init(address="local", num_cpus=3, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


def _jobs(policy: str, episodes: int, workers: int):
    import scenes

    task = list(scenes.get_scene("pick_place").tasks)[:1]
    c = EvalConfig.from_flat(
        policy=policy, scene="pick_place", axes=("pick_y",), out="-", episodes=episodes, workers=workers
    )
    return c, plan_episodes(c, task, {"pick_y": [0, 1]}, {(task[0], "pick_y", k): 0.03 * k for k in (0, 1)})


@pytest.mark.slow  # 70 s; the default suite's Ray == local check is test_engine_ray_cluster's resume test
@needs_ray
def test_ray_backend_matches_local(tmp_path, ray_session):
    """The oracle through ``evaluate --backend ray`` (2 simulator actors, per-episode oracle instances held by
    the one policy actor) gives the local backend's episodes."""
    from indgen_vla.app.engine.local import LocalOptions, run_local
    from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig
    from scenes.tabletop.oracle import OraclePolicy
    from tests.fixtures.resolved import evaluate

    c, jobs = _jobs("standin:oracle", 2, 1)
    rc = RunnerConfig(levels=scene_levels(get_scene("pick_place"), ["pick_y"]), cameras=(), image_size=(64, 64), max_steps=25,
                      privileged=True)  # fmt: skip
    ref = []
    run_local(
        jobs,
        rc,
        OraclePolicy,
        RunMeta("r", "standin:oracle", "", "pick_place"),
        ref.append,
        LocalOptions(workers=1, replan_steps=OraclePolicy.spec.replan_steps),
    )
    out = evaluate(EvalConfig.from_flat(policy="standin:oracle", scene="pick_place", axes=("pick_y",), levels="0:1",
                              episodes=2, max_steps=25, workers=2, backend="ray", out=str(tmp_path / "ray")),
                   quiet=True)  # fmt: skip
    df = pd.read_parquet(Path(out) / "episodes.parquet")
    assert len(ref) == 4 and all(r.status == "ok" for r in ref)
    assert sorted(map(tuple, df[list(ROW)].itertuples(index=False))) == _rows(ref)


@needs_ray
@pytest.mark.slow
def test_ray_batched_policy_actor_matches_local(ray_session, monkeypatch):
    """A batched policy: one instance in the policy actor serving 2 simulator actors, equal to local, whether the
    simulators call it over its node's socket (the default) or through Ray (``INDGEN_RAY_SOCKET=0``)."""
    from indgen_vla.app.engine.local import LocalOptions, run_local
    from indgen_vla.app.engine.ray_backend import run_ray
    from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig

    c, jobs = _jobs("test:feedback", 2, 2)
    rc = RunnerConfig(levels=scene_levels(get_scene("pick_place"), ["pick_y"]), cameras=(), image_size=(64, 64), max_steps=15,
                      privileged=False)  # fmt: skip
    meta, cls = RunMeta("r", "test:feedback", "", "pick_place"), feedback_policy_class()
    ref, got, stats = [], [], {}
    run_local(jobs, rc, cls, meta, ref.append, LocalOptions(workers=1, replan_steps=5))
    run_ray(jobs, rc, c, meta, got.append, 5, make_policy=cls, stats=stats)
    assert len(ref) == 4 and _rows(got) == _rows(ref)
    assert stats["policy_actors"] == 1 and sum(stats["batch_sizes"]) == 4 * 3  # 3 chunks per episode
    # a reset and 3 chunks per episode, none through Ray; each simulator built its first scene as it started
    assert stats["policy_calls"] == {"socket": 4 * (1 + 3)} and stats["scenes_prepared"] == 2
    monkeypatch.setenv("INDGEN_RAY_SOCKET", "0")
    got, stats = [], {}
    run_ray(jobs, rc, c, meta, got.append, 5, make_policy=cls, stats=stats)
    assert _rows(got) == _rows(ref) and stats["policy_calls"] == {"ray": 4 * (1 + 3)}


@needs_ray
def test_a_local_instance_runs_its_actors_at_the_drivers_priority(monkeypatch):
    """Ray's workers default to nice 15: beside busy processes at the default priority the simulators starved (8
    oracle episodes took 122-136 s against 6-7 s locally on 2 cores). The local instance ``run_ray`` starts sets 0."""
    import os

    import ray

    from indgen_vla.app.engine.ray_cluster import join

    monkeypatch.delenv("RAY_ADDRESS", raising=False)  # a local instance, not a cluster's own setting
    assert not ray.is_initialized()
    assert join(1)
    try:

        @ray.remote(num_cpus=1)
        class Probe:
            def niceness(self) -> int:
                return os.nice(0)

        assert ray.get(Probe.remote().niceness.remote()) == os.nice(0)
    finally:
        ray.shutdown()


def test_a_bad_knob_is_refused_before_the_run_directory_exists(tmp_path, monkeypatch, capsys):
    """One ``error:`` line, exit 2, and nothing written: the knobs are checked with the plan, not once Ray runs."""
    from indgen_vla.app.cli import main

    monkeypatch.setenv("INDGEN_RAY_SOCKET", "2")
    out = tmp_path / "run"
    argv = ["evaluate", "--policy", "standin:oracle", "--scene", "pick_place", "--axis", "pick_y", "--levels", "0:1",
            "--episodes", "1", "--backend", "ray", "--out", str(out)]  # fmt: skip
    assert main(argv) == 2
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "INDGEN_RAY_SOCKET='2'" in errors[0] and "must be 0 or 1" in errors[0]
    assert not out.exists()
