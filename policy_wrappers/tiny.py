"""Tiny randomly initialised LeRobot checkpoints (ACT, Diffusion) for tests and benchmarks; no downloads."""

from __future__ import annotations


def _stats(features: dict) -> dict:
    import torch

    stats = {}
    for key, feat in features.items():
        shape = tuple(feat.shape)
        if key.startswith("observation.images."):
            stats[key] = {
                "mean": torch.full((3, 1, 1), 0.4),
                "std": torch.full((3, 1, 1), 0.25),
                "min": torch.zeros(3, 1, 1),
                "max": torch.ones(3, 1, 1),
            }
        else:
            stats[key] = {
                "mean": torch.linspace(-0.1, 0.1, shape[0]),
                "std": torch.full(shape, 0.5),
                "min": -torch.ones(shape),
                "max": torch.ones(shape),
            }
    return stats


def build_tiny_checkpoint(kind: str, out_dir, cameras=("image", "image2"), size: int = 32) -> str:
    """Randomly initialise a tiny ACT or Diffusion policy and save it with its processors, like a Hub repo."""
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.policies.factory import make_pre_post_processors

    inputs = {f"observation.images.{c}": PolicyFeature(FeatureType.VISUAL, (3, size, size)) for c in cameras}
    inputs["observation.state"] = PolicyFeature(FeatureType.STATE, (8,))
    outputs = {"action": PolicyFeature(FeatureType.ACTION, (7,))}
    if kind == "act":
        from lerobot.policies.act.configuration_act import ACTConfig
        from lerobot.policies.act.modeling_act import ACTPolicy

        cfg = ACTConfig(
            input_features=inputs,
            output_features=outputs,
            pretrained_backbone_weights=None,
            dim_model=32,
            n_heads=2,
            dim_feedforward=64,
            n_encoder_layers=1,
            n_decoder_layers=1,
            latent_dim=8,
            chunk_size=10,
            n_action_steps=10,
            use_vae=False,
            device="cpu",
        )
        policy = ACTPolicy(cfg)
    elif kind == "diffusion":
        from lerobot.policies.diffusion.configuration_diffusion import DiffusionConfig
        from lerobot.policies.diffusion.modeling_diffusion import DiffusionPolicy

        cfg = DiffusionConfig(
            input_features=inputs,
            output_features=outputs,
            pretrained_backbone_weights=None,
            n_obs_steps=2,
            horizon=8,
            n_action_steps=4,
            down_dims=(16, 32),
            kernel_size=3,
            n_groups=4,
            diffusion_step_embed_dim=16,
            spatial_softmax_num_keypoints=8,
            crop_shape=None,
            use_group_norm=True,
            num_inference_steps=3,
            device="cpu",
        )
        policy = DiffusionPolicy(cfg)
    else:
        raise ValueError(kind)
    pre, post = make_pre_post_processors(cfg, dataset_stats=_stats({**inputs, **outputs}))
    out_dir = str(out_dir)
    policy.save_pretrained(out_dir)
    pre.save_pretrained(out_dir)
    post.save_pretrained(out_dir)
    return out_dir


def build_tiny_vlm_dir(out_dir) -> str:
    """A local stand-in for SmolVLA's ``vlm_model_name``: tiny SmolVLM config + char-level tokenizer + processor.

    Needs ``num2words`` (transformers' SmolVLMProcessor imports it; it is part of ``lerobot[smolvla]``).
    """
    from tokenizers import Tokenizer, models, pre_tokenizers
    from transformers import PreTrainedTokenizerFast
    from transformers.models.smolvlm import (
        SmolVLMConfig,
        SmolVLMImageProcessor,
        SmolVLMProcessor,
        SmolVLMVideoProcessor,
    )

    words = ["<unk>", "<pad>", "<|im_start|>", "<end_of_utterance>"] + [chr(c) for c in range(32, 127)]
    backend = Tokenizer(models.WordLevel({w: i for i, w in enumerate(words)}, unk_token="<unk>"))
    backend.pre_tokenizer = pre_tokenizers.Split("", "isolated")
    special = {
        "fake_image_token": "<fake_token_around_image>",
        "image_token": "<image>",
        "global_image_token": "<global-img>",
        "end_of_utterance_token": "<end_of_utterance>",
    }
    tok = PreTrainedTokenizerFast(
        tokenizer_object=backend,
        unk_token="<unk>",
        pad_token="<pad>",
        bos_token="<|im_start|>",
        eos_token="<end_of_utterance>",
        extra_special_tokens=special,
    )
    tok.add_special_tokens(
        {"additional_special_tokens": ["<fake_token_around_image>", "<image>", "<global-img>"]}
    )
    config = SmolVLMConfig(
        text_config=dict(
            model_type="llama",
            hidden_size=64,
            intermediate_size=128,
            num_hidden_layers=2,
            num_attention_heads=2,
            num_key_value_heads=1,
            head_dim=32,
            vocab_size=len(tok),
        ),
        vision_config=dict(
            hidden_size=32,
            intermediate_size=64,
            num_hidden_layers=1,
            num_attention_heads=2,
            image_size=64,
            patch_size=16,
        ),
        scale_factor=2,
        image_token_id=tok.convert_tokens_to_ids("<image>"),
    )
    image_proc = SmolVLMImageProcessor(
        size={"longest_edge": 64}, max_image_size={"longest_edge": 64}, do_image_splitting=False
    )
    out_dir = str(out_dir)
    config.save_pretrained(out_dir)
    SmolVLMProcessor(
        image_processor=image_proc, tokenizer=tok, video_processor=SmolVLMVideoProcessor(), image_seq_len=4
    ).save_pretrained(out_dir)
    return out_dir


def build_tiny_smolvla(out_dir, vlm_dir, cameras=("image", "image2"), size: int = 32) -> str:
    """A tiny randomly initialised SmolVLA whose backbone and tokenizer come from ``vlm_dir`` (no downloads)."""
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.policies.factory import make_pre_post_processors
    from lerobot.policies.smolvla.configuration_smolvla import SmolVLAConfig
    from lerobot.policies.smolvla.modeling_smolvla import SmolVLAPolicy

    inputs = {f"observation.images.{c}": PolicyFeature(FeatureType.VISUAL, (3, size, size)) for c in cameras}
    inputs["observation.state"] = PolicyFeature(FeatureType.STATE, (8,))
    outputs = {"action": PolicyFeature(FeatureType.ACTION, (7,))}
    cfg = SmolVLAConfig(
        input_features=inputs,
        output_features=outputs,
        vlm_model_name=str(vlm_dir),
        load_vlm_weights=False,
        resize_imgs_with_padding=(64, 64),
        chunk_size=10,
        n_action_steps=5,
        num_steps=2,
        num_vlm_layers=2,
        tokenizer_max_length=16,
        device="cpu",
    )
    policy = SmolVLAPolicy(cfg)
    pre, post = make_pre_post_processors(cfg, dataset_stats=_stats({**inputs, **outputs}))
    out_dir = str(out_dir)
    for obj in (policy, pre, post):
        obj.save_pretrained(out_dir)
    return out_dir
