"""``indgen budget``'s projection against reality: run a smoke, budget a larger protocol from it, run that protocol
at each worker count, and time each whole command as a user does (a fresh interpreter, start-up and exit included).
Prints one JSON line per worker count (projected low/expected/high, measured, the relative error) and the load
average at each run's start (docs/results/benchmarks/budget.md).

    .venv/bin/python scripts/bench_budget.py [--policy standin:oracle] [--workers 1,2] [--levels 0:2] [--episodes 6]
        [--max-steps 80] [--smoke-episodes 2] [--smoke-steps 30]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _indgen(*argv: str) -> tuple[float, subprocess.CompletedProcess]:
    env = {**os.environ, "HF_HUB_OFFLINE": "1", "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    t = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-m", "indgen_vla.app.cli", *argv], capture_output=True, text=True, env=env
    )
    if done.returncode != 0:
        raise SystemExit(f"indgen {' '.join(argv)} failed:\n{done.stderr[-3000:]}")
    return time.monotonic() - t, done


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--policy", default="standin:oracle")
    ap.add_argument("--scene", default="pick_place")
    ap.add_argument("--axis", default="pick_y")
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--levels", default="0:2")
    ap.add_argument("--episodes", default="6")
    ap.add_argument("--max-steps", default="80")
    ap.add_argument("--smoke-episodes", default="2")
    ap.add_argument("--smoke-steps", default="30")
    a = ap.parse_args()
    base = ["--policy", a.policy, "--scene", a.scene, "--axis", a.axis]
    target = [*base, "--levels", a.levels, "--episodes", a.episodes, "--max-steps", a.max_steps]
    with tempfile.TemporaryDirectory() as tmp:
        smoke = Path(tmp) / "smoke"
        load = os.getloadavg()[0]
        smoke_s, _ = _indgen("evaluate", *base, "--levels", "0", "--episodes", a.smoke_episodes, "--max-steps",
                             a.smoke_steps, "--workers", "1", "--out", str(smoke))  # fmt: skip
        print(json.dumps({"smoke_wall_s": round(smoke_s, 2), "load_1m": load}), flush=True)
        budget_s, done = _indgen("budget", *target, "--timing", str(smoke), "--workers", a.workers, "--json")
        projected = json.loads(done.stdout)["workers"]
        for w in a.workers.split(","):
            load = os.getloadavg()[0]
            measured, _ = _indgen("evaluate", *target, "--workers", w, "--out", str(Path(tmp) / f"w{w}"))
            timing = json.loads((Path(tmp) / f"w{w}" / "manifest.json").read_text())["timing"]
            p = projected[w]
            print(json.dumps({"workers": int(w), "projected_s": p["wall_s"], "bound": p["bound"],
                              "measured_s": round(measured, 2), "error": round(measured / p["wall_s"]["expected"] - 1, 3),
                              "inside": p["wall_s"]["low"] <= measured <= p["wall_s"]["high"], "load_1m": load,
                              "budget_s": round(budget_s, 2), "run_timing": timing}), flush=True)  # fmt: skip
        print(
            json.dumps({"smoke_timing": json.loads((smoke / "manifest.json").read_text())["timing"]}),
            flush=True,
        )


if __name__ == "__main__":
    main()
