"""Training support: which evaluated levels a policy's training data covered, and how the report marks them."""

import pytest

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.training_support import (
    TRAINED_NOTE,
    TrainedCell,
    cells_from_json,
    cells_from_records,
    cells_to_json,
    fully_trained,
    support_text,
    trained_levels,
    trained_text,
)
from indgen_vla.core.reporting.figures import plot_axis
from indgen_vla.core.reporting.report import render_markdown
from indgen_vla.core.reporting.summary import summarize
from indgen_vla.core.runs.records import RunDir
from tests.indgen_vla.core.runs.test_records import rec


def test_a_cell_covers_its_own_level_and_parameter_and_t0_on_every_axis():
    c = TrainedCell("pick_place", "milk", 2, "pick_y", 0.05)
    assert c.covers("pick_place", "milk", "pick_y", 2, 0.05)
    assert c.covers(
        "pick_place", "milk", "pick_y", 2, None
    )  # a level with no episode yet: matched by its index
    assert not c.covers("pick_place", "milk", "pick_y", 2, 0.1)  # the same index at another --step
    assert not c.covers("pick_place", "milk", "scale", 2, 0.05)
    assert not c.covers("pick_place", "bread", "pick_y", 2, 0.05)
    assert not c.covers("stack", "milk", "pick_y", 2, 0.05)
    t0 = TrainedCell("pick_place", "milk", 0)  # recorded without --axis
    assert t0.covers("pick_place", "milk", "scale", 0, 1.0) and not t0.covers(
        "pick_place", "milk", "scale", 1, 1.1
    )
    assert TrainedCell("pick_place", "milk", 0, "pick_y", 0.0).covers("pick_place", "milk", "scale", 0, 1.0)
    with pytest.raises(ConfigError, match="names no axis"):
        TrainedCell("pick_place", "milk", 1)


def test_cells_from_sidecar_records_count_episodes_and_round_trip_through_json():
    records = [{"scene": "pick_place", "task": "milk", "level": 0, "seed": 1},
               {"scene": "pick_place", "task": "milk", "level": 1, "axis": "pick_y", "param": 0.025, "seed": 2},
               {"scene": "pick_place", "task": "milk", "level": 1, "axis": "pick_y", "param": 0.025, "seed": 3}]  # fmt: skip
    cells = cells_from_records(records)
    assert sorted((c.level, c.axis, c.episodes) for c in cells) == [(0, None, 1), (1, "pick_y", 2)]
    assert cells_from_json(cells_to_json(cells)) == tuple(cells)
    assert cells_from_json(None) == () and cells_from_json([]) == ()
    with pytest.raises(ConfigError, match="malformed"):
        cells_from_json([{"scene": "pick_place", "level": 1}])
    assert support_text(cells) == "pick_place T0 (tasks milk); pick_place pick_y levels 1 (tasks milk)"


def test_trained_levels_per_task_and_the_report_cell_marks():
    cells = [TrainedCell("s", "a", k, "pick_y", 0.025 * k) for k in (0, 1)] + [TrainedCell("s", "b", 0)]
    rows = {t: [{"level": k, "param": 0.025 * k} for k in (-1, 0, 1, 2)] for t in ("a", "b")}
    got = trained_levels(cells, "s", "pick_y", rows)
    assert got == [{"level": 0, "tasks": ["a", "b"]}, {"level": 1, "tasks": ["a"]}]
    axis = {"pooled_tasks": ["a", "b"], "trained": got}
    assert [trained_text(axis, k) for k in (-1, 0, 1)] == ["", " · trained", " · trained (1/2 tasks)"]
    assert fully_trained(axis) == [0]
    assert trained_levels(cells, "other_scene", "pick_y", rows) == []


def _run(path, training=None):
    manifest = {
        "plan": {"x": 1},
        "policy": "standin:noop",
        "scene": "s",
        "axes": {"pick_y": {"signed": True}},
    }
    if training is not None:
        manifest["training_levels"] = training
    run = RunDir.create_or_resume(path, manifest)
    run.append([rec(k, i, success=i < 8 - 3 * abs(k)) for k in (-1, 0, 1, 2) for i in range(10)])
    return run


def test_summary_report_and_plot_mark_the_trained_levels(tmp_path):
    training = cells_to_json([TrainedCell("s", "t", k, "pick_y", 0.025 * k, 5) for k in (0, 1)])
    run = _run(tmp_path / "trained", training)
    s = summarize(run.episodes(), run.manifest)
    assert s["axes"]["pick_y"]["trained"] == [{"level": 0, "tasks": ["t"]}, {"level": 1, "tasks": ["t"]}]
    md = render_markdown([("ACT 0:1", s)])
    assert TRAINED_NOTE in md
    marked = [line.split(" | ")[0] for line in md.splitlines() if "· trained" in line]
    assert marked == ["| 0", "| 1"]
    plain = _run(tmp_path / "plain")
    s_plain = summarize(plain.episodes(), plain.manifest)
    assert "trained" not in s_plain["axes"]["pick_y"] and "trained" not in render_markdown([("ACT", s_plain)])


def test_the_plot_shades_the_trained_levels(tmp_path):
    from matplotlib.figure import Figure

    from indgen_vla.core.reporting.figures import draw_curves

    run = _run(
        tmp_path / "run", cells_to_json([TrainedCell("s", "t", k, "pick_y", 0.025 * k) for k in (0, 1)])
    )
    a = summarize(run.episodes(), run.manifest)["axes"]["pick_y"]
    ax = Figure().subplots()
    draw_curves(ax, [("ACT", a)], 0.2)
    bands = [
        p for p in ax.patches if p.get_alpha() == 0.08
    ]  # axvspan's Rectangles (the CI bands are not patches)
    spans = sorted(round(p.get_x() + p.get_width() / 2) for p in bands)
    assert spans == [0, 1] and "trained levels" in ax.get_legend_handles_labels()[1]
    assert plot_axis([("ACT", a)], "pick_y", 0.2, tmp_path / "p.png").stat().st_size > 1000
