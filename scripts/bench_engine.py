"""Benchmark the rollout engine against a bare ``env.step`` + policy loop, 1 vs 2 workers (with their start
costs and CPU seconds per process), batched vs per-env inference of a tiny in-process policy, pipelined vs
unpipelined with a LeRobot ACT whose forward costs about one control step, lazy vs per-step renders, and thread
overlap of physics and inference (the GIL). Prints one JSON object on its last line (docs/benchmarks.md).

    .venv/bin/python scripts/bench_engine.py [--quick] [--only engine|pipeline|render|gil]
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


CPU: dict[str, tuple[float, float]] = {}  # run label -> CPU seconds (main process, workers) of its last run


def engine_run(jobs, scene, spec_str, replan, max_steps, workers, pipeline=False) -> float:
    from indgen_vla.engine.local import run_local
    from indgen_vla.engine.rollout import RunMeta, RunnerConfig
    from policy_wrappers.registry import load_policy
    from scenes.planning import scene_levels

    rc = RunnerConfig(
        levels=scene_levels(scene, ["pick_y"]),
        cameras=(),
        image_size=(64, 64),
        max_steps=max_steps,
        privileged=False,
    )
    records = []
    t0 = time.perf_counter()
    with CpuMeter() as meter:
        run_local(jobs, rc, lambda: load_policy(spec_str), RunMeta("bench", spec_str, "", scene), records.append,
                  workers=workers, replan_steps=replan, pipeline=pipeline)  # fmt: skip
    assert len(records) == len(jobs) and all(r.status == "ok" for r in records)
    CPU[f"{workers}w{'p' if pipeline else ''}_{len(jobs)}x{max_steps}"] = (round(meter.main_s, 2),
                                                                          round(meter.workers_s, 2))  # fmt: skip
    return time.perf_counter() - t0


def worker_start_s(jobs, scene, spec_str, workers: int) -> float:
    """Fixed cost of a run: ``workers`` environments started, built and reset, each running one 1-step episode."""
    return engine_run(jobs[:workers], scene, spec_str, 1, 1, workers)


class CpuMeter:
    """CPU seconds of this process and of every worker process it started (sampled, as workers exit on close),
    so a run on a loaded machine still tells how the work splits: with idle cores the wall time of a pipelined
    run tends to max(policy process, worker), of an unpipelined one to their sum."""

    def __init__(self, period_s: float = 0.2):
        import threading

        import psutil

        self._me, self._period, self._seen = psutil.Process(), period_s, {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)

    def _sample(self) -> None:
        for child in self._me.children(recursive=True):
            try:
                if child.ppid() == self._me.pid and "forkserver" in " ".join(child.cmdline()):
                    continue  # the idle fork server itself (its children, the workers, share its command line)
                t = child.cpu_times()
                self._seen[child.pid] = t.user + t.system
            except Exception:  # exited between listing and reading
                pass

    def _loop(self) -> None:
        while not self._stop.wait(self._period):
            self._sample()

    def __enter__(self):
        self._t0 = time.process_time()
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()
        self.main_s, self.workers_s = time.process_time() - self._t0, sum(self._seen.values())


def pipeline_bench(
    scene: str, size: int, episodes: int, max_steps: int, repeats: int, device: str = "cpu"
) -> dict:
    """A LeRobot ACT (ResNet-18 backbone, random init) on one ``size``-px camera, acting every control step:
    its forward costs about one control step (physics + render). 1 worker, unpipelined vs pipelined, interleaved
    repeats; the records of both must be equal (the pipelined engine changes speed only)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: tests.fixtures
    import numpy as np

    import scenes
    from indgen_vla.engine.config import EvalConfig, plan_episodes
    from indgen_vla.engine.local import run_local
    from indgen_vla.engine.rollout import RunMeta, RunnerConfig
    from policy_wrappers.registry import load_policy
    from scenes.planning import scene_levels
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

    task = scenes.tasks(scene)[0]
    cfg = EvalConfig(policy="act", scene=scene, axes=("pick_y",), out="-", episodes=episodes)
    jobs = plan_episodes(cfg, [task], {"pick_y": [0]}, {(task, "pick_y", 0): 0.0})
    with tempfile.TemporaryDirectory() as d:
        path = build_tiny_checkpoint("act", d, cameras=("agentview",), size=size)
        policy = load_policy(f"lerobot:{path}", scene=scene, device=device)
        cams, hw = policy.spec.cameras, tuple(policy.spec.image_size or (size, size))
        env = scenes.make_env(
            scene, task=task, cameras=cams, image_size=hw
        )  # calibration: one step vs one act
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
            levels=scene_levels(scene, ["pick_y"]),
            cameras=cams,
            image_size=hw,
            max_steps=max_steps,
            privileged=False,
        )
        meta = RunMeta("bench", "act", "", scene)
        warm = [j for j in jobs[:2]]  # start the forkserver (imports) before timing: a one-off per process
        run_local(warm, dataclasses.replace(rc, max_steps=1), lambda: policy, meta, lambda r: None, workers=1,
                  replan_steps=1, close_policies=False, pipeline=True)  # fmt: skip
        times: dict[bool, list[float]] = {False: [], True: []}
        cpu: dict[bool, tuple[float, float]] = {}
        rows: dict[bool, list] = {}
        for _ in range(repeats):
            for pipelined in (False, True):
                records: list = []
                t0 = time.perf_counter()
                with CpuMeter() as meter:
                    run_local(jobs, rc, lambda: policy, meta, records.append, workers=1, replan_steps=1,
                              close_policies=False, pipeline=pipelined)  # fmt: skip
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

    from indgen_vla.interface import Observation
    from policy_wrappers.registry import load_policy
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
    import scenes
    from indgen_vla.engine.config import EvalConfig, plan_episodes
    from indgen_vla.engine.local import run_local
    from indgen_vla.engine.rollout import RunMeta, RunnerConfig
    from policy_wrappers.registry import load_policy
    from scenes.planning import scene_levels
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

    task = scenes.tasks(scene)[0]
    cfg = EvalConfig(policy="act", scene=scene, axes=("pick_y",), out="-", episodes=episodes)
    jobs = plan_episodes(cfg, [task], {"pick_y": [0]}, {(task, "pick_y", 0): 0.0})
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
                rc = RunnerConfig(levels=scene_levels(scene, ["pick_y"]), cameras=policy.spec.cameras, image_size=hw, max_steps=max_steps, privileged=False, lazy_render=lazy)  # fmt: skip
                records: list = []
                t0 = time.perf_counter()
                with CpuMeter() as meter:
                    run_local(jobs, rc, lambda: policy, RunMeta("bench", "act", "", scene), records.append,
                              workers=1, replan_steps=replan, close_policies=False)  # fmt: skip
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
    from policy_wrappers.registry import load_policy
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

    task = scenes.tasks(scene)[0]
    out = {}
    with tempfile.TemporaryDirectory() as d:
        policy = load_policy(f"lerobot:{build_tiny_checkpoint('act', d, cameras=('agentview',), size=size)}")
        hw = tuple(policy.spec.image_size or (size, size))
        for label, cams in (("physics", ()), ("physics+render", ("agentview",))):
            env = scenes.make_env(scene, task=task, cameras=cams or (), image_size=hw)
            render_env = scenes.make_env(scene, task=task, cameras=("agentview",), image_size=hw)
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


def runner_config(scene: str, cameras, hw, max_steps: int):
    """The RunnerConfig of the GPU-era parts below (one place to adapt when RunnerConfig changes)."""
    from indgen_vla.engine.rollout import RunnerConfig
    from scenes.planning import scene_levels

    return RunnerConfig(levels=scene_levels(scene, ["pick_y"]), cameras=tuple(cameras), image_size=tuple(hw),
                        max_steps=max_steps, privileged=False)  # fmt: skip


class GpuBusy:
    """Mean GPU utilisation (%) over a block, sampled by ``nvidia-smi`` every 100 ms (None without a GPU)."""

    def __enter__(self):
        import shutil
        import subprocess

        self.proc = None
        if shutil.which("nvidia-smi"):
            cmd = [
                "nvidia-smi",
                "--query-gpu=utilization.gpu",
                "--format=csv,noheader,nounits",
                "-lms",
                "100",
            ]
            self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        return self

    def __exit__(self, *exc) -> None:
        self.mean = None
        if self.proc is not None:
            self.proc.terminate()
            out, _ = self.proc.communicate(timeout=5)
            vals = [float(x) for x in out.split() if x.strip().replace(".", "").isdigit()]
            self.mean = round(sum(vals) / len(vals), 1) if vals else None


def _random_obs(spec, n: int, seed: int = 0):
    import numpy as np

    from indgen_vla.interface import Observation

    h, w = spec.image_size or (128, 128)
    rng = np.random.default_rng(seed)
    return [Observation({c: rng.integers(0, 255, (h, w, 3), dtype=np.uint8) for c in spec.cameras},
                        rng.normal(size=8).astype(np.float32), "pick up the milk") for _ in range(n)]  # fmt: skip


def _policy_options(precision: str, compile_mode: str) -> dict:
    """Spec options at their non-default values (``EvalConfig.policy_options``)."""
    return {
        k: v for k, v, off in (("precision", precision, "fp32"), ("compile", compile_mode, "off")) if v != off
    }


def model_alone(spec_str: str, batches: list[int], device: str, precision: str, seconds: float,
                compile_mode: str = "off") -> dict:  # fmt: skip
    """The policy's own ``act`` (pre-processing, forward, post-processing) on random observations: obs/s by batch
    size, and the GPU's busy share while it runs; the ceiling an in-engine run is compared with. ``first_call_s``
    per batch size is the warm-up call: with ``--compile`` it holds the compile (a second process reads the
    inductor cache, ``policy_wrappers.compile.cache_dir``)."""
    from policy_wrappers.registry import load_policy

    t0 = time.perf_counter()
    policy = load_policy(spec_str, device=device, **_policy_options(precision, compile_mode))
    out: dict = {"model": spec_str, "device": device, "precision": precision, "compile": compile_mode,
                 "load_s": round(time.perf_counter() - t0, 1)}  # fmt: skip
    if compile_mode != "off":
        from policy_wrappers.compile import cache_dir

        out["inductor_cache"] = str(cache_dir())
        out["inductor_cache_was_empty"] = not any(cache_dir().glob("*"))
    for b in batches:
        obs = _random_obs(policy.spec, b, seed=b)
        policy.reset(obs[0].instruction, seed=0)
        t1 = time.perf_counter()
        policy.act(obs)  # warm-up (kernels, autotuning, allocator; the compile with --compile)
        first = time.perf_counter() - t1
        n, t0 = 0, time.perf_counter()
        with GpuBusy() as busy:
            while n < 3 or time.perf_counter() - t0 < seconds:
                policy.act(obs)
                n += 1
        dt = (time.perf_counter() - t0) / n
        out[f"b{b}"] = {"ms_per_act": round(1000 * dt, 1), "obs_per_s": round(b / dt, 1), "calls": n,
                        "first_call_s": round(first, 2), "gpu_busy_pct": busy.mean}  # fmt: skip
    try:
        import torch

        if torch.cuda.is_available():
            out["max_gpu_mem_gib"] = round(torch.cuda.max_memory_allocated() / 2**30, 2)
    except Exception:
        pass
    policy.close()
    return out


class Pinner:
    """Pins this process to core 0 and each worker process (the fork server's children, in start order) to one
    of the other cores, round-robin, while the block runs (``--pin``: does pinning beat the kernel's placement?)."""

    def __init__(self, enabled: bool, period_s: float = 0.02):
        import threading

        self.enabled, self._period, self._done = enabled, period_s, set()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)

    def _loop(self) -> None:
        import psutil

        me, cores = psutil.Process(), sorted(os.sched_getaffinity(0))
        rest = cores[1:] or cores
        while not self._stop.wait(self._period):
            for child in sorted(me.children(recursive=True), key=lambda c: c.pid):
                try:
                    if child.pid in self._done or child.ppid() == me.pid:  # the fork server itself
                        continue
                    child.cpu_affinity([rest[len(self._done) % len(rest)]])
                    self._done.add(child.pid)
                except Exception:  # exited between listing and pinning
                    pass

    def __enter__(self):
        if self.enabled:
            self._saved = os.sched_getaffinity(0)
            self._cores = sorted(self._saved)
            os.sched_setaffinity(0, {self._cores[0]})
            self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        if self.enabled:
            self._stop.set()
            self._thread.join()
            os.sched_setaffinity(0, self._saved)


def scaling(spec_str: str, scene: str, workers: list[int], episodes: int, max_steps: int, cameras, size: int,
            device: str, precision: str, pin: bool = False, compile_mode: str = "off") -> dict:  # fmt: skip
    """Engine steps/s at each worker count with cameras rendered, the policy in the main process on ``device``;
    CPU seconds of the main process (the coordinator) and the GPU's busy share per run.

    Each count also runs W one-step episodes (the start: W fresh workers, forked, scene built, reset, rendered),
    so ``steps_per_s_net_of_start`` and ``workers_cpu_ms_per_step_net_of_start`` leave out what a longer run
    amortises: a short run at 16 workers pays twice the starts of 8 for the same steps."""
    import scenes
    from indgen_vla.engine.config import EvalConfig, plan_episodes
    from indgen_vla.engine.local import run_local
    from indgen_vla.engine.rollout import RunMeta
    from policy_wrappers.registry import load_policy

    task = scenes.tasks(scene)[0]
    cfg = EvalConfig(policy=spec_str, scene=scene, axes=("pick_y",), out="-", episodes=episodes)
    jobs = plan_episodes(cfg, [task], {"pick_y": [0]}, {(task, "pick_y", 0): 0.0})
    policy = load_policy(spec_str, device=device, **_policy_options(precision, compile_mode))
    cams = tuple(policy.spec.cameras) or tuple(cameras)
    hw = tuple(policy.spec.image_size or (size, size))
    replan = policy.spec.replan_steps
    meta = RunMeta("bench", spec_str, "", scene)
    run_local(jobs[:2], runner_config(scene, cams, hw, 2), lambda: policy, meta, lambda r: None, workers=2,
              replan_steps=replan, close_policies=False)  # warm-up: fork server, kernels  # fmt: skip
    out: dict = {"scaling_policy": spec_str, "scaling_cameras": list(cams), "scaling_image": hw[0],
                 "scaling_episodes": len(jobs), "scaling_max_steps": max_steps, "replan": replan}  # fmt: skip
    if pin:
        out["pinned"] = "coordinator on core 0, workers round-robin on the others"
    for w in workers:
        t0 = time.perf_counter()
        with CpuMeter() as start_meter, Pinner(pin):
            run_local(jobs[:w], runner_config(scene, cams, hw, 1), lambda: policy, meta, lambda r: None,
                      workers=w, replan_steps=replan, close_policies=False)  # fmt: skip
        start_s = time.perf_counter() - t0
        records: list = []
        t0 = time.perf_counter()
        with CpuMeter() as meter, GpuBusy() as busy, Pinner(pin):
            run_local(jobs, runner_config(scene, cams, hw, max_steps), lambda: policy, meta, records.append,
                      workers=w, replan_steps=replan, close_policies=False)  # fmt: skip
        wall = time.perf_counter() - t0
        steps = sum(r.steps for r in records)
        assert all(r.status == "ok" for r in records), [r.error for r in records if r.status != "ok"][:1]
        out[f"w{w}"] = {"wall_s": round(wall, 2), "control_steps": steps, "steps_per_s": round(steps / wall, 1),
                        "main_cpu_s": round(meter.main_s, 2), "workers_cpu_s": round(meter.workers_s, 2),
                        "main_cpu_ms_per_step": round(1000 * meter.main_s / steps, 3),
                        "workers_cpu_ms_per_step": round(1000 * meter.workers_s / steps, 3),
                        "start_wall_s": round(start_s, 2), "start_workers_cpu_s": round(start_meter.workers_s, 2),
                        "steps_per_s_net_of_start": round(steps / max(1e-9, wall - start_s), 1),
                        "workers_cpu_ms_per_step_net_of_start":
                            round(1000 * (meter.workers_s - start_meter.workers_s) / steps, 3),
                        "gpu_busy_pct": busy.mean}  # fmt: skip
        print(json.dumps({f"w{w}": out[f"w{w}"]}), flush=True)
    policy.close()
    return out


PROFILE_PARTS = (  # (label, function name, file suffix): cumulative CPU inside these calls of the main process
    # (the profiler is off during the model's forward, ``predict_action_chunk``)
    ("pre-processing (to_batch: stack, device copy, resize)", "to_batch", "lerobot_policy.py"),
    ("lerobot processors (normalise, tokenise, unnormalise)", "__call__", "pipeline.py"),
    ("receive (read + unpickle observations)", "recv", "engine/local.py"),
    ("send (pickle + write requests)", "send", "engine/local.py"),
    ("records + Parquet", "append", "records.py"),
)


def profile_coordinator(spec_str: str | None, scene: str, workers: int, episodes: int, max_steps: int,
                        size: int, device: str, profile_out: str | None = None, top_n: int = 15) -> dict:  # fmt: skip
    """CPU of the main process per control step, the model's forward excluded: what bounds one coordinator
    (1000 / ms-per-step steps/s). A tiny LeRobot ACT with two ``size``-px cameras (or ``spec_str``), real records
    and Parquet (``RunDir``), ``workers`` worker processes; a cProfile (CPU clock) run splits the time."""
    import cProfile
    import pstats

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import scenes
    from indgen_vla.engine.config import EvalConfig, plan_episodes
    from indgen_vla.engine.local import run_local
    from indgen_vla.engine.rollout import RunMeta
    from indgen_vla.records import RunDir
    from policy_wrappers.registry import load_policy
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

    task = scenes.tasks(scene)[0]
    cfg = EvalConfig(policy="act", scene=scene, axes=("pick_y",), out="-", episodes=episodes)
    jobs = plan_episodes(cfg, [task], {"pick_y": [0]}, {(task, "pick_y", 0): 0.0})
    with tempfile.TemporaryDirectory() as d:
        spec_str = (
            spec_str
            or f"lerobot:{build_tiny_checkpoint('act', d, cameras=('agentview', 'wrist'), size=size)}"
        )
        policy = load_policy(spec_str, device=device)
        forward = {"s": 0.0, "calls": 0}
        inner = getattr(policy, "policy", None)
        if inner is not None and hasattr(inner, "predict_action_chunk"):
            real = inner.predict_action_chunk

            def timed(*a, **k):
                t0 = time.process_time()
                forward["calls"] += 1
                if forward.get("prof") is not None:  # the profile covers the coordinator, not the model
                    forward["prof"].disable()
                try:
                    return real(*a, **k)
                finally:
                    forward["s"] += time.process_time() - t0
                    if forward.get("prof") is not None:
                        forward["prof"].enable()

            inner.predict_action_chunk = timed
        cams, hw = policy.spec.cameras, tuple(policy.spec.image_size or (size, size))
        rc, meta = runner_config(scene, cams, hw, max_steps), RunMeta("bench", spec_str, "", scene)
        run_local(jobs[:workers], runner_config(scene, cams, hw, 1), lambda: policy, meta, lambda r: None,
                  workers=workers, replan_steps=policy.spec.replan_steps, close_policies=False)  # warm-up  # fmt: skip
        out: dict = {"profile_policy": spec_str if "tmp" not in spec_str else f"lerobot ACT (tiny), 2 cameras {hw[0]}px",
                     "profile_workers": workers, "profile_episodes": len(jobs), "profile_max_steps": max_steps,
                     "replan": policy.spec.replan_steps, "device": device}  # fmt: skip
        for label, prof in (("plain", None), ("cprofile", cProfile.Profile(time.process_time))):
            run = RunDir.create_or_resume(Path(d) / f"run_{label}", {"run_id": label, "plan": {}})
            records: list = []

            def on_record(r, run=run, records=records):
                run.append([r])
                records.append(r)

            forward["s"], forward["prof"], forward["calls"] = 0.0, prof, 0
            t0, c0 = time.perf_counter(), time.process_time()
            if prof is not None:
                prof.enable()
            run_local(jobs, rc, lambda: policy, meta, on_record, workers=workers,
                      replan_steps=policy.spec.replan_steps, close_policies=False)  # fmt: skip
            if prof is not None:
                prof.disable()
                forward["prof"] = None
            cpu, wall = time.process_time() - c0, time.perf_counter() - t0
            steps = sum(r.steps for r in records)
            acts = max(1, round(steps / policy.spec.replan_steps))
            if prof is None:
                out.update({"coordinator_cpu_s": round(cpu - forward["s"], 3), "forward_cpu_s": round(forward["s"], 3),
                            "control_steps": steps, "wall_s": round(wall, 2),
                            "coordinator_ms_per_step": round(1000 * (cpu - forward["s"]) / steps, 4),
                            "coordinator_ms_per_act": round(1000 * (cpu - forward["s"]) / acts, 3),
                            "forward_calls": forward["calls"],  # batched rounds that reached the model
                            "forward_ms_per_call": round(1000 * forward["s"] / max(1, forward["calls"]), 2)})  # fmt: skip
                continue
            stats = pstats.Stats(prof).stats  # (file, line, name) -> (cc, nc, tt, ct, callers)
            parts = {}
            for name, func, suffix in PROFILE_PARTS:
                parts[name] = round(1000 * sum(v[3] for k, v in stats.items()
                                               if k[2] == func and k[0].endswith(suffix)) / steps, 4)  # fmt: skip
            parts["total (profiled, forward not profiled)"] = round(
                1000 * sum(v[2] for v in stats.values()) / steps, 4
            )
            out["profile_ms_per_step"] = parts
            if profile_out:
                prof.dump_stats(profile_out)
            top = sorted(stats.items(), key=lambda kv: -kv[1][2])[:top_n]  # by own CPU (tottime)
            out["profile_top_own_ms_per_step"] = {
                f"{Path(k[0]).name}:{k[1]}({k[2]})": round(1000 * v[2] / steps, 4) for k, v in top
            }
        policy.close()
    return out


WORKER_PARTS = (  # (label, function name, file suffix): cumulative CPU inside the outermost such call of one worker
    ("physics (scenes/sim.py step: controller + mj_step)", "step", "scenes/sim.py"),
    ("render (camera update + render + read)", "_render", "env.py"),
    ("reply pickling (pipe send)", "_dumps", "local.py"),
)


def profile_worker(scene: str, episodes: int, max_steps: int, size: int, replan: int, cameras: tuple) -> dict:
    """CPU of one worker per control step, in this process: ``EnvRunner.execute`` of ``replan``-step slices of a
    fixed random chunk (physics, lazy renders of ``cameras`` at ``size`` px, observation assembly) plus the
    pickling of each reply as the pipe sends it; a cProfile (CPU clock) run splits it. What is left after physics
    and rendering is what a worker could still cut."""
    import cProfile
    import pstats

    import numpy as np

    import scenes
    from indgen_vla.engine.config import EvalConfig, plan_episodes
    from indgen_vla.engine.local import _dumps
    from indgen_vla.engine.rollout import EnvRunner, action_dim

    task = scenes.tasks(scene)[0]
    cfg = EvalConfig(policy="act", scene=scene, axes=("pick_y",), out="-", episodes=episodes)
    jobs = plan_episodes(cfg, [task], {"pick_y": [0]}, {(task, "pick_y", 0): 0.0})
    rc = runner_config(scene, cameras, (size, size), max_steps)
    runner = EnvRunner(rc)
    rng = np.random.default_rng(0)
    chunk = rng.uniform(-0.3, 0.3, (replan, action_dim(rc.levels))).astype(np.float32)
    _dumps(runner.reset(jobs[0]))  # warm-up: scene build, first render
    out: dict = {"worker_scene": scene, "worker_cameras": list(cameras), "worker_size": size, "replan": replan,
                 "worker_episodes": len(jobs), "worker_max_steps": max_steps}  # fmt: skip
    for prof in (None, cProfile.Profile(time.process_time)):  # plain, then profiled
        steps, c0 = 0, time.process_time()
        if prof is not None:
            prof.enable()
        for job in jobs:
            t = runner.reset(job)
            _dumps(t)
            while not t.done:
                t = runner.execute(chunk)
                _dumps(t)
            steps += t.steps
        if prof is not None:
            prof.disable()
        cpu = time.process_time() - c0
        if prof is None:
            out.update({"worker_cpu_s": round(cpu, 3), "control_steps": steps,
                        "worker_ms_per_step": round(1000 * cpu / steps, 3)})  # fmt: skip
            continue
        stats = pstats.Stats(prof).stats
        parts = {name: round(1000 * max([v[3] for k, v in stats.items() if k[2] == func and k[0].endswith(suffix)],
                                        default=0.0) / steps, 4) for name, func, suffix in WORKER_PARTS}  # fmt: skip
        parts["total (profiled)"] = round(1000 * sum(v[2] for v in stats.values()) / steps, 4)
        parts["rest (resets, observation assembly, bookkeeping)"] = round(
            parts["total (profiled)"] - sum(parts[name] for name, _, _ in WORKER_PARTS), 4
        )
        out["worker_profile_ms_per_step"] = parts
        top = sorted(stats.items(), key=lambda kv: -kv[1][2])[:15]
        out["worker_top_own_ms_per_step"] = {  # name: [ms per control step, calls per control step]
            f"{Path(k[0]).name}:{k[1]}({k[2]})": [round(1000 * v[2] / steps, 4), round(v[1] / steps, 2)]
            for k, v in top
        }
    runner.close()
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
    ap.add_argument("--pin", action="store_true",
                    help="scaling part: pin the coordinator to core 0 and each worker to one other core")  # fmt: skip
    ap.add_argument("--seconds", type=float, default=5.0, help="model part: timed seconds per batch size")
    ap.add_argument("--profile-coordinator", action="store_true",
                    help="main-process CPU per control step (forward excluded) with a cProfile split")  # fmt: skip
    ap.add_argument("--profile-workers", type=int, default=2, help="--profile-coordinator: worker processes")
    ap.add_argument("--profile-worker", action="store_true",
                    help="one worker's CPU per control step (physics, renders, observation, pickling), in process")  # fmt: skip
    ap.add_argument(
        "--profile-out", default=None, help="--profile-coordinator: write the cProfile stats here"
    )
    ap.add_argument("--pipeline-size", type=int, default=128, help="camera size of the pipelining ACT")
    ap.add_argument("--episodes", type=int, default=None, help="engine part: episodes (default 16; quick 4)")
    ap.add_argument(
        "--max-steps", type=int, default=None, help="engine part: steps each (default 200; quick 40)"
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
                      args.pipeline_size, args.device, args.precision, args.pin, args.compile)  # fmt: skip
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
        eps, steps = (2, 20) if args.quick else (4, 60)
        res = pipeline_bench(args.scene, args.pipeline_size, eps, steps, repeats, args.device)
        print(json.dumps({**head, **res, "load_avg_end": os.getloadavg()[0]}))
        return
    from indgen_vla.engine.config import EvalConfig, plan_episodes

    episodes, max_steps = (4, 40) if args.quick else (16, 200)
    episodes, max_steps = args.episodes or episodes, args.max_steps or max_steps
    cfg = EvalConfig(policy=args.policy, scene=args.scene, axes=("pick_y",), out="-", episodes=episodes)
    import scenes

    task = scenes.tasks(args.scene)[0]
    jobs = plan_episodes(cfg, [task], {"pick_y": [0]}, {(t, "pick_y", 0): 0.0 for t in [task]})
    from policy_wrappers.registry import load_policy

    policy = load_policy(args.policy)
    replan = policy.spec.replan_steps
    scenes.make_env(args.scene, task=task, cameras=()).close()  # warm-up: imports and first model build
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
