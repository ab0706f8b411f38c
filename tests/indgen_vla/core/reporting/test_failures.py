"""Failure modes in summaries, reports, plots and comparisons (counts by hand)."""

import dataclasses
import json

import pandas as pd

from indgen_vla.app.cli import main
from indgen_vla.core.reporting.failures import UNCLASSIFIED, failure_counts, failure_shift
from indgen_vla.core.reporting.report import write_run_report
from indgen_vla.core.reporting.summary import summarize
from indgen_vla.core.runs.records import RunDir
from tests.indgen_vla.core.runs.test_records import rec


def run_with(path, modes_by_level: dict[int, list[str]], regime="h-only") -> RunDir:
    """A run whose episode i of level k failed as ``modes_by_level[k][i]`` ("none" = success)."""
    run = RunDir.create_or_resume(path, {"plan": {"x": 1}, "data_regime": regime, "policy": "standin:noop",
                                         "axes": {"pick_y": {"signed": True}}})  # fmt: skip
    recs = []
    for k, modes in modes_by_level.items():
        for i, m in enumerate(modes):
            status = "error" if m == "error" else "ok"
            recs.append(dataclasses.replace(rec(k, i, success=m == "none", status=status), failure=m))
    run.append(recs)
    return run


def test_counts_and_legacy_rows():
    df = pd.DataFrame({"failure": ["none", "none", "dropped", "", "error"]})
    assert failure_counts(df) == {"none": 2, "dropped": 1, "error": 1, UNCLASSIFIED: 1}
    assert failure_counts(pd.DataFrame({"x": [1, 2]})) == {UNCLASSIFIED: 2}


def test_summary_report_and_plot(tmp_path):
    run = run_with(tmp_path / "r", {0: ["none"] * 5 + ["no_grasp"], 1: ["none", "dropped", "dropped", "misplaced",
                                                                      "no_contact", "error"]})  # fmt: skip
    s = summarize(run.episodes(), run.manifest)
    lv = {r["level"]: r for r in s["axes"]["pick_y"]["levels"]}
    assert lv[0]["failures"] == {"none": 5, "no_grasp": 1}
    assert lv[1]["failures"] == {"none": 1, "no_contact": 1, "dropped": 2, "misplaced": 1, "error": 1}
    write_run_report(run, plots=True)
    md = (tmp_path / "r" / "report.md").read_text()
    assert "| level | none | no_contact | no_grasp | dropped | misplaced | error |" in md
    assert "| 1 | 1 | 1 | 0 | 2 | 1 | 1 |" in md
    assert (tmp_path / "r" / "plots" / "pick_y_failures.png").stat().st_size > 1000


def test_shift_between_runs(tmp_path):
    a = [
        {"level": 0, "failures": {"none": 8, "no_grasp": 2}},
        {"level": 1, "failures": {"none": 2, "no_grasp": 8}},
    ]
    b = [
        {"level": 0, "failures": {"none": 9, "dropped": 1}},
        {"level": 1, "failures": {"none": 6, "dropped": 4}},
    ]
    shift = failure_shift(a, b)
    by = {r["mode"]: r for r in shift["modes"]}
    assert by["no_grasp"]["share_a"] == 0.5 and by["no_grasp"]["share_b"] == 0.0
    assert by["dropped"]["diff"] == 0.25 and by["none"]["diff"] == 0.25
    assert shift["modes"][0]["mode"] == "no_grasp"  # the largest change comes first
    assert (shift["n_a"], shift["n_b"], by["dropped"]["count_a"], by["dropped"]["count_b"]) == (20, 20, 0, 5)
    ra = run_with(tmp_path / "a", {0: ["none", "no_grasp"] * 3})
    rb = run_with(tmp_path / "b", {0: ["none", "dropped"] * 3}, regime="h+mg")
    assert main(["compare", str(ra.path), str(rb.path), "--out", str(tmp_path / "c")]) == 0
    res = json.loads((tmp_path / "c" / "compare.json").read_text())
    assert {r["mode"] for r in res["axes"]["pick_y"]["failures"]["modes"]} == {"none", "no_grasp", "dropped"}
    md = (tmp_path / "c" / "compare.md").read_text()
    assert "| dropped | 0/6 = 0% | 3/6 = 50% | +50 pts |" in md and "descriptive: no CI, not tested" in md
    assert (tmp_path / "c" / "plots" / "pick_y_failures.png").exists()
