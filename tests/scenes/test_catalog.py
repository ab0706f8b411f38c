"""``indgen scenes`` / ``indgen axes`` listings and the certify CLI's error paths."""

from __future__ import annotations

import json

import pytest

from indgen_vla.cli import main
from scenes.catalog import SCENES


def test_scenes_json(capsys):
    assert main(["scenes", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == list(SCENES)
    pp = rows[0]
    assert pp["max_steps"] == 280 and "pick_y" in pp["axes"] and "milk" in pp["tasks"]


def test_axes_json_lists_every_table_row(capsys):
    assert main(["axes", "--json"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    expected = {"pick_y", "goal_y", "scale", "pick_x", "fixture_x", "horizon", "clutter", "stack", "distractor"}
    assert expected <= set(rows)
    assert rows["pick_y"]["step"] == 0.025 and rows["pick_y"]["levels"] == "-3..3"
    assert rows["goal_y"]["step"] == 0.0367 and rows["scale"]["step"] == 0.0667
    assert rows["stack"]["levels"] == "0..4" and rows["stack"]["scenes"] == ["stack"]
    assert rows["pick_y+distractor"]["scenes"] == ["pick_place", "stack"]


def test_tables_print(capsys):
    assert main(["scenes"]) == 0
    assert main(["axes"]) == 0
    out = capsys.readouterr().out
    assert "cabinet_pick" in out and "distractor" in out


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
