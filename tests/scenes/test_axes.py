"""Successors are pure single-field edits, and every default progression meets the paper's conditions 2 and 3."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import pytest

import scenes
from indgen_vla.errors import ConfigError, UnknownNameError
from indgen_vla.progression import ProgressionError, check_semantics_preserved, check_single_axis, spec_diff
from scenes.axes import (
    Composite,
    Shift,
    axis_param,
    check_progression,
    get_successor,
    load_preset,
    preset_names,
    spec_at_level,
)
from scenes.catalog import builtin_scenes
from scenes.registry import get_scene

SCENE_AXES = [(s.name, a) for s in builtin_scenes() for a in s.axes]


@pytest.mark.parametrize(("scene", "axis"), SCENE_AXES)
def test_each_step_changes_only_the_axis_field(scene, axis):
    succ = get_successor(axis)
    for task in get_scene(scene).tasks:
        base = get_scene(scene).base(task)
        levels = succ.axis.default_levels()
        for k in levels[:-1]:
            before, after = spec_at_level(base, succ, k), spec_at_level(base, succ, k + 1)
            assert check_single_axis(before, after, succ.fields, axis) == {succ.axis.field}


@pytest.mark.parametrize(("scene", "axis"), SCENE_AXES + [("pick_place", "pick_y+distractor")])
def test_levels_leave_the_easier_levels_support(scene, axis):
    sdef = get_scene(scene)
    supports = check_progression(sdef.base(sdef.tasks[0]), get_successor(axis))
    assert sorted(supports) == get_successor(axis).axis.default_levels()


def test_successor_is_pure_and_frozen():
    base = get_scene("pick_place").base("milk")
    copy = dataclasses.replace(base)
    succ = get_successor("pick_y")
    out = succ(base, 1)
    assert base == copy and out is not base
    assert out.pick.y == pytest.approx(base.pick.y + 0.025)
    assert succ(base, 1) == out  # same input, same output
    with pytest.raises(dataclasses.FrozenInstanceError):
        base.pick.y = 0.0  # type: ignore[misc]


def test_signed_and_one_sided_directions():
    base = get_scene("pick_place").base("milk")
    assert spec_at_level(base, get_successor("scale"), -3).pick.scale == pytest.approx(1 - 3 * 0.0667)
    assert spec_at_level(base, get_successor("distractor"), 4).distractors == 4
    with pytest.raises(ConfigError, match="one-sided"):
        get_successor("distractor")(base, -1)
    with pytest.raises(ConfigError, match="outside axis distractor's range"):
        spec_at_level(base, get_successor("distractor"), -1)
    with pytest.raises(ConfigError, match="outside"):
        spec_at_level(base, get_successor("pick_y"), 4)


def test_composition_steps_each_component_and_uses_abs_level_for_one_sided():
    base = get_scene("pick_place").base("milk")
    comp = get_successor("pick_y+distractor")
    assert isinstance(comp, Composite) and comp.axis.signed and comp.axis.max_level == 3
    spec = spec_at_level(base, comp, -2)
    assert spec.pick.y == pytest.approx(base.pick.y - 0.05)
    assert spec.distractors == 2
    assert spec_diff(base, spec) == {"pick.y", "distractors"}
    check_single_axis(spec_at_level(base, comp, 1), spec_at_level(base, comp, 2), comp.fields, comp.axis.name)
    assert axis_param(spec, comp, -2) == -2.0


def test_step_override_and_presets():
    assert scenes.get_axis("pick_y", step=0.03).step == 0.03
    assert isinstance(get_successor("pick_y", 0.03), Shift)
    with pytest.raises(ConfigError, match="whole number"):
        get_successor("clutter", 1.5)
    with pytest.raises(ConfigError, match="composition"):
        get_successor("pick_y+distractor", 0.03)
    assert {"paper", "quick"} <= set(preset_names())
    paper = load_preset("paper")
    for name in paper:
        assert scenes.get_axis(name).step == pytest.approx(paper[name]["step"])
        assert scenes.get_axis(name).max_level == paper[name]["max_level"]
    quick = get_successor("pick_y+distractor", overrides=load_preset("quick"))
    assert quick.axis.max_level == 1


def test_step_below_jitter_is_rejected():
    base = get_scene("pick_place").base("milk")
    with pytest.raises(ProgressionError, match="jitter"):
        check_progression(base, get_successor("pick_y", 0.015))


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
        scenes.make_env("pick_plac")
    with pytest.raises(UnknownNameError, match="did you mean 'pick_y'"):
        scenes.get_axis("pick_yy")
    with pytest.raises(UnknownNameError, match="did you mean 'milk'"):
        scenes.make_env("pick_place", task="mlk")
    with pytest.raises(UnknownNameError, match="axis of scene cabinet_pick"):
        scenes.make_env("cabinet_pick", axis="pick_y")


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
    assert len(scenes.tasks("pick_place")) >= 6
    assert "stack" in scenes.axes_for("stack")
    for t in scenes.tasks("pick_place"):
        assert get_scene("pick_place").instruction(t).startswith("pick up the ")


def test_import_is_light():
    code = (
        "import sys, scenes, scenes.catalog, scenes.axes, scenes.registry, scenes.libero; "
        "bad = [m for m in ('robosuite', 'mujoco', 'torch') if m in sys.modules]; print(bad); "
        "sys.exit(1 if bad else 0)"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=_repo_root())
    assert res.returncode == 0, res.stdout + res.stderr


def _repo_root() -> str:
    from pathlib import Path

    return str(Path(scenes.__file__).resolve().parent.parent)
