"""scripts/bench_report_scale.py writes run directories that the toolkit reads as real ones: report and compare take
them (paired: common seeds), a resume of the complete one finds nothing to run, an adaptive one stops early. Tiny
sizes (8 tasks, 2 episodes per level); the timings themselves are the benchmark's, never asserted."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from indgen_vla.app.cli import main
from indgen_vla.core.runs.records import COLUMNS, RunDir

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def bench():
    path = ROOT / "scripts" / "bench_report_scale.py"
    spec = importlib.util.spec_from_file_location("bench_report_scale", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture()
def runs(bench, tmp_path, monkeypatch):
    from indgen_vla.app.engine import run

    # build() patches the engine's call into the scene layer to name more tasks: put it back after the test
    monkeypatch.setattr(run, "resolve_scene_plan", run.resolve_scene_plan)
    out = {}
    for name, shift, errors in (("a", 0.0, 0.01), ("b", 0.4, 0.01), ("complete", 0.0, 0.0)):
        out[name] = tmp_path / name
        bench.build(8, str(out[name]), shift, error_rate=errors, episodes=2)
    return out


@pytest.mark.slow  # ~12 s: a report, a compare and a resume in a subprocess (benchmarks run on demand)
def test_built_runs_read_report_compare_and_resume_like_real_ones(bench, runs, tmp_path, capsys):
    a = RunDir.open(runs["a"])
    e = a.episodes()
    assert list(e.columns) == list(COLUMNS) and len(e) == 8 * 3 * 7 * 2
    assert {"bottle", "cylinder", "milk_1"} <= set(e["task"])  # pick_place's 7 tasks and one renamed copy
    ok = e[e["status"] == "ok"]
    assert set(ok["failure"]) <= {"none", "no_contact", "no_grasp", "dropped", "misplaced", "timeout_holding"}
    assert (ok["success"] == (ok["failure"] == "none")).all() and (ok["progress"][ok["success"]] == 5).all()
    assert set(e.loc[e["status"] == "error", "failure"]) <= {"error"}
    assert a.manifest["plan"]["episodes"] == 2 and "fingerprint" in a.manifest
    assert main(["report", str(runs["a"])]) == 0
    summary = json.loads((runs["a"] / "summary.json").read_text())
    assert len(summary["axes"]["pick_y"]["tasks"]) == 8
    assert main(["compare", str(runs["a"]), str(runs["b"]), "--out", str(tmp_path / "c")]) == 0
    result = json.loads((tmp_path / "c" / "compare.json").read_text())
    assert result["test"] == "mcnemar_exact"  # common random numbers: paired like common seeds
    capsys.readouterr()
    resume = subprocess.run([sys.executable, str(ROOT / "scripts" / "bench_report_scale.py"), "resume", "--tasks",
                             "8", "--episodes", "2", "--out", str(runs["complete"])], cwd=ROOT, capture_output=True,
                            text=True, timeout=300)  # fmt: skip
    assert resume.returncode == 0, resume.stderr[-2000:]
    assert "all 336 planned episodes are already in" in resume.stderr + resume.stdout


def test_builds_are_deterministic_and_an_adaptive_one_stops_early(bench, runs, tmp_path):
    again = tmp_path / "again"
    bench.build(8, str(again), 0.0, error_rate=0.01, episodes=2)
    pd.testing.assert_frame_equal(RunDir.open(runs["a"]).episodes(), RunDir.open(again).episodes())
    timing = bench.build(8, str(tmp_path / "ad"), 0.0, "kstar", episodes=10)
    assert timing["rounds"] >= 2 and 0 < timing["rows"] < 8 * 3 * 7 * 10
    assert RunDir.open(tmp_path / "ad").manifest["plan"]["adaptive"]["mode"] == "kstar"
