"""GR00T on RoboCasa365 against RoboCasa365's own code: its gym wrapper's keys and its N1.5 fork's evaluation.

Upstream, read for these tests (formulas written out here, never imported):
- robocasa/robocasa be22d659b02db8f6d7f3a3c3edc742934fdcbaae ``robocasa/wrappers/gym_wrapper.py``
  (PandaOmronKeyConverter.get_camera_config / map_obs / unmap_action, RoboCasaGymEnv.get_observation) and
  ``docs/benchmarking/foundation_model_learning.md`` (the published checkpoints are GR00T N1.5).
- robocasa-benchmark/Isaac-GR00T, RoboCasa365's GR00T N1.5 fork, read from its copy XingxinHE/Isaac-GR00T at
  9d7d7a9eb7ad30bd8ce30448d9ab53a918b45b10 ("GR00T N1.5 for RoboCasa"): ``scripts/run_eval.py`` (RobotInferenceServer
  with data config ``panda_omron``, SimulationInferenceClient, --n_action_steps 16), ``gr00t/eval/simulation.py``
  (gym.vector SyncVectorEnv/AsyncVectorEnv of MultiStepWrapper, the batch sent as is to ``get_action``),
  ``gr00t/eval/wrappers/multistep_wrapper.py`` (_get_obs: video (T, ...), state (T, D), annotation as is),
  ``gr00t/eval/service.py`` (TorchSerializer framing), ``gr00t/experiment/data_config.py`` (PandaOmronDataConfig).
"""

from __future__ import annotations

import numpy as np
import pytest
from test_groot import GrootServer
from test_robocasa_layouts import CAMS, our_state, robocasa_convert_action, robocasa_raw_obs

from indgen_vla.core.errors import ConfigError, PolicyError
from indgen_vla.core.protocol.interface import Observation
from policy_wrappers.specs import load_policy

pytest.importorskip("torch")
pytestmark = pytest.mark.timeout(60)

# PandaOmronDataConfig (data_config.py): the keys the N1.5 server reads and writes
FORK_VIDEO = ["video.robot0_agentview_left", "video.robot0_agentview_right", "video.robot0_eye_in_hand"]
FORK_STATE = ["state.end_effector_position_relative", "state.end_effector_rotation_relative", "state.gripper_qpos",
              "state.base_position", "state.base_rotation"]  # fmt: skip
FORK_ACTION = {"action.end_effector_position": 3, "action.end_effector_rotation": 3, "action.gripper_close": 1,
               "action.base_motion": 4, "action.control_mode": 1}  # fmt: skip
FORK_LANGUAGE = "annotation.human.task_description"


def _spec():
    from scenes.robocasa import PANDA_OMRON

    return PANDA_OMRON


def gym_wrapper_observation(raw: dict, images: dict, lang: str) -> dict:
    """RoboCasaGymEnv.get_observation: get_basic_observation casts non-image values to float32; map_obs names the
    state (hand./body. prefixes become state.); each camera under get_camera_config's mapped name; the language."""
    state_of = {"gripper_qpos": "robot0_gripper_qpos", "base_position": "robot0_base_pos",
                "base_rotation": "robot0_base_quat", "end_effector_position_relative": "robot0_base_to_eef_pos",
                "end_effector_rotation_relative": "robot0_base_to_eef_quat"}  # fmt: skip
    obs = {f"state.{k}": np.asarray(raw[v]).astype(np.float32) for k, v in state_of.items()}
    obs.update({f"video.{c}": images[c] for c in CAMS})
    obs["annotation.human.task_description"] = lang
    return obs


def multistep_obs(obs: dict) -> dict:
    """MultiStepWrapper._get_obs with video_delta_indices = state_delta_indices = [0]: a time axis of one."""
    return {k: (v if k.startswith("annotation") else np.stack([v], axis=0)) for k, v in obs.items()}


def vector_obs(per_env: list[dict]) -> dict:
    """gym.vector concatenate over the MultiStepWrapper's Dict space: Box values stacked in the space's dtype (uint8
    video, float32 state), the Text value a tuple."""
    out = {}
    for key in per_env[0]:
        values = [o[key] for o in per_env]
        out[key] = tuple(values) if key.startswith("annotation") else np.stack(values)
    return out


def _obs(seed: int, lang: str) -> tuple[Observation, dict, dict]:
    rng = np.random.default_rng(seed)
    images = {c: rng.integers(0, 256, (256, 256, 3), dtype=np.uint8) for c in CAMS}
    raw = robocasa_raw_obs(rng)
    return Observation(images=images, state=our_state(raw), instruction=lang), raw, images


class ModalityConfig:  # stands for gr00t.data.dataset.ModalityConfig, a class a client without gr00t cannot load
    def __init__(self, keys):
        self.delta_indices, self.modality_keys = [0], keys


def test_the_default_keys_are_robocasa365s_gym_wrapper_and_its_forks_data_config():
    """``layouts.GROOT_ROBOCASA365``: cameras under the gym wrapper's mapped names, state and action under
    PandaOmronDataConfig's keys, in its order (the order the client concatenates the returned keys in)."""
    from policy_wrappers.layouts import GROOT_ROBOCASA_KEYS, layout_for

    layout = layout_for("groot", _spec())
    assert layout is GROOT_ROBOCASA_KEYS["robocasa365"]
    assert [f"video.{k}" for k, _ in layout.cameras] == FORK_VIDEO and all(k == c for k, c in layout.cameras)
    assert [f"state.{k}" for k, _ in layout.state] == FORK_STATE
    assert [f"action.{k}" for k, _ in layout.action] == list(FORK_ACTION)
    assert dict(layout.action) == {k.split(".", 1)[1]: n for k, n in FORK_ACTION.items()}


def test_n15_sends_what_robocasa365s_fork_evaluation_sends_and_steps_its_action():
    """Two observations in one get_action, torch.save-framed: the server receives exactly the vector env's
    MultiStepWrapper batch (keys, dtypes, shapes, values; the language a tuple), and each of our 12-d actions,
    read by RoboCasa's convert_action, is the server's action.* at that env and step (the env unmaps by key,
    the gripper and control mode thresholded by RoboCasa); all 16 steps executed (--n_action_steps 16)."""
    rng = np.random.default_rng(3)
    reply = {k: rng.normal(size=(2, 16, n)).astype(np.float32) for k, n in FORK_ACTION.items()}
    (a, raw_a, img_a), (b, raw_b, img_b) = _obs(1, "open the drawer"), _obs(2, "close the drawer")
    fork_modality = {"video": ModalityConfig(FORK_VIDEO), "state": ModalityConfig(FORK_STATE)}
    with GrootServer(lambda d: reply, modality=fork_modality, wire="torch") as srv:
        policy = load_policy(f"groot:tcp://127.0.0.1:{srv.port}?api=n1.5", env_spec=_spec())
        assert policy.spec.batched and policy.spec.image_size == (256, 256) and not policy.spec.flip_180
        assert (policy.spec.chunk_size, policy.spec.replan_steps, policy.spec.action_dim) == (16, 16, 12)
        ours = policy.act([a, b])
        policy.close()
    assert [r["endpoint"] for r in srv.requests] == ["ping", "get_modality_config", "get_action"]
    sent = srv.requests[-1]["data"]
    want = vector_obs([multistep_obs(gym_wrapper_observation(raw_a, img_a, a.instruction)),
                       multistep_obs(gym_wrapper_observation(raw_b, img_b, b.instruction))])  # fmt: skip
    assert set(sent) == set(want) == {*FORK_VIDEO, *FORK_STATE, FORK_LANGUAGE}
    for key, value in want.items():
        if key == FORK_LANGUAGE:
            assert sent[key] == value == ("open the drawer", "close the drawer")
            continue
        assert sent[key].dtype == value.dtype and sent[key].shape == value.shape, key
        np.testing.assert_array_equal(sent[key], value)
    assert sent["video.robot0_eye_in_hand"].shape == (2, 1, 256, 256, 3)
    assert ours.shape == (2, 16, 12)
    for env in range(2):
        for step in range(16):
            got = robocasa_convert_action(ours[env, step])
            for key in FORK_ACTION:
                np.testing.assert_array_equal(got[key], reply[key][env, step])


def test_n15_serializer_mismatch_and_keys_mismatch_name_the_option():
    """A msgpack client at the fork's torch.save server, and a torch client at a later (msgpack) N1.5 server, each
    fail in one line naming ?serializer=; a server declaring Isaac-GR00T's RoboCasa keys names ?keys=squarefk."""
    with GrootServer(lambda d: {}, wire="torch") as srv:
        with pytest.raises(PolicyError, match=r"torch.save archives .*add \?serializer=torch"):
            load_policy(f"groot:tcp://127.0.0.1:{srv.port}?api=n1.5&serializer=msgpack", env_spec=_spec())
    with GrootServer(lambda d: {}) as srv:
        with pytest.raises(PolicyError, match=r"answers in msgpack.*add \?serializer=msgpack"):
            load_policy(f"groot:tcp://127.0.0.1:{srv.port}?api=n1.5", env_spec=_spec())
    squarefk = {"video": {"delta_indices": [0], "modality_keys": ["res256_image_side_0", "res256_image_side_1",
                                                                  "res256_image_wrist_0"]}}  # fmt: skip
    with GrootServer(lambda d: [{}, {}], modality=squarefk) as srv:
        with pytest.raises(
            PolicyError, match=r"server expects video keys .*res256_image_side_0.*add \?keys=squarefk"
        ):
            load_policy(f"groot:tcp://127.0.0.1:{srv.port}", env_spec=_spec())
    with pytest.raises(ConfigError, match="serializer"):
        load_policy("groot:tcp://127.0.0.1:1?serializer=pickle", env_spec=_spec())


def test_n15_over_msgpack_checks_the_declared_modalities():
    """``?serializer=msgpack`` (a later N1.5 service): the declared PandaOmronDataConfig keys are checked and the
    request keeps the fork's shapes."""
    seen = {}

    def reply(data):
        seen.update(data)
        return {k: np.zeros((1, 16, n), np.float32) for k, n in FORK_ACTION.items()}

    modality = {"video": {"delta_indices": [0], "modality_keys": FORK_VIDEO},
                "state": {"delta_indices": [0], "modality_keys": FORK_STATE},
                "language": {"delta_indices": [0], "modality_keys": [FORK_LANGUAGE]}}  # fmt: skip
    with GrootServer(reply, modality=modality) as srv:
        policy = load_policy(
            f"groot:tcp://127.0.0.1:{srv.port}?api=n1.5&serializer=msgpack", env_spec=_spec()
        )
        assert policy.act([_obs(4, "wash the pan")[0]]).shape == (1, 16, 12)
        policy.close()
    assert seen["state.gripper_qpos"].shape == (1, 1, 2) and seen["state.gripper_qpos"].dtype == np.float32
    assert seen[FORK_LANGUAGE] == ["wash the pan"]  # msgpack carries the tuple as an array


def test_n16_defaults_to_robocasa365s_keys_on_robocasa():
    """N1.6 on RoboCasa365 (a RoboCasa365-fine-tuned checkpoint served with --use-sim-policy-wrapper): the same
    gym-wrapper keys at 256 px, batched N1.6 framing, 8 of 16 steps executed."""

    def reply(data):
        obs = data["observation"]
        assert set(obs) == {*FORK_VIDEO, *FORK_STATE, FORK_LANGUAGE}
        assert obs["video.robot0_agentview_left"].shape == (1, 1, 256, 256, 3)
        return [{k: np.zeros((1, 16, n), np.float32) for k, n in FORK_ACTION.items()}, {}]

    with GrootServer(reply) as srv:
        policy = load_policy(f"groot:tcp://127.0.0.1:{srv.port}", env_spec=_spec())
        assert (policy.spec.image_size, policy.spec.replan_steps) == ((256, 256), 8)
        assert policy.act([_obs(5, "x")[0]]).shape == (1, 16, 12)
        policy.close()
