"""Reduced pi0.5 sizes (few layers, tiny widths) so the real PI05Policy code path runs on a CPU in tests.

lerobot's ``PI05Config`` accepts only ``gemma_2b`` / ``gemma_300m`` as variants, ``modeling_pi05.get_gemma_config``
turns them into sizes, and ``PaliGemmaWithExpertModel`` always builds SigLIP-So400m as the vision tower. A
checkpoint written by ``scripts/build_real_size.py --reduced`` carries ``MARKER`` beside its config.json; while
``reduced()`` is active (the builder, and the lerobot wrapper when it loads such a directory) those two variants
resolve to the sizes below and the vision tower is built at ``VISION``. Outside it lerobot is untouched.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

MARKER = "indgen_reduced.json"
# (width, depth, mlp_dim, num_heads, num_kv_heads, head_dim), the fields of lerobot's GemmaConfig
SIZES = {"gemma_2b": (64, 2, 128, 2, 1, 32), "gemma_300m": (48, 2, 96, 2, 1, 32)}
VISION = {"hidden_size": 32, "intermediate_size": 64, "num_hidden_layers": 1, "num_attention_heads": 2}


def is_reduced(path: str | Path) -> bool:
    """Whether a local checkpoint directory was built with reduced sizes."""
    return (Path(path) / MARKER).is_file()


@contextlib.contextmanager
def reduced():
    """Build pi0.5 models at the reduced sizes inside this block (restores lerobot's functions after)."""
    from lerobot.policies.pi05 import modeling_pi05 as m

    real_config, real_cls = m.get_gemma_config, m.PaliGemmaForConditionalGenerationWithPiGemma

    def get_gemma_config(variant: str):
        return m.GemmaConfig(*SIZES[variant]) if variant in SIZES else real_config(variant)

    def paligemma(config):  # lerobot has just set So400m's sizes on config.vision_config: shrink them
        for key, value in VISION.items():
            setattr(config.vision_config, key, value)
        config.vision_config.projection_dim = config.text_config.hidden_size
        return real_cls(config=config)

    m.get_gemma_config = get_gemma_config
    m.PaliGemmaForConditionalGenerationWithPiGemma = paligemma
    try:
        yield
    finally:
        m.get_gemma_config, m.PaliGemmaForConditionalGenerationWithPiGemma = real_config, real_cls
