"""Build pi0.5 (lerobot ``PI05Policy``: PaliGemma gemma_2b + SigLIP-So400m + a gemma_300m action expert) and
SmolVLA (SmolVLM2-500M's first 16 layers + its action expert) at their real sizes, randomly initialised and
offline (no weights are downloaded), into local directories that ``lerobot:<dir>`` loads like a Hub checkpoint.

    python scripts/build_real_size.py pi05 OUT [--reduced] [--device cuda]
    python scripts/build_real_size.py smolvla OUT [--reduced]

The tokenizers are local stand-ins (a word-level vocabulary written here): pi0.5 pads every prompt to its
``tokenizer_max_length`` (200 tokens) and SmolVLA to 48, so the model's compute does not depend on which tokenizer
made the ids. pi0.5's saved preprocessor names the upstream tokenizer (``google/paligemma-3b-pt-224``) as a Hub
checkpoint does; the printed spec points the wrapper's ``tokenizer=`` option at the local one. ``--reduced``:
the same code paths at a few layers and tiny widths (``policy_wrappers/lerobot_variants.py``), for CPU tests.
Speeds of the real-size models: ``scripts/bench_engine.py --only model`` and docs/results/benchmarks/gpu.md.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
from pathlib import Path

os.environ.setdefault("HF_HUB_OFFLINE", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

PALIGEMMA_TOKENIZER = "google/paligemma-3b-pt-224"  # what pi0.5's processor names (lerobot processor_pi05.py)
CAMERAS = {"pi05": ("base_0_rgb", "left_wrist_0_rgb"), "smolvla": ("front", "wrist")}
# HuggingFaceTB/SmolVLM2-500M-Video-Instruct's config.json (SmolLM2-360M text model, SigLIP-B/16-512 vision)
SMOLVLM2_500M = {
    "text": dict(model_type="llama", hidden_size=960, intermediate_size=2560, num_hidden_layers=32,
                 num_attention_heads=15, num_key_value_heads=5, head_dim=64, vocab_size=49280,
                 max_position_embeddings=8192, rope_theta=100000.0, rms_norm_eps=1e-5),
    "vision": dict(hidden_size=768, intermediate_size=3072, num_hidden_layers=12, num_attention_heads=12,
                   image_size=512, patch_size=16),
    "scale_factor": 4,
}  # fmt: skip
TINY_SMOLVLM = {
    "text": dict(model_type="llama", hidden_size=64, intermediate_size=128, num_hidden_layers=2,
                 num_attention_heads=2, num_key_value_heads=1, head_dim=32),
    "vision": dict(hidden_size=32, intermediate_size=64, num_hidden_layers=1, num_attention_heads=2,
                   image_size=64, patch_size=16),
    "scale_factor": 2,
}  # fmt: skip


def _stats(features: dict) -> dict:
    """Normalisation statistics of plausible magnitude (images in [0, 1], state/actions around 0)."""
    import torch

    out = {}
    for key, feat in features.items():
        shape = tuple(feat.shape)
        if key.startswith("observation.images."):
            out[key] = {"mean": torch.full((3, 1, 1), 0.4), "std": torch.full((3, 1, 1), 0.25),
                        "min": torch.zeros(3, 1, 1), "max": torch.ones(3, 1, 1),
                        "q01": torch.zeros(3, 1, 1), "q99": torch.ones(3, 1, 1)}  # fmt: skip
        else:
            out[key] = {"mean": torch.zeros(shape), "std": torch.full(shape, 0.5), "min": -torch.ones(shape),
                        "max": torch.ones(shape), "q01": -torch.ones(shape), "q99": torch.ones(shape)}  # fmt: skip
    return out


def build_tokenizer(out_dir: Path | None, extra_tokens: tuple[str, ...] = (), **kw):
    """A word-level tokenizer (pad 0, eos 1, bos 2; words, digits and punctuation), saved to ``out_dir``."""
    from tokenizers import Tokenizer, models, normalizers, pre_tokenizers
    from transformers import PreTrainedTokenizerFast

    words = ["<pad>", "<eos>", "<bos>", "<unk>", *extra_tokens]
    words += [str(i) for i in range(256)] + list(".,;:!?'\"()-_/\n")
    words += ("task state action pick place put the a an up on in into of to and with from milk bowl cube "
              "block cabinet drawer open close top bottom left right red green blue plate basket").split()  # fmt: skip
    words = list(dict.fromkeys(words))
    backend = Tokenizer(models.WordLevel({w: i for i, w in enumerate(words)}, unk_token="<unk>"))
    backend.normalizer = normalizers.Lowercase()
    backend.pre_tokenizer = pre_tokenizers.Sequence(
        [pre_tokenizers.WhitespaceSplit(), pre_tokenizers.Punctuation(), pre_tokenizers.Digits(True)]
    )
    kw = {"pad_token": "<pad>", "eos_token": "<eos>", "bos_token": "<bos>", "unk_token": "<unk>", **kw}
    tok = PreTrainedTokenizerFast(tokenizer_object=backend, **kw)
    if out_dir is not None:
        tok.save_pretrained(str(out_dir))
    return tok


def _features(names: tuple[str, ...], size: int) -> tuple[dict, dict]:
    from lerobot.configs.types import FeatureType, PolicyFeature

    inputs = {f"observation.images.{c}": PolicyFeature(FeatureType.VISUAL, (3, size, size)) for c in names}
    inputs["observation.state"] = PolicyFeature(FeatureType.STATE, (8,))
    return inputs, {"action": PolicyFeature(FeatureType.ACTION, (7,))}


def _save(out: Path, policy, pre, post) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for obj in (policy, pre, post):
        obj.save_pretrained(str(out))


def build_pi05(out: Path, reduced: bool = False, device: str = "cpu") -> str:
    """pi0.5 at gemma_2b + gemma_300m (or the reduced variants), bf16 weights; returns the spec to load it."""
    import torch
    from lerobot.policies.pi05 import processor_pi05
    from lerobot.policies.pi05.configuration_pi05 import PI05Config
    from lerobot.policies.pi05.modeling_pi05 import PI05Policy
    from lerobot.processor.tokenizer_processor import TokenizerProcessorStep

    from policy_wrappers import lerobot_variants

    out = Path(out)
    tok_dir = out / "tokenizer"
    build_tokenizer(tok_dir)
    size = 56 if reduced else 224
    inputs, outputs = _features(CAMERAS["pi05"], size)
    extra = (
        dict(tokenizer_max_length=48, num_inference_steps=3, chunk_size=10, n_action_steps=5)
        if reduced
        else {}
    )
    cfg = PI05Config(input_features=inputs, output_features=outputs, image_resolution=(size, size),
                     dtype="float32" if reduced else "bfloat16", device=device, **extra)  # fmt: skip
    sizes = lerobot_variants.reduced() if reduced else contextlib.nullcontext()
    with (
        torch.device(device),
        sizes,
    ):  # random init on the target device: minutes faster than CPU at 4 B params
        policy = PI05Policy(cfg)

    def tokenizer_step(**kw):  # built from the local tokenizer, saved under the upstream name (see docstring)
        step = TokenizerProcessorStep(**{**kw, "tokenizer_name": str(tok_dir)})
        step.tokenizer_name = PALIGEMMA_TOKENIZER
        return step

    real_step = processor_pi05.TokenizerProcessorStep
    processor_pi05.TokenizerProcessorStep = tokenizer_step
    try:
        pre, post = processor_pi05.make_pi05_pre_post_processors(
            cfg, dataset_stats=_stats({**inputs, **outputs})
        )
    finally:
        processor_pi05.TokenizerProcessorStep = real_step
    cfg.device = "cpu"  # the saved config names no machine; the wrapper's device= chooses
    _save(out, policy, pre, post)
    _write_meta(out, "pi05", reduced, policy)
    return f"lerobot:{out}?tokenizer={tok_dir}"


def build_vlm_dir(out: Path, sizes: dict) -> Path:
    """SmolVLA's ``vlm_model_name`` directory: a SmolVLM config of ``sizes`` plus a local tokenizer + processor."""
    from transformers.models.smolvlm import (
        SmolVLMConfig,
        SmolVLMImageProcessor,
        SmolVLMProcessor,
        SmolVLMVideoProcessor,
    )

    special = ["<fake_token_around_image>", "<image>", "<global-img>", "<end_of_utterance>", "<|im_start|>"]
    names = {
        "fake_image_token": special[0],
        "image_token": special[1],
        "global_image_token": special[2],
        "end_of_utterance_token": special[3],
    }  # what SmolVLMProcessor reads (tests/fixtures/tiny_policies.py)
    tok = build_tokenizer(None, extra_tokens=tuple(special), bos_token=special[4], eos_token=special[3],
                          extra_special_tokens=names)  # fmt: skip
    tok.add_special_tokens({"additional_special_tokens": special[:3]})
    text = {**sizes["text"], "vocab_size": max(sizes["text"].get("vocab_size", 0), len(tok))}
    config = SmolVLMConfig(text_config=text, vision_config=sizes["vision"], scale_factor=sizes["scale_factor"],
                           image_token_id=tok.convert_tokens_to_ids("<image>"))  # fmt: skip
    edge = sizes["vision"]["image_size"]
    image_proc = SmolVLMImageProcessor(size={"longest_edge": edge}, max_image_size={"longest_edge": edge},
                                       do_image_splitting=False)  # fmt: skip
    seq = (edge // sizes["vision"]["patch_size"]) ** 2 // sizes["scale_factor"] ** 2
    config.save_pretrained(str(out))
    SmolVLMProcessor(image_processor=image_proc, tokenizer=tok, video_processor=SmolVLMVideoProcessor(),
                     image_seq_len=seq).save_pretrained(str(out))  # fmt: skip
    return out


def build_smolvla(out: Path, reduced: bool = False, device: str = "cpu") -> str:
    """SmolVLA with SmolVLM2-500M's sizes (or tiny ones), randomly initialised; returns the spec to load it."""
    import torch
    from lerobot.policies.factory import make_pre_post_processors
    from lerobot.policies.smolvla.configuration_smolvla import SmolVLAConfig
    from lerobot.policies.smolvla.modeling_smolvla import SmolVLAPolicy

    out = Path(out)
    vlm = build_vlm_dir(out / "vlm", TINY_SMOLVLM if reduced else SMOLVLM2_500M)
    size = 64 if reduced else 256
    inputs, outputs = _features(CAMERAS["smolvla"], size)
    extra = dict(resize_imgs_with_padding=(64, 64), chunk_size=10, n_action_steps=5, num_steps=2,
                 num_vlm_layers=2, tokenizer_max_length=16) if reduced else {}  # fmt: skip
    cfg = SmolVLAConfig(input_features=inputs, output_features=outputs, vlm_model_name=str(vlm),
                        load_vlm_weights=False, device=device, **extra)  # fmt: skip
    with torch.device(device):
        policy = SmolVLAPolicy(cfg)
    pre, post = make_pre_post_processors(cfg, dataset_stats=_stats({**inputs, **outputs}))
    cfg.device = "cpu"
    _save(out, policy, pre, post)
    _write_meta(out, "smolvla", reduced, policy)
    return f"lerobot:{out}?vlm={vlm}"


def _write_meta(out: Path, kind: str, reduced: bool, policy) -> None:
    from policy_wrappers.lerobot_variants import MARKER

    params = sum(p.numel() for p in policy.parameters())
    meta = {"kind": kind, "reduced": reduced, "parameters": params, "random_init": True}
    (out / "indgen_build.json").write_text(json.dumps(meta, indent=1))
    if reduced and kind == "pi05":  # the wrapper builds this directory at the reduced sizes
        (out / MARKER).write_text(json.dumps(meta, indent=1))


BUILDERS = {"pi05": build_pi05, "smolvla": build_smolvla}


def main(argv: list[str] | None = None) -> str:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("kind", choices=sorted(BUILDERS))
    ap.add_argument("out", help="directory to write (a LeRobot pretrained_model layout)")
    ap.add_argument("--reduced", action="store_true", help="few layers, tiny widths (CPU tests)")
    ap.add_argument("--device", default="cpu", help="where to run the random init (cuda: much faster)")
    a = ap.parse_args(argv)
    spec = BUILDERS[a.kind](Path(a.out), reduced=a.reduced, device=a.device)
    print(json.dumps(json.loads((Path(a.out) / "indgen_build.json").read_text()) | {"spec": spec}))
    return spec


if __name__ == "__main__":
    main()
