"""The scene side of the plan: one resolution gives parameters, certificates and a builder that workers use."""

import pickle
import sys

import pytest

import scenes
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.axis_ref import AxisRef
from indgen_vla.core.protocol.plan import CERTIFIED, FAILED, UNCERTIFIED
from scenes.family import get_scene
from scenes.planning import resolve_scene_plan, scene_levels


def test_parameters_are_t0_plus_k_steps_and_certificates_come_from_the_committed_files():
    sp = resolve_scene_plan(get_scene("pick_place"), "lemon", ["pick_y", "goal_y"], "-3:3")
    y0 = scenes.get_scene("pick_place").base("lemon").pick.y
    for k in range(-3, 4):
        assert sp.cell("lemon", "pick_y", k).param == pytest.approx(y0 + 0.025 * k)
    assert sp.cell("lemon", "goal_y", -3).certificate == FAILED  # 0/1 in the committed certificate
    assert sp.cell("lemon", "goal_y", -3).evidence == "0/1 (failed)"
    assert sp.cell("lemon", "goal_y", 2).certificate == CERTIFIED
    assert sp.cell("lemon", "goal_y", 2).evidence == "59/59 (certified)"
    assert sp.levels == {"pick_y": tuple(range(-3, 4)), "goal_y": tuple(range(-3, 4))}


def test_a_step_no_certificate_was_made_at_leaves_every_level_uncertified():
    sp = resolve_scene_plan(get_scene("pick_place"), None, ["pick_y"], "0:2", step=0.03)
    assert {c.certificate for c in sp.cells} == {UNCERTIFIED} and {c.evidence for c in sp.cells} == {""}
    assert sp.cell("milk", "pick_y", 2).param == pytest.approx(sp.cell("milk", "pick_y", 0).param + 0.06)


def test_the_builder_pickles_and_builds_the_same_level_as_the_family():
    sp = resolve_scene_plan(get_scene("pick_place"), "milk", ["scale"], "2")
    builder = pickle.loads(pickle.dumps(sp.builder))
    assert builder.describe()["successors"] == {"scale": {"type": "Shift", "steps": {"scale": 0.0667}}}
    assert builder.preload == (
        "scenes.base_env",
        "scenes.sim",
        "mujoco",
        "scenes.robosuite_kernels",
        "scenes.asset_cache",
        "scenes.tabletop.env",
        "scenes.tabletop.builders",
    )
    env = builder.make_env("milk", "scale", 2, cameras=(), image_size=(64, 64), max_steps=5)
    sc = scenes.get_scene("pick_place")
    ref = sc.environment.make_env(
        "milk", sc.successor(AxisRef.parse("scale")), 2, cameras=(), image_size=(64, 64), max_steps=5
    )
    try:
        assert env.spec == ref.spec and env.axis_param == sp.cell("milk", "scale", 2).param
    finally:
        env.close()
        ref.close()


def test_scene_levels_needs_no_plan_and_refuses_an_unknown_axis_in_one_line():
    assert scene_levels(get_scene("pick_place"), ["pick_y"]).successors["pick_y"].axis.step == 0.025
    with pytest.raises(Exception, match=r"unknown axis 'pick_q'"):
        scene_levels(get_scene("pick_place"), ["pick_q"])


def test_the_plan_parses_each_axis_once_and_hands_out_the_resolved_axes():
    sp = resolve_scene_plan(
        get_scene("pick_place"), "milk", ["pick_y@distractor=2", "pick_y+scale", "pick_y@distractor=2"], "0:1"
    )
    assert list(sp.axes) == list(sp.refs) == ["pick_y@distractor=2", "pick_y+scale"]  # a repeat is one axis
    held = sp.axis("pick_y@distractor=2")
    assert (held.ref.ladder.name, held.ref.held, held.ref.held_level) == ("pick_y", "distractor", 2)
    assert held.spec is sp.axes["pick_y@distractor=2"] and held.levels == (0, 1)
    assert sp.axis("pick_y+scale").ref.components == ("pick_y", "scale")
    assert sp.builder.successor("milk", "pick_y+scale").axis.name == "pick_y+scale"
    with pytest.raises(ConfigError, match="write compositions as") as e:
        resolve_scene_plan(get_scene("pick_place"), None, ["pick_y+"])
    assert "\n" not in str(e.value)


def test_scene_levels_resolves_each_tasks_own_successor():
    """Without a plan (a T0 build), ``tasks`` gives a family whose steps differ by task its per-task successors."""
    builder = scene_levels(get_scene("pick_place"), ["pick_y"], tasks=["milk", "lemon"])
    assert builder.task_successors == {} and builder.successor("lemon", "pick_y").axis.step == 0.025


def test_evaluate_enters_scenes_once_to_resolve_the_plan_and_never_by_name(tmp_path):
    """Follow cfg from evaluate: the engine never looks a family up by name (its edge hands it the family) and calls
    one module-level function of scenes with it (the resolution); everything else it does with scenes is a method
    of an object the plan handed it (the family, builder, env)."""
    from indgen_vla.app.engine.config import EvalConfig
    from tests.fixtures.resolved import evaluate

    cfg = EvalConfig.from_flat(policy="standin:random", scene="pick_place", axes=("pick_y", "scale"), levels="0",
                     episodes=1, max_steps=1, workers=1, out=str(tmp_path / "run"))  # fmt: skip
    entered = set()

    def tracer(frame, event, arg):
        if event == "call":
            code, caller = frame.f_code, frame.f_back
            if (
                caller is not None
                and "/indgen_vla/app/engine/" in caller.f_code.co_filename
                and "/scenes/" in code.co_filename
                and "."
                not in code.co_qualname  # a module-level function, not a method of a handed-out object
            ):
                entered.add(f"{code.co_filename.split('/scenes/')[1]}:{code.co_qualname}")

    sys.setprofile(tracer)
    try:
        evaluate(cfg, quiet=True)
    finally:
        sys.setprofile(None)
    assert entered == {"planning.py:resolve_scene_plan"}


def test_the_fork_servers_preload_is_quiet():
    """The workers' fork server imports the preload in order (multiprocessing.forkserver): robosuite's three-line
    macro-file warning must not reach the user's terminal on every run (robosuite is imported via scenes.sim)."""
    import subprocess
    import sys

    from scenes.family import get_scene

    mods = ("indgen_vla.app.engine.local", *get_scene("pick_place").preload)
    code = f"import importlib\nfor m in {mods!r}:\n    importlib.import_module(m)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "macro" not in out.stderr, out.stderr


def test_level_0_keys_come_from_the_levels_spec_not_the_axis_name():
    sp = resolve_scene_plan(get_scene("pick_place"), "all", ["pick_y", "scale", "pick_y+distractor"], "0:1")
    for t in sp.tasks:  # level 0 of each is the task's T0 spec (a composition's level 0 adds no distractor)
        keys = {sp.cell(t, a, 0).env_key for a in sp.axes}
        assert len(keys) == 1 and "" not in keys
        assert sp.cell(t, "pick_y", 1).env_key == ""  # only level 0 is keyed
    assert len({sp.cell(t, "pick_y", 0).env_key for t in sp.tasks}) == len(sp.tasks)  # tasks differ
    # a preset that moves T0 itself is not needed to tell them apart: a step changes level 1, never level 0's key
    other = resolve_scene_plan(get_scene("pick_place"), "milk", ["pick_y"], "0:1", step=0.03)
    assert other.cell("milk", "pick_y", 0).env_key == sp.cell("milk", "pick_y", 0).env_key


def test_robocasa_pick_x_level_0_is_a_window_so_it_shares_nothing():
    from indgen_vla.core.protocol.plan import Cell, ScenePlan, shared_t0
    from indgen_vla.core.protocol.progression import AxisSpec
    from scenes.planning import env_key

    sc, task = scenes.get_scene("robocasa"), "PickPlaceCabinetToCounter"  # on both axes' task lists
    keys = {
        a: env_key(sc.level_identity(task, sc.successor(AxisRef.parse(a), None, None, task), 0))
        for a in ("pick_x", "clutter")
    }
    assert keys["pick_x"] != keys["clutter"] and "" not in keys.values()
    axes = {a: AxisSpec(a, "", a, 1.0, "", False, 1) for a in keys}
    cells = tuple(Cell(task, a, 0, 0.0, UNCERTIFIED, "", k) for a, k in keys.items())
    assert shared_t0(ScenePlan("robocasa", (task,), axes, {a: (0,) for a in keys}, cells, None)) == {}


def test_a_family_that_cannot_describe_its_level_shares_nothing(monkeypatch):
    monkeypatch.setattr(type(scenes.get_scene("pick_place")), "env_from_spec", False)
    sp = resolve_scene_plan(get_scene("pick_place"), "milk", ["pick_y", "scale"], "0")
    assert {c.env_key for c in sp.cells} == {""}


def test_a_configured_family_is_a_new_value_and_nothing_global_changes(monkeypatch):
    """``get_scene(name, options)`` returns ``Scene.configured``'s new value (no overlay a later lookup would see);
    the plan's builder holds it and pickles it for the workers."""
    import scenes.family

    monkeypatch.setenv("INDGEN_ROBOCASA_SPLIT", "all")
    registered = get_scene("robocasa")
    target = get_scene("robocasa", {"split": "target"})
    assert target is not registered and target != registered and target.split_choice()[0] == "target"
    assert get_scene("robocasa") is registered and registered.split_choice()[0] == "all"
    assert target == get_scene("robocasa", {"split": "target"})  # a value: equal options, equal families
    assert not hasattr(scenes.family, "_CONFIGURED") and not hasattr(scenes.family, "configure_scene")
    builder = scene_levels(get_scene("pick_place"), ["pick_y"])
    assert pickle.loads(pickle.dumps(builder)) == builder and builder.scene == "pick_place"
