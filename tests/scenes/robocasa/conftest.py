"""One placeholder kitchen-asset tree for every RoboCasa test module (writing it costs seconds)."""

from __future__ import annotations

import os

import pytest


@pytest.fixture(scope="package")  # torn down when the package's tests end
def placeholders(tmp_path_factory):
    """A fresh placeholder tree, pointed at by INDGEN_ROBOCASA_ASSETS while the RoboCasa tests run."""
    from scenes.robocasa.placeholders import write_placeholders

    root = tmp_path_factory.mktemp("robocasa_assets")
    write_placeholders(root)
    saved = os.environ.get("INDGEN_ROBOCASA_ASSETS")
    os.environ["INDGEN_ROBOCASA_ASSETS"] = str(root)
    yield root
    if saved is None:
        os.environ.pop("INDGEN_ROBOCASA_ASSETS", None)
    else:
        os.environ["INDGEN_ROBOCASA_ASSETS"] = saved
