"""Benchmark the Ray backend against the local one on this machine: the same oracle episodes of ``pick_place`` with 2
simulators either way (local: 2 worker processes, the policy in the main process; Ray: a local Ray instance, 2
simulator actors and 1 policy actor), reporting Ray's start, each run's wall time with and without its start, the
episodes per second once every simulator has finished one episode, and one policy call's round trip through a
policy actor. The records of both must be equal. Prints one JSON object on its last line (docs/results/benchmarks/ray.md).

    .venv/bin/python scripts/bench_ray.py [--episodes 12] [--max-steps 60] [--calls 300]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

ROW = ("task", "axis", "level", "episode", "seed", "success", "steps", "status", "failure")


def _jobs(episodes: int):
    import scenes
    from indgen_vla.app.engine.config import EvalConfig, plan_episodes

    task = scenes.tasks("pick_place")[0]
    cfg = EvalConfig.from_flat(policy="standin:oracle", scene="pick_place", axes=("pick_y",), out="-",
                               episodes=episodes, workers=2, backend="ray")  # fmt: skip
    return cfg, plan_episodes(cfg, [task], {"pick_y": [0]}, {(task, "pick_y", 0): 0.0})


def _timed(run) -> dict:
    """Wall time of ``run(on_record)``, and episodes/s after the first two finished (both simulators warm)."""
    stamps: list[float] = []
    records: list = []

    def on_record(r) -> None:
        stamps.append(time.perf_counter())
        records.append(r)

    t0 = time.perf_counter()
    run(on_record)
    wall = time.perf_counter() - t0
    steady = (len(stamps) - 2) / (stamps[-1] - stamps[1]) if len(stamps) > 2 else float("nan")
    return {"wall_s": round(wall, 2), "first_two_s": round(stamps[1] - t0, 2), "episodes_per_s": round(steady, 3),
            "rows": sorted(tuple(getattr(r, k) for k in ROW) for r in records)}  # fmt: skip


def round_trip_ms(calls: int) -> dict:
    """One ``act`` of a trivial policy: called in process vs through a policy actor from another actor."""
    import numpy as np
    import ray

    from indgen_vla.app.engine.ray_backend import _PolicyActor, _PolicyClient
    from indgen_vla.core.protocol.interface import Observation
    from policy_wrappers.registry import load_policy

    obs = Observation({}, np.zeros(8, np.float32), "pick")
    direct = load_policy("standin:random")
    direct.reset("pick", seed=0)
    t0 = time.perf_counter()
    for _ in range(calls):
        direct.act([obs])
    in_process = (time.perf_counter() - t0) / calls * 1e3

    @ray.remote(num_cpus=0)
    class Caller:
        def time_calls(self, actor, spec, n: int) -> list[float]:
            client = _PolicyClient(actor, 0, spec)
            client.reset("pick", seed=0)
            out = []
            for _ in range(n):
                t = time.perf_counter()
                client.act([obs])
                out.append((time.perf_counter() - t) * 1e3)
            return out

    actor = ray.remote(num_cpus=0, max_concurrency=4)(_PolicyActor).remote(
        lambda: load_policy("standin:random"), 32, 0.005
    )
    spec = ray.get(actor.hello.remote())
    times = ray.get(Caller.remote().time_calls.remote(actor, spec, calls))
    return {"in_process_ms": round(in_process, 3), "through_actor_median_ms": round(statistics.median(times), 3),
            "through_actor_p90_ms": round(sorted(times)[int(0.9 * len(times))], 3), "calls": calls}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=12)
    ap.add_argument("--max-steps", type=int, default=60)
    ap.add_argument("--calls", type=int, default=300)
    args = ap.parse_args()

    import ray

    from indgen_vla.app.engine.local import run_local
    from indgen_vla.app.engine.ray_backend import run_ray
    from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig
    from scenes.oracle import OraclePolicy
    from scenes.planning import scene_levels

    cfg, jobs = _jobs(args.episodes)
    rc = RunnerConfig(levels=scene_levels("pick_place", ["pick_y"]), cameras=(), image_size=(64, 64),
                      max_steps=args.max_steps, privileged=True)  # fmt: skip
    meta = RunMeta("bench", "standin:oracle", "", "pick_place")
    replan = OraclePolicy.spec.replan_steps
    local = _timed(lambda rec: run_local(jobs, rc, OraclePolicy, meta, rec, workers=2, replan_steps=replan))
    t0 = time.perf_counter()
    ray.init(address="local", num_cpus=3, include_dashboard=False, log_to_driver=False)
    ray_start = time.perf_counter() - t0
    try:
        on_ray = _timed(lambda rec: run_ray(jobs, rc, cfg, meta, rec, replan, make_policy=OraclePolicy))
        trip = round_trip_ms(args.calls)
    finally:
        ray.shutdown()
    assert local.pop("rows") == on_ray.pop("rows"), (
        "the Ray backend recorded other outcomes than the local one"
    )
    chunks = sum(-(-args.max_steps // replan) for _ in jobs)  # upper bound of policy calls of the run
    result = {
        "machine": f"{platform.machine()} {os.cpu_count()} cores", "load_1min": round(os.getloadavg()[0], 2),
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "episodes": len(jobs),
        "max_steps": args.max_steps, "replan_steps": replan, "local": local, "ray": on_ray,
        "ray_init_s": round(ray_start, 2), "policy_round_trip": trip, "policy_calls_at_most": chunks,
        "steady_ratio_local_over_ray": round(local["episodes_per_s"] / on_ray["episodes_per_s"], 3),
    }  # fmt: skip
    print(json.dumps(result))


if __name__ == "__main__":
    main()
