"""Dry run of the real protocol against a simulated "robot": the built-in ``stack`` scene (the paper's Stack task in
simulation) runs each episode the plan asks for with the privileged oracle, and the simulator's success predicate
judges it through the script form ``indgen real record RUN --outcome ...``; plan -> record -> report end to end."""

from __future__ import annotations

import json

import pytest

from indgen_vla.app.cli import main
from indgen_vla.app.real.design import RealRun
from indgen_vla.app.real.status import status
from indgen_vla.app.real.store import OPERATOR_FAILURES
from scenes.family import get_scene
from tests.fixtures.levels import level_param


@pytest.fixture
def robot():
    """The simulated robot: stack-scene runners (full episode length, and one cut short so the oracle fails)."""
    import indgen_vla.app.engine  # noqa: F401 - registers standin:oracle
    from indgen_vla.app.engine.rollout import EnvRunner, RunnerConfig
    from policy_wrappers.specs import load_policy
    from scenes.planning import scene_levels

    policy = load_policy("standin:oracle", scene_family=get_scene("stack"))
    levels = scene_levels(get_scene("stack"), ["stack"])
    runners = {n: EnvRunner(RunnerConfig(levels=levels, cameras=(), image_size=(32, 32), max_steps=n,
                                         privileged=True)) for n in (None, 30)}  # fmt: skip
    yield policy, runners
    for r in runners.values():
        r.close()
    policy.close()


def test_plan_record_report_against_a_simulated_robot(tmp_path, capsys, robot):
    import scenes
    from indgen_vla.app.engine.rollout import RunMeta, run_episode
    from indgen_vla.core.protocol.plan import EpisodeJob

    policy, runners = robot
    run = tmp_path / "run"
    assert main(["real", "plan", "--setup", "stack", "--levels", "0:1", "--episodes", "2", "--order", "blocked",
                 "--policy", "standin:oracle", "--operator", "sim", "--out", str(run)]) == 0  # fmt: skip
    rr = RealRun.open(run)
    task = scenes.get_scene("stack").select_tasks(None)[0]
    judged = []
    while (nxt := status(rr)["next"]) is not None:
        level, ep = nxt["level"], nxt["episode"]
        param = level_param("stack", task, "stack", level, None, None)
        assert param == pytest.approx(nxt["param"])  # the simulated riser height is the preset's, in inches
        job = EpisodeJob(task, "stack", level, ep, rr.seeds[ep], param)
        runner = runners[30 if (level, ep) == (1, 1) else None]  # one episode cut short: the oracle fails
        rec = run_episode(
            runner, policy, job, RunMeta("sim", "standin:oracle", "", "stack"), policy.spec.replan_steps
        )
        assert rec.status == "ok"
        mode = rec.failure if rec.failure in OPERATOR_FAILURES else ""
        outcome = "success" if rec.success else f"failure{':' + mode if mode else ''}"
        assert (
            main(["real", "record", str(run), "--outcome", outcome, "--note", f"sim steps {rec.steps}"]) == 0
        )
        judged.append((level, ep, rec.success, rec.failure))
    out = capsys.readouterr().out
    assert "run complete" in out and "report: " in out
    assert [(k, i, ok) for k, i, ok, _ in judged] == [(0, 0, True), (0, 1, True), (1, 0, True), (1, 1, False)]
    summary = json.loads((run / "summary.json").read_text())["axes"]["stack"]
    assert [(r["level"], r["param"], r["n"], r["successes"]) for r in summary["levels"]] == [
        (0, 0.0, 2, 2), (1, 0.25, 2, 1)]  # fmt: skip
    fails = summary["levels"][1]["failures"]
    assert sum(fails.values()) == 2 and fails.get("none") == 1
    report = (run / "report.md").read_text()
    assert (
        "standin:oracle" in report and "insufficient data (n = 2 of 2)" in report
    )  # 2 episodes < the data floor
    assert (run / "plots" / "stack.svg").is_file()
