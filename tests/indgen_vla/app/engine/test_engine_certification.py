"""``indgen evaluate`` against certificates: strictly-harder refused before any episode, per-task certificate
checks (failed levels refused, uncertified levels warned once per axis) and ``--axes-preset``."""

import argparse
import json

import pandas as pd
import pytest

from indgen_vla.app.cli import main
from indgen_vla.app.engine.config import EvalConfig, config_from_args
from indgen_vla.app.engine.run import check_feasible
from indgen_vla.core.errors import ConfigError, InfeasibleLevelError, UnknownNameError
from scenes.certificates import write_json_atomic
from tests.fixtures.resolved import build_plan, evaluate

pytestmark = pytest.mark.filterwarnings("ignore")


def cfg(tmp_path, **kw):
    base = dict(policy="standin:random", scene="stack", axes=("stack",), levels="0:2", episodes=1,
                workers=1, max_steps=3, out=str(tmp_path / "run"))  # fmt: skip
    base.update(kw)
    return EvalConfig.from_flat(**base)


@pytest.mark.parametrize(
    "extra,match",
    [
        (["--axis", "pick_y", "--step", "0.005"], "axis pick_y: level 1's parameter support"),
        (["--axis", "pick_y+distractor", "--axes-preset", "PRESET"], "component pick_y at step 0.005"),
    ],
)
def test_not_strictly_harder_is_refused_before_any_episode(tmp_path, capsys, extra, match):
    preset = tmp_path / "p.yaml"
    preset.write_text("axes:\n  pick_y: {step: 0.005}\n")
    extra = [str(preset) if x == "PRESET" else x for x in extra]
    out = tmp_path / "run"
    rc = main(["evaluate", "--policy", "standin:oracle", "--scene", "pick_place", *extra, "--levels", "0:2",
               "--episodes", "1", "--out", str(out)])  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert rc != 0 and len(err) == 1 and err[0].startswith("error:") and match in err[0], err
    assert "placement jitter" in err[0]
    assert not out.exists()  # refused before the run directory (and any episode) exists


def _cert(root, task, rows, axis="stack", step=0.25):
    full = [{"param": 0.0, "rate": r["successes"] / r["n"], **r} for r in rows]
    for r in full:
        r.setdefault("feasible", r["status"] == "certified")
    write_json_atomic(root / "stack" / task / axis / "certify.json",
                      {"scene": "stack", "task": task, "axis": axis, "step": step, "unit": "in",
                       "steps": {axis: step}, "levels": full})  # fmt: skip


def test_certificates_are_checked_per_task(tmp_path, monkeypatch):
    monkeypatch.setenv("INDGEN_CERT_DIR", str(tmp_path / "certs"))
    root = tmp_path / "certs"
    ok = {"n": 59, "successes": 59, "status": "certified"}
    _cert(root, "orange_on_blue", [{"level": k, **ok} for k in (0, 1, 2)])
    c = cfg(tmp_path)
    assert check_feasible(c, build_plan(c)) == []  # every requested level certified for the first task
    c_all = cfg(tmp_path, task="all")
    plan = build_plan(c_all)
    warnings = check_feasible(c_all, plan)
    assert len(warnings) == 1 and "axis stack" in warnings[0] and "uncertified" in warnings[0]
    assert "orange_on_blue" not in warnings[0] and all(t in warnings[0] for t in plan.tasks[1:])
    second = plan.tasks[1]
    _cert(root, second, [{"level": 0, **ok}, {"level": 1, "n": 3, "successes": 2, "status": "failed"},
                         {"level": 2, "n": 20, "successes": 20, "status": "insufficient"}])  # fmt: skip
    with pytest.raises(InfeasibleLevelError, match=f"task {second}: levels \\+1"):
        check_feasible(c_all, build_plan(c_all))  # the plan holds the certificates as resolved: resolve again
    allowed = cfg(tmp_path, task="all", allow_infeasible=True)
    warnings = check_feasible(allowed, build_plan(allowed))
    assert len(warnings) == 2 and "(--allow-infeasible)" in warnings[0]
    assert f"task {second}: levels +2" in warnings[1]  # 20/20 is not enough evidence


def test_axes_preset_option_reaches_config_and_plan(tmp_path):
    preset = tmp_path / "wide.yaml"
    preset.write_text("axes:\n  stack: {step: 0.5, max_level: 2}\n")
    ns = argparse.Namespace(policy="standin:random", scene="stack", axis="stack", out=str(tmp_path / "r"),
                            axes_preset=str(preset), episodes=1, workers=1, max_steps=3, levels="2")  # fmt: skip
    c = config_from_args(ns)
    assert c.plan.axes_preset == str(preset) and c.plan_dict(["t"], {"stack": [0]}, 3)["axes_preset"] == str(
        preset
    )
    assert "axes_preset" not in cfg(tmp_path).plan_dict(["t"], {"stack": [0]}, 3)  # old runs still resume
    assert build_plan(c).levels == {"stack": (2,)} and build_plan(c).axes["stack"].step == 0.5
    with pytest.raises(UnknownNameError, match="did you mean 'quick'"):
        cfg(tmp_path, axes_preset="quik")
    (tmp_path / "bad.yaml").write_text("axes: 3\n")
    with pytest.raises(ConfigError, match="top-level 'axes:' mapping"):
        cfg(tmp_path, axes_preset=str(tmp_path / "bad.yaml"))


@pytest.mark.slow
def test_axes_preset_reaches_the_workers(tmp_path):
    preset = tmp_path / "wide.yaml"
    preset.write_text("axes:\n  stack: {step: 0.5, max_level: 2}\n")
    c = cfg(tmp_path, axes_preset=str(preset), levels="2")
    out = evaluate(c, quiet=True)
    df = pd.read_parquet(out / "episodes.parquet")
    assert list(df["level"]) == [2] and list(df["param"]) == pytest.approx([1.0])  # 2 steps of 0.5 in
    assert json.loads((out / "manifest.json").read_text())["plan"]["axes_preset"] == str(preset)


@pytest.mark.parametrize("name,levels", [("quick", [-1, 0, 1]), ("paper", [-3, -2, -1, 0, 1, 2, 3])])
def test_shipped_axes_presets_resolve_for_compositions(tmp_path, name, levels):
    c = cfg(tmp_path, scene="pick_place", axes=("pick_y+distractor",), levels=None, axes_preset=name)
    plan = build_plan(c)
    assert list(plan.levels["pick_y+distractor"]) == levels
    assert "pick_y (0.025 m)" in plan.axes["pick_y+distractor"].description
