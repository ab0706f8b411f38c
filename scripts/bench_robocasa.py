"""RoboCasa365 speed (issue 25): build + reset, control steps/s without and with the three 256-px cameras, and the
worker pipe's overhead per step against a bare RoboCasa loop in the same venv (same backend, no pipe).

    INDGEN_ROBOCASA_ASSETS=DIR python scripts/bench_robocasa.py [--steps 200] [--task PickPlaceCounterToCabinet]
        [--split all]

Prints one markdown table for docs/results/benchmarks/robocasa.md. The bare loop runs ``scenes/robocasa/backend.py`` in the RoboCasa
venv's interpreter; the proxy loop drives the same backend through ``scenes.external`` (one worker); both build from
the same split (``--split``, default all: the kitchens every earlier figure was measured in). Besides wall-clock
steps/s the bare loop reports steps per CPU second of its process, and the load average is printed before and after:
on a shared machine wall-clock rates follow the load, so compare runs side by side, never across days.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import time
from pathlib import Path

import numpy as np

from scenes.family import get_scene

BARE = r"""
import json, sys, time
import numpy as np
sys.path.insert(0, sys.argv[1])
import backend as B
task, steps, cams = sys.argv[2], int(sys.argv[3]), [c for c in sys.argv[4].split(",") if c]
out = {}
cfg = {"task": task, "cameras": cams, "image_size": (256, 256), "edits": {}, "split": sys.argv[5]}
t = time.perf_counter(); lv = B.build(cfg)
lv.reset(3); out["first_reset_s"] = time.perf_counter() - t
t = time.perf_counter(); lv.reset(4); out["reset_s"] = time.perf_counter() - t
a = np.zeros(12); a[6] = -1.0; a[11] = -1.0
lv.step(a)
t, c = time.perf_counter(), time.process_time()
for _ in range(steps):
    lv.step(a)
out["step_s"], out["step_cpu_s"] = (time.perf_counter() - t) / steps, (time.process_time() - c) / steps
lv.close()
print(json.dumps(out))
"""


def bare(task: str, steps: int, cameras: tuple[str, ...], split: str) -> dict:
    from scenes.robocasa import _worker_env
    from scenes.robocasa.environment import find_python

    here = Path(__file__).resolve().parents[1] / "scenes" / "robocasa"
    env = {**os.environ, **_worker_env(), "PYTHONNOUSERSITE": "1"}
    env.pop("PYTHONPATH", None)
    r = subprocess.run([str(find_python()), "-c", BARE, str(here), task, str(steps), ",".join(cameras), split],
                       capture_output=True, text=True, env=env, check=True)  # fmt: skip
    return json.loads(r.stdout.strip().splitlines()[-1])


def proxy(task: str, steps: int, cameras: tuple[str, ...], split: str) -> dict:
    from scenes.external import close_idle_workers
    from scenes.planning import resolve_scene_plan
    from scenes.robocasa.splits import DEFAULT_REGISTRIES

    close_idle_workers()
    # the bare loop's kitchen arguments: the split, and the backend's default registries (none in its config)
    options = {"split": split, "obj_registries": ",".join(DEFAULT_REGISTRIES)}
    out = {}
    t = time.perf_counter()
    plan = resolve_scene_plan(get_scene("robocasa"), task, ("base_y",), [0], options=options)
    env = plan.builder.make_env(task, "base_y", 0, cameras=cameras, image_size=(256, 256), max_steps=None)
    try:
        env.reset(seed=3)
        out["first_reset_s"] = time.perf_counter() - t
        t = time.perf_counter()
        env.reset(seed=4)
        out["reset_s"] = time.perf_counter() - t
        a = np.zeros(12)
        a[6], a[11] = -1.0, -1.0
        env.step(a)
        t = time.perf_counter()
        for _ in range(steps):
            env.step(a)
        out["step_s"] = (time.perf_counter() - t) / steps
    finally:
        env.close()
        close_idle_workers()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--task", default="PickPlaceCounterToCabinet")
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--split", default="all", choices=("pretrain", "target", "all"),
                    help="RoboCasa365 split of both loops (default all)")  # fmt: skip
    args = ap.parse_args()
    from scenes.robocasa import PANDA_OMRON

    rows, load = [], os.getloadavg()[0]
    for cams in ((), PANDA_OMRON.cameras):
        b, p = bare(args.task, args.steps, cams, args.split), proxy(args.task, args.steps, cams, args.split)
        label = "no cameras" if not cams else f"{len(cams)} cameras 256 px"
        overhead = (p["step_s"] - b["step_s"]) / b["step_s"] * 100
        rows.append(
            f"| {label} | {b['first_reset_s']:.1f} / {p['first_reset_s']:.1f} | {b['reset_s']:.2f} / "
            f"{p['reset_s']:.2f} | {1 / b['step_s']:.1f} | {1 / b['step_cpu_s']:.1f} | {1 / p['step_s']:.1f} | "
            f"{overhead:+.1f} % |"
        )
    print(f"RoboCasa365 {args.task}, split {args.split}, {args.steps} steps, load {load:.2f} at start, "
          f"{os.getloadavg()[0]:.2f} at end")  # fmt: skip
    print("| cameras | first build+reset s (bare / proxy) | next reset s (bare / proxy) | steps/s bare | "
          "steps per CPU s bare | steps/s proxy | pipe overhead |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
