"""Pipelined local engine (two environments per worker, sim and inference overlapped) equals the unpipelined one:
same episodes, same outcomes, same observations and actions (short pick_place episodes)."""

from collections import Counter

import numpy as np
import pytest

from indgen_vla.app.engine.config import EvalConfig, plan_episodes
from indgen_vla.app.engine.local import LocalOptions, run_local
from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig
from indgen_vla.core.protocol.interface import PolicySpec
from scenes.family import get_scene
from scenes.planning import scene_levels
from tests.fixtures.feedback import feedback_policy_class
from tests.fixtures.renders import count_renders

pytestmark = pytest.mark.filterwarnings("ignore")


StateFeedback = feedback_policy_class()


class Logged:
    """Wraps a policy and logs every (observation state, action chunk) pair it serves, per instance."""

    def __init__(self, inner, log: Counter, instances: list):
        self.inner, self.log, self.spec = inner, log, inner.spec
        instances.append(self)

    def reset(self, instruction, seed=None):
        self.inner.reset(instruction, seed=seed)

    def act(self, observations):
        chunk = self.inner.act(observations)
        for o, c in zip(observations, chunk, strict=True):
            self.log[(o.state.tobytes(), np.asarray(c, np.float32).tobytes())] += 1
        return chunk

    def close(self):
        self.inner.close()


def _run(make_inner, privileged: bool, workers: int, pipeline: bool, max_steps: int):
    c = EvalConfig.from_flat(policy="test", scene="pick_place", axes=("pick_y",), out="-", episodes=2)
    import scenes

    task = list(scenes.get_scene("pick_place").tasks)[:1]
    jobs = plan_episodes(c, task, {"pick_y": [0, 1]}, {(task[0], "pick_y", k): 0.03 * k for k in (0, 1)})
    rc = RunnerConfig(levels=scene_levels(get_scene("pick_place"), ["pick_y"]), cameras=(), image_size=(64, 64), max_steps=max_steps,
                      privileged=privileged)  # fmt: skip
    log, instances, records = Counter(), [], []
    run_local(
        jobs,
        rc,
        lambda: Logged(make_inner(), log, instances),
        RunMeta("r", "test", "", "pick_place"),
        records.append,
        LocalOptions(workers=workers, replan_steps=5, pipeline=pipeline),
    )
    rows = sorted((r.task, r.axis, r.level, r.episode, r.seed, r.success, r.steps, r.status, r.failure)
                  for r in records)  # fmt: skip
    return rows, log, len(instances)


def test_pipelined_oracle_equals_unpipelined():
    """Per-episode policies (the oracle): one instance per environment, two environments in one worker."""
    from scenes.tabletop.oracle import OraclePolicy

    ref, ref_log, ref_n = _run(OraclePolicy, True, workers=1, pipeline=False, max_steps=30)
    got, got_log, got_n = _run(OraclePolicy, True, workers=1, pipeline=True, max_steps=30)
    assert len(ref) == 4 and all(r[7] == "ok" for r in ref)
    assert got == ref and got_log == ref_log
    assert len(ref_log) > 4  # observations change over the episode, so the log compares whole trajectories
    assert (ref_n, got_n) == (1, 2)  # the pipelined run really used two environments (two oracle instances)


@pytest.mark.slow  # 4 scene builds in 2 processes; the default suite keeps the 1-worker pipelined test above
def test_pipelined_batched_two_workers_equals_one_worker():
    """A batched policy whose actions depend on the state: 2 workers x 2 lanes equal 1 unpipelined worker."""
    ref, ref_log, _ = _run(StateFeedback, False, workers=1, pipeline=False, max_steps=20)
    got, got_log, _ = _run(StateFeedback, False, workers=2, pipeline=True, max_steps=20)
    assert len(ref) == 4 and got == ref
    assert set(got_log) == set(ref_log)  # 2 workers pad each batch to 2 rows, so rows repeat in the log
    assert sum(ref_log.values()) == 4 * 20 // 5  # one chunk of 5 actions per act, 20 steps per episode


def test_batched_act_is_padded_to_the_worker_count():
    """Which workers wait in a round depends on timing: a batched policy still sees one batch size, and each
    environment gets its own row (a per-env policy is never padded)."""
    from types import SimpleNamespace

    from indgen_vla.app.engine.batching import act as _act

    sizes = []

    class Sizes(StateFeedback):
        def act(self, observations):
            sizes.append(len(observations))
            return super().act(observations)

    policy, plain = Sizes(), StateFeedback()
    obs = [SimpleNamespace(obs=_o(k)) for k in range(3)]
    for waiting in ([(1, obs[1])], [(0, obs[0]), (2, obs[2])], [(0, obs[0]), (1, obs[1]), (2, obs[2])]):
        got = _act([policy], policy.spec, waiting, "test", None, pad_to=3)
        assert [i for i, _ in got] == [i for i, _ in waiting]
        for i, chunk in got:
            np.testing.assert_array_equal(chunk, plain.act([obs[i].obs])[0])
    assert sizes == [3, 3, 3]


def _o(k: int):
    from indgen_vla.core.protocol.interface import Observation

    return Observation({}, np.linspace(-1, 1, 8).astype(np.float32) * (k + 1), "go")


class ImageFeedback(StateFeedback):
    """StateFeedback that also reads the camera: logs stay comparable, the render must be real."""

    spec = PolicySpec(
        "standin", "test:image", chunk_size=5, replan_steps=5, cameras=("agentview",), batched=True
    )


@pytest.mark.slow  # ~7 s: two rendered runs; the pipelined == unpipelined check stays in the default suite
def test_lazy_render_reads_the_same_observations(monkeypatch):
    """Skipping the renders nobody reads (all but a chunk slice's last step) changes no observation the policy
    sees, no action and no record; it renders once per slice instead of once per step."""

    calls = count_renders(monkeypatch)
    logs = {}
    for lazy in (False, True):
        log, records = Counter(), []
        rc = RunnerConfig(levels=scene_levels(get_scene("pick_place"), ["pick_y"]), cameras=("agentview",), image_size=(32, 32), max_steps=10,
                          privileged=False, lazy_render=lazy)  # fmt: skip
        c = EvalConfig.from_flat(policy="test", scene="pick_place", axes=("pick_y",), out="-", episodes=2)
        import scenes

        task = list(scenes.get_scene("pick_place").tasks)[:1]
        jobs = plan_episodes(c, task, {"pick_y": [0]}, {(task[0], "pick_y", 0): 0.0})

        def make(log=log):
            policy = Logged(ImageFeedback(), log, [])
            act = policy.act

            def act_logging_images(observations):
                for o in observations:
                    log[("image", o.images["agentview"].tobytes())] += 1
                return act(observations)

            policy.act = act_logging_images
            return policy

        calls["n"] = 0
        run_local(
            jobs,
            rc,
            make,
            RunMeta("r", "test", "", "pick_place"),
            records.append,
            LocalOptions(workers=1, replan_steps=5),
        )
        logs[lazy] = (
            log,
            sorted((r.episode, r.seed, r.steps, r.status, r.failure) for r in records),
            calls["n"],
        )
    assert logs[True][:2] == logs[False][:2] and len(logs[True][1]) == 2
    assert logs[False][2] == 2 * (1 + 10)  # eager: the reset and every step
    assert logs[True][2] == 2 * (1 + 2)  # lazy: the reset and the last step of each 5-step slice


def test_pipeline_flag(tmp_path):
    """--pipeline/--no-pipeline reach EvalConfig (the flag beats a preset); Ray refuses it in one line."""
    import argparse

    from indgen_vla.app.engine.config import config_from_args
    from indgen_vla.core.errors import ConfigError

    preset = tmp_path / "p.yaml"
    preset.write_text("scene: pick_place\naxis: pick_y\npolicy: standin:noop\nout: x\npipeline: true\n")
    assert config_from_args(argparse.Namespace(config=str(preset))).run.pipeline is True
    assert config_from_args(argparse.Namespace(config=str(preset), pipeline=False)).run.pipeline is False
    assert config_from_args(argparse.Namespace(config=str(preset), pipeline=None)).run.pipeline is True
    with pytest.raises(ConfigError, match="--pipeline is for --backend local"):
        EvalConfig.from_flat(policy="p", scene="s", axes=("a",), out="x", pipeline=True, backend="ray")
    with pytest.raises(ConfigError, match="pipeline must be true or false"):
        EvalConfig.from_flat(policy="p", scene="s", axes=("a",), out="x", pipeline="yes")
