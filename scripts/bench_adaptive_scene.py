"""Adaptive vs fixed evaluation on a real scene (docs/adaptive.md, benchmark part b).

    .venv/bin/python scripts/bench_adaptive_scene.py [--work runs/bench_adaptive_scene] [--workers 2]

The shipped stand-in (``checkpoints/act_pick_place_human``) on ``pick_place`` / ``pick_y`` −3..3 with the same
seeds: a fixed run of ``--episodes`` per level, then ``--adaptive kstar`` and ``--adaptive curve`` capped at the
same number. Prints each design's k* per direction, episodes used and the saving; every run resumes.
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
os.environ.setdefault("HF_HUB_OFFLINE", "1")
ROOT = Path(__file__).resolve().parents[1]


def run(out: Path, episodes: int, workers: int, adaptive: str | None) -> tuple[dict, int, float]:
    """Evaluate (or resume) one design; return its pick_y summary, the episodes it ran and its wall time."""
    indgen = str(Path(sys.executable).with_name("indgen"))
    cmd = [indgen, "evaluate", "--policy", f"lerobot:{ROOT / 'checkpoints' / 'act_pick_place_human'}",
           "--scene", "pick_place", "--axis", "pick_y", "--levels=-3:3", "--episodes", str(episodes),
           "--workers", str(workers), "--seed", "0", "--out", str(out)]  # fmt: skip
    if adaptive:
        cmd += ["--adaptive", adaptive]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    summary = json.loads((out / "summary.json").read_text())["axes"]["pick_y"]
    return summary, sum(r["n"] + r["errors"] for r in summary["levels"]), time.perf_counter() - t0


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", default="runs/bench_adaptive_scene", help="run directories go here")
    p.add_argument("--episodes", type=int, default=50, help="episodes per level (the adaptive cap)")
    p.add_argument("--workers", type=int, default=2)
    a = p.parse_args()
    work = (ROOT / a.work).resolve()
    rows = {}
    for name, adaptive in (("fixed", None), ("adaptive kstar", "kstar"), ("adaptive curve", "curve")):
        rows[name] = run(work / name.replace(" ", "_"), a.episodes, a.workers, adaptive)
    fixed_n = rows["fixed"][1]
    print(f"pick_place / pick_y -3..3, shipped stand-in, cap {a.episodes} per level, {a.workers} workers")
    for name, (s, n, wall) in rows.items():
        brk = s["break_level"]
        print(f"{name:15s} k* +{brk.get('pos')} / {brk.get('neg')}  episodes {n:4d} "
              f"({100 * (1 - n / fixed_n):.0f}% fewer than fixed)  wall {wall / 60:.1f} min")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
