"""Shared fixtures: one recorded T0 demo (rendering dominates its cost, so the regime tests share it)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def one_demo(tmp_path_factory):
    """One noisy-oracle pick_place demo at 32 px (both cameras) and its ``record_demos`` stats."""
    pytest.importorskip("lerobot")
    from indgen_vla.regimes.demos import record_demos

    out = tmp_path_factory.mktemp("one_demo") / "demos"
    stats = record_demos("pick_place", out, n=1, image_size=32, seed=3)
    return out, stats
