"""``indgen axes --scene robocasa`` shows the family's own steps and ranges, not the shared table (issue 41)."""

from __future__ import annotations

import json


def test_robocasa_axes_show_each_tasks_pick_step_and_the_families_ranges(capsys):
    from indgen_vla.app.cli import main
    from scenes.robocasa import AXIS_TASKS, PICK_REGIONS

    assert main(["axes", "--scene", "robocasa", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    pick = {t: r for r in rows if r["name"] == "pick_x" for t in r["tasks"]}
    assert set(pick) == set(AXIS_TASKS["pick_x"])
    assert all(
        abs(pick[t]["step"] - PICK_REGIONS[t].width / 5) < 1e-9 and pick[t]["levels"] == "0..4" for t in pick
    )
    (fixture,) = [r for r in rows if r["name"] == "fixture_x"]
    (horizon,) = [r for r in rows if r["name"] == "horizon"]
    assert (fixture["step"], fixture["levels"], horizon["step"], horizon["levels"]) == (
        0.125,
        "0..3",
        0.125,
        "0..3",
    )
    assert fixture["tasks"] == list(AXIS_TASKS["fixture_x"])
