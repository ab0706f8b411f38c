"""The wall-time model: costs read back from a run's timing, one round's parts, the bound it names."""

import pytest

from indgen_vla.app.studies.wall_time import EXIT_S, HIGH, LOW, Costs, from_timing, project, rollout_seconds
from indgen_vla.core.errors import ConfigError

TIMING = {  # one in-process worker on 2 cores, CPU policy: what engine/timing.py records
    "process_start_to_evaluate_s": 1.0, "startup_s": 3.0, "rollout_s": 13.0, "end_s": 2.0, "workers": 1,
    "processes": 0, "batched": False, "replan_steps": 1, "device": "cpu", "cores": 2, "episodes": 4, "steps": 400,
    "sim_s": 8.0, "reset_s": 4.4, "build_s": 4.0, "builds": 2, "act": {"1": [400, 0.4]}, "rounds": 404,
    "replies": 404, "wait_s": 0.0, "loop_s": 12.8,
}  # fmt: skip


def test_costs_from_a_timing_record_by_hand():
    c = from_timing(TIMING, steps_per_episode=100)
    assert c.sim_s_per_step == pytest.approx(0.02)
    assert c.reset_s == pytest.approx(0.1) and c.build_s == pytest.approx(2.0)
    assert c.act_at(1) == (pytest.approx(0.001), "1.00 ms a call over 1 environment(s) (measured at 1)")
    # in process the workers' seconds run inside the loop: 12.8 − 0.4 act − 8 − 4.4 = 0 s of coordinator
    assert c.coord_s_per_reply == pytest.approx(0.0, abs=1e-9)
    assert c.fixed_s == pytest.approx(1 + 3 + 2 + EXIT_S)


def test_one_worker_projection_by_hand():
    """4 episodes × 100 steps at 1 worker: each episode 100 × (20 ms + 1 ms act) + 0.1 s reset = 2.2 s; 4 episodes
    on one slot: 4 + 0.5 tail = 4.5 episodes = 9.9 s; builds: 2 cells on one worker = 4 s; plus 7 s fixed."""
    c = from_timing(TIMING, steps_per_episode=100)
    assert rollout_seconds(c, [4], 1, 1, 2) == pytest.approx(9.9 + 4.0)
    p = project(c, 1, 1, 2, [4])
    assert p.expected == pytest.approx(7.0 + 13.9)
    assert (p.low, p.high) == (pytest.approx(LOW * p.expected), pytest.approx(HIGH * p.expected))
    assert p.bound == "simulators"


def test_more_workers_than_cores_slow_each_step_and_say_so():
    c = from_timing(TIMING, steps_per_episode=100)
    p8 = project(c, 8, 1, 2, [400])
    assert p8.round_s["simulators"] == pytest.approx(0.02 * 9 / 2)  # 8 workers + the CPU policy on 2 cores
    assert p8.bound.startswith("simulators (8 workers share 2 cores)")
    assert p8.steps_per_s < 2 / 0.02  # never more than the cores' worth


def test_a_slow_batched_policy_bounds_the_round():
    c = Costs(sim_s_per_step=0.005, reset_s=0, build_s=0, act_s={8: 0.4, 16: 0.45}, batched=True,
              coord_s_per_reply=1e-4, fixed_s=10, steps_per_episode=100, cores=16, on_cpu_policy=False)  # fmt: skip
    p = project(c, 12, 5, 10, [1000])
    assert p.bound == "policy"
    assert p.round_s["policy"] == pytest.approx(0.4 + 0.05 * 4 / 8)  # interpolated between 8 and 16
    assert "extrapolated" in project(c, 32, 5, 10, [1000]).act_note


def test_bad_timing_is_refused_in_one_line():
    with pytest.raises(ConfigError, match="lacks"):
        from_timing({"steps": 1}, 10)
    with pytest.raises(ConfigError, match="no finished episode"):
        from_timing({**TIMING, "steps": 0}, 10)


def test_a_smoke_on_a_busy_box_widens_the_interval():
    """Load 8 on 2 cores: the smoke saw a quarter of the box, the run may see more or less: √4 = 2× wider."""
    calm, busy = from_timing(TIMING, 100), from_timing({**TIMING, "load_avg_1m": 8.0}, 100)
    a, b = project(calm, 1, 1, 2, [4]), project(busy, 1, 1, 2, [4])
    assert b.expected == pytest.approx(a.expected)
    assert (b.low, b.high) == (pytest.approx(a.low / 2), pytest.approx(a.high * 2))


def test_every_act_description_carries_its_milliseconds_and_no_act_names_no_bound():
    """budget prints "act <description>": each names the seconds it uses (it printed a bare "measured at 1"), and
    without any act latency (--steps-per-s) no bound is named, as the note and docs/budget.md say."""
    c = Costs(sim_s_per_step=0.005, reset_s=0, build_s=0, act_s={8: 0.4, 16: 0.45}, batched=True,
              coord_s_per_reply=1e-4, fixed_s=10, steps_per_episode=100, cores=16, on_cpu_policy=False)  # fmt: skip
    assert c.act_at(8)[1] == "400.00 ms a call over 8 environment(s) (measured at 8)"
    assert c.act_at(12)[1].startswith(
        "425.00 ms a call over 12 environment(s) (interpolated between batches 8"
    )
    assert c.act_at(32)[1].startswith(
        "450.00 ms a call over 32 environment(s) (extrapolated flat from batch 16"
    )
    blind = Costs(sim_s_per_step=0.01, reset_s=0, build_s=0, act_s={}, batched=True, coord_s_per_reply=0,
                  fixed_s=10, steps_per_episode=100, cores=10**6, on_cpu_policy=False)  # fmt: skip
    assert blind.act_at(2) == (0.0, "not measured")
    assert project(blind, 2, 1, 1, [10]).bound == "none named (no act latency known)"
