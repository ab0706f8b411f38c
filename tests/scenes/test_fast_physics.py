"""The fast OSC_POSE control step reproduces stock robosuite 1.4 bit for bit (``scenes.sim.FastControl``)."""

from __future__ import annotations

import numpy as np
import pytest

from indgen_vla.core.errors import SceneError
from scenes.listing import builtin_scenes
from scenes.privileged import with_privileged
from scenes.tabletop.oracle import OraclePolicy
from tests.fixtures.levels import level_env

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


def _actions(n: int, seed: int) -> np.ndarray:
    """Seeded actions over the whole range, the gripper flipping between open and closed."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(-1.0, 1.0, size=(n, 7))
    a[:, 6] = np.sign(rng.uniform(-1.0, 1.0, size=n))
    a[n // 3 :: 7, 6] = 0.0  # a zero gripper command holds the integrated gripper state
    return a


def _trajectory(env, fast: bool, actions: np.ndarray, seed: int) -> dict[str, np.ndarray]:
    """Reset ``env`` to ``seed`` and step ``actions``; every state the engine reads, per step."""
    env._rs.fast_physics = fast
    env.reset(seed=seed)
    d = env._rs.sim.data._data
    out: dict[str, list] = {
        k: [] for k in ("qpos", "qvel", "ctrl", "qacc_warmstart", "state", "contacts", "rew")
    }
    for a in actions:
        obs, rew, *_ = env.step(a)
        out["qpos"].append(d.qpos.copy())
        out["qvel"].append(d.qvel.copy())
        out["ctrl"].append(d.ctrl.copy())
        out["qacc_warmstart"].append(d.qacc_warmstart.copy())
        out["state"].append(obs.state)
        out["contacts"].append(d.contact.geom[: d.ncon].copy().ravel())
        out["rew"].append(rew)
    rs = env._rs
    return {
        **{k: np.array(v) for k, v in out.items() if k != "contacts"},
        "contacts": np.concatenate(out["contacts"]),
        "clock": np.array([rs.timestep, rs.cur_time]),
        "gripper": rs.robots[0].gripper.current_action.copy(),
    }


def _assert_identical(fast: dict, stock: dict) -> None:
    for key in stock:
        assert np.array_equal(fast[key], stock[key]), f"{key} differs between fast and stock physics"


@pytest.fixture(scope="module", params=[s.name for s in builtin_scenes()])
def env(request):
    e = level_env(request.param, cameras=(), max_steps=10**6)
    yield e
    e.close()


def _compare(env, steps: int, seed: int) -> None:
    acts = _actions(steps, seed)
    fast = _trajectory(env, True, acts, seed)
    stock = _trajectory(env, False, acts, seed)
    assert not np.array_equal(stock["qpos"][0], stock["qpos"][-1]), "the arm never moved: the test is vacuous"
    _assert_identical(fast, stock)
    # and stock first, then fast: the fast path leaves nothing behind that changes a later episode
    _assert_identical(_trajectory(env, True, acts, seed), stock)


def test_fast_matches_stock_on_every_builtin_scene(env):
    _compare(env, steps=25, seed=7)


@pytest.mark.slow
def test_fast_matches_stock_over_200_steps(env):
    _compare(env, steps=200, seed=3)


def _oracle_episode(env, fast: bool, seed: int, steps: int) -> tuple[np.ndarray, np.ndarray, str]:
    env._rs.fast_physics = fast
    obs, _ = env.reset(seed=seed)
    policy = OraclePolicy()
    policy.reset(env.instruction, seed)
    actions, qpos, success = [], [], False
    for _ in range(steps):
        obs = with_privileged(obs, env)
        a = policy.act([obs])[0, 0]
        obs, _, terminated, truncated, info = env.step(a)
        actions.append(a)
        qpos.append(env._rs.sim.data.qpos.copy())
        success = info["success"]
        if terminated or truncated:
            break
    return np.array(actions), np.array(qpos), f"{success}:{env.failure_mode(success)}:{policy.phase}"


@pytest.mark.parametrize(
    ("scene", "steps"), [("pick_place", 60), pytest.param("stack", 400, marks=pytest.mark.slow)]
)
def test_oracle_episode_is_identical(scene, steps):
    """The oracle's actions (closed loop on privileged state), states and outcome do not change."""
    env = level_env(scene, cameras=())
    try:
        fa, fq, fo = _oracle_episode(env, True, 11, steps)
        sa, sq, so = _oracle_episode(env, False, 11, steps)
    finally:
        env.close()
    assert np.array_equal(fa, sa) and np.array_equal(fq, sq) and fo == so


def test_fast_path_refuses_what_it_cannot_reproduce():
    import mujoco

    env = level_env("pick_place", cameras=(), max_steps=10**6)
    try:
        env.reset(seed=0)
        assert env._rs.fast_physics  # the default
        env._rs.sim.model._model.opt.solver = mujoco.mjtSolver.mjSOL_PGS
        env.reset(seed=0)
        with pytest.raises(SceneError, match="PGS solver.*fast_physics=False"):
            env.step(np.zeros(7))
        env._rs.fast_physics = False
        env.reset(seed=0)
        env.step(np.zeros(7))  # stock robosuite still steps it
    finally:
        env.close()


def _libero_run(env, fast: bool, actions: np.ndarray) -> dict[str, np.ndarray]:
    env.fast_physics = fast
    obs, _ = env.reset(seed=5, options={"episode": 2})
    d = env._env.sim.data._data
    out: dict[str, list] = {
        "qpos": [d.qpos.copy()],
        "qvel": [],
        "state": [obs.state],
        "image": [],
        "success": [],
    }
    for a in actions:
        obs, _, _, _, info = env.step(a)
        out["qpos"].append(d.qpos.copy())
        out["qvel"].append(d.qvel.copy())
        out["state"].append(obs.state)
        out["image"].append([obs.images[c] for c in env.cameras])
        out["success"].append(info["success"])
    return {k: np.array(v) for k, v in out.items()}


@pytest.mark.slow
@pytest.mark.parametrize(("steps", "cameras"), [(5, ()), (200, ("agentview",))])
def test_libero_fast_matches_stock(mini, steps, cameras):
    """A LIBERO task (miniature assets): settle steps, states, observables (camera images too) and success.

    Slow (a LIBERO build takes ~20 s); by default ``test_libero.py::test_level0_matches_lerobot_libero_env``
    compares this fast path's frames with lerobot's stock ``LiberoEnv`` pixel for pixel.
    """
    pytest.importorskip("libero")
    env = level_env("libero_object", cameras=cameras, image_size=(16, 16), max_steps=10**6)
    try:
        acts = _actions(steps, seed=9)
        stock = _libero_run(env, False, acts)
        fast = _libero_run(env, True, acts)
    finally:
        env.close()
    assert not np.array_equal(stock["qpos"][0], stock["qpos"][-1])
    _assert_identical(fast, stock)
