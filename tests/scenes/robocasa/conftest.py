"""One placeholder kitchen-asset tree per test process for every RoboCasa test module (writing it costs seconds)."""

from __future__ import annotations

import os

import pytest


@pytest.fixture(scope="session")
def placeholder_tree(tmp_path_factory):
    """The tree, written once per process: pytest-xdist's ``--dist loadfile`` interleaves this package's files with
    others', so a package-scoped tree was torn down and written again between them (about 6 s each time)."""
    from scenes.robocasa.placeholders import write_placeholders

    root = tmp_path_factory.mktemp("robocasa_assets")
    write_placeholders(root)
    return root


@pytest.fixture(scope="package")  # torn down when the package's tests end
def placeholders(placeholder_tree):
    """The tree, pointed at by INDGEN_ROBOCASA_ASSETS while the RoboCasa tests run."""
    saved = os.environ.get("INDGEN_ROBOCASA_ASSETS")
    os.environ["INDGEN_ROBOCASA_ASSETS"] = str(placeholder_tree)
    yield placeholder_tree
    if saved is None:
        os.environ.pop("INDGEN_ROBOCASA_ASSETS", None)
    else:
        os.environ["INDGEN_ROBOCASA_ASSETS"] = saved
