"""Successors are pure single-field edits, and every default progression meets the paper's conditions 2 and 3."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import pytest

import scenes
from indgen_vla.core.errors import ConfigError, UnknownNameError
from indgen_vla.core.protocol.axis_ref import AxisRef
from indgen_vla.core.protocol.progression import (
    ProgressionError,
    check_semantics_preserved,
    check_single_axis,
    spec_diff,
)
from scenes.axes import (
    Composite,
    Held,
    Shift,
    axis_components,
    axis_param,
    check_progression,
    get_successor,
    load_preset,
    preset_names,
    spec_at_level,
    successor_steps,
)
from scenes.family import get_scene
from scenes.listing import builtin_scenes
from tests.fixtures.levels import level_env


def _successor(name: str, *args, **kwargs):
    """The shared table's successor of the axis ``name`` (parsed here, as the entrances parse it)."""
    return get_successor(AxisRef.parse(name), *args, **kwargs)


SCENE_AXES = [(s.name, a) for s in builtin_scenes() for a in s.axes]


@pytest.mark.parametrize(("scene", "axis"), SCENE_AXES)
def test_each_step_changes_only_the_axis_field(scene, axis):
    succ = _successor(axis)
    for task in get_scene(scene).tasks:
        base = get_scene(scene).base(task)
        levels = succ.axis.default_levels()
        for k in levels[:-1]:
            before, after = spec_at_level(base, succ, k), spec_at_level(base, succ, k + 1)
            assert check_single_axis(before, after, succ.fields, axis) == {succ.axis.field}


@pytest.mark.parametrize(("scene", "axis"), SCENE_AXES + [("pick_place", "pick_y+distractor")])
def test_levels_leave_the_easier_levels_support(scene, axis):
    sdef = get_scene(scene)
    supports = check_progression(sdef.base(sdef.tasks[0]), _successor(axis))
    assert sorted(supports) == _successor(axis).axis.default_levels()


def test_successor_is_pure_and_frozen():
    base = get_scene("pick_place").base("milk")
    copy = dataclasses.replace(base)
    succ = _successor("pick_y")
    out = succ(base, 1)
    assert base == copy and out is not base
    assert out.pick.y == pytest.approx(base.pick.y + 0.025)
    assert succ(base, 1) == out  # same input, same output
    with pytest.raises(dataclasses.FrozenInstanceError):
        base.pick.y = 0.0  # type: ignore[misc]


def test_signed_and_one_sided_directions():
    base = get_scene("pick_place").base("milk")
    assert spec_at_level(base, _successor("scale"), -3).pick.scale == pytest.approx(1 - 3 * 0.0667)
    assert spec_at_level(base, _successor("distractor"), 4).distractors == 4
    with pytest.raises(ConfigError, match="one-sided"):
        _successor("distractor")(base, -1)
    with pytest.raises(ConfigError, match="outside axis distractor's range"):
        spec_at_level(base, _successor("distractor"), -1)
    with pytest.raises(ConfigError, match="outside"):
        spec_at_level(base, _successor("pick_y"), 4)


def test_composition_steps_each_component_and_uses_abs_level_for_one_sided():
    base = get_scene("pick_place").base("milk")
    comp = _successor("pick_y+distractor")
    assert isinstance(comp, Composite) and comp.axis.signed and comp.axis.max_level == 3
    spec = spec_at_level(base, comp, -2)
    assert spec.pick.y == pytest.approx(base.pick.y - 0.05)
    assert spec.distractors == 2
    assert spec_diff(base, spec) == {"pick.y", "distractors"}
    check_single_axis(spec_at_level(base, comp, 1), spec_at_level(base, comp, 2), comp.fields, comp.axis.name)
    assert axis_param(spec, comp, -2) == -2.0


def test_step_override_and_presets():
    assert _successor("pick_y", 0.03).axis.step == 0.03
    assert isinstance(_successor("pick_y", 0.03), Shift)
    with pytest.raises(ConfigError, match="whole number"):
        _successor("clutter", 1.5)
    with pytest.raises(ConfigError, match="composition"):
        _successor("pick_y+distractor", 0.03)
    assert {"paper", "quick"} <= set(preset_names())
    paper = load_preset("paper")
    for name in paper:
        assert _successor(name).axis.step == pytest.approx(paper[name]["step"])
        assert _successor(name).axis.max_level == paper[name]["max_level"]
    quick = _successor("pick_y+distractor", overrides=load_preset("quick"))
    assert quick.axis.max_level == 1


def test_step_below_jitter_is_rejected():
    base = get_scene("pick_place").base("milk")
    with pytest.raises(ProgressionError, match="jitter"):
        check_progression(base, _successor("pick_y", 0.015))


def test_bad_preset(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("axes:\n  pick_y: {stepp: 0.1}\n")
    with pytest.raises(ConfigError, match="only 'step' and 'max_level'"):
        load_preset(bad)
    bad.write_text("axes:\n  pik_y: {step: 0.1}\n")
    with pytest.raises(UnknownNameError, match="did you mean 'pick_y'"):
        load_preset(bad)
    with pytest.raises(UnknownNameError):
        load_preset("no_such_preset")


def test_bad_names_suggest():
    with pytest.raises(UnknownNameError, match="did you mean 'pick_place'"):
        level_env("pick_plac")
    with pytest.raises(UnknownNameError, match="did you mean 'pick_y'"):
        _successor("pick_yy")
    with pytest.raises(UnknownNameError, match="did you mean 'milk'"):
        level_env("pick_place", task="mlk")
    with pytest.raises(UnknownNameError, match="axis of scene cabinet_pick"):
        level_env("cabinet_pick", axis="pick_y")


def test_one_predicate_per_scene_is_shared():
    check_semantics_preserved([get_scene("pick_place").success_predicate] * 3, "x")
    assert len({id(s.success_predicate) for s in builtin_scenes()}) == 3


def test_api_lists():
    assert scenes.scene_names() == [
        "pick_place",
        "stack",
        "cabinet_pick",
        "libero_object",
        "libero_spatial",
        "robocasa",
    ]
    assert len(list(scenes.get_scene("pick_place").tasks)) >= 6
    assert "stack" in list(scenes.get_scene("stack").axes)
    for t in list(scenes.get_scene("pick_place").tasks):
        assert get_scene("pick_place").instruction(t).startswith("pick up the ")


def test_import_is_light():
    code = (
        "import sys, scenes, scenes.tabletop, scenes.axes, scenes.family, scenes.libero; "
        "bad = [m for m in ('robosuite', 'mujoco', 'torch') if m in sys.modules]; print(bad); "
        "sys.exit(1 if bad else 0)"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=_repo_root())
    assert res.returncode == 0, res.stdout + res.stderr


def _repo_root() -> str:
    from pathlib import Path

    return str(Path(scenes.__file__).resolve().parent.parent)


# ---- held axes A@B=j: A's ladder with B held at its level j (a row of the 2-D grid A x B) -------------------------
@pytest.mark.parametrize(("inner", "held", "at"), [("pick_y", "distractor", 2), ("scale", "pick_y", -2),
                                                   ("pick_y+scale", "goal_y", 3)])  # fmt: skip
def test_held_level_k_is_b_applied_j_times_then_a_k_times(inner, held, at):
    base = get_scene("pick_place").base("milk")
    succ, a, b = _successor(f"{inner}@{held}={at}"), _successor(inner), _successor(held)
    assert isinstance(succ, Held) and succ.axis.name == f"{inner}@{held}={at}"
    assert (succ.axis.signed, succ.axis.max_level, succ.axis.step) == (
        a.axis.signed,
        a.axis.max_level,
        a.axis.step,
    )
    for k in a.axis.default_levels():
        spec = spec_at_level(base, succ, k)
        assert spec == spec_at_level(spec_at_level(base, b, at), a, k)
        assert axis_param(spec, succ, k) == axis_param(spec, a, k)  # the ladder's own parameter
    # one step moves the ladder's fields only, never the held one
    assert check_single_axis(spec_at_level(base, succ, 0), spec_at_level(base, succ, 1), succ.fields, inner)
    assert successor_steps(succ) == {**successor_steps(a), **successor_steps(b), "held_level": float(at)}
    check_progression(base, succ)


def test_held_at_zero_is_exactly_the_axis():
    base = get_scene("pick_place").base("milk")
    held, plain = _successor("pick_y@distractor=0"), _successor("pick_y")
    for k in plain.axis.default_levels():
        assert spec_at_level(base, held, k) == spec_at_level(base, plain, k)
    assert check_progression(base, held) == check_progression(base, plain)
    assert spec_at_level(base, _successor("pick_y@distractor=3"), 0).distractors == 3
    assert axis_components(AxisRef.parse("pick_y+scale@base_y=1")) == ["pick_y", "scale", "horizon"]


@pytest.mark.parametrize(
    ("name", "match"),
    [
        (
            "pick_y@distractor=5",
            "held level 5 is outside axis distractor's range 0..4; hold it at one of 0..4",
        ),
        ("pick_y@distractor", "write a held axis as A@B=j"),
        ("pick_y@distractor=x", "held level 'x' is not an integer"),
        ("pick_y@distractor=0:3", "range form A@B=i:j is for --axis"),
        ("pick_y@pick_y=1", "holds pick_y, which its ladder pick_y already moves"),
        ("pick_y+distractor@distractor=1", "holds distractor, which its ladder pick_y\\+distractor already"),
        ("pick_y@goal_y+scale=1", "the held axis must be a single axis, e.g. pick_y@goal_y=1"),
        ("pick_y@goal_y=1@scale=2", "hold one axis at a time"),
        ("pick_y@@goal_y=1", "hold one axis at a time"),
        ("@goal_y=1", "write a held axis as A@B=j"),
    ],
)
def test_bad_held_axes_are_refused_in_one_line(name, match):
    with pytest.raises(ConfigError, match=match) as e:
        _successor(name)
    assert "\n" not in str(e.value)


def test_held_axes_need_the_scenes_axes_and_stay_off_robocasa():
    get_scene("pick_place").check_axis(AxisRef.parse("pick_y@distractor=2"))
    with pytest.raises(UnknownNameError, match="axis of scene pick_place 'clutter'") as e:
        get_scene("pick_place").check_axis(AxisRef.parse("pick_y@clutter=1"))
    # a real axis on the wrong scene names the scenes it runs on (the "did you mean" alone pointed at 'scale')
    assert str(e.value).endswith("; 'clutter' runs on cabinet_pick, robocasa") and "\n" not in str(e.value)
    with pytest.raises(UnknownNameError, match="unknown axis 'nope'"):
        _successor("pick_y@nope=1")
    with pytest.raises(
        ConfigError, match="held axes \\(A@B=j\\) do not run there; evaluate pick_x and clutter"
    ):
        get_scene("robocasa").check_axis(AxisRef.parse("pick_x@clutter=1"))


def test_scenes_builds_only_through_a_level_builder():
    """One road to an environment: the name-keyed helpers are gone; a run, certify, demos and mimicgen build through
    ``scenes.planning`` (a plan's builder), whose family methods take the parsed axis."""
    for gone in ("make_env", "successor_for", "level_param", "get_axis", "check_axis_progression"):
        assert not hasattr(scenes, gone), gone
    sc = get_scene("pick_place")
    ref = AxisRef.parse("pick_y+distractor")
    sc.check_axis(ref)
    assert sc.successor(ref).axis.name == "pick_y+distractor"
    assert sc.select_tasks(None, (ref,)) == ["milk"]
