"""Shared fixtures: realistic observations and tiny randomly initialised LeRobot checkpoints (offline)."""

from __future__ import annotations

import os
import shutil
import sys

import numpy as np
import pytest

os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
sys.path.insert(0, os.path.dirname(__file__))  # the loopback helpers (tests run with --import-mode=importlib)

from indgen_vla.core.protocol.interface import Observation  # noqa: E402
from tests.fixtures.tiny_policies import build_tiny_checkpoint  # noqa: E402,F401


def make_obs(seed: int = 0, size: int = 256, instruction: str = "put the bowl on the plate") -> Observation:
    """A LIBERO-like observation: two uint8 renders with structure (so flips are detectable) and a state."""
    rng = np.random.default_rng(seed)
    images = {}
    for cam in ("agentview", "wrist"):
        img = rng.integers(0, 256, size=(size, size, 3), dtype=np.uint8)
        img[: size // 4] = 255  # bright top band: a 180° flip moves it to the bottom
        images[cam] = img
    state = np.concatenate([rng.normal(0, 0.2, 3), rng.normal(0, 1, 3), [0.04, -0.04]]).astype(np.float32)
    return Observation(images=images, state=state, instruction=instruction)


@pytest.fixture
def obs_factory():
    return make_obs


@pytest.fixture(scope="session")
def tiny_act(tmp_path_factory) -> str:
    pytest.importorskip("lerobot")
    return build_tiny_checkpoint("act", tmp_path_factory.mktemp("act"))


@pytest.fixture(scope="session")
def tiny_diffusion(tmp_path_factory) -> str:
    pytest.importorskip("lerobot")
    pytest.importorskip("diffusers", reason="lerobot's Diffusion policy needs lerobot[diffusion] (diffusers)")
    return build_tiny_checkpoint("diffusion", tmp_path_factory.mktemp("diffusion"))


@pytest.fixture
def hub_cache(tmp_path, monkeypatch):
    """An offline Hugging Face cache; ``put(dir, repo_id)`` lays a checkpoint out as a downloaded snapshot."""
    import huggingface_hub.constants as hf_constants

    monkeypatch.setattr(hf_constants, "HF_HUB_CACHE", str(tmp_path))
    monkeypatch.setattr(hf_constants, "HF_HUB_OFFLINE", True)
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")

    def put(src: str, repo_id: str) -> None:
        repo = tmp_path / ("models--" + repo_id.replace("/", "--"))
        rev = "0123456789abcdef0123456789abcdef01234567"
        (repo / "refs").mkdir(parents=True)
        (repo / "refs" / "main").write_text(rev)
        shutil.copytree(src, repo / "snapshots" / rev)

    return put
