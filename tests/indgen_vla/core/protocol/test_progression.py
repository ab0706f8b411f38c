import dataclasses
from dataclasses import dataclass

import pytest

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.progression import (
    AxisSpec,
    ProgressionError,
    apply_level,
    check_semantics_preserved,
    check_single_axis,
    check_strictly_harder,
    expand_axes,
    parse_levels,
    spec_diff,
)

PICK_Y = AxisSpec("pick_y", "translate the pick object along y", "pick.y", 0.025, "m", True, 3)
CLUTTER = AxisSpec("clutter", "add one clutter object", "clutter", 1, "objects", False, 5)


@dataclass(frozen=True)
class Obj:
    x: float
    y: float


@dataclass(frozen=True)
class Spec:
    pick: Obj
    goal: Obj
    clutter: int = 0


def shift_pick(spec: Spec, direction: int = 1) -> Spec:
    return dataclasses.replace(spec, pick=dataclasses.replace(spec.pick, y=spec.pick.y + direction * 0.025))


def leaky(spec: Spec, direction: int = 1) -> Spec:
    return dataclasses.replace(shift_pick(spec, direction), clutter=spec.clutter + 1)


BASE = Spec(Obj(0.0, 0.0), Obj(0.1, 0.2))


def test_parse_levels():
    assert parse_levels("-3:3", PICK_Y) == [-3, -2, -1, 0, 1, 2, 3]
    assert parse_levels("0,2,1", CLUTTER) == [0, 1, 2]
    assert parse_levels(None, CLUTTER) == [0, 1, 2, 3, 4, 5]
    assert parse_levels("2", PICK_Y) == [2]
    with pytest.raises(ConfigError, match="outside axis clutter's range 0..5"):
        parse_levels("-1:2", CLUTTER)
    with pytest.raises(ConfigError, match="not a range"):
        parse_levels("a:b", PICK_Y)
    with pytest.raises(ConfigError, match="start 3 is after end"):
        parse_levels("3:-3", PICK_Y)


def test_axis_spec_validation():
    with pytest.raises(ConfigError):
        AxisSpec("bad", "", "f", -1.0, "m", True, 3)
    assert PICK_Y.param(-2) == pytest.approx(-0.05)
    assert PICK_Y.with_step(0.01).param(3) == pytest.approx(0.03)


def test_apply_level_signed():
    assert apply_level(BASE, shift_pick, 3).pick.y == pytest.approx(0.075)
    assert apply_level(BASE, shift_pick, -2).pick.y == pytest.approx(-0.05)
    assert apply_level(BASE, shift_pick, 0) is BASE


def test_single_axis_control():
    assert spec_diff(BASE, shift_pick(BASE)) == {"pick.y"}
    check_single_axis(BASE, shift_pick(BASE), ["pick.y"], "pick_y")
    check_single_axis(BASE, shift_pick(BASE), ["pick"], "pick_y")  # a parent path allows its children
    with pytest.raises(ProgressionError, match="changed clutter"):
        check_single_axis(BASE, leaky(BASE), ["pick.y"], "pick_y")
    with pytest.raises(ProgressionError, match="unchanged"):
        check_single_axis(BASE, BASE, ["pick.y"], "pick_y")


def test_semantics_preserved():
    def pred(state):
        return True

    check_semantics_preserved([pred, pred, pred])
    with pytest.raises(ProgressionError, match="different success predicate"):
        check_semantics_preserved([pred, lambda s: True])


def test_strictly_harder():
    # jittered supports: +-1 cm at each level, 2.5 cm steps -> fine
    ok = {k: (0.025 * k - 0.01, 0.025 * k + 0.01) for k in range(-3, 4)}
    check_strictly_harder(ok, "pick_y")
    # jitter wider than the step: level 1 lies inside level 0's support
    bad = {k: (0.025 * k - 0.05, 0.025 * k + 0.05) for k in range(0, 3)}
    with pytest.raises(ProgressionError, match="level 1's parameter support .* overlaps .* is 0.1 wide here"):
        check_strictly_harder(bad, "pick_y")
    check_strictly_harder(bad, "pick_y", strict=False)  # the paper's weaker wording: some tasks outside
    check_strictly_harder({0: (0, 0), 1: (1, 1), 2: (2, 2)})
    # level 2 falls back inside the union of levels 0 and 1
    with pytest.raises(ProgressionError, match="inside the easier"):
        check_strictly_harder({0: (0.0, 1.0), 1: (0.5, 2.0), 2: (0.2, 1.5)}, strict=False)
    check_strictly_harder({0: (0.0, 0.0), 1: (1.0, 1.0), 2: (0.5, 0.5)})  # between supports: outside
    # directions are independent: -1 is not compared with +1
    check_strictly_harder({-1: (-1, -1), 0: (0, 0), 1: (1, 1)})


def test_held_names_are_valid_axis_names_and_ranges_expand():
    assert AxisSpec("pick_y@goal_y=-1", "", "pick.y", 0.025, "m", True, 3).name == "pick_y@goal_y=-1"
    with pytest.raises(ConfigError, match="must be alphanumeric"):
        AxisSpec("pick y@goal_y=1", "", "pick.y", 0.025, "m", True, 3)
    assert expand_axes(["pick_y@distractor=0:3"]) == tuple(f"pick_y@distractor={j}" for j in range(4))
    assert expand_axes(["scale", "pick_y@goal_y=-1:1", "pick_y+distractor"]) == (
        "scale", "pick_y@goal_y=-1", "pick_y@goal_y=0", "pick_y@goal_y=1", "pick_y+distractor"
    )  # fmt: skip
    assert expand_axes(["pick_y@distractor=2"]) == ("pick_y@distractor=2",)


@pytest.mark.parametrize(
    ("axes", "match"),
    [
        (["pick_y@distractor=3:1"], "start 3 is after end 1; write it as pick_y@distractor=1:3"),
        (["pick_y@distractor=0:x"], "a held range is A@B=i:j with integers i <= j"),
        (["pick_y@distractor=0:2", "pick_y@distractor=1"], "--axis names pick_y@distractor=1 more than once"),
        (["pick_y", "pick_y"], "--axis names pick_y more than once"),
    ],
)
def test_bad_held_ranges_are_refused_in_one_line(axes, match):
    with pytest.raises(ConfigError, match=match):
        expand_axes(axes)
