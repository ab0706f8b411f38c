"""RoboCasa365's episode length is each task's own, as RoboCasa registers it (issue 41)."""

from __future__ import annotations

import json
import subprocess

import pytest

from scenes.robocasa.departures import DEVIATIONS, SPAWN_JITTER
from scenes.robocasa.horizons import TASK_HORIZONS


def _python():
    from scenes.robocasa.environment import find_python

    return find_python(required=False)


needs_venv = pytest.mark.skipif(
    _python() is None, reason="RoboCasa venv missing: run 'make robocasa' (indgen setup robocasa, ~1 min)"
)


@needs_venv
def test_every_tasks_horizon_is_robocasas_registered_one():
    """robocasa/robocasa robocasa/utils/dataset_registry_utils.py ``get_task_horizon(task)`` returns the task's
    ``horizon`` of ``ATOMIC_TASK_DATASETS`` / ``COMPOSITE_TASK_DATASETS`` in robocasa/utils/dataset_registry.py
    (be22d659 = the pinned rlinf-robocasa365 1.0.1): asked of the pinned install itself, for all 17 tasks."""
    from scenes.family import get_scene

    tasks = get_scene("robocasa").tasks
    assert set(TASK_HORIZONS) == set(tasks) and len(tasks) == 17
    code = (
        "import json, sys\nfrom robocasa.utils.dataset_registry_utils import get_task_horizon\n"
        "print(json.dumps({t: get_task_horizon(t) for t in sys.argv[1:]}))"
    )
    out = subprocess.run([str(_python()), "-c", code, *tasks], capture_output=True, text=True, check=True)
    assert json.loads(out.stdout.strip().splitlines()[-1]) == TASK_HORIZONS


def test_a_task_runs_its_own_horizon_unless_max_steps_replaces_it():
    from indgen_vla.core.protocol.deviations import protocol_deviations
    from scenes.family import get_scene

    sc = get_scene("robocasa")
    assert sc.task_max_steps("PickPlaceSinkToCounter") == 900 and sc.task_max_steps("TurnOnBlender") == 300
    assert sc.task_max_steps("PickPlaceCounterToCabinet@11-34") == 750  # a canonical kitchen keeps the task's
    facts = {"max_steps": dict(TASK_HORIZONS), "horizon_source": "RoboCasa's get_task_horizon"}
    assert protocol_deviations(None, facts) == []
    (line,) = protocol_deviations(500, facts)
    assert "--max-steps 500 replaces RoboCasa's get_task_horizon" in line and "300..900" in line
    assert protocol_deviations(500, {"max_steps": 280}) == []  # a family with one horizon: no deviation


def _noop_episode(task: str, axis: str, out) -> tuple:
    """``indgen evaluate --policy standin:noop --task TASK --levels 0 --episodes 1``: its episodes, manifest, dir."""
    import pandas as pd

    from indgen_vla.app.engine.config import EvalConfig
    from tests.fixtures.resolved import evaluate

    cfg = EvalConfig.from_flat(policy="standin:noop", scene="robocasa", task=task, axes=(axis,), levels="0", episodes=1,
                     workers=1, out=str(out))  # fmt: skip
    run = evaluate(cfg, quiet=True)
    return pd.read_parquet(run / "episodes.parquet"), json.loads((run / "manifest.json").read_text()), run


@needs_venv
@pytest.mark.slow  # ~15 s of CPU (300 RoboCasa steps, the engine); test_the_oracle_turns_the_blender_on checks the env
def test_a_noop_episode_on_turn_on_blender_runs_300_steps(placeholders, tmp_path):
    """robocasa/utils/dataset_registry.py registers TurnOnBlender's horizon as 300: a standin:noop episode runs
    that many steps; the manifest and fingerprint record every task's registered horizon, the standing deviations
    and no --max-steps one; its
    summary.json and report.md name the level uncertified."""
    df, manifest, run = _noop_episode("TurnOnBlender", "fixture_x", tmp_path / "run")
    assert list(df.status) == ["ok"] and list(df.steps) == [300] and not df.success.any()
    assert manifest["fingerprint"]["horizon"] == TASK_HORIZONS and manifest["deviations"] == list(DEVIATIONS)
    assert manifest["resolved"]["environment"]["protocol"]["max_steps"]["TurnOnBlender"] == 300
    summary = json.loads((run / "summary.json").read_text())
    assert summary["axes"]["fixture_x"]["certification"] == {"TurnOnBlender": {"uncertified": [0]}}
    assert (
        "**uncertified** (no certificate with enough evidence; `indgen certify` can make one) at TurnOnBlender: 0"
        in ((run / "report.md").read_text())
    )


@needs_venv
@pytest.mark.slow  # ~30 s of CPU (900 RoboCasa steps); the 300-step episode above runs by default
def test_a_noop_episode_on_pick_place_sink_to_counter_runs_900_steps(placeholders):
    """robocasa/utils/dataset_registry.py registers PickPlaceSinkToCounter's horizon as 900 (the old flat 500
    cut it 400 steps short). Level 0 at the task's own step: a narrow sink kitchen narrows its own window, so the
    plan accepts it (a 3 cm step is refused: level 1's window would overlap level 0's)."""
    import numpy as np

    from tests.fixtures.levels import level_env

    env = level_env("robocasa", task="PickPlaceSinkToCounter", axis="pick_x", cameras=())
    try:
        env.reset(seed=0)
        steps, done = 0, False
        while not done:
            _, _, term, trunc, _ = env.step(np.zeros(12))
            steps, done = steps + 1, term or trunc
        assert env.max_steps == steps == 900 and trunc
    finally:
        env.close()


@needs_venv
def test_the_spawn_jitter_robocasa_defaults_to_is_recorded_as_set_to_zero(placeholders):
    """robocasa/robocasa robocasa/environments/kitchen/kitchen.py: Kitchen.__init__ defaults
    robot_spawn_deviation_pos_x=0.15, robot_spawn_deviation_pos_y=0.05; the manifest's protocol facts record that
    default beside the 0 the worker builds with, and the deviation in words."""
    from scenes.family import get_scene

    code = (
        "import inspect\nfrom robocasa.environments.kitchen.kitchen import Kitchen\n"
        "p = inspect.signature(Kitchen.__init__).parameters\n"
        "print(p['robot_spawn_deviation_pos_x'].default, p['robot_spawn_deviation_pos_y'].default)"
    )
    out = subprocess.run([str(_python()), "-c", code], capture_output=True, text=True, check=True)
    x, y = (float(v) for v in out.stdout.strip().splitlines()[-1].split())
    assert SPAWN_JITTER["robocasa_default"] == {"pos_x": x, "pos_y": y}
    facts = get_scene("robocasa").environment.protocol_facts()
    assert facts["spawn_jitter"] == {**SPAWN_JITTER} and facts["spawn_jitter"]["pos_x"] == 0.0
    assert any(d.startswith("robot spawn jitter 0") for d in facts["deviations"])


@needs_venv
def test_the_base_controller_enters_the_fingerprint(placeholders):
    """The worker builds with create_env's controller config (robocasa/utils/env_utils.py, be22d659), not
    robosuite's default, since issue 41: a run made before reads another simulator and is not resumed as this one."""
    from indgen_vla.core.protocol.fingerprint import build_fingerprint, differences
    from scenes.family import get_scene
    from scenes.robocasa import BASE_CONTROLLER

    env = {"scene": "robocasa", "environment": get_scene("robocasa").environment.environment_versions()}
    kw = dict(max_steps=None, warmup_steps=0, cameras=(), image_size=(0, 0), render_backend="", policy={})
    now = build_fingerprint({"environment": env}, {}, **kw)
    assert now["simulator"]["worker:base_controller"] == BASE_CONTROLLER
    before = {**env, "environment": {k: v for k, v in env["environment"].items() if k != "base_controller"}}
    diff = differences(build_fingerprint({"environment": before}, {}, **kw), now)
    assert [(f, changes) for f, _, _, changes in diff] == [("simulator", True)]
