"""The BlockEnv learners' table: each method's key and description, and the variant options it accepts; apart from
the models so that a ``FitConfig`` is checked without importing torch."""

from __future__ import annotations

from indgen_vla.core.errors import ConfigError

METHODS = {
    "rnn": "goal-conditioned 2-layer LSTM over MLP-encoded grids, three linear heads",
    "transformer": "causal Transformer with learned absolute positions, whole history each step",
    "transformer_rope": "causal pre-norm Transformer with rotary position embeddings",
    "transformer_goal_act": "RoPE Transformer + o_0 goal token + previous action in each token",
    "trm": "Tiny Recursive Model on p×p-patch tokens (option patch, default 3): latent z and answer y refined recursively, deep supervision",
    "maml": "first-order MAML over levels 0-2, one inner step (alpha 0.05), adapted on the test level",
    "ind": "RoPE Transformer + analytic legality head + factored joint head, masked and gated",
    "local_equivariant": "ours: fully convolutional local scorer of (cell, θ), translation-equivariant",
}


# Variant options a method accepts (FitConfig.extra): name -> (type, default, what it changes). Defaults are
# the configuration of the committed Table 1; the others exist for the ablations in docs/results/blockenv_ablations.md.
OPTIONS: dict[str, dict[str, tuple[type, object, str]]] = {
    "ind": {
        "gate_scale": (
            float,
            1.0,
            "weight of log σ(legal) added to the pick logits at inference (0: no gate)",
        ),
        "mask": (bool, True, "mask unoccupied cells to -inf at inference"),
        "legal_weight": (float, 1.0, "weight of the legality BCE beside the action cross-entropy"),
        "legal_pos_weight": (float, 1.0, "BCE weight of the rare legal (positive) cells"),
        "legal_head": (
            str,
            "global",
            "legality logits read from the trunk ('global'), from a 3x3 conv over the "
            "current grid ('local'), or their sum ('both')",
        ),
    },
    "maml": {
        "head": (str, "factored", "'factored' (rows, cols, θ heads) or 'joint' (one softmax over (r, c, θ))")
    },
    "trm": {"patch": (int, 3, "cells per token side (1: one token per cell, as the original TRM)")},
}


def check_options(method: str, extra: dict) -> dict:
    """``extra`` validated against OPTIONS[method], with defaults filled in; unknown keys are refused."""
    spec = OPTIONS.get(method, {})
    unknown = sorted(set(extra) - set(spec))
    if unknown:
        allowed = ", ".join(spec) or "none"
        raise ConfigError(f"{method} has no option(s) {', '.join(unknown)}; allowed: {allowed}")
    out = {}
    for name, (typ, default, _) in spec.items():
        v = extra.get(name, default)
        if typ is float and isinstance(v, int) and not isinstance(v, bool):
            v = float(v)
        if not isinstance(v, typ) or (typ is not bool and isinstance(v, bool)):
            raise ConfigError(f"{method} option {name} must be {typ.__name__}, got {v!r}")
        if typ in (int, float) and v < 0:
            raise ConfigError(f"{method} option {name} must be >= 0, got {v}")
        out[name] = v
    if method == "maml" and out["head"] not in ("factored", "joint"):
        raise ConfigError(f"maml option head must be 'factored' or 'joint', got {out['head']!r}")
    if method == "ind" and out["legal_head"] not in ("global", "local", "both"):
        raise ConfigError(
            f"ind option legal_head must be 'global', 'local' or 'both', got {out['legal_head']!r}"
        )
    if method == "trm" and out["patch"] < 1:
        raise ConfigError(f"trm option patch must be >= 1, got {out['patch']}")
    return out
