"""The profiling parts of ``scripts/bench_engine.py`` (issue 28 item 1): the coordinator's CPU per control step
(the model's forward excluded) and one worker's, each with a cProfile split.

Imported by ``bench_engine.py`` (run as a script, so this folder is on ``sys.path``); not an entry point."""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from _engine_box import level0_jobs, runner_config

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
    from indgen_vla.app.engine.local import LocalOptions, run_local
    from indgen_vla.app.engine.rollout import RunMeta
    from indgen_vla.core.runs.records import RunDir
    from policy_wrappers.specs import load_policy
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

    task, jobs = level0_jobs(scene, episodes)
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
        hist = policy.spec.history_steps
        rc, meta = runner_config(scene, cams, hw, max_steps, hist), RunMeta("bench", spec_str, "", scene)
        run_local(
            jobs[:workers],
            runner_config(scene, cams, hw, 1, hist),
            lambda: policy,
            meta,
            lambda r: None,
            LocalOptions(workers=workers, replan_steps=policy.spec.replan_steps, close_policies=False),
        )  # warm-up
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
            run_local(
                jobs,
                rc,
                lambda: policy,
                meta,
                on_record,
                LocalOptions(workers=workers, replan_steps=policy.spec.replan_steps, close_policies=False),
            )
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

    from indgen_vla.app.engine.local import _dumps
    from indgen_vla.app.engine.rollout import EnvRunner, action_dim

    task, jobs = level0_jobs(scene, episodes)
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
