"""Each policy family's RoboCasa365 convention against its upstream formula (never against our helpers).

Our native RoboCasa365 vectors follow RoboCasa's own code: robocasa v1.0.1 ``robocasa/utils/env_utils.py``
``convert_action`` splits the flat action arm first (end_effector_position 0:3, end_effector_rotation 3:6,
gripper_close 6:7, base_motion 7:11, control_mode 11:12) and our state is robot0_base_to_eef_pos (3),
robot0_base_to_eef_quat (4), robot0_base_pos (3), robot0_base_quat (4), robot0_gripper_qpos (2)
(scenes/robocasa/backend.py ``step``). The expected values below are those upstream formulas written out.
"""

from __future__ import annotations

import numpy as np
import pytest

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import TABLETOP, Observation

CAMS = ("robot0_agentview_left", "robot0_agentview_right", "robot0_eye_in_hand")


def _spec():
    from scenes.robocasa import PANDA_OMRON

    return PANDA_OMRON


def robocasa_convert_action(flat: np.ndarray) -> dict:
    """robocasa/robocasa (v1.0.1, be22d659) robocasa/utils/env_utils.py ``convert_action``, verbatim slices."""
    return {
        "action.end_effector_position": flat[0:3],
        "action.end_effector_rotation": flat[3:6],
        "action.gripper_close": flat[6:7],
        "action.base_motion": flat[7:11],
        "action.control_mode": flat[11:12],
    }


def robocasa_raw_obs(rng) -> dict:
    """The robosuite observation keys RoboCasa's gym wrapper reads (PandaOmronKeyConverter.map_obs)."""
    return {
        "robot0_base_to_eef_pos": rng.normal(size=3), "robot0_base_to_eef_quat": rng.normal(size=4),
        "robot0_base_pos": rng.normal(size=3), "robot0_base_quat": rng.normal(size=4),
        "robot0_gripper_qpos": rng.normal(size=2),
    }  # fmt: skip


def our_state(raw: dict) -> np.ndarray:
    """Our 16-d state as scenes/robocasa/backend.py ``step`` concatenates it."""
    keys = ("robot0_base_to_eef_pos", "robot0_base_to_eef_quat", "robot0_base_pos", "robot0_base_quat",
            "robot0_gripper_qpos")  # fmt: skip
    return np.concatenate([raw[k] for k in keys]).astype(np.float32)


def test_the_native_action_is_robocasas_convert_action_order():
    """Our EnvSpec's action_parts, sliced in order, are RoboCasa's convert_action dict."""
    spec, flat = _spec(), np.arange(12.0)
    upstream, lo = robocasa_convert_action(flat), 0
    for name, size in spec.action_parts:
        np.testing.assert_array_equal(upstream[f"action.{name}"], flat[lo : lo + size])
        lo += size


def test_lerobot_state_and_action_follow_lerobots_robocasa_wrapper():
    """huggingface/lerobot 0.6.1 src/lerobot/envs/robocasa.py: ``_format_raw_obs`` builds agent_pos from
    state.base_position, state.base_rotation, state.end_effector_position_relative,
    state.end_effector_rotation_relative, state.gripper_qpos (PandaOmronKeyConverter.map_obs: robot0_base_pos,
    robot0_base_quat, robot0_base_to_eef_pos, robot0_base_to_eef_quat, robot0_gripper_qpos); ``convert_action``
    reads base_motion 0:4, control_mode 4:5, end_effector_position 5:8, end_effector_rotation 8:11, gripper 11:12."""
    from lerobot.envs.robocasa import convert_action as lerobot_convert_action

    from policy_wrappers.layouts import layout_for

    spec = _spec()
    layout = layout_for("lerobot", spec)
    raw = robocasa_raw_obs(np.random.default_rng(0))
    agent_pos = np.concatenate([raw["robot0_base_pos"], raw["robot0_base_quat"], raw["robot0_base_to_eef_pos"],
                                raw["robot0_base_to_eef_quat"], raw["robot0_gripper_qpos"]]).astype(np.float32)  # fmt: skip
    np.testing.assert_array_equal(layout.state_to_policy(spec)(our_state(raw)), agent_pos)
    theirs = np.random.default_rng(1).normal(size=(2, 3, 12))  # a (B, T, 12) chunk in lerobot's order
    ours = layout.action_to_scene(spec)(theirs)
    for b in range(2):
        for t in range(3):
            want, got = lerobot_convert_action(theirs[b, t]), robocasa_convert_action(ours[b, t])
            assert set(want) == set(got)
            for key in want:
                np.testing.assert_array_equal(got[key], want[key])
    assert dict(layout.cameras) == {c: c for c in CAMS}  # envs/configs.py: observation.images.<raw name>


def test_openpi_and_groot_layouts_follow_their_upstream_clients():
    """openpi: robocasa-benchmark/openpi examples/robocasa/main.py (read from its copy J-Oyasumi/openpi_robocasa;
    TRI-ML/openpi-priors' examples/robocasa/main.py has the same state order, resize, replan and convert_action)
    sends state = concat(state.end_effector_position_relative, state.end_effector_rotation_relative,
    state.base_position, state.base_rotation, state.gripper_qpos) and steps ``convert_action(action)`` (RoboCasa's,
    arm first). GR00T: squarefk/robocasa robocasa/models/robots/__init__.py PandaOmronKeyConverter.unmap_action
    reads action.end_effector_position/rotation, gripper_close, base_motion, control_mode by key."""
    from policy_wrappers.layouts import layout_for

    spec = _spec()
    raw = robocasa_raw_obs(np.random.default_rng(2))
    openpi = layout_for("openpi", spec)
    sent = np.concatenate([raw["robot0_base_to_eef_pos"], raw["robot0_base_to_eef_quat"], raw["robot0_base_pos"],
                           raw["robot0_base_quat"], raw["robot0_gripper_qpos"]]).astype(np.float32)  # fmt: skip
    np.testing.assert_array_equal(openpi.state_to_policy(spec)(our_state(raw)), sent)
    flat = np.arange(12.0)
    np.testing.assert_array_equal(openpi.action_to_scene(spec)(flat), flat)  # convert_action's own order
    assert dict(openpi.cameras) == {"observation/image": "robot0_agentview_left",
                                    "observation/wrist_image": "robot0_eye_in_hand",
                                    "observation/right_image": "robot0_agentview_right"}  # fmt: skip
    from policy_wrappers.layouts import GROOT_SQUAREFK

    assert dict(GROOT_SQUAREFK.cameras) == {"res256_image_side_0": "robot0_agentview_left",
                                   "res256_image_side_1": "robot0_agentview_right",
                                   "res256_image_wrist_0": "robot0_eye_in_hand"}  # fmt: skip


def test_layouts_are_chosen_by_the_scene_family():
    from policy_wrappers.layouts import layout_for

    assert layout_for("lerobot", TABLETOP) is None and layout_for("lerobot", None) is None
    with pytest.raises(
        ConfigError, match="openvla-oft has no convention for scene family robocasa_panda_omron"
    ):
        layout_for("openvla-oft", _spec())


@pytest.mark.parametrize(
    "spec", ["openvla-oft:http://127.0.0.1:9", "univla:ws://127.0.0.1:9", "rynnvla:ws://127.0.0.1:9"]
)
def test_a_libero_only_family_is_refused_on_robocasa_before_it_connects(spec):
    """Nothing listens on port 9: the refusal names the missing convention, not a refused connection (a user who
    then starts the server would only be refused later)."""
    from policy_wrappers.specs import load_policy

    with pytest.raises(ConfigError, match="has no convention for scene family robocasa_panda_omron"):
        load_policy(spec, env_spec=_spec())


def _robocasa_obs(seed: int, size: int = 16) -> tuple[Observation, dict]:
    """An observation in our layout and the robosuite keys it came from."""
    rng = np.random.default_rng(seed)
    images = {c: rng.integers(0, 256, (size, size, 3), dtype=np.uint8) for c in CAMS}
    raw = robocasa_raw_obs(rng)
    return Observation(images=images, state=our_state(raw), instruction="open the cabinet"), raw


@pytest.fixture(scope="module")
def tiny_robocasa_act(tmp_path_factory) -> str:
    """A random-init ACT with RoboCasa365's feature names (lerobot's robocasa env): three raw camera names,
    16-d observation.state, 12-d action."""
    pytest.importorskip("lerobot")
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

    out = tmp_path_factory.mktemp("robocasa_act")
    return build_tiny_checkpoint("act", out, cameras=CAMS, size=16, state_dim=16, action_dim=12)


def test_a_lerobot_robocasa_checkpoint_gets_lerobots_state_and_returns_our_action(tiny_robocasa_act):
    """The wrapper feeds the checkpoint lerobot's agent_pos and its images under the raw camera names, and turns
    the checkpoint's base-first chunk into our arm-first one: the same model, called the way lerobot-eval calls
    it (its batch built by lerobot's formula), gives lerobot's action dict, which equals RoboCasa's dict of ours."""
    import torch
    from lerobot.envs.robocasa import convert_action as lerobot_convert_action

    from policy_wrappers.specs import load_policy

    policy = load_policy(f"lerobot:{tiny_robocasa_act}", env_spec=_spec())
    assert policy.spec.action_dim == 12 and set(policy.spec.cameras) == set(CAMS) and not policy.spec.flip_180
    assert policy.layout.name.startswith("lerobot-robocasa")
    (obs, raw), (other, _) = _robocasa_obs(3), _robocasa_obs(4)
    ours = policy.act([obs, other])
    agent_pos = np.concatenate([raw["robot0_base_pos"], raw["robot0_base_quat"], raw["robot0_base_to_eef_pos"],
                                raw["robot0_base_to_eef_quat"], raw["robot0_gripper_qpos"]]).astype(np.float32)  # fmt: skip
    batch = {
        f"observation.images.{c}": torch.from_numpy(obs.images[c]).permute(2, 0, 1)[None].float() / 255
        for c in CAMS
    }  # fmt: skip  (lerobot envs/utils.py preprocess_observation: HWC uint8 -> CHW [0, 1])
    batch["observation.state"] = torch.from_numpy(agent_pos)[None]
    batch["task"] = ["open the cabinet"]
    with torch.inference_mode():
        theirs = policy.post(policy.policy.predict_action_chunk(policy.pre(batch))).numpy()[0]
    for t in range(ours.shape[1]):
        want, got = lerobot_convert_action(theirs[t]), robocasa_convert_action(ours[0, t])
        for key in want:
            np.testing.assert_allclose(got[key], want[key], atol=1e-5)
    policy.close()


def test_a_lerobot_robocasa_checkpoint_is_refused_on_the_tabletop(tiny_robocasa_act):
    from indgen_vla.core.errors import PolicyError
    from policy_wrappers.specs import load_policy

    with pytest.raises((PolicyError, ConfigError), match="don't know which camera|shape \\(12,\\)"):
        load_policy(f"lerobot:{tiny_robocasa_act}", env_spec=TABLETOP)


def upstream_groot_process_img(img: np.ndarray) -> np.ndarray:
    """squarefk/robocasa robocasa/utils/gym_utils/gymnasium_groot.py ``GrootRoboCasaEnv.process_img``, as written
    upstream (FINAL_IMAGE_RESOLUTION = (256, 256); the INTER_AREA lands in ``dst``)."""
    import cv2

    h, w, _ = img.shape
    if h != w:
        dim = max(h, w)
        y_offset, x_offset = (dim - h) // 2, (dim - w) // 2
        img = np.pad(img, ((y_offset, y_offset), (x_offset, x_offset), (0, 0)))
        h, w = dim, dim
    if (h, w) != (256, 256):
        img = cv2.resize(img, (256, 256), cv2.INTER_AREA)
    return np.copy(img)


GROOT_STATE = {  # squarefk/robocasa PandaOmronKeyConverter.map_obs: state.<name> <- robosuite key
    "gripper_qpos": "robot0_gripper_qpos", "base_position": "robot0_base_pos", "base_rotation": "robot0_base_quat",
    "end_effector_position_relative": "robot0_base_to_eef_pos",
    "end_effector_rotation_relative": "robot0_base_to_eef_quat",
}  # fmt: skip
GROOT_ACTION = {"end_effector_position": 3, "end_effector_rotation": 3, "gripper_close": 1, "base_motion": 4,
                "control_mode": 1}  # fmt: skip


def test_groot_n16_on_robocasa_sends_groots_keys_and_returns_robocasas_action():
    """``?keys=squarefk``, a loopback N1.6 server declaring ROBOCASA_PANDA_OMRON's modalities: the client sends video.res256_* (our
    512 renders through GR00T's process_img), state.<name> (map_obs), and our action is RoboCasa's own
    convert_action order of the returned action.<name> keys (unmap_action reads them by key)."""
    from test_groot import GrootServer

    from policy_wrappers.specs import load_policy

    modality = {
        "video": {"delta_indices": [0], "modality_keys": ["res256_image_side_0", "res256_image_side_1",
                                                            "res256_image_wrist_0"]},
        "state": {"delta_indices": [0], "modality_keys": list(GROOT_STATE)},
        "action": {"delta_indices": list(range(16)), "modality_keys": list(GROOT_ACTION)},
        "language": {"delta_indices": [0], "modality_keys": ["annotation.human.action.task_description"]},
    }  # fmt: skip
    rng = np.random.default_rng(5)
    reply_actions = {
        f"action.{k}": rng.normal(size=(1, 16, n)).astype(np.float32) for k, n in GROOT_ACTION.items()
    }

    def reply(data):
        return [reply_actions, {}]

    rng = np.random.default_rng(6)
    images = {c: rng.integers(0, 256, (512, 512, 3), dtype=np.uint8) for c in CAMS}
    raw = robocasa_raw_obs(rng)
    obs = Observation(images=images, state=our_state(raw), instruction="close the stand mixer head")
    with GrootServer(reply, modality=modality) as srv:
        policy = load_policy(f"groot:tcp://127.0.0.1:{srv.port}?keys=squarefk", env_spec=_spec())
        assert policy.spec.image_size == (512, 512) and (
            policy.spec.chunk_size,
            policy.spec.replan_steps,
        ) == (16, 8)
        assert set(policy.spec.cameras) == set(CAMS) and policy.spec.action_dim == 12
        ours = policy.act([obs])
        policy.close()
    sent = srv.requests[-1]["data"]["observation"]
    for key, cam in (("side_0", "robot0_agentview_left"), ("side_1", "robot0_agentview_right"),
                     ("wrist_0", "robot0_eye_in_hand")):  # fmt: skip
        np.testing.assert_array_equal(
            sent[f"video.res256_image_{key}"][0, 0], upstream_groot_process_img(images[cam])
        )
    for name, robosuite_key in GROOT_STATE.items():
        np.testing.assert_allclose(sent[f"state.{name}"][0, 0], raw[robosuite_key], rtol=1e-6)
    assert sent["annotation.human.action.task_description"] == ["close the stand mixer head"]
    got = robocasa_convert_action(ours[0, 0])
    for name in GROOT_ACTION:
        np.testing.assert_allclose(got[f"action.{name}"], reply_actions[f"action.{name}"][0, 0])


def test_groot_on_robocasa_refuses_n15_with_squarefk_keys_and_a_server_wanting_other_state():
    from test_groot import GrootServer

    from indgen_vla.core.errors import PolicyError
    from policy_wrappers.specs import load_policy

    with pytest.raises(ConfigError, match="keys=squarefk is Isaac-GR00T N1.6's RoboCasa set-up"):
        load_policy("groot:tcp://127.0.0.1:1?api=n1.5&keys=squarefk", env_spec=_spec())
    modality = {"state": {"delta_indices": [0], "modality_keys": ["joint_position", "gripper_qpos"]}}
    with GrootServer(lambda d: None, modality=modality) as srv:
        with pytest.raises(PolicyError, match="server expects state keys"):
            load_policy(f"groot:tcp://127.0.0.1:{srv.port}", env_spec=_spec())


def test_openpi_on_robocasa_sends_robocasa365s_client_request():
    """robocasa-benchmark/openpi examples/robocasa/main.py (its copy J-Oyasumi/openpi_robocasa): images
    video.robot0_agentview_left / _eye_in_hand / _agentview_right through openpi_client's resize_with_pad(224),
    state = concat(state.end_effector_position_relative, state.end_effector_rotation_relative, state.base_position,
    state.base_rotation, state.gripper_qpos), replan_steps 5, and each action stepped as convert_action(action)."""
    from test_openpi import (
        openpi_resize_with_pad,
        openpi_server,
    )  # openpi_client's resize_with_pad, written out

    from policy_wrappers.specs import load_policy

    seen = []
    actions = np.random.default_rng(7).normal(size=(10, 12)).astype(np.float32)
    rng = np.random.default_rng(8)
    images = {c: rng.integers(0, 256, (256, 256, 3), dtype=np.uint8) for c in CAMS}
    raw = robocasa_raw_obs(rng)
    obs = Observation(images=images, state=our_state(raw), instruction="turn on the kettle")
    with openpi_server(lambda o: {"actions": actions}, seen) as srv:
        policy = load_policy(f"openpi:ws://127.0.0.1:{srv.port}", env_spec=_spec())
        assert (policy.spec.replan_steps, policy.spec.flip_180, policy.spec.image_size) == (
            5,
            False,
            (256, 256),
        )
        ours = policy.act([obs])
        policy.close()
    req = seen[0]
    assert set(req) == {"observation/image", "observation/wrist_image", "observation/right_image",
                        "observation/state", "prompt"}  # fmt: skip
    for key, cam in (("image", "robot0_agentview_left"), ("wrist_image", "robot0_eye_in_hand"),
                     ("right_image", "robot0_agentview_right")):  # fmt: skip
        want = openpi_resize_with_pad(images[cam], 224, 224)  # upright: no flip, unlike the LIBERO client
        np.testing.assert_array_equal(req[f"observation/{key}"], want)
    state = np.concatenate([raw["robot0_base_to_eef_pos"], raw["robot0_base_to_eef_quat"], raw["robot0_base_pos"],
                            raw["robot0_base_quat"], raw["robot0_gripper_qpos"]]).astype(np.float32)  # fmt: skip
    np.testing.assert_array_equal(req["observation/state"], state)
    assert req["prompt"] == "turn on the kettle"
    for t in range(
        10
    ):  # the client steps convert_action(action): ours must be that action in RoboCasa's order
        want, got = robocasa_convert_action(actions[t]), robocasa_convert_action(ours[0, t])
        for key in want:
            np.testing.assert_array_equal(got[key], want[key])
