"""``indgen scenes`` / ``indgen axes`` listings and the certify CLI's error paths."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys

import pytest

from indgen_vla.cli import main
from scenes.catalog import SCENES


def test_scenes_json(capsys):
    assert main(["scenes", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == [*SCENES, "libero_object", "libero_spatial"]
    pp = rows[0]
    assert pp["max_steps"] == 280 and "pick_y" in pp["axes"] and "milk" in pp["tasks"] and pp["needs"] is None


def _listing(tmp_path, *argv: str) -> tuple[list, list]:
    """Run the listing in a fresh interpreter without LIBERO's assets; return its rows and heavy modules loaded."""
    code = (
        "import json, sys; from indgen_vla.cli import main; main(sys.argv[1:]); heavy = ('torch', 'robosuite', "
        "'mujoco', 'lerobot', 'libero'); print(json.dumps(sorted(m for m in heavy if m in sys.modules)), file=sys.stderr)"
    )
    env = {**os.environ, "INDGEN_LIBERO_ASSETS": str(tmp_path), "INDGEN_CACHE": str(tmp_path / "cache")}
    r = subprocess.run(
        [sys.executable, "-c", code, *argv], capture_output=True, text=True, env=env, timeout=120
    )
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout), json.loads(r.stderr.strip().splitlines()[-1])


def test_libero_listed_without_assets_or_simulator(tmp_path):
    """``indgen scenes`` / ``axes`` list libero_object and its axes with no assets, importing no simulator."""
    rows, heavy = _listing(tmp_path, "scenes", "--json")
    assert heavy == [] and not (tmp_path / "cache").exists()
    lib = {r["name"]: r for r in rows}["libero_object"]
    assert lib["axes"] == ["pick_y", "goal_y", "scale", "distractor"] and lib["max_steps"] == 280
    assert "LIBERO's assets" in lib["needs"]
    if importlib.util.find_spec("libero") is not None:
        assert len(lib["tasks"]) == 10 and lib["tasks"][0] == "alphabet_soup"
        assert "missing" in lib["needs"] and "hf download lerobot/libero-assets" in lib["needs"]
    rows, heavy = _listing(tmp_path, "axes", "--json")
    assert heavy == []
    by = {r["name"]: r["scenes"] for r in rows}
    for axis in ("pick_y", "goal_y", "scale", "distractor", "pick_y+distractor"):
        assert "libero_object" in by[axis], axis
    assert "libero_object" not in by["stack"] and "libero_object" not in by["clutter"]
    assert "libero_spatial" in by["scale"] and "libero_spatial" in by["distractor"]
    assert "libero_spatial" not in by["pick_y"] and "libero_spatial" not in by["goal_y"]


def test_libero_spatial_listed_with_scale_and_distractor_only(tmp_path):
    """``indgen scenes`` lists libero_spatial with scale and distractor only; pick_y on it is a one-line error."""
    rows, _ = _listing(tmp_path, "scenes", "--json")
    spatial = {r["name"]: r for r in rows}["libero_spatial"]
    assert spatial["axes"] == ["scale", "distractor"] and spatial["max_steps"] == 280
    if importlib.util.find_spec("libero") is None:
        return
    assert len(spatial["tasks"]) == 10 and "on_the_cookie_box" in spatial["tasks"]
    env = {**os.environ, "INDGEN_LIBERO_ASSETS": str(tmp_path), "INDGEN_CACHE": str(tmp_path / "cache")}
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "indgen_vla.cli",
            "certify",
            "--scene",
            "libero_spatial",
            "--axis",
            "pick_y",
            "--out",
            str(tmp_path / "cert"),
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    err = r.stderr.strip()
    assert r.returncode == 2 and "\n" not in err and "Traceback" not in err, err
    assert "axis of scene libero_spatial 'pick_y'" in err and "known: distractor, scale" in err


def test_axes_json_lists_every_table_row(capsys):
    assert main(["axes", "--json"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    expected = {
        "pick_y",
        "goal_y",
        "scale",
        "pick_x",
        "fixture_x",
        "horizon",
        "clutter",
        "stack",
        "distractor",
    }
    assert expected <= set(rows)
    assert rows["pick_y"]["step"] == 0.025 and rows["pick_y"]["levels"] == "-3..3"
    assert rows["goal_y"]["step"] == 0.0367 and rows["scale"]["step"] == 0.0667
    assert rows["stack"]["levels"] == "0..4" and rows["stack"]["scenes"] == ["stack"]
    assert rows["pick_y+distractor"]["scenes"] == ["pick_place", "stack", "libero_object"]


def test_tables_print(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "400")  # rich wraps cells at the terminal width
    assert main(["scenes"]) == 0
    assert main(["axes"]) == 0
    out = capsys.readouterr().out
    assert (
        "cabinet_pick" in out and "distractor" in out and "libero_object" in out and "LIBERO's assets" in out
    )


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--scene", "stak", "--axis", "stack"], "did you mean 'stack'"),
        (["--scene", "stack", "--axis", "stak"], "did you mean 'stack'"),
        (["--scene", "stack", "--axis", "stack", "--levels", "3:9"], "outside axis stack's range"),
        (["--scene", "stack", "--axis", "stack", "--episodes", "0"], "--episodes must be >= 1"),
    ],
)
def test_certify_bad_input_is_one_line(argv, needle, tmp_path, capsys):
    assert main(["certify", *argv, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and "\n" not in err and "Traceback" not in err
