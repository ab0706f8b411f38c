"""pick_x's window on the range RoboCasa samples in each kitchen (``scenes/robocasa/pick_window.py``): the levels
divide that range, the window is 4 cm or a level's step where that is narrower, and a kitchen that cannot hold
them all holds none (hand-computed cases; no simulator)."""

from __future__ import annotations

import pytest

from scenes.robocasa.pick_window import LevelUnavailable, level_offset, window_width


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
def test_a_kitchen_whose_fifth_is_narrower_than_4_cm_draws_in_windows_a_fifth_wide(level):
    """1/5 of a 0.20 m range is 4 cm, of 0.15 m 3 cm: the window is that fifth (4 cm is wider than a level there,
    and windows wider than a step would overlap; RoboCasa's ``rng.uniform`` draws in [low, high), so windows one
    step wide share no point), and levels 0..4 tile the range; a wider kitchen keeps the 4 cm window."""
    for width, step in ((0.20, 0.04), (0.15, 0.03), (0.201, 0.0402)):
        assert window_width(width, pick(level)) == pytest.approx(min(0.04, step))
        assert level_offset(width, pick(level), nominal=level * 0.1, where="w") == pytest.approx(level * step)
        # level 4's window ends in the range
        assert 4 * step + window_width(width, pick(level)) <= width + 1e-12
    assert window_width(0.5, pick(level)) == 0.04 and window_width(0.30, pick(level, 0.30, step=0.06)) == 0.04


def test_a_kitchen_with_no_room_for_the_objects_centre_holds_no_level():
    """A buffer of half the range leaves the centre no room: every level of the episode, level 0 included, is
    unavailable, with the kitchen in one line."""
    with pytest.raises(LevelUnavailable, match=r"^T seed 6 \(layout 27, style 43\): a 0\.060 m range") as e:
        level_offset(0.06, pick(2), nominal=0.2, where="T seed 6 (layout 27, style 43)", buffer=0.03)
    assert "\n" not in str(e.value) and "not retried" in str(e.value) and e.value.unavailable


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


def test_pick_place_sink_to_counters_footprint_leaves_windows_a_fifth_wide():
    """0.25 m less a 3 cm buffer at each end leaves 0.19 m for the centre: a level is 0.038 m and so is the window
    (4 cm would overlap the next level's); with --step 0.06 a 0.30 m range less 2 cm each end (0.26 m) cannot hold
    level 4's window at 0.24..0.28 m."""
    got = [level_offset(0.25, pick(k, 0.25), nominal=k * 0.05, where="w", buffer=0.03) for k in range(5)]
    assert got == pytest.approx([0.0, 0.038, 0.076, 0.114, 0.152])
    assert window_width(0.25, pick(0, 0.25), buffer=0.03) == pytest.approx(0.038)
    with pytest.raises(
        LevelUnavailable, match=r"0\.260 m for the object's centre.*level 4's window at 0\.240\.\.0\.280"
    ) as e:
        level_offset(0.30, pick(2, 0.30, step=0.06), nominal=0.12, where="w", buffer=0.02)
    assert "\n" not in str(e.value) and "0.020 m of it inside each end" in str(e.value)
    assert level_offset(0.30, pick(2, 0.30, step=0.06), nominal=0.12, where="w", buffer=0.01) == 0.12
