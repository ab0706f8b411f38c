"""``compile=``: torch.compile of a lerobot policy's per-call forward (policy_wrappers/compile.py)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from indgen_vla.core.errors import ConfigError
from policy_wrappers import compile as pcompile
from policy_wrappers.specs import load_policy

pytest.importorskip("lerobot")
pytestmark = pytest.mark.timeout(300)


def test_compile_option_is_checked_targets_the_forward_and_keeps_a_stable_cache(
    tiny_act, tmp_path, monkeypatch
):
    """Unknown modes and CUDA graphs on CPU are refused in one line before anything loads; the per-call forward
    (not the training loss) is what gets wrapped; the cache dir is the user's, else ~/.cache/indgen/inductor.
    torch.compile itself is not called here (importing inductor alone takes seconds): the slow test does."""
    with pytest.raises(
        ConfigError, match="compile must be one of off, default, reduce-overhead, max-autotune"
    ):
        load_policy(f"lerobot:{tiny_act}?compile=fast")
    with pytest.raises(
        ConfigError, match="compile=reduce-overhead captures CUDA graphs and needs a CUDA device"
    ):
        load_policy(f"lerobot:{tiny_act}", compile="reduce-overhead")  # what --compile passes

    from torch._inductor.runtime.cache_dir_utils import default_cache_dir

    monkeypatch.delenv(pcompile.CACHE_ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert pcompile.cache_dir() == tmp_path / "xdg" / "indgen" / "inductor"
    # what importing torch._inductor (lerobot's load, via torchvision) leaves in the variable: still "unset"
    monkeypatch.setenv(pcompile.CACHE_ENV, default_cache_dir())
    assert pcompile.cache_dir() == tmp_path / "xdg" / "indgen" / "inductor"
    assert pcompile.os.environ[pcompile.CACHE_ENV] == str(tmp_path / "xdg" / "indgen" / "inductor")
    monkeypatch.setenv(pcompile.CACHE_ENV, str(tmp_path / "mine"))  # the user's own choice wins
    assert pcompile.cache_dir() == tmp_path / "mine"

    policy = load_policy(f"lerobot:{tiny_act}")
    assert pcompile._target(policy.policy) == (policy.policy.model, "forward")  # ACT's predict_action_chunk
    assert pcompile.compile_forward(policy.policy, "off", "cpu", "act") == ""  # off: untouched
    policy.policy.config.compile_model = True  # lerobot's own flag would compile the same method twice
    with pytest.raises(ConfigError, match="compile_model=true"):
        pcompile.compile_forward(policy.policy, "default", "cpu", "act")


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
        inner = compiled.policy.model
        assert hasattr(inner.forward, "_torchdynamo_orig_callable")  # the per-call forward only
        assert not hasattr(
            compiled.policy.forward, "_torchdynamo_orig_callable"
        )  # the training loss: untouched
        assert any((tmp_path / "inductor").rglob("*")), "inductor wrote nothing to the cache dir"
    finally:
        torch._dynamo.reset()


@pytest.mark.slow  # one inductor compile on CPU (~1 min)
def test_compile_cache_defaults_to_indgens_dir_in_a_fresh_process(tiny_act, tmp_path):
    """Where a user's ``--compile`` run caches when they set nothing: ~/.cache/indgen/inductor (here under
    $XDG_CACHE_HOME), not torch's /tmp default, although loading the policy imports torch._inductor, which writes
    that default into $TORCHINDUCTOR_CACHE_DIR. A fresh interpreter, so the load is what imports inductor."""
    code = (
        "import numpy as np; from indgen_vla.core.protocol.interface import Observation; "
        "from policy_wrappers.specs import load_policy; "
        f"p = load_policy('lerobot:{tiny_act}', compile='default'); "
        "o = Observation({c: np.zeros((32, 32, 3), np.uint8) for c in p.spec.cameras}, np.zeros(8, np.float32), "
        "'pick'); p.reset('pick', seed=0); p.act([o])"
    )
    env = {k: v for k, v in os.environ.items() if k != pcompile.CACHE_ENV}
    env["XDG_CACHE_HOME"] = str(tmp_path)
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert f"(cache: {tmp_path / 'indgen' / 'inductor'})" in proc.stderr  # the line the wrapper prints
    assert any((tmp_path / "indgen" / "inductor").rglob("*")), "inductor wrote nothing to indgen's cache dir"
