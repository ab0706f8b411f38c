"""pick_x's window on the range RoboCasa samples in each kitchen (``scenes/robocasa/pick_window.py``): the levels
divide that range, and a kitchen that cannot hold them all holds none (hand-computed cases; no simulator)."""

from __future__ import annotations

import pytest

from scenes.robocasa.pick_window import LevelUnavailable, level_offset


def pick(level: int, declared: float = 0.5, step: float | None = None, top: int = 4) -> dict:
    return {"cfg": "obj", "declared": declared, "level": level, "top": top, "step": step, "progressions": 5}


def test_an_unclipped_kitchen_keeps_the_plans_offsets():
    """Where RoboCasa samples the whole declared width, level k is the plan's k x width / 5, bit for bit."""
    for k in range(5):
        assert level_offset(0.5, pick(k), nominal=k * 0.1, where="w") == k * 0.1


def test_a_clipped_kitchen_divides_its_own_range():
    """CounterToBlender seed 0 on the placeholder tree: RoboCasa samples 0.365 m of the declared 0.50 m, so a level
    is 0.073 m (not 0.10 m: level 4's window would end at 0.44 m, past the range's 0.365 m)."""
    assert [level_offset(0.365, pick(k), nominal=k * 0.1, where="w") for k in range(5)] == pytest.approx(
        [0.0, 0.073, 0.146, 0.219, 0.292]
    )
    assert 4 * 0.073 + 0.04 <= 0.365  # level 4's window ends inside the range


@pytest.mark.parametrize("level", [0, 2])
def test_a_kitchen_too_narrow_for_five_windows_holds_no_level(level):
    """1/5 of 0.20 m is the 4 cm window itself: adjacent levels would touch (condition 2 is strict), so every
    level of the episode, level 0 included, is unavailable, with the kitchen in one line."""
    with pytest.raises(LevelUnavailable, match=r"^T seed 6 \(layout 27, style 43\): a 0\.200 m range") as e:
        level_offset(0.20, pick(level), nominal=level * 0.1, where="T seed 6 (layout 27, style 43)")
    assert "\n" not in str(e.value) and "not retried" in str(e.value) and e.value.unavailable
    assert level_offset(0.201, pick(level), nominal=0.0, where="w") == pytest.approx(level * 0.0402)


def test_a_users_step_is_metres_and_the_top_level_must_fit():
    """--step 0.06 on a 0.30 m region: 4 x 0.06 + 0.04 = 0.28 m fits a 0.30 m or 0.28 m range, not a 0.27 m one;
    a preset's top level 1 needs only 0.10 m."""
    assert level_offset(0.30, pick(3, 0.30, step=0.06), nominal=0.18, where="w") == 0.18
    assert level_offset(0.28, pick(3, 0.30, step=0.06), nominal=0.18, where="w") == 0.18
    with pytest.raises(LevelUnavailable, match=r"level 4's window at 0\.240\.\.0\.280 m leaves it"):
        level_offset(0.27, pick(0, 0.30, step=0.06), nominal=0.0, where="w")
    assert level_offset(0.10, pick(1, 0.30, step=0.06, top=1), nominal=0.06, where="w") == 0.06


def test_the_ladder_divides_the_range_of_the_objects_centre():
    """RoboCasa keeps a 3 cm buffer inside each end of an unclipped 0.30 m range (``_sample_x``): the centre's range
    is 0.24 m, a level 0.048 m, and level 4's window ends at 0.232 m, inside it (not the plan's 0.06 m a level)."""
    got = [level_offset(0.30, pick(k, 0.30), nominal=k * 0.06, where="w", buffer=0.03) for k in range(5)]
    assert got == pytest.approx([0.0, 0.048, 0.096, 0.144, 0.192])
    assert 4 * 0.048 + 0.04 <= 0.30 - 2 * 0.03


def test_an_object_whose_footprint_leaves_too_little_of_the_range_holds_no_level():
    """0.25 m less a 3 cm buffer at each end leaves 0.19 m for the centre, whose fifth is narrower than the window;
    with --step 0.06 a 0.30 m range less 2 cm each end (0.26 m) cannot hold level 4's window at 0.24..0.28 m."""
    with pytest.raises(
        LevelUnavailable, match=r"^w: a 0\.250 m range .*, 0\.190 m for the object's centre .*"
    ) as e:
        level_offset(0.25, pick(0, 0.25), nominal=0.0, where="w", buffer=0.03)
    assert "\n" not in str(e.value) and "0.030 m of it inside each end" in str(e.value)
    with pytest.raises(
        LevelUnavailable, match=r"0\.260 m for the object's centre.*level 4's window at 0\.240\.\.0\.280"
    ):
        level_offset(0.30, pick(2, 0.30, step=0.06), nominal=0.12, where="w", buffer=0.02)
    assert level_offset(0.30, pick(2, 0.30, step=0.06), nominal=0.12, where="w", buffer=0.01) == 0.12
