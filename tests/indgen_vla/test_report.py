import json
import math

import pytest

from indgen_vla.cli import main
from indgen_vla.records import RunDir
from indgen_vla.report import summarize
from tests.indgen_vla.test_records import rec


def make_run(path, successes_by_level, regime="h-only", errors=0):
    run = RunDir.create_or_resume(path, {"plan": {"x": 1}, "data_regime": regime, "policy": "standin:noop",
                                         "axes": {"pick_y": {"signed": True}}})  # fmt: skip
    recs = []
    for level, (s, n) in successes_by_level.items():
        recs += [rec(level, i, success=i < s) for i in range(n)]
    recs += [rec(0, 100 + i, status="error") for i in range(errors)]
    run.append(recs)
    return run


def test_summary_schema_and_values(tmp_path):
    run = make_run(tmp_path, {-1: (1, 10), 0: (9, 10), 1: (5, 10), 2: (1, 10)}, errors=2)
    s = summarize(run.episodes(), run.manifest, gamma=0.2)
    ax = s["axes"]["pick_y"]
    lv = {r["level"]: r for r in ax["levels"]}
    assert lv[0]["n"] == 10 and lv[0]["successes"] == 9 and lv[0]["errors"] == 2
    assert lv[0]["rate"] == pytest.approx(0.9)
    assert lv[0]["ci_low"] == pytest.approx(0.59585, abs=1e-4)  # Wilson 9/10
    assert lv[-1]["param"] == pytest.approx(-0.025)
    assert ax["break_level"] == {"pos": 2, "neg": -1}
    assert ax["trend"]["pos"]["p_decreasing"] < 0.05


def test_report_cli_writes_outputs(tmp_path, capsys):
    a = make_run(tmp_path / "a", {0: (10, 10), 1: (8, 10), -1: (9, 10)}, regime="h-only")
    b = make_run(tmp_path / "b", {0: (10, 10), 1: (1, 10), -1: (2, 10), -2: (1, 10)}, regime="h+mg")
    assert main(["report", str(a.path), str(b.path), "--out", str(tmp_path / "cmp")]) == 0
    summary = json.loads((a.path / "summary.json").read_text())
    assert summary["gamma"] == 0.2
    assert summary["axes"]["pick_y"]["break_level"] == {"pos": None, "neg": None}
    assert (a.path / "plots" / "pick_y.png").stat().st_size > 1000
    md = (tmp_path / "cmp" / "report.md").read_text()
    assert "h-only" in md and "h+mg" in md and "| **k\\*** |" in md
    assert (tmp_path / "cmp" / "plots" / "pick_y.png").exists()
    b_sum = json.loads((b.path / "summary.json").read_text())
    assert b_sum["axes"]["pick_y"]["break_level"] == {"pos": 1, "neg": -2}  # 2/10 is not < 0.2
    assert not math.isnan(b_sum["axes"]["pick_y"]["levels"][0]["rate"])


def test_report_bad_inputs(tmp_path, capsys):
    assert main(["report", str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: run directory") and "Traceback" not in err and err.count("\n") == 1
    empty = RunDir.create_or_resume(tmp_path / "empty", {"plan": {}})
    assert main(["report", str(empty.path)]) == 2
    assert "no finished episodes" in capsys.readouterr().err
    make_run(tmp_path / "ok", {0: (1, 2)})
    assert main(["report", str(tmp_path / "ok"), "--gamma", "1.5"]) == 2
    assert "--gamma" in capsys.readouterr().err


def test_labels_show_local_checkpoints_relative_to_the_working_directory(tmp_path, monkeypatch):
    from indgen_vla.report import _short_spec

    monkeypatch.chdir(tmp_path)
    assert _short_spec(f"lerobot:{tmp_path}/ckpts/a") == "lerobot:ckpts/a"
    assert _short_spec("lerobot:/elsewhere/b") == "lerobot:/elsewhere/b"
    assert _short_spec("openpi:ws://gpu:8000") == "openpi:ws://gpu:8000"
    assert _short_spec("lerobot:org/model") == "lerobot:org/model" and _short_spec(None) is None
