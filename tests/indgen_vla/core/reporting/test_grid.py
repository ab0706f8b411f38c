"""The 2-D grid of held axes A@B=j: rows found, cells and k* against hand-computed values, the heatmap, end to end."""

import json
import math

import numpy as np
import pytest

from indgen_vla.core.reporting.grid import (
    cell_text,
    find_grids,
    grid_lines,
    grid_matrix,
    grid_plot_name,
    plot_grids,
)
from indgen_vla.core.reporting.report import _fmt_break, _fmt_rate, render_markdown
from indgen_vla.core.reporting.summary import summarize
from indgen_vla.core.runs.records import RunDir
from tests.indgen_vla.core.runs.test_records import rec

# (held level j) -> level k -> (successes, n): row 0 breaks at k = 1; row 2's level 1 is below the data floor (n < 5)
CELLS = {0: {0: (9, 10), 1: (1, 10)}, 2: {0: (8, 10), 1: (1, 2)}}


def grid_summary(tmp_path, cells=CELLS, inner="pick_y@distractor={}"):
    names = {j: inner.format(j) for j in cells}
    run = RunDir.create_or_resume(tmp_path, {"plan": {}, "policy": "standin:noop",
                                             "axes": {n: {"signed": True} for n in names.values()}})  # fmt: skip
    run.append([rec(k, i, success=i < s, axis=names[j]) for j, row in cells.items() for k, (s, n) in row.items()
                for i in range(n)])  # fmt: skip
    return summarize(run.episodes(), run.manifest, gamma=0.2)


def test_rows_are_the_held_axes_of_one_pair_and_the_axis_itself_is_row_0():
    a = {"levels": []}
    grids = find_grids({"pick_y@distractor=1": a, "pick_y@distractor=3": a, "goal_y@scale=-1": a, "scale": a})
    assert [(g.inner, g.held, list(g.rows)) for g in grids] == [("pick_y", "distractor", [1, 3])]
    # A itself is row 0 (the same environments as A@B=0) where the run has no A@B=0
    (g,) = find_grids({"pick_y@distractor=2": a, "pick_y": a, "pick_y@distractor=bad": a})
    assert g.names == {0: "pick_y", 2: "pick_y@distractor=2"}
    assert find_grids({"pick_y@distractor=2": a, "goal_y": a}) == []  # one row is no grid
    assert grid_plot_name(g) == "grid_pick_y_distractor.png"


def test_matrix_and_cells_hold_the_pooled_rates_and_n(tmp_path):
    (g,) = find_grids(grid_summary(tmp_path)["axes"])
    js, ks, rate, n = grid_matrix(g)
    assert (js, ks) == ([0, 2], [0, 1])
    np.testing.assert_allclose(rate, [[0.9, 0.1], [0.8, np.nan]])  # 1/2 is below the data floor: no rate
    assert n.tolist() == [[10, 10], [10, 2]]
    assert cell_text(0.9, 10) == "90%\nn=10" and cell_text(math.nan, 2) == "insufficient\nn=2"
    assert cell_text(math.nan, 0) == "–"
    assert cell_text(0.9, 10, (0.596, 0.982)) == "90%\n[60, 98]\nn=10"


def test_grid_table_rows_are_held_levels_with_the_reports_cells_and_each_rows_kstar(tmp_path):
    s = grid_summary(tmp_path)
    lines = grid_lines([("h-only", s)], _fmt_rate, _fmt_break)
    assert lines[0] == "## Grid `pick_y` × `distractor`"
    header = lines.index("| distractor j \\ pick_y k | 0 | 1 | k\\* |")
    row0, row2 = (line.split(" | ") for line in lines[header + 2 : header + 4])
    # Wilson 95 %: 9/10 -> [60, 98], 1/10 -> [2, 40], 8/10 -> [49, 94]
    assert (
        row0[0] == "| 0"
        and row0[1].startswith("90% [60, 98] (n=10)")
        and row0[2].startswith("10% [2, 40] (n=10)")
    )
    assert row0[3] == "+: L1, −: none |"  # 10 % < γ = 0.2 at k = 1; no negative level evaluated
    assert row2[0] == "| 2" and row2[1].startswith("80% [49, 94] (n=10)")
    assert row2[2] == "insufficient data (n = 2)" and row2[3] == "+: undetermined, −: none |"
    assert (
        "each row its own ladder; task t." in lines[2]
        and "--axes pick_y@distractor=2:pick_y@distractor=0" in lines[2]
    )
    # the report places it after the overview, and a single held axis makes no grid
    md = render_markdown([("h-only", s)])
    assert md.index("## Grid `pick_y` × `distractor`") < md.index("## Axis `pick_y@distractor=0`")
    one = grid_summary(tmp_path / "one", {2: CELLS[2]})
    assert "## Grid" not in render_markdown([("h-only", one)])


def test_several_runs_get_a_table_each_and_one_heatmap_with_a_panel_each(tmp_path):
    a, b = grid_summary(tmp_path / "a"), grid_summary(tmp_path / "b", {0: CELLS[0], 1: CELLS[2]})
    md = "\n".join(grid_lines([("A", a), ("B", b)], _fmt_rate, _fmt_break))
    assert "## Grid `pick_y` × `distractor` — A" in md and "## Grid `pick_y` × `distractor` — B" in md
    (path,) = plot_grids([("A", a), ("B", b)], 0.2, tmp_path / "plots")
    assert path == tmp_path / "plots" / "grid_pick_y_distractor.png" and path.stat().st_size > 5000


@pytest.mark.filterwarnings("ignore")
@pytest.mark.slow  # ~7 s: a grid of runs; the grid's report is unit-tested by default
def test_evaluate_runs_a_grid_from_one_range_and_reports_it(tmp_path, capsys):
    """pick_y with distractor held at 0 and 1, from the --axis range: expanded in the manifest, A@B=0 shares T0 with
    pick_y (the same environment) and A@B=1 does not; the report holds the grid and its heatmap."""
    import pandas as pd

    from indgen_vla.app.cli import main

    out = tmp_path / "run"
    args = ["evaluate", "--policy", "standin:random", "--scene", "pick_place", "--axis", "pick_y,pick_y@distractor=0:1",
            "--levels", "0:1", "--episodes", "2", "--workers", "1", "--max-steps", "8", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["config"]["axes"] == ["pick_y", "pick_y@distractor=0", "pick_y@distractor=1"]
    assert manifest["t0_sharing"]["groups"] == {"milk": [["pick_y", "pick_y@distractor=0"]]}
    steps = manifest["resolved"]["environment"]["successors"]["pick_y@distractor=1"]
    assert steps == {"type": "Held", "steps": {"pick_y": 0.025, "distractor": 1.0, "held_level": 1.0}}
    df = pd.read_parquet(out / "episodes.parquet").set_index(["axis", "level", "episode"])
    assert (df.loc["pick_y@distractor=0", "shared_from"].loc[0] == "pick_y").all()
    assert (df.loc["pick_y@distractor=1", "shared_from"] == "").all()
    assert df.loc["pick_y@distractor=1", "param"].loc[1].tolist() == df.loc["pick_y", "param"].loc[1].tolist()
    md = (out / "report.md").read_text()
    assert "## Grid `pick_y` × `distractor`" in md and "| 1 | insufficient data (n = 2 of 2) |" in md
    assert main(["report", str(out)]) == 0  # the PNGs, the heatmap among them, are drawn by `indgen report`
    assert (out / "plots" / "grid_pick_y_distractor.png").stat().st_size > 5000
    bad = [*args[:6], "pick_y@distractor=1:0", *args[7:-1], str(tmp_path / "bad")]
    capsys.readouterr()
    assert main(bad) == 2
    err = capsys.readouterr().err
    assert "start 1 is after end 0; write it as pick_y@distractor=0:1" in err and err.count("\n") == 1
