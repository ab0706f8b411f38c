"""``univla:`` / ``rynnvla:`` clients against ``scripts/serve/libero_vla.py`` serving tiny callables in the
upstream models' places (the real models need their own environments and a GPU)."""

from __future__ import annotations

import importlib.util
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from indgen_vla.core.errors import ConfigError, PolicyError, UnknownNameError
from policy_wrappers.serve import PolicyServer
from policy_wrappers.specs import load_policy
from scenes.family import get_scene

pytestmark = pytest.mark.timeout(60)

_path = Path(__file__).resolve().parents[2] / "scripts" / "serve" / "libero_vla.py"
_spec = importlib.util.spec_from_file_location("libero_vla_server", _path)
server_script = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = server_script
_spec.loader.exec_module(server_script)


@contextmanager
def serving(session):
    """The script's server (openpi protocol, a policy per connection) on an ephemeral loopback port."""
    srv = PolicyServer(session(), host="127.0.0.1", port=0, unflip=False, session=session)
    port = srv.start_background()
    try:
        yield port
    finally:
        srv.stop()


class FakeEmuVLAModel:
    """In ``EmuVLAModel``'s place: records ``step``'s arguments, returns a fixed 10-step chunk."""

    def __init__(self, actions):
        self.actions, self.steps, self.resets = actions, [], 0

    def reset(self):
        self.resets += 1

    def step(self, image, goal):
        self.steps.append((image, goal))
        return self.actions


def univla_session(model):
    spec = server_script.server_spec("univla", server_script.UNIVLA_CHUNK, "fake")
    return lambda: server_script.UniVLASession(model, spec)


def rynnvla_session(infer, suite="libero_object"):
    spec = server_script.server_spec("rynnvla", server_script.RYNNVLA_HORIZON[suite], "fake")
    return lambda: server_script.RynnVLASession(infer, spec)


def test_univla_gets_what_evaluate_libero_emu_sends_and_its_chunk_whole(obs_factory):
    """baaivision/UniVLA reference/RoboVLMs/eval/libero: ``get_libero_env(task, resolution=256)``;
    ``libero_utils.py:get_libero_image`` / ``get_libero_wrist_image`` are ``img[::-1, ::-1]``; ``prepare_observation``
    sends {full_image, wrist_image, state} and ``model.step(observation, task_description)``; the eval executes every
    row of the returned chunk (``action_counter = action.shape[0]``), which ``step`` already de-normalised."""
    actions = np.linspace(-1, 1, 70).reshape(10, 7)
    model = FakeEmuVLAModel(actions)
    with serving(univla_session(model)) as port:
        policy = load_policy(f"univla:ws://127.0.0.1:{port}")
        spec = policy.spec
        assert (spec.family, spec.chunk_size, spec.replan_steps, spec.image_size) == (
            "univla",
            10,
            10,
            (256, 256),
        )
        obs = obs_factory(1, size=256)
        policy.reset(obs.instruction, seed=3)
        chunk = policy.act([obs])
        policy.close()
    image, goal = model.steps[0]
    assert set(image) == {"full_image", "wrist_image", "state"} and goal == obs.instruction
    assert np.array_equal(image["full_image"], obs.images["agentview"][::-1, ::-1])
    assert np.array_equal(image["wrist_image"], obs.images["wrist"][::-1, ::-1])
    assert np.allclose(image["state"], obs.state)
    assert model.resets >= 1  # the episode start reached EmuVLAModel.reset
    assert chunk.shape == (1, 10, 7) and np.allclose(chunk[0], actions)  # no client-side action mapping


def test_rynnvla_unnormalisation_is_the_eval_solvers_min_max():
    """rynnvla-002/eval_solver_libero_continous_w_state.py:Solver.unnorm_action_min_max:
    ``(a + 1) / 2 * (max - min + 1e-8) + min`` with the hard-coded bounds; the gripper stays continuous."""
    a = np.array([[-1.0, 1.0, 0.0, 0.5, -0.5, 0.25, 0.3]])
    want = [
        -0.9375,
        0.9375 + 1e-8 - 0.0,
        (0.9375 * 2 + 1e-8) / 2 - 0.9375,
        0.75 * (0.34821429 + 0.24214286 + 1e-8) - 0.24214286,  # 0.2006250...
        0.25 * (0.75 + 1e-8) - 0.375,
        0.625 * (0.375 + 0.36428571 + 1e-8) - 0.36428571,
        0.65 * (2 + 1e-8) - 1.0,  # 0.3: neither binarised nor sign-flipped
    ]
    assert np.allclose(server_script.rynnvla_unnormalize(a)[0], want, atol=1e-12)
    assert abs(server_script.rynnvla_unnormalize(a)[0, 3] - 0.200625) < 1e-7
    assert server_script.rynnvla_unnormalize(np.zeros((5, 9))).shape == (5, 7)  # dims past 7 dropped


def test_rynnvla_gets_the_step_before_each_query_from_the_engine():
    """``val_libero`` appends each policy step's frames to ``his_img`` and ``Chameleon_utils.py`` takes
    ``his_img[-1:]``: the frames of the env step just before the query, none at the first. The ``rynnvla:`` client
    declares ``history_steps=1``, the engine renders that step, the request carries it (flipped like the current
    frames) and the server hands it to the model: not the previous query's frames, 5 steps earlier."""
    from indgen_vla.app.engine.rollout import EnvRunner, RunnerConfig
    from indgen_vla.core.protocol.interface import validate_chunk
    from indgen_vla.core.protocol.plan import EpisodeJob
    from scenes.planning import scene_levels

    calls, sent = [], []

    def infer(cur, wrist, task, his_img, his_wrist, state):
        calls.append(([np.asarray(h) for h in his_img], [np.asarray(h) for h in his_wrist]))
        return np.tile([0.9, 0.2, -0.3, 0.0, 0.0, 0.0, -1.0], (5, 1))  # moves the arm: frames differ

    levels = scene_levels(get_scene("pick_place"), ["pick_y"])
    with serving(rynnvla_session(infer)) as port:
        policy = load_policy(f"rynnvla:ws://127.0.0.1:{port}")
        assert policy.spec.history_steps == 1
        rc = RunnerConfig(levels=levels, cameras=policy.spec.cameras, image_size=(32, 32), max_steps=15,
                          privileged=False, history_steps=policy.spec.history_steps)  # fmt: skip
        runner = EnvRunner(rc)
        try:
            t = runner.reset(EpisodeJob(_first_task(), "pick_y", 0, 0, seed=5, param=0.0))
            policy.reset(t.obs.instruction, seed=5)
            while not t.done:
                sent.append(t.obs)
                chunk = validate_chunk(policy.act([t.obs]), 1, "rynnvla")
                t = runner.execute(chunk[0])
        finally:
            runner.close()
            policy.close()
    assert [len(h) for h, _ in calls] == [0, 1, 1] and [o.history for o in sent[:1]] == [()]
    for (his, his_wrist), obs, previous in zip(calls[1:], sent[1:], sent[:-1], strict=True):
        (before,) = (
            obs.history
        )  # the engine's step t-1 (tests/indgen_vla/app/engine/test_engine_history.py checks it)
        assert np.array_equal(his[0], before["agentview"][::-1, ::-1])
        assert np.array_equal(his_wrist[0], before["wrist"][::-1, ::-1])
        # not the previous query's frames (what the server used before)
        assert not np.array_equal(his[0], previous.images["agentview"][::-1, ::-1])


def _first_task() -> str:
    import scenes

    return list(scenes.get_scene("pick_place").tasks)[0]


def test_rynnvla_history_state_and_episode_reset(obs_factory, caplog):
    """``val_libero``: images flipped at 256 (``libero_utils.py:get_libero_image``), the raw 8-d state, and
    ``his_2_third_view_wrist_w_state``. A client that sends no history (observations without any) gets the
    previous query's frames instead (empty at an episode's first query), said once in the server's log."""
    calls = []
    norm = np.tile(np.array([0.0, 0.5, -0.5, 1.0, -1.0, 0.25, 0.9]), (5, 1))

    def infer(cur, wrist, task, his_img, his_wrist, state):
        calls.append(
            (np.asarray(cur), np.asarray(wrist), task, [np.asarray(h) for h in his_img], his_wrist, state)
        )
        return norm

    server_script._warn_query_history.cache_clear()  # once per server process: another test may have said it
    with caplog.at_level("WARNING", logger="libero_vla"), serving(rynnvla_session(infer)) as port:
        policy = load_policy(f"rynnvla:ws://127.0.0.1:{port}")
        assert (policy.spec.chunk_size, policy.spec.replan_steps) == (5, 5)
        first, second = obs_factory(1), obs_factory(2)
        policy.reset(first.instruction, seed=0)
        chunk = policy.act([first])
        policy.act([second])
        policy.act([second])
        policy.reset(first.instruction, seed=1)  # same task, next episode: history must not leak
        policy.act([first])
        policy.close()
    cur, wrist, task, his, his_wrist, state = calls[0]
    assert np.array_equal(cur, first.images["agentview"][::-1, ::-1]) and task == first.instruction
    assert np.array_equal(wrist, first.images["wrist"][::-1, ::-1])
    assert his == [] and his_wrist == [] and state.dtype == np.float64 and np.allclose(state, first.state)
    assert len(calls[1][3]) == 1 and np.array_equal(calls[1][3][0], cur)  # the previous query's frames
    assert np.array_equal(np.asarray(calls[1][4][0]), wrist)
    assert calls[3][3] == []
    assert np.allclose(chunk[0], server_script.rynnvla_unnormalize(norm))
    fallback = [r for r in caplog.records if "sent no history frames" in r.getMessage()]
    assert len(fallback) == 1  # once, not at every query


def test_rynnvla_history_is_per_connection(obs_factory):
    seen = []

    def infer(cur, wrist, task, his_img, his_wrist, state):
        seen.append(len(his_img))
        return np.zeros((5, 7))

    with serving(rynnvla_session(infer)) as port:
        a, b = (load_policy(f"rynnvla:ws://127.0.0.1:{port}") for _ in range(2))
        a.act([obs_factory(1)])
        b.act([obs_factory(2)])  # another simulator's first query: no history from a's
        a.act([obs_factory(3)])
        a.close(), b.close()
    assert seen == [0, 0, 1]


def test_chunk_mismatch_and_wrong_server_are_one_line(obs_factory):
    with serving(rynnvla_session(lambda *a: np.zeros((10, 7)), "libero_spatial")) as port:
        with pytest.raises(ConfigError, match=r"predicts 10 actions per query, not 5; pass \?chunk=10"):
            load_policy(f"rynnvla:ws://127.0.0.1:{port}")
        with pytest.raises(ConfigError, match="is family='rynnvla', not univla"):
            load_policy(f"univla:ws://127.0.0.1:{port}")
        policy = load_policy(f"rynnvla:ws://127.0.0.1:{port}?chunk=10")
        assert (policy.spec.chunk_size, policy.spec.replan_steps) == (10, 10)
        assert policy.act([obs_factory(0)]).shape == (1, 10, 7)
        policy.close()
        with pytest.raises(UnknownNameError, match="replan_steps"):
            load_policy(f"rynnvla:ws://127.0.0.1:{port}?chunk=10&replan_steps=2")


def test_a_plain_openpi_server_is_refused():
    from loopback import WebsocketServer

    from policy_wrappers import msgpack_numpy

    async def handler(ws):
        await ws.send(msgpack_numpy.packb({"action_horizon": 10}))
        async for _ in ws:
            pass

    with WebsocketServer(handler) as srv:
        with pytest.raises(
            ConfigError, match="a plain openpi server, not univla; start `python scripts/serve"
        ):
            load_policy(f"univla:ws://127.0.0.1:{srv.port}")


def test_a_wrong_model_output_is_a_policy_error(obs_factory):
    with serving(rynnvla_session(lambda *a: np.zeros((1, 5, 7)))) as port:
        policy = load_policy(f"rynnvla:ws://127.0.0.1:{port}")
        with pytest.raises(PolicyError, match=r"shape \(1, 5, 7\).*is --suite the checkpoint's suite\?"):
            policy.act([obs_factory(0)])
        policy.close()


@pytest.mark.parametrize(
    "spec, message",
    [
        ("univla:http://127.0.0.1:1", "this family takes ws:// or wss://"),
        ("rynnvla:ws://127.0.0.1:1?chunk=x", "option chunk='x' must be an integer"),
        ("rynnvla:ws://127.0.0.1:1?chunk=0", "chunk_size must be >= 1, got 0"),
        ("univla:ws://127.0.0.1:1?replan=11", "replan_steps must be in 1..chunk_size"),
    ],
)
def test_bad_specs_are_one_line(spec, message):
    with pytest.raises(ConfigError, match=message):
        load_policy(spec)


def test_server_main_refuses_a_bad_port_before_loading(capsys):
    argv = ["--port", "70000", "rynnvla", "--ckpt", "c", "--suite", "libero_object", "--tokenizer", "t"]
    assert server_script.main(argv) == 2
    assert "--port must be in 0..65535, got 70000" in capsys.readouterr().err
