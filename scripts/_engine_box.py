"""The GPU-box parts of ``scripts/bench_engine.py`` (issue 28): the policy alone by batch size, engine steps/s by
worker count with cameras (pinned or not, pipelined or not) against that ceiling, and the meters they share.

Imported by ``bench_engine.py`` (run as a script, so this folder is on ``sys.path``); not an entry point."""

from __future__ import annotations

import json
import os
import time

from scenes.family import get_scene


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


def runner_config(scene: str, cameras, hw, max_steps: int, history_steps: int = 0):
    """The RunnerConfig of the GPU-era parts below (one place to adapt when RunnerConfig changes); a policy that
    reads earlier steps' frames (``PolicySpec.history_steps``) gets them rendered, as ``evaluate`` does."""
    from indgen_vla.app.engine.rollout import RunnerConfig
    from scenes.planning import scene_levels

    return RunnerConfig(levels=scene_levels(get_scene(scene), ["pick_y"]), cameras=tuple(cameras), image_size=tuple(hw),
                        max_steps=max_steps, privileged=False, history_steps=history_steps)  # fmt: skip


def level0_jobs(scene: str, episodes: int) -> tuple[str, list]:
    """(task, jobs): ``episodes`` planned episodes of the scene's first task at pick_y level 0, the cell every part
    of the benchmark runs (seeds as ``evaluate`` plans them)."""
    import scenes
    from indgen_vla.app.engine.config import EvalConfig, plan_episodes

    task = list(scenes.get_scene(scene).tasks)[0]
    cfg = EvalConfig.from_flat(policy="bench", scene=scene, axes=("pick_y",), out="-", episodes=episodes)
    return task, plan_episodes(cfg, [task], {"pick_y": [0]}, {(task, "pick_y", 0): 0.0})


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

    from indgen_vla.core.protocol.interface import Observation

    h, w = spec.image_size or (128, 128)
    rng = np.random.default_rng(seed)
    return [Observation({c: rng.integers(0, 255, (h, w, 3), dtype=np.uint8) for c in spec.cameras},
                        rng.normal(size=8).astype(np.float32), "pick up the milk") for _ in range(n)]  # fmt: skip


def _policy_options(precision: str, compile_mode: str) -> dict:
    """Spec options at their non-default values (``EvalConfig.policy_options``)."""
    return {
        k: v for k, v, off in (("precision", precision, "fp32"), ("compile", compile_mode, "off")) if v != off
    }


def time_act(policy, obs: list, seconds: float) -> dict:
    """One batched ``act`` on ``obs``, after a warm-up call (kernels, autotuning, allocator; the compile with
    ``--compile``): ms per call over at least 3 calls and ``seconds``, and the GPU's busy share meanwhile."""
    policy.reset(obs[0].instruction, seed=0)
    t1 = time.perf_counter()
    policy.act(obs)
    first = time.perf_counter() - t1
    n, t0 = 0, time.perf_counter()
    with GpuBusy() as busy:
        while n < 3 or time.perf_counter() - t0 < seconds:
            policy.act(obs)
            n += 1
    dt = (time.perf_counter() - t0) / n
    return {"ms_per_act": round(1000 * dt, 1), "obs_per_s": round(len(obs) / dt, 1), "calls": n,
            "first_call_s": round(first, 2), "gpu_busy_pct": busy.mean}  # fmt: skip


def model_alone(spec_str: str, batches: list[int], device: str, precision: str, seconds: float,
                compile_mode: str = "off") -> dict:  # fmt: skip
    """The policy's own ``act`` (pre-processing, forward, post-processing) on random observations: obs/s by batch
    size, and the GPU's busy share while it runs; the ceiling an in-engine run is compared with. ``first_call_s``
    per batch size is the warm-up call: with ``--compile`` it holds the compile (a second process reads the
    inductor cache, ``policy_wrappers.compile.cache_dir``)."""
    from policy_wrappers.specs import load_policy

    t0 = time.perf_counter()
    policy = load_policy(spec_str, device=device, **_policy_options(precision, compile_mode))
    out: dict = {"model": spec_str, "device": device, "precision": precision, "compile": compile_mode,
                 "load_s": round(time.perf_counter() - t0, 1)}  # fmt: skip
    if compile_mode != "off":
        from policy_wrappers.compile import cache_dir

        out["inductor_cache"] = str(cache_dir())
        out["inductor_cache_was_empty"] = not any(cache_dir().glob("*"))
    for b in batches:
        out[f"b{b}"] = time_act(policy, _random_obs(policy.spec, b, seed=b), seconds)
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

        # the cores saved before ``__enter__`` pinned this process: a thread started after that inherits core 0
        # alone, and computing them here put every worker on core 0 with the coordinator: the 5.4x "slowdown" of 11-26
        me, rest = psutil.Process(), self._cores[1:] or self._cores
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


def fork_server_cpu_s() -> float | None:
    """CPU seconds of the workers' fork server itself: its preload (imports, numba kernels, MuJoCo's asset cache
    warmed with the first task), paid once per process before the first worker forks; None when none runs."""
    import psutil

    for child in psutil.Process().children():
        try:
            if "forkserver" in " ".join(child.cmdline()):
                t = child.cpu_times()
                return round(t.user + t.system, 2)
        except psutil.Error:
            pass
    return None


def scaling(spec_str: str, scene: str, workers: list[int], episodes: int, max_steps: int, cameras, size: int,
            device: str, precision: str, pin: bool = False, compile_mode: str = "off", pipeline: bool = False,
            seconds: float = 2.0) -> dict:  # fmt: skip
    """Engine steps/s at each worker count with cameras rendered, the policy in the main process on ``device``;
    CPU seconds of the main process (the coordinator) and the GPU's busy share per run.

    Each count also runs its start alone (W fresh workers forked, scenes built, reset and rendered: one 1-step
    episode per environment, two per worker when ``pipeline``), so ``steps_per_s_net_of_start`` and
    ``workers_cpu_ms_per_step_net_of_start`` leave out what a longer run amortises: a short run at 16 workers pays
    twice the starts of 8 for the same steps (None when the start took over 90 % of the run: too short to tell).
    A batched policy is then timed alone at batch W (the engine pads
    every round to the worker count): ``ceiling_steps_per_s`` = W x replan / its ``act``, what the engine would
    reach if the model were all it waited for, and ``share_of_model_alone`` = the net rate over it (issue 28:
    >= 0.8 when the model is the bottleneck)."""
    from indgen_vla.app.engine.local import LANES, LocalOptions, run_local
    from indgen_vla.app.engine.rollout import RunMeta
    from policy_wrappers.specs import load_policy

    task, jobs = level0_jobs(scene, episodes)
    policy = load_policy(spec_str, device=device, **_policy_options(precision, compile_mode))
    cams = tuple(policy.spec.cameras) or tuple(cameras)
    hw = tuple(policy.spec.image_size or (size, size))
    replan, hist = policy.spec.replan_steps, policy.spec.history_steps
    meta = RunMeta("bench", spec_str, "", scene)
    run_local(
        jobs[:2],
        runner_config(scene, cams, hw, 2, hist),
        lambda: policy,
        meta,
        lambda r: None,
        LocalOptions(workers=2, replan_steps=replan, close_policies=False),
    )  # warm-up: fork server, kernels
    out: dict = {"scaling_policy": spec_str, "scaling_cameras": list(cams), "scaling_image": hw[0],
                 "scaling_episodes": len(jobs), "scaling_max_steps": max_steps, "replan": replan,
                 "pipeline": pipeline, "fork_server_cpu_s": fork_server_cpu_s()}  # fmt: skip
    if pin:
        out["pinned"] = "coordinator on core 0, workers round-robin on the others"
    for w in workers:
        envs = w * (LANES if pipeline else 1)
        t0 = time.perf_counter()
        with CpuMeter() as start_meter, Pinner(pin):
            run_local(
                jobs[:envs],
                runner_config(scene, cams, hw, 1, hist),
                lambda: policy,
                meta,
                lambda r: None,
                LocalOptions(workers=w, replan_steps=replan, close_policies=False, pipeline=pipeline),
            )
        start_s = time.perf_counter() - t0
        records: list = []
        t0 = time.perf_counter()
        with CpuMeter() as meter, GpuBusy() as busy, Pinner(pin):
            run_local(
                jobs,
                runner_config(scene, cams, hw, max_steps, hist),
                lambda: policy,
                meta,
                records.append,
                LocalOptions(workers=w, replan_steps=replan, close_policies=False, pipeline=pipeline),
            )
        wall = time.perf_counter() - t0
        steps = sum(r.steps for r in records)
        assert all(r.status == "ok" for r in records), [r.error for r in records if r.status != "ok"][:1]
        net = steps / (wall - start_s) if wall - start_s > 0.1 * wall else None  # else: too short a run
        row = {"wall_s": round(wall, 2), "control_steps": steps, "steps_per_s": round(steps / wall, 1),
               "main_cpu_s": round(meter.main_s, 2), "workers_cpu_s": round(meter.workers_s, 2),
               "main_cpu_ms_per_step": round(1000 * meter.main_s / steps, 3),
               "workers_cpu_ms_per_step": round(1000 * meter.workers_s / steps, 3),
               "start_wall_s": round(start_s, 2), "start_workers_cpu_s": round(start_meter.workers_s, 2),
               "steps_per_s_net_of_start": net and round(net, 1),
               "workers_cpu_ms_per_step_net_of_start":
                   round(1000 * (meter.workers_s - start_meter.workers_s) / steps, 3),
               "gpu_busy_pct": busy.mean}  # fmt: skip
        if policy.spec.batched:
            alone = time_act(policy, _random_obs(policy.spec, w, seed=w), seconds)
            ceiling = w * replan * 1000 / alone["ms_per_act"]
            row.update({"model_alone_ms_per_act": alone["ms_per_act"],
                        "model_alone_gpu_busy_pct": alone["gpu_busy_pct"],
                        "ceiling_steps_per_s": round(ceiling, 1),
                        "share_of_model_alone": net and round(net / ceiling, 3)})  # fmt: skip
        out[f"w{w}"] = row
        print(json.dumps({f"w{w}": row}), flush=True)
    policy.close()
    return out
