"""The lerobot adapter on tiny random ACT / Diffusion checkpoints, loaded offline like a Hub id."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from indgen_vla.core.errors import ConfigError, PolicyError
from policy_wrappers.specs import load_policy

pytest.importorskip("lerobot")
pytestmark = pytest.mark.timeout(120)


def test_act_loads_by_hub_id_offline_and_acts(tiny_act, hub_cache, obs_factory):
    hub_cache(tiny_act, "indgen-test/tiny-act")
    policy = load_policy("lerobot:indgen-test/tiny-act")
    spec = policy.spec
    assert (spec.chunk_size, spec.replan_steps, spec.image_size, spec.batched) == (10, 10, (32, 32), True)
    assert spec.cameras == ("agentview", "wrist") and spec.flip_180  # LIBERO names image/image2
    policy.reset("put the bowl on the plate", seed=0)
    obs = [obs_factory(i) for i in range(3)]  # 256x256 renders, resized to the declared 32x32
    chunk = policy.act(obs)
    assert chunk.shape == (3, 10, 7) and chunk.dtype == np.float32 and np.all(np.isfinite(chunk))
    one_by_one = np.concatenate([policy.act([o]) for o in obs])
    assert np.allclose(chunk, one_by_one, atol=1e-5)
    with pytest.raises(PolicyError) as e:
        load_policy("lerobot:indgen-test/not-there")
    assert str(e.value) == (  # one sentence of ours: the Hub's own ("check your connection ...") dropped
        "policy lerobot:indgen-test/not-there: 'indgen-test/not-there' is not in the local cache and HF_HUB_OFFLINE "
        "is set; fetch it once online (hf download indgen-test/not-there) or pass a local pretrained_model directory"
    )


def test_to_batch_matches_lerobot_env_pipeline(tiny_act, obs_factory):
    """Our conversion == lerobot's preprocess_observation + LIBERO env processor (flip H and W)."""
    import torch
    from lerobot.envs.utils import preprocess_observation

    policy = load_policy(f"lerobot:{tiny_act}")
    obs = [obs_factory(i, size=32) for i in range(2)]
    ours = policy.to_batch(obs)
    env_obs = {
        "pixels": {
            "image": np.stack([o.images["agentview"] for o in obs]),
            "image2": np.stack([o.images["wrist"] for o in obs]),
        },
        "agent_pos": np.stack([o.state for o in obs]),
    }
    ref = preprocess_observation(env_obs)
    for key in ("observation.images.image", "observation.images.image2"):
        assert torch.equal(ours[key], torch.flip(ref[key], dims=[2, 3]))
    assert torch.equal(ours["observation.state"], ref["observation.state"])
    assert ours["task"] == [o.instruction for o in obs]


def test_act_chunk_matches_select_action(tiny_act, obs_factory):
    """The chunk we return starts with what lerobot's own select_action would execute."""
    import torch

    policy = load_policy(f"lerobot:{tiny_act}")
    obs = [obs_factory(7, size=32)]
    chunk = policy.act(obs)
    policy.reset(obs[0].instruction)
    with torch.inference_mode():
        first = policy.post(policy.policy.select_action(policy.pre(policy.to_batch(obs))))
    assert np.allclose(chunk[:, 0], first.numpy(), atol=1e-5)


def test_act_temporal_ensemble_follows_select_action(tiny_act, tmp_path, obs_factory):
    """ACT with temporal_ensemble_coeff: one ensembled action per step, as lerobot's ACTPolicy.select_action."""
    import json
    import shutil

    import torch

    ckpt = tmp_path / "act_te"
    shutil.copytree(tiny_act, ckpt)
    cfg = json.loads((ckpt / "config.json").read_text())
    cfg.update(temporal_ensemble_coeff=0.01, n_action_steps=1)
    (ckpt / "config.json").write_text(json.dumps(cfg))
    ours = ref = load_policy(f"lerobot:{ckpt}")
    assert (ours.spec.chunk_size, ours.spec.replan_steps, ours.spec.batched) == (1, 1, False)
    seq = [[obs_factory(i, size=32)] for i in range(4)]
    ours.reset("x")
    got = [ours.act(o) for o in seq]
    ref.policy.reset()  # lerobot's own loop on the same model from here
    with torch.inference_mode():
        want = [ref.post(ref.policy.select_action(ref.pre(ref.to_batch(o)))).numpy() for o in seq]
        firsts = [
            ref.post(ref.policy.predict_action_chunk(ref.pre(ref.to_batch(o)))[:, 0]).numpy() for o in seq
        ]
    for g, w in zip(got, want, strict=True):
        assert g.shape == (1, 1, 7) and np.allclose(g[:, 0], w, atol=1e-5)
    assert not np.allclose(
        got[-1][:, 0], firsts[-1], atol=1e-4
    )  # the ensemble is not the newest chunk's head


def test_diffusion_history_and_seed_match_select_action(tiny_diffusion, obs_factory):
    """A history policy is asked every step and follows lerobot's select_action step for step."""
    pytest.importorskip("diffusers")
    import torch

    policy = load_policy(f"lerobot:{tiny_diffusion}")
    assert not policy.spec.batched and policy.n_obs_steps == 2
    assert (policy.spec.chunk_size, policy.spec.replan_steps) == (4, 1)
    seq = [[obs_factory(i, size=32)] for i in range(6)]  # six different consecutive observations
    policy.reset("x", seed=3)
    ours = [policy.act(o) for o in seq]
    assert [c.shape[1] for c in ours] == [4, 3, 2, 1, 4, 3]  # the remaining queue, replanned when empty
    policy.reset("x", seed=3)
    assert np.array_equal(ours[0], policy.act(seq[0]))  # the episode seed fixes the diffusion noise
    policy.reset("x", seed=3)
    torch.manual_seed(3)  # lerobot draws from the global generator, which our instance leaves alone
    with torch.inference_mode():
        theirs = [
            policy.post(policy.policy.select_action(policy.pre(policy.to_batch(o)))).numpy() for o in seq
        ]
    for c, t in zip(ours, theirs, strict=True):
        assert np.allclose(c[:, 0], t, atol=1e-5)


def test_camera_map_and_errors(tmp_path, obs_factory):
    from conftest import build_tiny_checkpoint

    ckpt = build_tiny_checkpoint("act", tmp_path / "cams", cameras=("top", "gripper"), size=16)
    with pytest.raises(ConfigError, match=r"\?cameras=top:agentview"):
        load_policy(f"lerobot:{ckpt}")
    policy = load_policy(f"lerobot:{ckpt}?cameras=gripper:wrist,top:agentview&flip=0&replan=4")
    assert not policy.spec.flip_180 and policy.spec.replan_steps == 4 and policy.spec.image_size == (16, 16)
    assert policy.act([obs_factory(0)]).shape == (1, 10, 7)
    with pytest.raises(ConfigError, match="lacks"):
        load_policy(f"lerobot:{ckpt}?cameras=front:agentview,gripper:wrist")
    with pytest.raises(PolicyError, match="no such checkpoint directory"):
        load_policy(f"lerobot:{tmp_path}/missing")
    with pytest.raises(PolicyError, match="no config.json"):
        load_policy(f"lerobot:{tmp_path}")
    with pytest.raises(ConfigError, match="exceeds"):
        load_policy(f"lerobot:{ckpt}?cameras=gripper:wrist,top:agentview&replan=11")


def test_standin_checkpoint_dir_delegates(tiny_act, obs_factory):
    policy = load_policy(f"standin:{tiny_act}")
    assert policy.spec.family == "standin" and policy.act([obs_factory()]).shape == (1, 10, 7)


def test_tiny_smolvla_with_local_backbone(tmp_path, hub_cache, obs_factory):
    """SmolVLA through the Hub-id path, its VLM config + tokenizer from a local dir (``?vlm=`` relocates it)."""
    pytest.importorskip(
        "num2words", reason="transformers' SmolVLMProcessor needs num2words (lerobot[smolvla])"
    )
    from tests.fixtures.tiny_policies import build_tiny_smolvla, build_tiny_vlm_dir

    vlm = build_tiny_vlm_dir(tmp_path / "vlm")
    hub_cache(build_tiny_smolvla(tmp_path / "smolvla", vlm), "indgen-test/tiny-smolvla")
    moved = shutil.move(vlm, tmp_path / "vlm-moved")
    with pytest.raises(PolicyError, match="cannot load"):
        load_policy("lerobot:indgen-test/tiny-smolvla")  # the saved vlm_model_name no longer exists
    policy = load_policy(f"lerobot:indgen-test/tiny-smolvla?vlm={moved}")
    assert (policy.spec.chunk_size, policy.spec.replan_steps, policy.spec.batched) == (10, 5, True)
    policy.reset("pick up the bowl", seed=0)
    chunk = policy.act([obs_factory(0), obs_factory(1)])
    policy.reset("pick up the bowl", seed=0)
    assert chunk.shape == (2, 10, 7) and np.array_equal(chunk, policy.act([obs_factory(0), obs_factory(1)]))


def test_a_typo_in_a_local_checkpoint_path_names_the_near_directory(tmp_path, monkeypatch):
    """`lerobot:checkpoints/act_pick_place_humn` (one slash, so it also reads as a Hub id) used to fail with
    the Hub's "cannot find the requested files in the local cache"; it now names the directory meant."""
    (tmp_path / "checkpoints" / "act_pick_place_human").mkdir(parents=True)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    with pytest.raises(PolicyError, match=r"did you mean 'checkpoints/act_pick_place_human'\?$"):
        load_policy("lerobot:checkpoints/act_pick_place_humn")


def test_an_episode_noise_does_not_depend_on_other_instances(tiny_diffusion, obs_factory):
    """Per-environment instances (one per slot, acting from threads) draw their episodes' diffusion noise from their
    own streams: another instance's reset and acts in between change no action (seen before: torch's global
    generator was shared, so with two slots an episode's noise depended on the other slot's schedule)."""
    pytest.importorskip("diffusers")
    a, b = load_policy(f"lerobot:{tiny_diffusion}"), load_policy(f"lerobot:{tiny_diffusion}")
    seq = [[obs_factory(i, size=32)] for i in range(5)]  # the chunk is 4: two predictions each
    a.reset("x", seed=3)
    alone = [a.act(o) for o in seq]
    a.reset("x", seed=3)
    b.reset("x", seed=4)
    for k, o in enumerate(seq):
        np.testing.assert_array_equal(a.act(o), alone[k], err_msg=f"step {k}")
        b.act(o)
