"""Per-family conventions as transforms: each pipeline is the upstream eval's steps in order; options override."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import policy_wrappers
from indgen_vla.core.errors import ConfigError, UnknownNameError
from indgen_vla.core.registry import Registry
from policy_wrappers import specs as registry
from policy_wrappers.image_tools import (
    center_crop_tf,
    convert_gripper,
    flip_180,
    resize_jpeg_lanczos,
    resize_with_pad,
)
from policy_wrappers.transforms import (
    LIBERO_GROOT_N15,
    LIBERO_GROOT_N16,
    LIBERO_OFT,
    LIBERO_OPENPI,
    LIBERO_OPENVLA,
    CenterCrop,
    Flip180,
    GripperMap,
    JpegLanczos,
    ResizeWithPad,
    compose,
)


def test_family_pipelines_are_the_upstream_steps_in_order():
    img = np.random.default_rng(0).integers(0, 256, (64, 48, 3), dtype=np.uint8)
    assert np.array_equal(LIBERO_OPENPI.images(img), resize_with_pad(flip_180(img), 224, 224))
    assert np.array_equal(LIBERO_OFT.images(img), resize_jpeg_lanczos(flip_180(img), 224, 224))
    assert np.array_equal(
        LIBERO_OPENVLA.images(img), center_crop_tf(resize_jpeg_lanczos(flip_180(img), 224, 224), 0.9)
    )
    assert np.array_equal(LIBERO_GROOT_N15.images(img), flip_180(img))  # 256 sent as is
    chunk = np.full((1, 2, 7), 0.9, np.float32)
    for conv in (LIBERO_OFT, LIBERO_OPENVLA, LIBERO_GROOT_N15, LIBERO_GROOT_N16):
        assert np.array_equal(conv.actions(chunk), convert_gripper(chunk, "01inv"))
    assert LIBERO_OPENPI.actions(chunk) is chunk  # pi0.5 emits LIBERO's -1/+1 already


def test_chunking_defaults_per_family():
    assert LIBERO_OPENPI.chunking() == (10, 5) and LIBERO_OPENPI.chunking(3) == (3, 3)
    assert LIBERO_OFT.chunking() == (8, 8) and LIBERO_OFT.chunking(16) == (16, 16)  # replan = whole chunk
    assert LIBERO_OPENVLA.chunking() == (1, 1)
    assert LIBERO_GROOT_N15.chunking() == (16, 1) and LIBERO_GROOT_N16.chunking() == (16, 8)
    assert LIBERO_GROOT_N16.chunking(4) == (4, 4) and LIBERO_GROOT_N16.chunking(16, 2) == (16, 2)


def test_override_changes_only_what_is_given():
    assert LIBERO_OPENPI.override() == LIBERO_OPENPI
    assert LIBERO_OPENPI.override(flip=False).images == compose(ResizeWithPad(224))
    assert LIBERO_OPENPI.override(flip=False).override(flip=True) == LIBERO_OPENPI  # flip goes first again
    assert LIBERO_OFT.override(size=128).images == compose(Flip180(), JpegLanczos(128))
    assert LIBERO_GROOT_N16.override(size=224).images == compose(Flip180(), ResizeWithPad(224))
    assert LIBERO_OPENVLA.override(crop=False).images == LIBERO_OFT.images
    assert LIBERO_OFT.override(crop=True).images.find(CenterCrop) == CenterCrop(0.9)
    assert LIBERO_OFT.override(gripper="raw").actions == compose(GripperMap("raw"))
    assert LIBERO_OPENPI.override(render=128).render == 128 and not LIBERO_OPENPI.override(flip=False).flips


@pytest.mark.parametrize(
    "make", [lambda: ResizeWithPad(4), lambda: GripperMap("inv"), lambda: CenterCrop(1.5)]
)
def test_bad_steps_are_refused(make):
    with pytest.raises(ConfigError):
        make()


def test_spec_options_build_configs_without_restating_defaults():
    from policy_wrappers.openpi import OPTIONS, OpenpiConfig

    options = registry.Options("openpi:ws://h:1", {"chunk": "4", "flip": "0", "timeout": "2.5"})
    values = options.fields(OpenpiConfig, OPTIONS)
    assert values == {"chunk_size": 4, "flip_180": False, "timeout_s": 2.5}  # absent options left out
    config = OpenpiConfig(url="ws://h:1", **values)
    assert config.chunking() == (4, 4) and config.connect_timeout_s == OpenpiConfig.connect_timeout_s
    assert config.conventions.images == compose(ResizeWithPad(224))
    with pytest.raises(ConfigError, match="timeouts must be positive"):
        OpenpiConfig(url="ws://h:1", timeout_s=0)


def test_register_standin_from_outside(monkeypatch):
    fresh: Registry = Registry("stand-in policy")
    monkeypatch.setattr(registry, "STANDINS", fresh)
    with pytest.raises(UnknownNameError, match="stand-in"):
        registry.load_policy("standin:still")
    registry.register_standin("still", "policy_wrappers.standin:NoopPolicy", "a test stand-in")
    registry.register_standin("still", "policy_wrappers.standin:NoopPolicy", "a test stand-in")  # idempotent
    assert registry.load_policy("standin:still").spec.batched
    assert {"name": "standin:still", "description": "a test stand-in"} in registry.catalog()["standins"]


def test_policy_wrappers_never_refers_to_scenes():
    """The oracle is registered by the application; this package imports and names no ``scenes`` module."""
    for path in Path(policy_wrappers.__file__).parent.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                names = [node.value] if ":" in node.value and " " not in node.value else []
            else:
                continue
            assert not any(n == "scenes" or n.startswith("scenes.") for n in names), f"{path.name}: {names}"
