"""Benchmark the scenes wrapper against a bare robosuite loop on the same scene.

For each scene: physics control steps/s with no cameras (``SceneEnv.step`` vs the underlying robosuite
env's ``step``), and rendered frames/s with both cameras at 128x128 (``SceneEnv.step`` with cameras vs
robosuite ``step`` + the same two MuJoCo renders). Blocks are interleaved so background load hits both
sides alike. Prints a markdown table and, on its last line, one JSON object.

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

import scenes  # noqa: E402
from scenes.catalog import SCENES  # noqa: E402  (built-in scenes: the bare-robosuite baseline needs them)
from scenes.sim import CAMERA_NAMES  # noqa: E402

CAMS = ("agentview", "wrist")
SIZE = (128, 128)


def _actions(n: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    a = rng.uniform(-0.3, 0.3, size=(n, 7))
    a[:, 6] = np.sign(a[:, 6])
    return a


def _wrapper(env, actions) -> float:
    env.reset(seed=0)
    t = time.perf_counter()
    for a in actions:
        env.step(a)
    return time.perf_counter() - t


def _bare(env, actions, render: bool) -> float:
    """The same robosuite env stepped directly; optionally the same two renders, nothing else."""
    import mujoco

    env.reset(seed=0)
    rs = env._rs
    renderer = mujoco.Renderer(rs.sim.model._model, height=SIZE[0], width=SIZE[1]) if render else None
    opt = mujoco.MjvOption()
    opt.geomgroup[0] = 0
    t = time.perf_counter()
    for a in actions:
        rs.step(a)
        if renderer is not None:
            for cam in CAMS:
                renderer.update_scene(rs.sim.data._data, camera=CAMERA_NAMES[cam], scene_option=opt)
                renderer.render()
    dt = time.perf_counter() - t
    if renderer is not None:
        renderer.close()
    return dt


def bench_scene(scene: str, steps: int, repeats: int) -> dict:
    actions = _actions(steps)
    out = {"scene": scene}
    env = scenes.make_env(scene, cameras=(), max_steps=10**6)
    try:
        w, b = [], []
        for _ in range(repeats):
            w.append(_wrapper(env, actions))
            b.append(_bare(env, actions, render=False))
        out["physics_steps_per_s_wrapper"] = steps / min(w)
        out["physics_steps_per_s_bare"] = steps / min(b)
    finally:
        env.close()
    env = scenes.make_env(scene, cameras=CAMS, image_size=SIZE, max_steps=10**6)
    try:
        rsteps = max(steps // 4, 10)
        w, b = [], []
        for _ in range(repeats):
            w.append(_wrapper(env, actions[:rsteps]))
            b.append(_bare(env, actions[:rsteps], render=True))
        out["frames_per_s_wrapper"] = rsteps * len(CAMS) / min(w)
        out["frames_per_s_bare"] = rsteps * len(CAMS) / min(b)
    finally:
        env.close()
    out["physics_overhead_pct"] = 100 * (
        out["physics_steps_per_s_bare"] / out["physics_steps_per_s_wrapper"] - 1
    )
    out["render_overhead_pct"] = 100 * (out["frames_per_s_bare"] / out["frames_per_s_wrapper"] - 1)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--scenes", default=",".join(SCENES))
    args = ap.parse_args()
    rows = [bench_scene(s, args.steps, args.repeats) for s in args.scenes.split(",")]
    print(
        "| scene | physics steps/s (wrapper / bare) | overhead | frames/s 2x128² (wrapper / bare) | overhead |"
    )
    print("|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['scene']} | {r['physics_steps_per_s_wrapper']:.0f} / {r['physics_steps_per_s_bare']:.0f} | "
            f"{r['physics_overhead_pct']:+.1f} % | {r['frames_per_s_wrapper']:.1f} / {r['frames_per_s_bare']:.1f} | "
            f"{r['render_overhead_pct']:+.1f} % |"
        )
    print(json.dumps({"bench": "scenes", "steps": args.steps, "repeats": args.repeats, "rows": rows}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
