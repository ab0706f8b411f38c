"""The package tree is the layering: indgen_vla's top holds only the public names and the two layer packages."""

from pathlib import Path

import indgen_vla

PKG = Path(indgen_vla.__file__).parent


def test_top_level_is_the_two_layers():
    """A new module goes into app/ or core/, where the layers contract (pyproject.toml) covers it."""
    top = sorted(p.name for p in PKG.iterdir() if p.name != "__pycache__" and not p.name.startswith("."))
    assert top == ["__init__.py", "app", "core"], top
