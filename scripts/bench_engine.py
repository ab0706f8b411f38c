"""Benchmark the rollout engine against a bare ``env.step`` + policy loop, 1 vs 2 workers (with their start
costs and CPU seconds per process), batched vs per-env inference of a tiny in-process policy, pipelined vs
unpipelined with a LeRobot ACT whose forward costs about one control step, lazy vs per-step renders, and thread
overlap of physics and inference (the GIL). Prints one JSON object on its last line (docs/results/benchmarks/engine.md).

    .venv/bin/python scripts/bench_engine.py [--quick] [--only engine|pipeline|render|gil]

A GPU box (``_engine_box.py``): ``--only model`` (``--policy`` alone by ``--batches``), ``--only scaling``
(engine steps/s by ``--workers`` with cameras, ``--pin``, ``--pipeline``, against the policy alone at each
batch); the coordinator's and one worker's CPU per control step (``_engine_profile.py``):
``--profile-coordinator``, ``--profile-worker``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

from _engine_box import CpuMeter, level0_jobs, model_alone, scaling
from _engine_profile import profile_coordinator, profile_worker

from scenes.family import get_scene

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("HF_HUB_OFFLINE", "1")


def bare_loop(jobs, scene, policy, replan, max_steps) -> float:
    """The reference: the same episodes with nothing but make_env / reset / act / step."""
    from scenes.planning import scene_levels

    t0 = time.perf_counter()
    env = None
    for job in jobs:
        if env is None:
            env = scene_levels(get_scene(scene), [job.axis]).make_env(job.task, job.axis, job.level, cameras=(),
                                                           image_size=(128, 128), max_steps=max_steps)  # fmt: skip
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


CPU: dict[str, tuple[float, float]] = {}  # run label -> CPU seconds (main process, workers) of its last run


def engine_run(jobs, scene, spec_str, replan, max_steps, workers, pipeline=False) -> float:
    from indgen_vla.app.engine.local import LocalOptions, run_local
    from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig
    from policy_wrappers.specs import load_policy
    from scenes.planning import scene_levels

    rc = RunnerConfig(
        levels=scene_levels(get_scene(scene), ["pick_y"]),
        cameras=(),
        image_size=(64, 64),
        max_steps=max_steps,
        privileged=False,
    )
    records = []
    t0 = time.perf_counter()
    with CpuMeter() as meter:
        run_local(
            jobs,
            rc,
            lambda: load_policy(spec_str),
            RunMeta("bench", spec_str, "", scene),
            records.append,
            LocalOptions(workers=workers, replan_steps=replan, pipeline=pipeline),
        )
    assert len(records) == len(jobs) and all(r.status == "ok" for r in records)
    CPU[f"{workers}w{'p' if pipeline else ''}_{len(jobs)}x{max_steps}"] = (round(meter.main_s, 2),
                                                                          round(meter.workers_s, 2))  # fmt: skip
    return time.perf_counter() - t0


def worker_start_s(jobs, scene, spec_str, workers: int) -> float:
    """Fixed cost of a run: ``workers`` environments started, built and reset, each running one 1-step episode."""
    return engine_run(jobs[:workers], scene, spec_str, 1, 1, workers)


def pipeline_bench(
    scene: str, size: int, episodes: int, max_steps: int, repeats: int, device: str = "cpu"
) -> dict:
    """A LeRobot ACT (ResNet-18 backbone, random init) on one ``size``-px camera, acting every control step:
    its forward costs about one control step (physics + render). 1 worker, unpipelined vs pipelined, interleaved
    repeats; the records of both must be equal (the pipelined engine changes speed only)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: tests.fixtures
    import numpy as np

    from indgen_vla.app.engine.local import LocalOptions, run_local
    from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig
    from policy_wrappers.specs import load_policy
    from scenes.planning import scene_levels
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

    task, jobs = level0_jobs(scene, episodes)
    with tempfile.TemporaryDirectory() as d:
        path = build_tiny_checkpoint("act", d, cameras=("agentview",), size=size)
        policy = load_policy(f"lerobot:{path}", scene=scene, device=device)
        cams, hw = policy.spec.cameras, tuple(policy.spec.image_size or (size, size))
        # calibration: one step vs one act
        env = scene_levels(get_scene(scene), ["pick_y"]).make_env(
            task, "pick_y", 0, cameras=cams, image_size=hw, max_steps=None
        )
        obs, _ = env.reset(seed=0)
        policy.reset(obs.instruction, seed=0)
        policy.act([obs])
        t0 = time.perf_counter()
        for _ in range(10):
            chunk = policy.act([obs])
        t_act = (time.perf_counter() - t0) / 10
        t0 = time.perf_counter()
        for _ in range(10):
            obs, *_ = env.step(np.asarray(chunk[0, 0]))
        t_step = (time.perf_counter() - t0) / 10
        env.close()
        rc = RunnerConfig(
            levels=scene_levels(get_scene(scene), ["pick_y"]),
            cameras=cams,
            image_size=hw,
            max_steps=max_steps,
            privileged=False,
        )
        meta = RunMeta("bench", "act", "", scene)
        warm = [j for j in jobs[:2]]  # start the forkserver (imports) before timing: a one-off per process
        run_local(
            warm,
            dataclasses.replace(rc, max_steps=1),
            lambda: policy,
            meta,
            lambda r: None,
            LocalOptions(workers=1, replan_steps=1, close_policies=False, pipeline=True),
        )
        times: dict[bool, list[float]] = {False: [], True: []}
        cpu: dict[bool, tuple[float, float]] = {}
        rows: dict[bool, list] = {}
        for _ in range(repeats):
            for pipelined in (False, True):
                records: list = []
                t0 = time.perf_counter()
                with CpuMeter() as meter:
                    run_local(
                        jobs,
                        rc,
                        lambda: policy,
                        meta,
                        records.append,
                        LocalOptions(workers=1, replan_steps=1, close_policies=False, pipeline=pipelined),
                    )
                times[pipelined].append(time.perf_counter() - t0)
                cpu[pipelined] = (round(meter.main_s, 2), round(meter.workers_s, 2))
                rows[pipelined] = sorted(
                    (r.episode, r.seed, r.success, r.steps, r.status, r.failure) for r in records
                )
        policy.close()
    assert all(r[4] == "ok" for r in rows[False]), rows[False]
    steps = len(jobs) * max_steps
    t_off, t_on = min(times[False]), min(times[True])
    return {
        "pipeline_policy": f"lerobot ACT resnet18, 1 camera {hw[0]}px, replan 1", "pipeline_episodes": len(jobs),
        "pipeline_max_steps": max_steps, "act_ms": round(1000 * t_act, 1), "control_step_ms": round(1000 * t_step, 1),
        "unpipelined_s": round(t_off, 2), "pipelined_s": round(t_on, 2),
        "steps_per_s_unpipelined": round(steps / t_off, 2), "steps_per_s_pipelined": round(steps / t_on, 2),
        "pipeline_gain": round(t_off / t_on, 3), "pipeline_identical": rows[False] == rows[True],
        "pipeline_times": {"off": [round(t, 2) for t in times[False]], "on": [round(t, 2) for t in times[True]]},
        "cpu_s_unpipelined_main_workers": cpu[False], "cpu_s_pipelined_main_workers": cpu[True],
        "idle_bound_gain": round(sum(cpu[False]) / max(cpu[True]), 3),
    }  # fmt: skip


def batched_gain(batch: int, reps: int) -> float:
    """Time one act() over a batch of 8 observations vs 8 single-observation calls (tiny LeRobot ACT)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: tests.fixtures
    import numpy as np

    from indgen_vla.core.protocol.interface import Observation
    from policy_wrappers.specs import load_policy
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

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


def lazy_render_bench(scene: str, size: int, episodes: int, max_steps: int, repeats: int) -> dict:
    """A tiny LeRobot ACT (chunk 10, two cameras) executing whole chunks, 1 worker: rendering only the observation
    each chunk ends on (``lazy_render``, the default) vs rendering every step; records must be equal."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from indgen_vla.app.engine.local import LocalOptions, run_local
    from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig
    from policy_wrappers.specs import load_policy
    from scenes.planning import scene_levels
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

    task, jobs = level0_jobs(scene, episodes)
    times: dict[bool, list[float]] = {False: [], True: []}
    cpu: dict[bool, float] = {}
    rows: dict[bool, list] = {}
    with tempfile.TemporaryDirectory() as d:
        policy = load_policy(
            f"lerobot:{build_tiny_checkpoint('act', d, cameras=('agentview', 'wrist'), size=size)}"
        )
        hw = tuple(policy.spec.image_size or (size, size))
        replan = policy.spec.replan_steps
        for _ in range(repeats):
            for lazy in (False, True):
                rc = RunnerConfig(levels=scene_levels(get_scene(scene), ["pick_y"]), cameras=policy.spec.cameras, image_size=hw, max_steps=max_steps, privileged=False, lazy_render=lazy)  # fmt: skip
                records: list = []
                t0 = time.perf_counter()
                with CpuMeter() as meter:
                    run_local(
                        jobs,
                        rc,
                        lambda: policy,
                        RunMeta("bench", "act", "", scene),
                        records.append,
                        LocalOptions(workers=1, replan_steps=replan, close_policies=False),
                    )
                times[lazy].append(time.perf_counter() - t0)
                cpu[lazy] = round(meter.main_s + meter.workers_s, 2)
                rows[lazy] = sorted(
                    (r.episode, r.seed, r.success, r.steps, r.status, r.failure) for r in records
                )
        policy.close()
    t_eager, t_lazy = min(times[False]), min(times[True])
    return {
        "render_policy": f"lerobot ACT, 2 cameras {hw[0]}px, replan {replan}", "render_episodes": len(jobs),
        "render_max_steps": max_steps, "eager_s": round(t_eager, 2), "lazy_s": round(t_lazy, 2),
        "lazy_render_gain": round(t_eager / t_lazy, 3), "lazy_render_cpu_gain": round(cpu[False] / cpu[True], 3),
        "cpu_s_eager_lazy": (cpu[False], cpu[True]), "lazy_render_identical": rows[False] == rows[True],
    }  # fmt: skip


def gil_overlap(scene: str, size: int, n: int) -> dict:
    """Why workers are processes: a thread stepping the scene and a thread running an ACT forward, vs the same
    work one after the other (ratio 0.5 = full overlap, 1.0 = none: the GIL serialises them)."""
    import threading

    import numpy as np

    import scenes
    from policy_wrappers.specs import load_policy
    from scenes.planning import scene_levels
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

    task = list(scenes.get_scene(scene).tasks)[0]
    levels = scene_levels(get_scene(scene), ["pick_y"])  # level 0: T0
    out = {}
    with tempfile.TemporaryDirectory() as d:
        policy = load_policy(f"lerobot:{build_tiny_checkpoint('act', d, cameras=('agentview',), size=size)}")
        hw = tuple(policy.spec.image_size or (size, size))
        for label, cams in (("physics", ()), ("physics+render", ("agentview",))):
            env = levels.make_env(task, "pick_y", 0, cameras=cams or (), image_size=hw, max_steps=None)
            render_env = levels.make_env(
                task, "pick_y", 0, cameras=("agentview",), image_size=hw, max_steps=None
            )
            obs, _ = render_env.reset(seed=0)
            policy.reset(obs.instruction, seed=0)
            policy.act([obs])

            def sim(env=env):
                env.reset(seed=1)
                for _ in range(n):
                    env.step(np.zeros(7))

            def infer(obs=obs):
                for _ in range(n):
                    policy.act([obs])

            t0 = time.perf_counter()
            sim()
            infer()
            serial = time.perf_counter() - t0
            threads = [threading.Thread(target=f) for f in (sim, infer)]
            t0 = time.perf_counter()
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            out[f"threads_vs_serial_{label}"] = round((time.perf_counter() - t0) / serial, 3)
            env.close()
            render_env.close()
        policy.close()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="few short episodes (CI smoke run)")
    ap.add_argument("--scene", default="pick_place")
    ap.add_argument("--policy", default="standin:random")
    ap.add_argument(
        "--repeats", type=int, default=None, help="interleaved repeats, best kept (default 3; quick 1)"
    )
    ap.add_argument("--only", choices=["engine", "pipeline", "render", "gil", "model", "scaling"], default=None,
                    help="run one part only (model: --policy alone by --batches; scaling: --workers with cameras)")  # fmt: skip
    ap.add_argument("--device", default="cpu", help="where the policy runs (model, scaling, pipeline parts)")
    ap.add_argument("--precision", default="fp32", choices=["fp32", "bf16"], help="bf16: autocast forward")
    ap.add_argument("--compile", default="off", choices=["off", "default", "reduce-overhead", "max-autotune"],
                    help="model/scaling parts: torch.compile the policy's forward (first_call_s holds the compile)")  # fmt: skip
    ap.add_argument("--batches", default="1,4,16,64", help="model part: batch sizes")
    ap.add_argument("--workers", default="1,2,4,8,16", help="scaling part: worker counts")
    ap.add_argument(
        "--cameras", default="agentview,wrist", help="scaling part: cameras of a camera-less policy"
    )
    ap.add_argument("--pipeline", action="store_true",
                    help="scaling part: two environments per worker, one steps while the policy acts for the other")  # fmt: skip
    ap.add_argument("--pin", action="store_true",
                    help="scaling part: pin the coordinator to core 0 and each worker to one other core")  # fmt: skip
    ap.add_argument("--seconds", type=float, default=5.0,
                    help="model part: timed seconds per batch size (scaling part: per worker count)")  # fmt: skip
    ap.add_argument("--profile-coordinator", action="store_true",
                    help="main-process CPU per control step (forward excluded) with a cProfile split")  # fmt: skip
    ap.add_argument("--profile-workers", type=int, default=2, help="--profile-coordinator: worker processes")
    ap.add_argument("--profile-worker", action="store_true",
                    help="one worker's CPU per control step (physics, renders, observation, pickling), in process")  # fmt: skip
    ap.add_argument(
        "--profile-out", default=None, help="--profile-coordinator: write the cProfile stats here"
    )
    ap.add_argument("--pipeline-size", type=int, default=128, help="camera size of the pipelining ACT")
    ap.add_argument(
        "--episodes",
        type=int,
        default=None,
        help="episodes (engine part 16, scaling 32, pipeline 4; quick 4)",
    )
    ap.add_argument(
        "--max-steps",
        type=int,
        default=None,
        help="steps each (engine part 200, scaling 100, pipeline 60; quick 40)",
    )
    args = ap.parse_args()
    import torch

    torch.set_num_threads(1)
    repeats = args.repeats or (1 if args.quick else 3)
    head = {"machine": f"{platform.machine()} {os.cpu_count()} cores", "load_avg_start": os.getloadavg()[0],
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}  # fmt: skip
    ints = lambda text: [int(x) for x in text.split(",") if x.strip()]  # noqa: E731
    if args.profile_coordinator:
        eps, steps = (4, 40) if args.quick else (args.episodes or 8, args.max_steps or 100)
        spec = None if args.policy == "standin:random" else args.policy
        res = profile_coordinator(
            spec,
            args.scene,
            args.profile_workers,
            eps,
            steps,
            args.pipeline_size,
            args.device,
            args.profile_out,
        )
        print(json.dumps({**head, **res, "load_avg_end": os.getloadavg()[0]}))
        return
    if args.profile_worker:
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        eps, steps = (2, 40) if args.quick else (args.episodes or 4, args.max_steps or 100)
        res = profile_worker(args.scene, eps, steps, args.pipeline_size, 10, tuple(args.cameras.split(",")))
        print(json.dumps({**head, **res, "load_avg_end": os.getloadavg()[0]}))
        return
    if args.only == "model":
        res = model_alone(
            args.policy, ints(args.batches), args.device, args.precision, args.seconds, args.compile
        )
        print(json.dumps({**head, **res}))
        return
    if args.only == "scaling":
        eps, steps = (4, 40) if args.quick else (args.episodes or 32, args.max_steps or 100)
        res = scaling(args.policy, args.scene, ints(args.workers), eps, steps, args.cameras.split(","),
                      args.pipeline_size, args.device, args.precision, args.pin, args.compile, args.pipeline,
                      args.seconds)  # fmt: skip
        print(json.dumps({**head, **res, "load_avg_end": os.getloadavg()[0]}))
        return
    if args.only == "gil":
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        print(json.dumps({**head, **gil_overlap(args.scene, args.pipeline_size, 20 if args.quick else 60)}))
        return
    if args.only == "render":
        eps, steps = (2, 20) if args.quick else (4, 60)
        res = lazy_render_bench(args.scene, args.pipeline_size, eps, steps, repeats)
        print(json.dumps({**head, **res, "load_avg_end": os.getloadavg()[0]}))
        return
    if args.only == "pipeline":
        eps, steps = (2, 20) if args.quick else (args.episodes or 4, args.max_steps or 60)
        res = pipeline_bench(args.scene, args.pipeline_size, eps, steps, repeats, args.device)
        print(json.dumps({**head, **res, "load_avg_end": os.getloadavg()[0]}))
        return
    episodes, max_steps = (4, 40) if args.quick else (16, 200)
    episodes, max_steps = args.episodes or episodes, args.max_steps or max_steps
    from scenes.planning import scene_levels

    task, jobs = level0_jobs(args.scene, episodes)
    from policy_wrappers.specs import load_policy

    policy = load_policy(args.policy)
    replan = policy.spec.replan_steps
    # warm-up: imports and first model build
    scene_levels(get_scene(args.scene), ["pick_y"]).make_env(task, "pick_y", 0, cameras=(), image_size=(128, 128),
                                                  max_steps=None).close()  # fmt: skip
    steps = len(jobs) * max_steps
    times: dict[str, list[float]] = {"bare": [], "1w": [], "2w": [], "start_1w": [], "start_2w": []}
    for _ in range(repeats):  # interleaved, so a burst of load elsewhere hits every variant alike
        times["bare"].append(bare_loop(jobs, args.scene, policy, replan, max_steps))
        times["1w"].append(engine_run(jobs, args.scene, args.policy, replan, max_steps, workers=1))
        times["2w"].append(engine_run(jobs, args.scene, args.policy, replan, max_steps, workers=2))
        times["start_1w"].append(worker_start_s(jobs, args.scene, args.policy, 1))
        times["start_2w"].append(worker_start_s(jobs, args.scene, args.policy, 2))
    t_bare, t_eng1, t_eng2 = min(times["bare"]), min(times["1w"]), min(times["2w"])
    gain = batched_gain(8, 5 if args.quick else 20)
    s1, s2 = min(times["start_1w"]), min(times["start_2w"])
    result = {
        **head, "scene": args.scene, "policy": args.policy,
        "episodes": len(jobs), "max_steps": max_steps, "repeats": repeats,
        "bare_s": round(t_bare, 3), "engine_1w_s": round(t_eng1, 3), "engine_2w_s": round(t_eng2, 3),
        "steps_per_s_bare": round(steps / t_bare, 1), "steps_per_s_engine_1w": round(steps / t_eng1, 1),
        "episodes_per_s_1w": round(len(jobs) / t_eng1, 3), "episodes_per_s_2w": round(len(jobs) / t_eng2, 3),
        "overhead_ratio": round(t_eng1 / t_bare - 1, 4),
        "speedup_2_workers": round(t_eng1 / t_eng2, 3),
        "batched_gain": round(gain, 3),
        "start_1w_s": round(s1, 3), "start_2w_s": round(s2, 3),
        "speedup_2_workers_net_of_start": round((t_eng1 - s1) / (t_eng2 - s2), 3),
        "cpu_s_main_workers": CPU,
    }  # fmt: skip
    if args.only is None:
        eps, steps = (2, 20) if args.quick else (4, 60)
        result.update(pipeline_bench(args.scene, args.pipeline_size, eps, steps, repeats, args.device))
    result["load_avg_end"] = os.getloadavg()[0]
    print(json.dumps(result))


if __name__ == "__main__":
    main()
