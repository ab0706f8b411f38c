"""The kitchen asset check wants objects (issue 41): RoboCasa's wheel bundles a 3.5 MB asset folder (fixtures and
layouts, no objects) that used to pass it; the hint names where RoboCasa's download really writes."""

from __future__ import annotations

import pytest

from indgen_vla.core.errors import SceneError
from tests.scenes.robocasa.test_robocasa import needs_venv


@needs_venv
def test_the_wheels_bundled_assets_are_refused_and_the_download_path_is_named(placeholders, monkeypatch):
    """robocasa/robocasa robocasa/scripts/download_kitchen_assets.py writes every asset type under
    ``robocasa.__path__[0]/models/assets`` (objects under ``objects/<registry>``); the pinned wheel ships that folder
    without ``objects``."""
    from scenes.robocasa.environment import find_assets, is_asset_tree, venv_assets

    bundled = venv_assets()
    assert (bundled / "fixtures" / "fixture_registry").is_dir() and not (bundled / "objects").exists()
    assert not is_asset_tree(bundled) and is_asset_tree(placeholders)
    monkeypatch.setenv("INDGEN_ROBOCASA_ASSETS", str(bundled))
    with pytest.raises(
        SceneError, match=r"no object models under objects/ .*it writes into .*robocasa/models/assets"
    ):
        find_assets()
    monkeypatch.delenv("INDGEN_ROBOCASA_ASSETS")
    monkeypatch.setenv("INDGEN_CACHE", str(placeholders.parent / "empty-cache"))  # no default tree either
    monkeypatch.setenv("INDGEN_ROBOCASA_VENV", str(bundled.parents[5]))
    with pytest.raises(
        SceneError, match=r"looked in .*robocasa-assets and .*models/assets: no object models"
    ):
        find_assets()
