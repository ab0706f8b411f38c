"""``PolicySpec.history_steps``: the engine renders the env step(s) before each query and attaches their images as
``Observation.history`` (RynnVLA-002's his_2), only for policies that ask, without changing any outcome."""

from collections import Counter

import numpy as np
import pytest

from indgen_vla.app.engine.config import EvalConfig, plan_episodes
from indgen_vla.app.engine.local import LocalOptions, run_local
from indgen_vla.app.engine.rollout import EnvRunner, RunMeta, RunnerConfig
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import Observation, PolicySpec, ScenePreview
from indgen_vla.core.protocol.plan import EpisodeJob
from scenes.family import get_scene
from scenes.planning import scene_levels
from tests.fixtures.feedback import feedback_policy_class
from tests.fixtures.renders import count_renders

pytestmark = pytest.mark.filterwarnings("ignore")

CAMS, SIZE, WARMUP = ("agentview", "wrist"), (32, 32), 1


def _task() -> str:
    import scenes

    return list(scenes.get_scene("pick_place").tasks)[0]


def _by_hand(env, job: EpisodeJob, actions: np.ndarray) -> list[Observation]:
    """A second env of the same level stepped action by action, every step rendered: observation s is step s's."""
    obs, _ = env.reset(seed=job.seed, options={"episode": job.episode})
    for _ in range(WARMUP):
        obs, *_ = env.step(np.array([0, 0, 0, 0, 0, 0, -1.0]))
    seen = [obs]
    for a in actions:
        obs, _, terminated, truncated, _ = env.step(a)
        seen.append(obs)
        if terminated or truncated:
            break
    return seen


def _same_images(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[c], b[c]) for c in a)


@pytest.mark.slow  # ~6 s: test_served_vla's RynnVLA test checks the same history by default
def test_history_is_the_step_before_each_query():
    """Each query's ``history`` is the frame of step t-1 (a by-hand env's render there), whether the slice it ends
    is 3 actions long or 1; none at an episode's first query (not the warm-up's frames: upstream's ``his_img``
    starts empty), and none leaking from an episode that ended mid-slice into the next one on the same runner."""
    # the horizon counts warm-up steps; replan 3: queries at steps 0, 3, 6 and the third slice ends at step 7,
    # two actions early
    steps, max_steps = 7, 7 + WARMUP
    levels = scene_levels(get_scene("pick_place"), ["pick_y"])
    cams = CAMS[:1]  # one camera keeps it fast (both: test_served_vla.py's engine test)
    rc = RunnerConfig(levels=levels, cameras=cams, image_size=SIZE, max_steps=max_steps, privileged=False,
                      warmup_steps=WARMUP, history_steps=1)  # fmt: skip
    runner = EnvRunner(rc)
    hand = levels.make_env(_task(), "pick_y", 0, cameras=cams, image_size=SIZE, max_steps=max_steps)
    actions = np.random.default_rng(3).uniform(-1, 1, size=(9, 7)).astype(np.float32)
    try:
        for episode, replan in enumerate((3, 1)):
            job = EpisodeJob(_task(), "pick_y", 0, episode, seed=20 + episode, param=0.0)
            truth = _by_hand(hand, job, actions)
            t, s, queries = runner.reset(job), 0, 0
            while not t.done:
                assert not t.error, t.error
                assert np.array_equal(t.obs.state, truth[s].state)
                assert _same_images(t.obs.images, truth[s].images)
                if s == 0:
                    assert t.obs.history == ()
                else:
                    (before,) = t.obs.history
                    assert _same_images(before, truth[s - 1].images) and set(before) == set(cams)
                queries += 1
                t = runner.execute(actions[s : s + replan])
                s = t.steps
            assert t.steps == steps == len(truth) - 1 and queries == -(-steps // replan)
    finally:
        runner.close()
        hand.close()


class _SeesHistory:
    """A batched state-feedback policy that reads a camera (so frames are rendered) and logs what it saw."""

    def __init__(self, history_steps: int, log: Counter):
        self.inner, self.log = feedback_policy_class()(), log
        self.spec = PolicySpec("standin", "test:history", chunk_size=5, replan_steps=5, cameras=("agentview",),
                               batched=True, history_steps=history_steps)  # fmt: skip

    def reset(self, instruction, seed=None):
        pass

    def act(self, observations):
        chunk = self.inner.act(observations)
        for o, c in zip(observations, chunk, strict=True):
            self.log[(o.state.tobytes(), c.tobytes())] += 1
            self.log[("history", len(o.history))] += 1
        return chunk

    def close(self):
        pass


@pytest.mark.slow  # ~5 s: two rendered runs; the history's content stays checked by default
def test_history_renders_only_when_asked_and_changes_no_outcome(monkeypatch):
    """The extra render does not step the simulator: the same states, actions and records with and without it; a
    policy without history gets none and one render per query, one with history one more per query."""
    renders = count_renders(monkeypatch)
    c = EvalConfig.from_flat(policy="test", scene="pick_place", axes=("pick_y",), out="-", episodes=2)
    jobs = plan_episodes(c, [_task()], {"pick_y": [0]}, {(_task(), "pick_y", 0): 0.0})
    runs = {}
    for k in (0, 1):
        log, records = Counter(), []
        rc = RunnerConfig(levels=scene_levels(get_scene("pick_place"), ["pick_y"]), cameras=("agentview",), image_size=SIZE,
                          max_steps=10, privileged=False, history_steps=k)  # fmt: skip
        renders["n"] = 0
        run_local(
            jobs,
            rc,
            lambda k=k, log=log: _SeesHistory(k, log),
            RunMeta("r", "test", "", "pick_place"),
            records.append,
            LocalOptions(workers=1, replan_steps=5),
        )
        rows = sorted((r.episode, r.seed, r.success, r.steps, r.status, r.failure) for r in records)
        history = {key[1]: n for key, n in log.items() if key[0] == "history"}
        runs[k] = ({key: n for key, n in log.items() if key[0] != "history"}, rows, history, renders["n"])
    assert runs[0][:2] == runs[1][:2] and len(runs[0][1]) == 2 and all(r[4] == "ok" for r in runs[0][1])
    assert runs[0][2] == {0: 4}  # 2 episodes x 2 queries (steps 0 and 5), never any history
    assert runs[1][2] == {0: 2, 1: 2}  # the first query of each episode has none
    assert runs[0][3] == 2 * (1 + 2)  # the reset and the last step of each 5-step slice
    assert runs[1][3] == 2 * (1 + 2 * 2)  # + the step before each slice's last


def test_history_steps_reach_the_runner_config():
    """``evaluate`` builds every backend's ``RunnerConfig`` (local workers, pipeline lanes, Ray actors, early
    workers) in ``_runner_config``, from the loaded spec or the preview: the history travels with it."""
    from types import SimpleNamespace

    from indgen_vla.app.engine.policy_source import runner_config as _runner_config

    cfg = EvalConfig.from_flat(policy="test", scene="pick_place", axes=("pick_y",), out="-", episodes=1)
    plan = SimpleNamespace(builder=scene_levels(get_scene("pick_place"), ["pick_y"]))
    spec = PolicySpec("rynnvla", "x", cameras=CAMS, history_steps=1)
    assert _runner_config(cfg, plan, spec).history_steps == 1
    assert _runner_config(cfg, plan, ScenePreview(CAMS, history_steps=1)) == _runner_config(cfg, plan, spec)
    assert _runner_config(cfg, plan, PolicySpec("standin", "y", cameras=CAMS)).history_steps == 0


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"history_steps": -1}, "history_steps must be an integer >= 0, got -1"),
        ({"history_steps": True}, "history_steps must be an integer >= 0, got True"),
        ({"history_steps": 1, "cameras": ()}, "history_steps=1 keeps camera images, but it reads no camera"),
    ],
)
def test_bad_history_specs_are_one_line(kwargs, message):
    with pytest.raises(ConfigError, match=message):
        PolicySpec("standin", "test:bad", **kwargs)


def test_history_images_are_checked_like_images():
    state, img = np.zeros(8, np.float32), np.zeros((4, 4, 3), np.uint8)
    obs = Observation({"agentview": img}, state, "go", history=({"agentview": img},))
    assert obs.history[0]["agentview"] is img
    with pytest.raises(ValueError, match=r"history\[0\] image 'agentview' must be uint8 HxWx3, got float32"):
        Observation({"agentview": img}, state, "go", history=({"agentview": img.astype(np.float32)},))
    with pytest.raises(ValueError, match="history must be a tuple of image dicts, got list"):
        Observation({"agentview": img}, state, "go", history=[{"agentview": img}])
