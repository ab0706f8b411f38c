"""Grouped (one-pass) reductions equal the per-cell filters they replace, on tables with every awkward row a run can
hold: error rows, unknown and legacy failure modes, missing progress, tasks whose parameters differ per level."""

import json

import numpy as np
import pandas as pd
import pytest

from indgen_vla.app.engine.adaptive import ladder_outcomes, outcomes_of
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.reporting.failures import failure_counts, failure_counts_by
from indgen_vla.core.reporting.levels import by_task, level_counts, level_rows, one_param
from indgen_vla.core.reporting.partial_credit import level_progress, level_progress_by
from indgen_vla.core.stats.breakpoint import cells_from_frame, cells_from_records
from indgen_vla.core.stats.frames import group_items
from indgen_vla.core.stats.metrics import success_rate

FAILURES = ["none", "no_contact", "dropped", "", None, "misplaced", "not_a_mode", "error"]


def table(n=400, seed=0) -> pd.DataFrame:
    """Episode rows of three tasks × levels −2..2 in shuffled order; task "c" has a per-episode jitter in its
    parameter at level 1, task "b" a missing parameter at level −1."""
    rng = np.random.default_rng(seed)
    task = rng.choice(["a", "b", "c"], n)
    level = rng.integers(-2, 3, n)
    param = 0.025 * level + np.where(task == "a", 0.0, 0.5)
    param = np.where((task == "c") & (level == 1), param + rng.normal(0, 1e-3, n), param)
    param = np.where((task == "b") & (level == -1) & (rng.random(n) < 0.3), np.nan, param)
    status = np.where(rng.random(n) < 0.1, "error", "ok")
    progress = pd.array([None if rng.random() < 0.2 else int(v) for v in rng.integers(0, 7, n)], dtype="Int8")
    return pd.DataFrame({
        "task": task, "axis": "pick_y", "level": level, "param": param, "episode": np.arange(n),
        "success": rng.random(n) < 0.5, "status": status, "failure": rng.choice(np.array(FAILURES, object), n),
        "progress": progress,
    })  # fmt: skip


def per_cell(df, keys):
    """The cells of ``df`` by filtering it once per key (the reference the grouped reductions replace)."""
    for key in df[keys].drop_duplicates().itertuples(index=False):
        d = df[np.logical_and.reduce([df[k] == v for k, v in zip(keys, key, strict=True)])]
        yield tuple(key), d


@pytest.mark.parametrize("keys", [["level"], ["task", "level"]])
def test_grouped_failures_and_progress_equal_the_per_cell_ones(keys):
    df = table()
    fails, prog = failure_counts_by(df, keys), level_progress_by(df, keys)
    cells = list(per_cell(df, keys))
    assert {k: failure_counts(d) for k, d in cells} == fails
    assert {k: level_progress(d) for k, d in cells if level_progress(d) is not None} == prog
    legacy = df.drop(columns=["failure", "progress"])  # a run written before both columns
    assert failure_counts_by(legacy, keys) == {k: failure_counts(d) for k, d in per_cell(legacy, keys)}
    assert level_progress_by(legacy, keys) == {}


def test_level_rows_from_counts_equal_the_per_level_filter():
    df = table()
    levels = [-3, -2, -1, 0, 1, 2]  # -3 has no row: n = 0, param None, no failures, no progress
    for task, d in per_cell(df, ["task"]):
        rows = level_rows(d, levels, 50, "wilson")
        grouped = {(lv,): c for (t, lv), c in level_counts(df, ["task", "level"]).items() if (t,) == task}
        assert json.dumps(level_rows(d, levels, 50, "wilson", grouped)) == json.dumps(rows)  # NaN rate at -3
        for r in rows:
            x = d[d["level"] == r["level"]]
            ok = x[x["status"] == "ok"]
            want = success_rate(int(ok["success"].sum()), len(ok))
            assert (r["n"], r["successes"], r["errors"]) == (want.n, want.successes, len(x) - len(ok))
            assert r["param"] == one_param(x)
            assert r["failures"] == failure_counts(x) and r["progress"] == level_progress(x)
    pooled = {r["level"]: r["param"] for r in level_rows(df, levels, None, "wilson")}
    assert all(p is None for p in pooled.values())  # the tasks' parameters differ: no one parameter per level
    c = {r["level"]: r["param"] for r in level_rows(df[df["task"] == "c"], levels, None, "wilson")}
    assert c[1] is None and c[2] == pytest.approx(0.55)  # jittered level 1; level 2 one value


def test_by_task_splits_rows_and_counts_like_a_filter_per_task():
    df = table()
    frames, counts = by_task(df)
    assert sorted(frames) == sorted(counts) == ["a", "b", "c"]
    for t in "abc":
        pd.testing.assert_frame_equal(frames[t], df[df["task"] == t])
        assert counts[t] == level_counts(df[df["task"] == t])


def test_cells_from_frame_equal_cells_from_records():
    df = table()
    df["seed_run"] = np.where(
        df["episode"] % 2 == 0, 7, 11
    )  # an integer cluster key prints as 7, not np.int64(7)
    df["param"] = df["param"].fillna(0.3)
    for keys in [(), ("task",), ("seed_run", "task")]:
        cols = ["level", "param", "success", "status", *keys]
        assert cells_from_frame(df[cols], keys) == cells_from_records(df[cols].to_dict("records"), keys)
    no_status = df.drop(columns="status")  # every row counts as ok
    assert cells_from_frame(no_status) == cells_from_records(no_status.to_dict("records"))
    assert cells_from_frame(df[df["status"] == "nope"]) == []
    with pytest.raises(ConfigError, match="lacks column 'param'"):
        cells_from_frame(df.drop(columns="param"))


def test_a_cells_param_is_its_episodes_value_or_their_mean():
    """Each RoboCasa pick_x episode records its own kitchen's offset: the break point's cell takes their mean; a cell
    of one value keeps it bit for bit (0.1 three times, not 0.30000000000000004 / 3)."""
    rows = [{"level": 1, "param": p, "success": True} for p in (0.1, 0.1, 0.1)]
    rows += [{"level": 2, "param": p, "success": False} for p in (0.2, 0.146)]
    for cells in (cells_from_records(rows), cells_from_frame(pd.DataFrame(rows))):
        assert [(c.level, c.param, c.n) for c in cells] == [(1, 0.1, 3), (2, pytest.approx(0.173), 2)]


def test_group_items_gives_python_keys_and_values():
    df = pd.DataFrame({"task": ["a", "a", "b"], "level": [1, 1, -2]})
    items = list(group_items(df.groupby(["task", "level"], sort=False).size()))
    assert items == [(("a", 1), 2), (("b", -2), 1)]
    assert [type(x) for k, v in items for x in (*k, v)] == [str, int, int, str, int, int]
    assert list(group_items(df.groupby("level", sort=False).size())) == [((1,), 2), ((-2,), 1)]


def test_ladder_outcomes_equal_one_filter_per_ladder():
    df = table()
    df["axis"] = np.where(df["episode"] % 3 == 0, "scale", "pick_y")
    want = {(t, a): outcomes_of(df, t, a) for t in "abc" for a in ("pick_y", "scale")}
    assert ladder_outcomes(df) == want and all(want.values())
    assert ladder_outcomes(df.iloc[:0]) == {}
