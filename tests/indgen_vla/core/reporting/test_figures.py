"""The paper's figure types: every axis in one figure (Fig. 3/4), the axes × levels overview (Table 2), the contact
sheet of level previews (Fig. 5)."""

import numpy as np
import pytest
from PIL import Image

from indgen_vla.app.cli import main
from indgen_vla.core.reporting.figures import (
    AXES_PLOT,
    KSTAR_LABEL,
    axes_figure,
    axis_order,
    contact_sheet,
    largest_drop,
    overview_lines,
)
from indgen_vla.core.reporting.summary import summarize
from indgen_vla.core.runs.records import EpisodeRecord, RunDir

SIGNED = {"signed": True, "step": 0.025, "unit": "m"}


def _run(path, outcomes, label="h-only", axes_info=None):
    """A run dir from {axis: {level: successes of 10}}; the manifest plans the axes in ``outcomes``' order."""
    axes_info = axes_info or {a: SIGNED for a in outcomes}
    run = RunDir.create_or_resume(path, {"plan": {"tasks": ["milk"]}, "data_regime": label,
                                         "policy": "standin:noop", "axes": axes_info})  # fmt: skip
    run.append([EpisodeRecord(run_id="r", policy="p", data_regime=label, scene="s", task="milk", axis=a, level=k,
                              param=0.025 * k, episode=i, seed=i, success=i < s, steps=1, status="ok", error="")
                for a, levels in outcomes.items() for k, s in levels.items() for i in range(10)])  # fmt: skip
    return run


THREE = {"pick_y": {-1: 6, 0: 9, 1: 1}, "goal_y": {-1: 9, 0: 9, 1: 10}, "scale": {0: 10, 1: 10}}


def _summary(tmp_path, outcomes=THREE, name="a", label="h-only"):
    run = _run(tmp_path / name, outcomes, label)
    return label, summarize(run.episodes(), run.manifest)


def test_axes_figure_has_one_panel_per_axis_with_every_run(tmp_path):
    a = _summary(tmp_path, name="a", label="h-only")
    b = _summary(tmp_path, {"pick_y": {-1: 2, 0: 10, 1: 0}}, name="b", label="h+mg")
    fig = axes_figure([a, b], 0.2, ["pick_y", "goal_y", "scale"], {"pick_y": SIGNED})
    panels = [ax for ax in fig.axes if ax.get_visible()]
    assert [ax.get_title() for ax in panels] == ["pick_y\n2.5 cm per level", "goal_y", "scale"]
    assert panels[0].get_shared_y_axes().joined(panels[0], panels[2])  # one success axis for every panel
    labels = [[line.get_label() for line in ax.get_lines()] for ax in panels]
    assert labels[0].count("h-only") == 1 and labels[0].count("h+mg") == 1  # both runs overlaid on pick_y
    assert "h+mg" not in labels[1] and all("γ = 0.2" in lbls for lbls in labels)
    # k*: h-only breaks at +1 (1/10), h+mg at +1 (0/10; its 2/10 at −1 is not below γ): two rings on pick_y
    rings = [ln for ln in panels[0].get_lines() if ln.get_marker() == "o" and ln.get_markersize() == 10]
    assert sorted((ln.get_xdata()[0], ln.get_ydata()[0]) for ln in rings) == [(1, 0.0), (1, 0.1)]
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend[0] == "h-only (n = 10 per level; task milk)" and KSTAR_LABEL in legend
    assert any(line.get_label() == KSTAR_LABEL for line in panels[0].get_lines())  # a ring of the first run


def test_more_than_four_axes_wrap_onto_a_second_row(tmp_path):
    outcomes = {a: {0: 9, 1: 5} for a in ("pick_y", "goal_y", "scale", "pick_x", "horizon")}
    fig = axes_figure([_summary(tmp_path, outcomes)], 0.2)
    assert len(fig.axes) == 8 and sum(ax.get_visible() for ax in fig.axes) == 5
    # no manifest order given: alphabetical
    assert [ax.get_title() for ax in fig.axes[:5]] == sorted(outcomes)


def test_axis_order_follows_the_manifests():
    s = ("x", {"axes": {"scale": {}, "goal_y": {}, "pick_y": {}, "extra": {}}})
    assert axis_order([s], [{"axes": {"pick_y": {}, "goal_y": {}}}, {"axes": {"scale": {}}}]) == [
        "pick_y", "goal_y", "scale", "extra"]  # fmt: skip


def test_report_writes_axes_png_for_two_or_more_axes_single_and_overlay(tmp_path, capsys):
    a = _run(tmp_path / "a", THREE, "h-only")
    one = _run(tmp_path / "one", {"pick_y": {0: 10, 1: 3}}, "single")
    assert main(["report", str(a.path), str(one.path), "--out", str(tmp_path / "cmp")]) == 0
    with Image.open(a.path / "plots" / AXES_PLOT) as im:  # 3 panels in one row, 130 dpi
        assert im.size == (round((3 * 3.1 + 0.5) * 130), round((2.6 + 0.5 + 0.2) * 130))
    with Image.open(tmp_path / "cmp" / "plots" / AXES_PLOT) as im:  # the overlay: 2 runs, a taller legend
        assert im.size == (round((3 * 3.1 + 0.5) * 130), round((2.6 + 0.5 + 0.4) * 130))
    assert not (one.path / "plots" / AXES_PLOT).exists()  # one axis: its own plot is that figure
    md = (a.path / "report.md").read_text()
    assert "## Overview" in md and md.index("## Overview") < md.index("## Axis `pick_y`")
    assert "## Overview" not in (one.path / "report.md").read_text()
    overlay = (tmp_path / "cmp" / "report.md").read_text()
    assert "| `pick_y` | h-only / standin:noop |" in overlay  # overlay rows name the run


def test_overview_table_matches_table_2(tmp_path):
    """Axes as rows in the planned order, levels as columns, the largest drop from T0 bold and in its column:
    pick_y 9/10 at T0, 1/10 at +1 -> 80 pp; goal_y never falls below T0; scale has no level −1."""
    lines = overview_lines([_summary(tmp_path)], ["pick_y", "goal_y", "scale"])
    header, _, pick, goal, scale = lines[4:9]
    assert header == "| axis | −1 | 0 (T0) | +1 | largest drop from T0 (pp, 95 % CI) |"
    assert pick.startswith(
        "| `pick_y` | 60% [31, 83] n=10 | 90% [60, 98] n=10 | **10% [2, 40] n=10** | 80 pp at +1"
    )
    assert goal.endswith("| 90% [60, 98] n=10 | 100% [72, 100] n=10 | none: no level below T0 |")
    assert scale.startswith("| `scale` | – | 100% [72, 100] n=10 |") and "Every row: task milk." in lines[2]
    # one axis: its own table shows the same
    assert overview_lines([_summary(tmp_path, {"pick_y": {0: 9, 1: 1}}, name="b")]) == []


def test_largest_drop_levels_ties_and_holes():
    def row(k, rate, n=10):
        return {"level": k, "rate": rate, "n": n, "ci_low": max(rate - 0.2, 0), "ci_high": min(rate + 0.2, 1)}

    d = largest_drop([row(-2, 0.1), row(-1, 0.5), row(0, 0.9), row(1, 0.5), row(2, 0.1)])
    assert d["level"] == 2 and d["drop"] == pytest.approx(0.8)  # a tie at equal |k| goes to the + side
    # ties go to the level nearer T0
    assert largest_drop([row(0, 0.9), row(1, 0.2), row(2, 0.2)])["level"] == 1
    lo, hi = largest_drop([row(0, 0.7), row(1, 0.3)])["ci"]  # MOVER: 0.4 ∓ √(0.2² + 0.2²)
    assert lo == pytest.approx(0.4 - 0.2 * 2**0.5) and hi == pytest.approx(0.4 + 0.2 * 2**0.5)
    assert largest_drop([row(0, 0.5), row(1, 0.9)]) == {"level": None, "drop": 0.0}
    # T0 below the data floor: no drop to state
    assert largest_drop([row(0, 0.9, n=2) | {"insufficient": True}, row(1, 0.1)]) is None
    assert largest_drop([row(0, 0.9)]) is None
    # a paired run: the drop and its interval are the level's paired change from T0 (contrasts.py), negated
    v = {"delta": -0.35, "ci": [-0.55, -0.1], "n_pairs": 20, "insufficient": False}
    d = largest_drop([row(0, 0.7), row(1, 0.3) | {"vs_t0": v}])
    assert d == {"level": 1, "drop": 0.35, "ci": (0.55, 0.1)[::-1], "paired": True}
    unpaired = {**v, "n_pairs": 0}  # no pairs: the unpaired interval again
    assert largest_drop([row(0, 0.7), row(1, 0.3) | {"vs_t0": unpaired}])["paired"] is False


def test_contact_sheet_one_tile_per_image_with_its_caption():
    imgs = [np.full((32, 32, 3), 40 * i, np.uint8) for i in range(3)]
    fig = contact_sheet([("pick_y", [(im, f"k = {i}") for i, im in enumerate(imgs)]),
                         ("scale", [(imgs[0], "k = 0")])], "title")  # fmt: skip
    visible = [ax for ax in fig.axes if ax.get_visible()]
    assert len(fig.axes) == 6 and len(visible) == 4
    assert [ax.get_xlabel() for ax in visible] == ["k = 0", "k = 1", "k = 2", "k = 0"]
    assert np.array_equal(visible[2].get_images()[0].get_array(), imgs[2])
    assert visible[0].get_ylabel() == "pick_y" and visible[3].get_ylabel() == "scale"
