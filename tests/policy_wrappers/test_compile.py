"""``compile=``: torch.compile of a lerobot policy's per-call forward (policy_wrappers/compile.py)."""

from __future__ import annotations

import numpy as np
import pytest

from indgen_vla.errors import ConfigError
from policy_wrappers import compile as pcompile
from policy_wrappers.registry import load_policy

pytest.importorskip("lerobot")
pytestmark = pytest.mark.timeout(300)


def test_compile_option_is_checked_wraps_the_forward_and_keeps_a_stable_cache(
    tiny_act, tmp_path, monkeypatch
):
    """Unknown modes and CUDA graphs on CPU are refused in one line; a valid mode wraps only the per-call
    forward (lazily: nothing compiles until the first act); the cache dir is the user's, else ~/.cache/indgen."""
    with pytest.raises(
        ConfigError, match="compile must be one of off, default, reduce-overhead, max-autotune"
    ):
        load_policy(f"lerobot:{tiny_act}?compile=fast")
    with pytest.raises(
        ConfigError, match="compile=reduce-overhead captures CUDA graphs and needs a CUDA device"
    ):
        load_policy(f"lerobot:{tiny_act}", compile="reduce-overhead")  # what --compile passes

    monkeypatch.delenv(pcompile.CACHE_ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert pcompile.cache_dir() == tmp_path / "xdg" / "indgen" / "inductor"
    monkeypatch.setenv(pcompile.CACHE_ENV, str(tmp_path / "mine"))  # the user's own choice wins
    assert pcompile.cache_dir() == tmp_path / "mine"

    policy = load_policy(f"lerobot:{tiny_act}?compile=default")
    assert policy.config.compile == "default"
    inner = policy.policy.model
    assert "forward" in vars(inner) and hasattr(inner.forward, "_torchdynamo_orig_callable")
    assert not hasattr(policy.policy.forward, "_torchdynamo_orig_callable")  # the training loss: untouched


@pytest.mark.slow  # inductor's C++ compile on CPU takes tens of seconds; the fast test above covers the option
def test_compiled_act_matches_eager(tiny_act, tmp_path, monkeypatch, obs_factory):
    """Compiling changes nothing beyond float tolerance, at two batch sizes (padded like the engine pads)."""
    import torch

    monkeypatch.setenv(pcompile.CACHE_ENV, str(tmp_path / "inductor"))
    eager = load_policy(f"lerobot:{tiny_act}")
    compiled = load_policy(f"lerobot:{tiny_act}", compile="default")
    try:
        for rows, pad in ((1, None), (2, 4)):
            obs = [obs_factory(i, size=32) for i in range(rows)]
            want, got = eager.act(obs, pad_to=pad), compiled.act(obs, pad_to=pad)
            assert got.shape == want.shape == (rows, eager.spec.chunk_size, 7)
            assert np.allclose(got, want, atol=1e-4, rtol=1e-4), np.abs(got - want).max()
        assert any((tmp_path / "inductor").rglob("*")), "inductor wrote nothing to the cache dir"
    finally:
        torch._dynamo.reset()
