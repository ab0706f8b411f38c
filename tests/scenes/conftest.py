"""Shared fixtures and checks for the scene tests."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    """Point the adapter at a freshly generated miniature asset tree (and a private LIBERO config dir)."""
    from scenes.libero.miniature import write_miniature_assets

    root = write_miniature_assets(tmp_path_factory.mktemp("libero_assets"))
    yield from libero_tree(root, tmp_path_factory.mktemp("indgen_cache"))


@pytest.fixture(scope="module")
def real(tmp_path_factory):
    """Point indgen at LIBERO's complete tree where ``indgen setup libero`` installs it (the wheels' listing), or skip
    with the reason; a test that takes this fixture is a ``real_assets`` test (tests/conftest.py counts them)."""
    from tests.conftest import REAL_ASSETS_SKIP, complete_libero_tree

    root = complete_libero_tree()
    if root is None:
        pytest.skip(REAL_ASSETS_SKIP)
    yield from libero_tree(root, tmp_path_factory.mktemp("cache"))


def libero_tree(root, cache):
    """While the fixture lasts, indgen reads LIBERO's assets from ``root`` and caches into ``cache`` (and a private
    LIBERO config dir); the variables are restored after."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("INDGEN_LIBERO_ASSETS", str(root))
        mp.setenv("INDGEN_CACHE", str(cache))
        mp.delenv("LIBERO_CONFIG_PATH", raising=False)
        yield root


def assert_steps_match(env, ref, action, steps=3):
    """Step ``env`` and lerobot's ``ref`` alike ``steps`` times; their agentview frames must agree."""
    a = np.array(action, dtype=np.float32)
    for _ in range(steps):
        obs, *_ = env.step(a)
        robs, *_ = ref.step(a)
    np.testing.assert_array_equal(obs.images["agentview"], robs["pixels"]["image"])
