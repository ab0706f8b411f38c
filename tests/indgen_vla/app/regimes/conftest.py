"""Shared fixtures: recorded demos (rendering and the dataset writes dominate their cost, so the regime tests share
them)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def one_demo(tmp_path_factory):
    """One noisy-oracle pick_place demo at 32 px (both cameras) and its ``record_demos`` stats."""
    pytest.importorskip("lerobot")
    from indgen_vla.app import api
    from indgen_vla.app.regimes.demos import DemosConfig

    out = tmp_path_factory.mktemp("one_demo") / "demos"
    stats = api.demos(DemosConfig(scene="pick_place", out=out, n=1, image_size=32, seed=3, workers=1))
    return out, stats


@pytest.fixture(scope="session")
def demos(tmp_path_factory):
    """Two state-only noisy-oracle T0 demos of pick_place (the default path: no --axis), with object poses."""
    pytest.importorskip("lerobot")
    from indgen_vla.app import api
    from indgen_vla.app.regimes.demos import DemosConfig

    out = tmp_path_factory.mktemp("train") / "demos"
    api.demos(DemosConfig(scene="pick_place", out=out, n=2, seed=5, cameras=(), objects=True, workers=1))
    return out


@pytest.fixture(scope="session")
def level_demos(tmp_path_factory):
    """One state-only demo at each of pick_y levels 0 and 1 (``indgen demos --axis pick_y --levels 0:1``), the same
    seed and options as ``demos``, and the ``record_demos`` stats."""
    pytest.importorskip("lerobot")
    from indgen_vla.app import api
    from indgen_vla.app.regimes.demos import DemosConfig, LevelRequest

    out = tmp_path_factory.mktemp("levels") / "demos"
    stats = api.demos(
        DemosConfig(
            scene="pick_place",
            out=out,
            n=1,
            seed=5,
            cameras=(),
            objects=True,
            at=LevelRequest(axes=("pick_y",), levels="0:1"),
            workers=1,
        )
    )
    return out, stats
