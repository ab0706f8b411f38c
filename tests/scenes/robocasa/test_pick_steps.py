"""RoboCasa365's pick_x step is each task's own (appendix B: the valid sampling region / the number of
progressions, 5), resolved and recorded before any episode runs; a step whose levels leave a region is refused."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.axis_ref import AxisRef
from scenes.family import get_scene
from tests.scenes.robocasa.test_robocasa import needs_venv

# hand-computed: RoboCasa 1.0.1's pick region (m) / 5
STEPS = {"CheesyBread": 0.2, "CoffeeSetupMug": 0.06, "PickPlaceCabinetToCounter": 0.1,
         "PickPlaceCounterToBlender": 0.1, "PickPlaceCounterToCabinet": 0.12, "PickPlaceCounterToDrawer": 0.12,
         "PickPlaceCounterToSink": 0.06, "PickPlaceCounterToStandMixer": 0.06, "PickPlaceSinkToCounter": 0.05}  # fmt: skip


def test_each_tasks_step_is_its_region_over_five():
    from scenes.family import get_scene
    from scenes.robocasa import AXIS_TASKS

    sc = get_scene("robocasa")
    assert list(STEPS) == list(AXIS_TASKS["pick_x"])  # appendix B's nine tasks, in its order
    for task, step in STEPS.items():
        axis = sc.successor(AxisRef.parse("pick_x"), task=task).axis
        assert (axis.step, axis.max_level) == (step, 4)
    assert (
        sc.successor(AxisRef.parse("pick_x"), task="PickPlaceSinkToCounter@11-34").axis.step == 0.05
    )  # a canonical kitchen
    # a preset's range narrows the levels and keeps the step (the quick preset: levels 0..1)
    assert (
        sc.successor(
            AxisRef.parse("pick_x"), overrides={"pick_x": {"max_level": 1}}, task="PickPlaceSinkToCounter"
        ).axis.step
        == 0.05
    )
    # --step and a preset's step are the user's: the same for every task
    assert sc.successor(AxisRef.parse("pick_x"), 0.05, task="PickPlaceCounterToCabinet").axis.step == 0.05
    assert (
        sc.successor(
            AxisRef.parse("pick_x"), overrides={"pick_x": {"step": 0.05}}, task="CheesyBread"
        ).axis.step
        == 0.05
    )
    # in a composition the pick component takes the task's step
    comp = sc.successor(AxisRef.parse("pick_x+horizon"), task="PickPlaceCounterToSink")
    assert [p.axis.step for p in comp.parts] == [0.06, 0.125]
    with pytest.raises(ConfigError, match="not on axis pick_x's task list"):
        sc.successor(AxisRef.parse("pick_x"), task="CloseStandMixerHead")


def test_the_worker_gets_what_its_pick_window_needs():
    """The worker divides each kitchen's range itself (``pick_window.level_offset``) for the task's own step (also
    when --step equals it); a user's step stays metres; only pick_x alone records the episode's offset as param."""
    from scenes.family import get_scene

    sc = get_scene("robocasa")

    def pick(task, axis="pick_x", step=None, level=2):
        return sc.level_config(task, sc.successor(AxisRef.parse(axis), step, task=task), level, (), (64, 64))[
            "pick"
        ]

    assert pick("CheesyBread") == {"cfg": "cheese", "declared": 1.0, "level": 2, "top": 4, "step": None,
                                   "progressions": 5, "report": True}  # fmt: skip
    assert pick("CheesyBread", step=0.2)["step"] is None and pick("CheesyBread", step=0.05)["step"] == 0.05
    composed = pick("PickPlaceCounterToSink", "pick_x+horizon")
    assert (composed["step"], composed["report"], composed["top"], composed["cfg"]) == (None, False, 3, "obj")
    assert pick("PickPlaceCounterToSink", "base_y") is None


@pytest.mark.parametrize(
    ("task", "step", "fits"),
    [("PickPlaceSinkToCounter", 0.0525, True), ("PickPlaceSinkToCounter", 0.06, False),  # 4 x 0.06 + 0.04 > 0.25
     ("PickPlaceCounterToCabinet", 0.12, True), ("PickPlaceCabinetToCounter", 0.12, False)],  # 0.52 > 0.50
)  # fmt: skip
def test_a_step_whose_top_level_leaves_the_region_is_refused(task, step, fits):
    from indgen_vla.core.protocol.progression import ProgressionError
    from scenes.family import get_scene

    sc = get_scene("robocasa")
    successor = sc.successor(AxisRef.parse("pick_x"), step, task=task)
    if fits:
        sc.check_progression(task, successor, True)
        return
    with pytest.raises(ProgressionError, match=rf"{task}'s level-4 pick window .* region") as e:
        sc.check_progression(task, successor, True)
    assert "\n" not in str(e.value) and "drop --step" in str(e.value)


def _site_packages() -> Path:
    from scenes.robocasa.environment import find_python

    return next(Path(find_python()).parent.parent.glob("lib/python3*/site-packages"))


@needs_venv
def test_pick_regions_are_the_pinned_robocasas_own():
    """Each PICK_REGIONS entry against the installed RoboCasa's source at the line it cites: ``size=(width, ..)``
    inside the named object config of the task's class (or the class it inherits _get_obj_cfgs from)."""
    from scenes.robocasa import PICK_REGIONS

    atomic = _site_packages() / "robocasa/environments/kitchen/atomic"
    for task, region in PICK_REGIONS.items():
        file, line = region.source.split(":")
        lines = (atomic / file).read_text().splitlines()
        n = int(line) - 1
        size = re.search(r"size=\(([\d.]+),", lines[n])
        assert size and float(size.group(1)) == region.width, f"{task}: {region.source} is {lines[n].strip()}"
        above = lines[:n]
        cfg = next(ln for ln in reversed(above) if "name=" in ln)
        assert f'name="{region.cfg}"' in cfg, f"{task}: the config at {region.source} is {cfg.strip()}"
        owner = (
            next(ln for ln in reversed(above) if ln.startswith("class ")).split("(")[0].removeprefix("class ")
        )
        src = "\n".join(lines)
        assert owner == task or re.search(rf"^class {task}\({owner}\)", src, re.M), f"{task}: {owner}'s line"


@needs_venv
def test_the_plan_records_each_tasks_step_and_its_offsets(placeholders):
    """--task all on pick_x: every level's parameter is the task's own offset in metres, the plan carries each
    task's step (resume matches it) and the manifest's environment names them; --step is one step for all."""
    from indgen_vla.app.engine.config import EvalConfig
    from scenes.planning import resolve_scene_plan

    plan = resolve_scene_plan(get_scene("robocasa"), "all", ["pick_x"], "0:4")
    params = plan.params()
    for task, step in STEPS.items():
        assert [params[(task, "pick_x", k)] for k in range(5)] == pytest.approx([k * step for k in range(5)])
    assert plan.task_steps == {"pick_x": {t: {"pick_x": s} for t, s in STEPS.items()}}
    described = plan.builder.describe()["successors"]["pick_x"]
    assert described == {"type": "Shift", "task_steps": plan.task_steps["pick_x"]}
    cfg = EvalConfig.from_flat(policy="standin:noop", scene="robocasa", axes=("pick_x",), out="x")
    assert (
        cfg.plan_dict(list(plan.tasks), {"pick_x": [0]}, None, plan.task_steps)["task_steps"]
        == plan.task_steps
    )
    assert "task_steps" not in cfg.plan_dict(
        list(plan.tasks), {"pick_x": [0]}, None
    )  # other families: unchanged
    one = resolve_scene_plan(get_scene("robocasa"), "all", ["pick_x"], "0:1", step=0.05)
    assert one.task_steps == {} and {c.param for c in one.cells if c.level == 1} == {0.05}
    horizon = resolve_scene_plan(
        get_scene("robocasa"), "all", ["base_y"], "0:1"
    )  # no per-task step: nothing recorded
    assert horizon.task_steps == {} and horizon.builder.task_successors == {}


@needs_venv
def test_a_step_that_leaves_a_region_exits_2_before_any_episode(placeholders, tmp_path, capsys):
    from indgen_vla.app.cli import main

    out = tmp_path / "run"
    code = main(["evaluate", "--policy", "standin:noop", "--scene", "robocasa", "--task", "all", "--axis", "pick_x",
                 "--step", "0.12", "--levels", "0:1", "--episodes", "1", "--out", str(out)])  # fmt: skip
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "CoffeeSetupMug's level-4 pick window" in err
    assert not out.exists()


@needs_venv
@pytest.mark.slow  # ~10 s: two kitchens built; test_robocasa covers the "obj" tasks
def test_cheesy_bread_moves_its_cheese(placeholders):
    """CheesyBread's pick object is the cheese (no "obj" config): level 1 moves its window by 1/5 of the range
    RoboCasa samples its centre in, in the episode's kitchen (that range less the cheese's buffer at each end)."""
    from scenes.robocasa.pick_window import PICK_KEY
    from tests.scenes.robocasa.test_robocasa import _changed, _levels

    (m0, s0), (m1, _) = _levels("CheesyBread", "pick_x", (0, 1), seed=3)
    assert _changed(m0, m1) == {"object_cfgs", PICK_KEY}
    c0, c1 = ([c for c in m["object_cfgs"] if c["name"] == "cheese"][0]["placement"] for m in (m0, m1))
    (lo, hi), b = m0[PICK_KEY]["range"], m0[PICK_KEY]["buffer"]
    dx = c1["offset"][0] - c0.get("offset", (0.0,))[0]
    assert (
        dx == pytest.approx((hi - lo - 2 * b) / 5) == pytest.approx(m1[PICK_KEY]["offset"])
        and hi - lo <= 1.0 + 1e-9
    )
    assert m1[PICK_KEY]["cfg"] == "cheese" and c0["size"][0] == pytest.approx(1.0)


@needs_venv
def test_certificates_are_keyed_by_the_tasks_own_step(placeholders, tmp_path, monkeypatch):
    """A certificate made at a task's own step is found under the axis's plain folder; one at another step (e.g. the
    0.12 m every task used before) lives beside it and is not that task's."""
    import json

    from scenes.certificates import asset_stamp, cert_path, find_certification

    monkeypatch.setenv("INDGEN_CERT_DIR", str(tmp_path))
    task = "PickPlaceSinkToCounter"
    assert cert_path(get_scene("robocasa"), task, "pick_x").parent.name == "pick_x"
    assert (
        cert_path(get_scene("robocasa"), task, "pick_x", step=0.05).parent.name == "pick_x"
    )  # its own step, given
    assert cert_path(get_scene("robocasa"), task, "pick_x", step=0.04).parent.name == "pick_x@pick_x=0.04"
    for steps in ({"pick_x": 0.05}, {"pick_x": 0.12}):
        path = cert_path(get_scene("robocasa"), task, "pick_x")
        path.parent.mkdir(parents=True, exist_ok=True)
        cert = {"scene": "robocasa", "task": task, "axis": "pick_x", "steps": steps, "levels": [],
                "assets": asset_stamp(get_scene("robocasa"))}  # fmt: skip
        path.write_text(json.dumps(cert))
        found = find_certification(get_scene("robocasa"), task, "pick_x")
        assert (found is not None) == (steps == {"pick_x": 0.05})


@needs_venv
@pytest.mark.slow  # ~40 s: three short RoboCasa runs; test_robocasa's pick_x test covers the worker by default
def test_a_run_records_each_kitchens_offset_and_its_unavailable_episodes_once(placeholders, tmp_path, capsys):
    """CounterToBlender, --seed 0: episodes 0..2 draw kitchens whose range is 0.485, 0.50 and 0.404 m, 0.437, 0.452
    and 0.356 m of it for the object's centre (RoboCasa's buffer, 2.4 cm at each end). At the task's own step level
    1 records a fifth of that, 0.0875, 0.0904 and 0.0711 m (1 and 2 workers alike), and pools to no one parameter;
    at --step 0.09 episode 2's kitchen cannot hold level 4's window (0.36..0.40 m): one error row per level, not
    retried, and the run exits 6 (finished; only unavailable episodes besides ok ones)."""
    import pandas as pd

    from indgen_vla.app.cli import main

    args = ["evaluate", "--policy", "standin:noop", "--scene", "robocasa", "--task", "PickPlaceCounterToBlender",
            "--axis", "pick_x", "--levels", "0:1", "--episodes", "3", "--max-steps", "2"]  # fmt: skip
    runs = {}
    for name, extra in (
        ("own", ["--workers", "1"]),
        ("own2", ["--workers", "2"]),
        ("step", ["--step", "0.09"]),
    ):
        runs[name] = (main([*args, *extra, "--out", str(tmp_path / name)]), tmp_path / name)
    own = pd.read_parquet(runs["own"][1] / "episodes.parquet").sort_values(["level", "episode"])
    assert runs["own"][0] == 0 and (own["status"] == "ok").all()
    assert list(own["param"]) == pytest.approx([0, 0, 0, 0.0875, 0.0904, 0.0711], abs=5e-4)
    cols = ["level", "episode", "seed", "param", "status"]
    two = pd.read_parquet(runs["own2"][1] / "episodes.parquet").sort_values(["level", "episode"])
    assert own[cols].values.tolist() == two[cols].values.tolist()  # the seed decides, not the worker
    summary = (runs["own"][1] / "summary.json").read_text()
    assert '"param": null' in summary  # level 1: each kitchen's own offset, no one parameter
    err = capsys.readouterr().err
    assert "note: 2 episode(s) are unavailable" in err and "ended with errors" not in err
    step = pd.read_parquet(runs["step"][1] / "episodes.parquet").sort_values(["level", "episode"])
    assert runs["step"][0] == 6 and list(step["status"]) == ["ok", "ok", "unavailable"] * 2
    bad = step[step["status"] == "unavailable"]["error"]
    assert (
        bad.str.startswith("attempt 1: EpisodeUnavailableError").all()
        and bad.str.contains("0.404 m range").all()
        and bad.str.contains(r"level 4's window at 0\.360\.\.0\.400 m").all()
    )
    assert list(step[step["status"] == "ok"]["param"]) == pytest.approx([0, 0, 0.09, 0.09])
