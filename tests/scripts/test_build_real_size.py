"""scripts/build_real_size.py: pi0.5 and SmolVLA built offline (random init) and acting through ``lerobot:<dir>``."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from indgen_vla.core.protocol.interface import Observation, act_padded

_spec = importlib.util.spec_from_file_location(
    "build_real_size", Path(__file__).resolve().parents[2] / "scripts" / "build_real_size.py"
)
build = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(build)


def _obs(spec, n: int, seed: int = 0) -> list[Observation]:
    h, w = spec.image_size
    rng = np.random.default_rng(seed)
    return [Observation({c: rng.integers(0, 255, (h, w, 3), dtype=np.uint8) for c in spec.cameras},
                        rng.normal(size=8).astype(np.float32), "pick up the milk") for _ in range(n)]  # fmt: skip


def _act_and_pad(spec_str: str, device: str = "cpu") -> None:
    from policy_wrappers.specs import load_policy

    policy = load_policy(spec_str, device=device)
    assert policy.spec.batched and set(policy.spec.cameras) == {"agentview", "wrist"}
    obs = _obs(policy.spec, 3)
    policy.reset(obs[0].instruction, seed=0)
    padded = act_padded(policy, obs[:2], 4, spec_str)  # padding after pre-processing ...
    policy.reset(obs[0].instruction, seed=0)
    rows = policy.act(obs[:2] + obs[:1] * 2)[:2]  # ... equals padding the observations
    assert padded.shape == (2, policy.spec.chunk_size, 7) and np.isfinite(padded).all()
    np.testing.assert_allclose(padded, rows, atol=1e-5)
    policy.close()


@pytest.mark.slow  # ~30 s on 2 cores: the reduced model still has Gemma's 257k-token embedding
def test_reduced_pi05_builds_loads_and_acts(tmp_path):
    spec = build.build_pi05(tmp_path / "pi05", reduced=True)
    assert spec == f"lerobot:{tmp_path / 'pi05'}?tokenizer={tmp_path / 'pi05' / 'tokenizer'}"
    saved = (tmp_path / "pi05" / "policy_preprocessor.json").read_text()
    assert (
        build.PALIGEMMA_TOKENIZER in saved
    )  # the upstream name, as a Hub checkpoint has; tokenizer= relocates
    _act_and_pad(spec)


def test_reduced_smolvla_builds_loads_and_acts(tmp_path):
    pytest.importorskip(
        "num2words", reason="transformers' SmolVLMProcessor needs num2words (lerobot[smolvla])"
    )
    _act_and_pad(build.build_smolvla(tmp_path / "smolvla", reduced=True))


def test_reduced_sizes_leave_lerobot_untouched_outside_the_block():
    from lerobot.policies.pi05 import modeling_pi05 as m

    from policy_wrappers import lerobot_variants

    real = m.get_gemma_config("gemma_2b")
    with lerobot_variants.reduced():
        assert m.get_gemma_config("gemma_2b").width == lerobot_variants.SIZES["gemma_2b"][0]
    assert (
        m.get_gemma_config("gemma_2b").width == real.width == 2048
    )  # lerobot's modeling_pi05.get_gemma_config


@pytest.mark.gpu
def test_real_size_pi05_acts_on_cuda(tmp_path):
    torch = pytest.importorskip("torch")
    if not torch.cuda.is_available():
        pytest.skip("needs a CUDA device")
    spec = build.build_pi05(tmp_path / "pi05", device="cuda")
    meta = (tmp_path / "pi05" / "indgen_build.json").read_text()
    assert '"parameters": 41' in meta  # 4.14 B with embeddings (docs/results/benchmarks/gpu.md)
    _act_and_pad(spec + "&precision=bf16", device="cuda")


def _compiled_matches_eager(spec_str: str, mode: str, device: str) -> None:
    """Same seed, same observations: the compiled per-call forward (``compile=``) gives the eager actions, noise
    included (drawn by the eager ``sample_actions`` around the compiled flow step)."""
    import torch

    from policy_wrappers.specs import load_policy

    eager, compiled = load_policy(spec_str, device=device), load_policy(spec_str, device=device, compile=mode)
    model = compiled.policy.model  # one flow step is compiled, not the whole (loop-unrolling) sample_actions
    assert "_torchdynamo_orig_callable" in vars(model.denoise_step)
    assert "sample_actions" not in vars(model)
    obs = _obs(eager.spec, 2)
    try:
        for _ in range(2):  # the second call runs the compiled (or CUDA-graph replayed) code
            eager.reset(obs[0].instruction, seed=3)
            want = eager.act(obs)
            compiled.reset(obs[0].instruction, seed=3)
            got = compiled.act(obs)
            np.testing.assert_allclose(got, want, atol=2e-4, rtol=1e-4)
    finally:
        torch._dynamo.reset()


@pytest.mark.slow  # minutes: inductor's CPU compile of a reduced VLM; test_compile.py's fast test covers the option
def test_reduced_smolvla_compiled_matches_eager(tmp_path, monkeypatch):
    pytest.importorskip(
        "num2words", reason="transformers' SmolVLMProcessor needs num2words (lerobot[smolvla])"
    )
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", str(tmp_path / "inductor"))
    _compiled_matches_eager(build.build_smolvla(tmp_path / "smolvla", reduced=True), "default", "cpu")


@pytest.mark.gpu
@pytest.mark.parametrize("mode", ["default", "reduce-overhead"])
def test_reduced_pi05_compiled_on_cuda_matches_eager(tmp_path, monkeypatch, mode):
    torch = pytest.importorskip("torch")
    if not torch.cuda.is_available():
        pytest.skip("needs a CUDA device")
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", str(tmp_path / "inductor"))
    _compiled_matches_eager(build.build_pi05(tmp_path / "pi05", reduced=True, device="cuda"), mode, "cuda")


def test_flow_noise_is_drawn_per_query_not_per_batch(tmp_path):
    """A sampling VLA's actions for one episode's query depend on that query (its ``QUERY_KEY``: episode seed, steps
    taken), not on which other episodes share the batch, their order, or when they reset (the engine batches
    whichever simulators wait, so a shared noise stream made an episode's noise depend on the schedule)."""
    pytest.importorskip(
        "num2words", reason="transformers' SmolVLMProcessor needs num2words (lerobot[smolvla])"
    )
    import dataclasses

    from indgen_vla.core.protocol.interface import QUERY_KEY
    from policy_wrappers.specs import load_policy

    policy = load_policy(build.build_smolvla(tmp_path / "smolvla", reduced=True))
    a, b = (
        dataclasses.replace(o, extras={QUERY_KEY: key})
        for o, key in zip(_obs(policy.spec, 2), [(11, 0), (22, 5)], strict=True)
    )
    try:
        policy.reset(a.instruction, seed=1)
        together = policy.act([a, b])
        policy.reset(
            a.instruction, seed=2
        )  # another episode starts: the stream a shared generator would reseed
        alone_b = policy.act([b])
        swapped = act_padded(policy, [b, a], 4, "smolvla")
        np.testing.assert_allclose(alone_b[0], together[1], atol=1e-5)
        np.testing.assert_allclose(swapped[1], together[0], atol=1e-5)
        later = policy.act([dataclasses.replace(a, extras={QUERY_KEY: (11, 5)})])  # the episode's next query
        assert np.abs(later[0] - together[0]).max() > 1e-3  # the noise does depend on the query
    finally:
        policy.close()
