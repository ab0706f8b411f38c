"""Benchmark the physics step and the scenes wrapper against bare robosuite loops on the same scene.

For each scene, per 20 Hz control step (25 MuJoCo steps), no cameras, the same seeded actions: stock robosuite
1.4 (``env.step`` with ``fast_physics=False``), the bit-identical fast path (``scenes.sim.FastControl``, the
default), raw ``mj_step`` replaying the fast path's recorded controls (MuJoCo alone: the floor), and
``SceneEnv.step`` (the wrapper on the fast path); wall and CPU ms, best of the interleaved repeats. Then
rendered frames/s with both cameras at 128x128 (``SceneEnv.step`` with cameras vs robosuite ``step`` + the
same two MuJoCo renders). Prints a markdown table and, on its last line, one JSON object.

    .venv/bin/python scripts/bench_scenes.py [--steps 200] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from scenes.family import get_scene  # noqa: E402
from scenes.listing import builtin_scenes  # noqa: E402  (the bare-robosuite baseline needs a built-in scene)
from scenes.planning import scene_levels  # noqa: E402
from scenes.sim import CAMERA_NAMES  # noqa: E402

CAMS = ("agentview", "wrist")
SIZE = (128, 128)


def _actions(n: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    a = rng.uniform(-0.3, 0.3, size=(n, 7))
    a[:, 6] = np.sign(a[:, 6])
    return a


class _Clock:
    """Wall and CPU seconds of one block."""

    def __enter__(self):
        self.wall, self.cpu = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc):
        self.wall, self.cpu = time.perf_counter() - self.wall, time.process_time() - self.cpu


def _wrapper(env, actions) -> tuple[float, float]:
    env._rs.fast_physics = True
    env.reset(seed=0)
    with _Clock() as c:
        for a in actions:
            env.step(a)
    return c.wall, c.cpu


class _Recorder:
    """Stands in for the ``mujoco`` module inside ``FastControl``: records ``ctrl`` at every ``mj_step``."""

    def __init__(self):
        import mujoco

        self.mujoco, self.ctrls = mujoco, []

    def __getattr__(self, name):
        return getattr(self.mujoco, name)

    def mj_step(self, m, d):
        self.ctrls.append(d.ctrl.copy())
        self.mujoco.mj_step(m, d)


def _record_controls(env, actions) -> tuple[list[np.ndarray], np.ndarray]:
    """The fast path's per-substep controls for ``actions`` and its final qpos."""
    from scenes.sim import FastControl

    env.reset(seed=0)
    rs = env._rs
    rs.fast_physics, rs._indgen_fast = True, FastControl(rs)
    rec = rs._indgen_fast.mujoco = _Recorder()
    for a in actions:
        rs.step(a)
    qpos = rs.sim.data.qpos.copy()
    env.reset(seed=0)  # drops the recording FastControl
    return rec.ctrls, qpos


def _raw(env, ctrls, qpos_end) -> tuple[float, float]:
    """MuJoCo alone: ``mj_step`` with the recorded controls (the same trajectory, checked bit for bit)."""
    import mujoco

    env.reset(seed=0)
    m, d = env._rs.sim.model._model, env._rs.sim.data._data
    with _Clock() as c:
        for u in ctrls:
            d.ctrl[:] = u
            mujoco.mj_step(m, d)
    if not np.array_equal(d.qpos, qpos_end):
        raise RuntimeError("replaying the recorded controls did not reproduce the fast path's trajectory")
    return c.wall, c.cpu


def _bare(env, actions, render: bool, fast: bool = True) -> tuple[float, float]:
    """The same robosuite env stepped directly; optionally the same two renders, nothing else."""
    import mujoco

    env.reset(seed=0)
    rs = env._rs
    rs.fast_physics = fast
    renderer = mujoco.Renderer(rs.sim.model._model, height=SIZE[0], width=SIZE[1]) if render else None
    opt = mujoco.MjvOption()
    opt.geomgroup[0] = 0
    with _Clock() as c:
        for a in actions:
            rs.step(a)
            if renderer is not None:
                for cam in CAMS:
                    renderer.update_scene(rs.sim.data._data, camera=CAMERA_NAMES[cam], scene_option=opt)
                    renderer.render()
    rs.fast_physics = True
    if renderer is not None:
        renderer.close()
    return c.wall, c.cpu


def t0_env(scene: str, cameras: tuple[str, ...], image_size: tuple[int, int]):
    """``scene``'s T0 (level 0 of its first axis, its first task), built as a run builds it, without a step limit."""
    sc = get_scene(scene)
    return scene_levels(get_scene(scene), [sc.default_axis]).make_env(
        sc.resolve_task(None), sc.default_axis, 0, cameras=cameras, image_size=image_size, max_steps=10**6
    )


def bench_scene(scene: str, steps: int, repeats: int, render: bool = True) -> dict:
    actions = _actions(steps)
    out: dict = {"scene": scene}
    env = t0_env(scene, cameras=(), image_size=SIZE)
    try:
        ctrls, qpos_end = _record_controls(env, actions)
        runs: dict[str, list[tuple[float, float]]] = {k: [] for k in ("stock", "fast", "raw", "wrapper")}
        for _ in range(repeats):
            runs["stock"].append(_bare(env, actions, render=False, fast=False))
            runs["fast"].append(_bare(env, actions, render=False, fast=True))
            runs["raw"].append(_raw(env, ctrls, qpos_end))
            runs["wrapper"].append(_wrapper(env, actions))
        for k, v in runs.items():
            out[f"ms_per_step_{k}"] = 1e3 * min(w for w, _ in v) / steps
            out[f"cpu_ms_per_step_{k}"] = 1e3 * min(c for _, c in v) / steps
        out["physics_steps_per_s_wrapper"] = 1e3 / out["ms_per_step_wrapper"]
        out["physics_steps_per_s_bare"] = 1e3 / out["ms_per_step_fast"]
        out["speedup_fast_vs_stock"] = out["ms_per_step_stock"] / out["ms_per_step_fast"]
        out["cpu_speedup_fast_vs_stock"] = out["cpu_ms_per_step_stock"] / out["cpu_ms_per_step_fast"]
        out["fast_vs_raw"] = out["ms_per_step_fast"] / out["ms_per_step_raw"]
    finally:
        env.close()
    out["physics_overhead_pct"] = 100 * (
        out["physics_steps_per_s_bare"] / out["physics_steps_per_s_wrapper"] - 1
    )
    if not render:
        return out
    env = t0_env(scene, cameras=CAMS, image_size=SIZE)
    try:
        rsteps = max(steps // 4, 10)
        w, b = [], []
        for _ in range(repeats):
            w.append(_wrapper(env, actions[:rsteps])[0])
            b.append(_bare(env, actions[:rsteps], render=True)[0])
        out["frames_per_s_wrapper"] = rsteps * len(CAMS) / min(w)
        out["frames_per_s_bare"] = rsteps * len(CAMS) / min(b)
    finally:
        env.close()
    out["render_overhead_pct"] = 100 * (out["frames_per_s_bare"] / out["frames_per_s_wrapper"] - 1)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--scenes", default=",".join(s.name for s in builtin_scenes()))
    ap.add_argument(
        "--no-render", action="store_true", help="physics columns only (skip the 2-camera frames)"
    )
    args = ap.parse_args()
    if args.steps < 1 or args.repeats < 1:
        print("bench_scenes: --steps and --repeats must be >= 1", file=sys.stderr)
        return 2
    rows = [bench_scene(s, args.steps, args.repeats, not args.no_render) for s in args.scenes.split(",")]
    print(
        "| scene | ms/control step: stock robosuite | fast path | raw mj_step | speed-up (CPU) | fast / raw "
        "| SceneEnv (fast) | wrapper overhead | frames/s 2x128² (wrapper / bare) | overhead |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['scene']} | {r['ms_per_step_stock']:.2f} | {r['ms_per_step_fast']:.2f} | "
            f"{r['ms_per_step_raw']:.2f} | {r['speedup_fast_vs_stock']:.2f}× ({r['cpu_speedup_fast_vs_stock']:.2f}×) | "
            f"{r['fast_vs_raw']:.2f}× | {r['ms_per_step_wrapper']:.2f} | {r['physics_overhead_pct']:+.1f} % | "
            + (
                f"{r['frames_per_s_wrapper']:.1f} / {r['frames_per_s_bare']:.1f} | {r['render_overhead_pct']:+.1f} % |"
                if "frames_per_s_wrapper" in r
                else "— | — |"
            )
        )
    print(json.dumps({"bench": "scenes", "steps": args.steps, "repeats": args.repeats, "rows": rows}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
