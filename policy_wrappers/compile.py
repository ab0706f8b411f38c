"""Opt-in ``torch.compile`` of a LeRobot policy's per-call forward, with a persistent on-disk compile cache.

Only the part each ``predict_action_chunk`` runs is compiled, never the pre/post-processors or the whole policy
object. For the flow-matching VLAs (pi0, pi0.5, SmolVLA) that is one denoising step (``denoise_step``), which the
Euler loop calls ``num_inference_steps`` times per ``act``: lerobot's own ``compile_model`` wraps the whole
``sample_actions`` instead, and dynamo unrolls that loop, so its graph holds the prefix pass plus ten copies of the
action expert (reduced pi0.5 on CPU: 3,094 traced calls and 110 s against 279 calls and 44 s for one step; the
real-size pi0.5's whole-``sample_actions`` compile outran 4 min on the H100 box, docs/results/benchmarks/compile.md). The step
graph is compiled once and reused by every step; the prefix (SigLIP + Gemma over the prompt) stays eager: at the
batch sizes the engine runs it is compute-bound, while the action expert's many small kernels are launch-bound.
The first call at a batch size pays the compile;
inductor's FX-graph and autotune results land in ``cache_dir()``, so the next process reuses them. The engine
pads every batched call to the worker count (``interface.act_padded``), so one run compiles one batch shape.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import COMPILE_MODES, CUDA_GRAPH_COMPILE_MODES

MODES, CUDA_ONLY = (
    COMPILE_MODES,
    CUDA_GRAPH_COMPILE_MODES,
)  # shared with --compile (indgen_vla/core/protocol/interface.py)
CACHE_ENV = "TORCHINDUCTOR_CACHE_DIR"


def check_mode(mode: str, device: str, who: str) -> None:
    """One clear line for an unknown mode, or a CUDA-graph mode on a device without CUDA (refused, not rewritten)."""
    if mode not in MODES:
        raise ConfigError(f"{who}: compile must be one of {', '.join(MODES)}, got {mode!r}")
    if mode in CUDA_ONLY and not str(device).startswith("cuda"):
        raise ConfigError(
            f"{who}: compile={mode} captures CUDA graphs and needs a CUDA device (got device {device!r}); "
            "use compile=default on CPU, or --device cuda"
        )


def cache_dir() -> Path:
    """The inductor cache every run shares: $TORCHINDUCTOR_CACHE_DIR if the user set it, else
    ~/.cache/indgen/inductor (torch's default lives in /tmp, which a reboot or a fresh container empties).

    Importing ``torch._inductor`` (lerobot's load does, through torchvision) writes inductor's own default into the
    variable, so a value equal to that default counts as unset; the line ``compile_forward`` prints names the
    directory used."""
    from torch._inductor.runtime.cache_dir_utils import default_cache_dir

    value = os.environ.get(CACHE_ENV)
    if value and value != default_cache_dir():
        return Path(value)
    base = Path(os.environ.get("XDG_CACHE_HOME") or "~/.cache").expanduser()
    path = base / "indgen" / "inductor"
    os.environ[CACHE_ENV] = str(path)  # read by inductor (and Triton's cache below it) at compile time
    utils = sys.modules.get("torch._inductor.utils")
    if utils is not None:  # paths inductor already derived from the old value (functools caches)
        utils.clear_caches()
    return path


def _target(policy) -> tuple[object, str]:
    """(object, method name) of the per-call forward: one flow step (``denoise_step``) of the flow-matching VLAs,
    the diffusion sampler, or the inner model's ``forward`` (ACT, VQ-BeT, ...)."""
    model = getattr(policy, "model", None)
    if model is not None and callable(getattr(model, "sample_actions", None)):  # pi0, pi0.5, SmolVLA
        step = "denoise_step" if callable(getattr(model, "denoise_step", None)) else "sample_actions"
        return model, step
    diffusion = getattr(policy, "diffusion", None)
    if diffusion is not None and callable(getattr(diffusion, "generate_actions", None)):
        return diffusion, "generate_actions"
    if model is not None and callable(getattr(model, "forward", None)):
        return model, "forward"
    raise ConfigError(
        f"compile= does not know the per-call forward of {type(policy).__name__}; run it with compile=off"
    )


def compile_forward(policy, mode: str, device: str, who: str) -> str:
    """Wrap the policy's per-call forward with ``torch.compile(mode=...)`` in place; returns what was wrapped.

    lerobot's own ``compile_model`` must be off (it would compile the same method twice). ``mode="off"`` leaves
    the policy untouched."""
    check_mode(mode, device, who)
    if mode == "off":
        return ""
    if getattr(getattr(policy, "config", None), "compile_model", False):
        raise ConfigError(
            f"{who}: the checkpoint's config sets compile_model=true (lerobot's own compile); "
            "set it false in config.json or drop compile="
        )
    import torch

    cache_dir()
    import torch._inductor.config as inductor_config

    # a compiled sampler that draws its own noise (diffusion; flow matching when lerobot's denoise_step is absent):
    # inductor's generated random kernels (Philox, on CUDA) draw other numbers than eager for the same seed; eager's
    # RNG ops keep a seed's noise equal (on CPU the two already agree: checked 2026-11-24 for torch.normal; on CUDA
    # test_reduced_pi05_compiled_on_cuda_matches_eager)
    inductor_config.fallback_random = True
    obj, name = _target(policy)
    compiled = torch.compile(getattr(obj, name), mode=mode)
    if mode in CUDA_ONLY and name == "denoise_step":
        compiled = _new_cuda_graph_step_per_call(compiled)
    setattr(obj, name, compiled)
    print(
        f"[indgen] {who}: torch.compile(mode={mode}) on {type(obj).__name__}.{name}; the first call per batch "
        f"size compiles (cache: {os.environ[CACHE_ENV]})",
        file=sys.stderr,
    )
    return f"{type(obj).__name__}.{name}"


def _new_cuda_graph_step_per_call(compiled):
    """Each flow step replays the one recorded CUDA graph: a step boundary per call.

    ``torch.compiler.cudagraph_mark_step_begin`` is torch's idiom for a graph invoked in a loop. The Euler loop
    still holds the previous step's velocity when it calls the next step; CUDA-graph trees keep outputs that are
    still referenced (recording another graph around them) unless a new step has begun. The loop has read that
    velocity (``x_t + dt * v_t``) before the next call, so letting the replay overwrite it is safe."""
    import functools

    import torch

    @functools.wraps(compiled)
    def step(*args, **kwargs):
        torch.compiler.cudagraph_mark_step_begin()
        return compiled(*args, **kwargs)

    return step
