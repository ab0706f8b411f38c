"""Evaluation seeds, the held-out set training data avoids, and ``fresh_seed``'s bump."""

from indgen_vla.core.protocol.plan import plan_jobs
from indgen_vla.core.protocol.seeding import (
    HELD_OUT_EPISODES,
    HELD_OUT_RUN_SEEDS,
    episode_seed,
    evaluation_seed,
    fresh_seed,
    held_out_seeds,
)


def test_held_out_seeds_are_the_seeds_evaluate_plans_at_every_level():
    params = {("milk", "pick_y", k): 0.025 * k for k in (-1, 0, 1)}
    held = held_out_seeds("pick_place", "milk")
    assert len(held) == HELD_OUT_RUN_SEEDS * HELD_OUT_EPISODES  # no two (run seed, episode) share a seed
    for run_seed in (0, 9):
        jobs = plan_jobs("pick_place", ["milk"], {"pick_y": [-1, 0, 1]}, params, episodes=50, seed=run_seed)
        assert {j.seed for j in jobs} <= held
        assert {j.seed for j in jobs} == {
            evaluation_seed(run_seed, "pick_place", "milk", e) for e in range(50)
        }
    assert evaluation_seed(42, "pick_place", "milk", 3) not in held
    assert evaluation_seed(42, "pick_place", "milk", 3) in held_out_seeds("pick_place", "milk", also=(42,))


def test_fresh_seed_keeps_a_free_seed_and_bumps_a_taken_one():
    plain = episode_seed(7, "demos", "pick_place", "milk", 0)
    assert fresh_seed(7, "demos", "pick_place", "milk", 0, avoid=()) == plain
    bumped = fresh_seed(7, "demos", "pick_place", "milk", 0, avoid={plain})
    assert bumped == episode_seed(7, "demos", "pick_place", "milk", 0, 1) != plain
    second = episode_seed(7, "demos", "pick_place", "milk", 0, 2)
    assert fresh_seed(7, "demos", "pick_place", "milk", 0, avoid={plain, bumped}) == second
