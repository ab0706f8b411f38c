"""A small run's report (issue 56): ``write_run_report`` as a run's end calls it (summary, report.md, report.html and
the SVG success curve) against the same with the PNG set (``plots=True``: what every run's end drew before, and what
``indgen report`` draws), in fresh interpreters taking turns (A B A B ...), so both see the same load.

Two real run directories are made first by ``indgen evaluate --policy standin:random --scene pick_place --axis pick_y
--max-steps 1``: 6 episodes at level 0 (the shape of the end-to-end benchmark, ``bench_startup.py``) and 6 episodes at
each of levels -2..2. Each child imports the reporting module (not timed: the evaluate process has it), then times
one call ("cold": its lazy imports included, as at the end of ``indgen evaluate``) and a second call ("warm": as in a
test process that has reported before). Prints one JSON object on its last line (docs/results/benchmarks/speed.md).

    .venv/bin/python scripts/bench_report.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CHILD = r"""
import json, sys, time
from indgen_vla.core.reporting.report import write_run_report
from indgen_vla.core.runs.records import RunDir
run, plots = RunDir.open(sys.argv[1]), sys.argv[2] == "png"
t = time.perf_counter(); write_run_report(run, plots=plots); cold = time.perf_counter() - t
t = time.perf_counter(); write_run_report(run, plots=plots); warm = time.perf_counter() - t
print(json.dumps({"cold": cold, "warm": warm}))
"""
SHAPES = {"1 level x 6": "0", "5 levels x 6": "-2:2"}
VARIANTS = ("svg", "png")  # the run's own report now; with the PNG set (before, and indgen report)


def env() -> dict:
    return {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), "HF_HUB_OFFLINE": "1",
            "OMP_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)}  # fmt: skip


def make_run(out: Path, levels: str) -> Path:
    """A real run directory of ``standin:random`` (1 step an episode, 2 workers)."""
    cmd = [sys.executable, "-m", "indgen_vla.app.cli", "evaluate", "--policy", "standin:random", "--scene",
           "pick_place", "--axis", "pick_y", "--levels", levels, "--episodes", "6", "--max-steps", "1",
           "--workers", "2", "--out", str(out)]  # fmt: skip
    subprocess.run(cmd, env=env(), cwd=ROOT, check=True, capture_output=True)
    return out


def one(run: Path, variant: str) -> dict:
    proc = subprocess.run([sys.executable, "-c", CHILD, str(run), variant], env=env(), cwd=ROOT, check=True,
                          capture_output=True, text=True)  # fmt: skip
    return json.loads(proc.stdout.strip().splitlines()[-1])


def stats(xs: list[float]) -> dict:
    return {"median": round(statistics.median(xs), 4), "min": round(min(xs), 4), "max": round(max(xs), 4)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    load = [os.getloadavg()[0]]
    out: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        for shape, levels in SHAPES.items():
            run = make_run(Path(tmp) / shape.replace(" ", "_"), levels)
            for variant in VARIANTS:  # caches, .pyc, page cache
                one(run, variant)
            rows: dict[str, list[dict]] = {v: [] for v in VARIANTS}
            for _ in range(a.repeats):
                for variant in VARIANTS:
                    rows[variant].append(one(run, variant))
                    load.append(os.getloadavg()[0])
            out[shape] = {
                **{f"{v}_{k}_s": stats([r[k] for r in rows[v]]) for v in VARIANTS for k in ("cold", "warm")},
                "png_over_svg_cold": stats(
                    [p["cold"] / s["cold"] for s, p in zip(rows["svg"], rows["png"], strict=True)]
                ),
            }
    print(json.dumps({"bench": "report", "machine": f"{platform.node()} {platform.machine()} {os.cpu_count()} cores",
                      "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "repeats": a.repeats,
                      "load_avg": [round(x, 2) for x in load], **out}))  # fmt: skip


if __name__ == "__main__":
    main()
