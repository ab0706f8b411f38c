"""Where a CPU (EGL on Mesa llvmpipe) frame's time goes: frames/s per offscreen render option, each with its
pixel difference from the default render (the one ``SceneEnv`` makes; faithful = identical pixels).

Each option changes one thing of the default: the offscreen buffer size, multisampling, the shadow map, scene
flags, image size, one vs two cameras, llvmpipe threads (``LP_NUM_THREADS``, one child process per value).
Measures ``update_scene`` and ``render`` (draw + read pixels) separately. Prints a markdown table and, on its
last line, one JSON object. Changes nothing in the engine.

    MUJOCO_GL=egl .venv/bin/python scripts/bench_render.py [--scene pick_place] [--frames 30] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

# name -> (model.vis tweaks, scene flags switched off, image size, cameras); None means "as the default"
OPTIONS: dict[str, tuple[dict, tuple[str, ...], int | None, tuple[str, ...] | None]] = {
    "default (SceneEnv: offscreen buffer 640x480, 4x MSAA, shadow map 4096)": ({}, (), None, None),
    "offscreen buffer = image size": ({"buffer": "image"}, (), None, None),
    "no multisampling (offsamples 0)": ({"offsamples": 0}, (), None, None),
    "2x multisampling": ({"offsamples": 2}, (), None, None),
    "shadow map 1024": ({"shadowsize": 1024}, (), None, None),
    "shadows off (mjRND_SHADOW)": ({}, ("mjRND_SHADOW",), None, None),
    "reflections off (mjRND_REFLECTION)": ({}, ("mjRND_REFLECTION",), None, None),
    "skybox off (mjRND_SKYBOX)": ({}, ("mjRND_SKYBOX",), None, None),
    "buffer = image, no MSAA": ({"buffer": "image", "offsamples": 0}, (), None, None),
    "image 64x64": ({}, (), 64, None),
    "image 256x256": ({}, (), 256, None),
    "two cameras (agentview + wrist), per frame": ({}, (), None, ("agentview", "wrist")),
}
DEFAULT = next(iter(OPTIONS))


def _renderer(env, size: int, tweaks: dict):
    """A MuJoCo renderer on ``env``'s model with ``tweaks`` applied at context creation (then restored)."""
    import mujoco

    m = env._mj_model()
    q, g = m.vis.quality, m.vis.global_
    saved = (q.offsamples, q.shadowsize, g.offwidth, g.offheight)
    q.offsamples = tweaks.get("offsamples", q.offsamples)
    q.shadowsize = tweaks.get("shadowsize", q.shadowsize)
    if tweaks.get("buffer") == "image":
        g.offwidth, g.offheight = size, size
    else:  # what SceneEnv._render does
        g.offwidth, g.offheight = max(g.offwidth, size), max(g.offheight, size)
    try:
        return mujoco.Renderer(m, height=size, width=size)
    finally:
        q.offsamples, q.shadowsize, g.offwidth, g.offheight = saved


class _Option:
    """One render option's renderer, kept alive so that options can be timed interleaved."""

    def __init__(self, env, size, tweaks, flags_off, cams):
        import mujoco

        self.mujoco, self.flags_off, self.cams = mujoco, flags_off, cams
        self.r = _renderer(env, size, tweaks)
        self.opt = mujoco.MjvOption()
        self.opt.geomgroup[0] = 0  # like SceneEnv: visual meshes only
        self.data = env._mj_data()
        self.best_u = self.best_r = float("inf")
        self.images = self.frame()  # warm-up: a context's first render uploads textures and meshes

    def frame(self) -> list[np.ndarray]:
        from scenes.sim import CAMERA_NAMES

        out = []
        for cam in self.cams:
            self.r.update_scene(self.data, camera=CAMERA_NAMES[cam], scene_option=self.opt)
            for f in self.flags_off:
                self.r.scene.flags[getattr(self.mujoco.mjtRndFlag, f)] = 0
            out.append(self.r.render().copy())
        return out

    def time_block(self, frames: int) -> None:
        from scenes.sim import CAMERA_NAMES

        tu = tr = 0.0
        for _ in range(frames):
            for cam in self.cams:
                t0 = time.perf_counter()
                self.r.update_scene(self.data, camera=CAMERA_NAMES[cam], scene_option=self.opt)
                for f in self.flags_off:
                    self.r.scene.flags[getattr(self.mujoco.mjtRndFlag, f)] = 0
                t1 = time.perf_counter()
                self.r.render()
                tu, tr = tu + t1 - t0, tr + time.perf_counter() - t1
        self.best_u, self.best_r = min(self.best_u, tu / frames), min(self.best_r, tr / frames)

    def timing(self) -> dict:
        total = self.best_u + self.best_r
        return {
            "ms_update_scene": 1e3 * self.best_u,
            "ms_render": 1e3 * self.best_r,
            "frames_per_s": len(self.cams) / total,
        }


def _diff(a: list[np.ndarray], b: list[np.ndarray]) -> dict:
    if a[0].shape != b[0].shape:
        return {"pixels_differing_pct": None, "max_abs_diff": None, "mean_abs_diff": None}
    d = np.abs(a[0].astype(int) - b[0].astype(int))  # the agentview frame
    return {
        "pixels_differing_pct": 100 * float(np.any(d > 0, axis=-1).mean()),
        "max_abs_diff": int(d.max()),
        "mean_abs_diff": float(d.mean()),
    }


def child(scene: str, size: int, frames: int, repeats: int, only_default: bool) -> list[dict]:
    """All options (or only the default) in this process; rows with timings and pixel differences."""
    from scenes.family import get_scene
    from scenes.planning import resolve_scene_plan

    axis = get_scene(scene).default_axis  # level 0: T0 on every axis
    plan = resolve_scene_plan(get_scene(scene), None, (axis,), [0])
    env = plan.builder.make_env(plan.tasks[0], axis, 0, cameras=(), image_size=(128, 128), max_steps=10**6)
    try:
        env.reset(seed=0)
        rng = np.random.default_rng(0)
        for a in rng.uniform(-0.5, 0.5, size=(10, 7)):  # an arm away from home: a generic frame
            env.step(a)
        opts = {}
        for name, (tweaks, flags_off, osize, cams) in OPTIONS.items():
            if not only_default or name == DEFAULT:
                opts[name] = _Option(env, osize or size, tweaks, flags_off, cams or ("agentview",))
        for _ in range(repeats):  # interleaved blocks: background load hits every option alike
            for o in opts.values():
                o.time_block(frames)
        ref = opts[DEFAULT].images
        rows = [
            {"option": k, "size": o.r.height, "cameras": len(o.cams), **o.timing(), **_diff(o.images, ref)}
            for k, o in opts.items()
        ]
        for o in opts.values():
            o.r.close()
        return rows
    finally:
        env.close()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="pick_place")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--lp-threads", default="1,2", help="LP_NUM_THREADS values for the default render")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.frames < 1 or args.repeats < 1 or not 8 <= args.size <= 2048:
        print("bench_render: --frames and --repeats must be >= 1 and --size in 8..2048", file=sys.stderr)
        return 2
    if args.child:
        print(json.dumps(child(args.scene, args.size, args.frames, args.repeats, only_default=True)))
        return 0
    rows = child(args.scene, args.size, args.frames, args.repeats, only_default=False)
    base = ["--scene", args.scene, "--size", str(args.size), "--frames", str(args.frames)]
    base += ["--repeats", str(args.repeats)]
    for n in [v for v in args.lp_threads.split(",") if v]:
        env = {**os.environ, "LP_NUM_THREADS": n}
        out = subprocess.run(
            [sys.executable, __file__, *base, "--child"], env=env, capture_output=True, text=True, check=True
        )
        (row,) = json.loads(out.stdout.strip().splitlines()[-1])
        row["option"] = f"LP_NUM_THREADS={n} (default render)"
        rows.append(row)
    print(
        "| option | size | ms update_scene | ms render+read | frames/s | pixels differing | max / mean abs diff |"
    )
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        same = (
            "n/a (other size)" if r["pixels_differing_pct"] is None else f"{r['pixels_differing_pct']:.2f} %"
        )
        md = "—" if r["max_abs_diff"] is None else f"{r['max_abs_diff']} / {r['mean_abs_diff']:.3f}"
        print(
            f"| {r['option']} | {r['size']}² ×{r['cameras']} | {r['ms_update_scene']:.2f} | {r['ms_render']:.2f} | "
            f"{r['frames_per_s']:.1f} | {same} | {md} |"
        )
    print(json.dumps({"bench": "render", "scene": args.scene, "frames": args.frames, "rows": rows}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
