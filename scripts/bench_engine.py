"""Benchmark the rollout engine against a bare ``env.step`` + policy loop, 1 vs 2 workers, and
batched vs per-env inference of a tiny in-process policy. Prints one JSON object on its last line.

    .venv/bin/python scripts/bench_engine.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("HF_HUB_OFFLINE", "1")


def bare_loop(jobs, scene, policy, replan, max_steps) -> float:
    """The reference: the same episodes with nothing but make_env / reset / act / step."""
    import scenes

    t0 = time.perf_counter()
    env = None
    for job in jobs:
        if env is None:
            env = scenes.make_env(scene, task=job.task, axis=job.axis, level=job.level, cameras=(),
                                  max_steps=max_steps)  # fmt: skip
        obs, _ = env.reset(seed=job.seed)
        policy.reset(obs.instruction, seed=job.seed)
        done = False
        while not done:
            chunk = policy.act([obs])[0]
            for a in chunk[:replan]:
                obs, _, term, trunc, info = env.step(a)
                if term or trunc or info.get("success"):
                    done = True
                    break
    env.close()
    return time.perf_counter() - t0


def engine_run(jobs, scene, spec_str, replan, max_steps, workers) -> float:
    from indgen_vla.engine.local import run_local
    from indgen_vla.engine.rollout import RunMeta, RunnerConfig
    from policy_wrappers.registry import load_policy

    rc = RunnerConfig(
        scene=scene, cameras=(), image_size=(64, 64), max_steps=max_steps, step=None, privileged=False
    )
    records = []
    t0 = time.perf_counter()
    run_local(jobs, rc, lambda: load_policy(spec_str), RunMeta("bench", spec_str, "", scene), records.append,
              workers=workers, replan_steps=replan)  # fmt: skip
    assert len(records) == len(jobs) and all(r.status == "ok" for r in records)
    return time.perf_counter() - t0


def batched_gain(batch: int, reps: int) -> float:
    """Time one act() over a batch of 8 observations vs 8 single-observation calls (tiny LeRobot ACT)."""
    import numpy as np

    from indgen_vla.interface import Observation
    from policy_wrappers.registry import load_policy
    from policy_wrappers.tiny import build_tiny_checkpoint

    with tempfile.TemporaryDirectory() as d:
        path = build_tiny_checkpoint("act", d, cameras=("agentview", "wrist"), size=64)
        policy = load_policy(f"lerobot:{path}")
        h, w = policy.spec.image_size or (64, 64)
        rng = np.random.default_rng(0)
        obs = [Observation({c: rng.integers(0, 255, (h, w, 3), dtype=np.uint8) for c in policy.spec.cameras},
                           rng.normal(size=8).astype(np.float32), "pick up the milk") for _ in range(batch)]  # fmt: skip
        policy.reset("pick up the milk", seed=0)
        policy.act(obs)  # warm-up
        t0 = time.perf_counter()
        for _ in range(reps):
            policy.act(obs)
        t_batched = time.perf_counter() - t0
        t0 = time.perf_counter()
        for _ in range(reps):
            for o in obs:
                policy.act([o])
        t_single = time.perf_counter() - t0
        policy.close()
    return t_single / t_batched


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="few short episodes (CI smoke run)")
    ap.add_argument("--scene", default="pick_place")
    ap.add_argument("--policy", default="standin:random")
    ap.add_argument(
        "--repeats", type=int, default=None, help="interleaved repeats, best kept (default 3; quick 1)"
    )
    args = ap.parse_args()
    import torch

    torch.set_num_threads(1)
    from indgen_vla.engine.config import EvalConfig, plan_episodes

    episodes, max_steps = (4, 40) if args.quick else (16, 200)
    cfg = EvalConfig(policy=args.policy, scene=args.scene, axes=("pick_y",), out="-", episodes=episodes)
    import scenes

    task = scenes.tasks(args.scene)[0]
    jobs = plan_episodes(cfg, [task], {"pick_y": [0]}, {(t, "pick_y", 0): 0.0 for t in [task]})
    from policy_wrappers.registry import load_policy

    policy = load_policy(args.policy)
    replan = policy.spec.replan_steps
    scenes.make_env(args.scene, task=task, cameras=()).close()  # warm-up: imports and first model build
    steps = len(jobs) * max_steps
    repeats = args.repeats or (1 if args.quick else 3)
    times: dict[str, list[float]] = {"bare": [], "1w": [], "2w": []}
    for _ in range(repeats):  # interleaved, so a burst of load elsewhere hits every variant alike
        times["bare"].append(bare_loop(jobs, args.scene, policy, replan, max_steps))
        times["1w"].append(engine_run(jobs, args.scene, args.policy, replan, max_steps, workers=1))
        times["2w"].append(engine_run(jobs, args.scene, args.policy, replan, max_steps, workers=2))
    t_bare, t_eng1, t_eng2 = min(times["bare"]), min(times["1w"]), min(times["2w"])
    gain = batched_gain(8, 5 if args.quick else 20)
    result = {
        "machine": f"{platform.machine()} {os.cpu_count()} cores", "scene": args.scene, "policy": args.policy,
        "episodes": len(jobs), "max_steps": max_steps, "repeats": repeats,
        "bare_s": round(t_bare, 3), "engine_1w_s": round(t_eng1, 3), "engine_2w_s": round(t_eng2, 3),
        "steps_per_s_bare": round(steps / t_bare, 1), "steps_per_s_engine_1w": round(steps / t_eng1, 1),
        "episodes_per_s_1w": round(len(jobs) / t_eng1, 3), "episodes_per_s_2w": round(len(jobs) / t_eng2, 3),
        "overhead_ratio": round(t_eng1 / t_bare - 1, 4),
        "speedup_2_workers": round(t_eng1 / t_eng2, 3),
        "batched_gain": round(gain, 3),
    }  # fmt: skip
    print(json.dumps(result))


if __name__ == "__main__":
    main()
