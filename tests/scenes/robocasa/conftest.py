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
    """The tree, pointed at by INDGEN_ROBOCASA_ASSETS while the RoboCasa tests run, under RoboCasa365 split "all"
    with RoboCasa's own registries (``scenes.robocasa.splits.LEGACY``): the kitchens each seed draws, which the
    tests' seeds and the placeholder results in docs/ were chosen and measured under. test_splits sets its own."""
    names = ("INDGEN_ROBOCASA_ASSETS", "INDGEN_ROBOCASA_SPLIT", "INDGEN_ROBOCASA_OBJ_REGISTRIES")
    saved = {k: os.environ.get(k) for k in names}
    os.environ.update(INDGEN_ROBOCASA_ASSETS=str(placeholder_tree), INDGEN_ROBOCASA_SPLIT="all")
    os.environ.pop("INDGEN_ROBOCASA_OBJ_REGISTRIES", None)
    yield placeholder_tree
    for k, v in saved.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v
