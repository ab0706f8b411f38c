"""A level ladder from LeRobot's side against indgen evaluate on the same work: the shipped ACT along pick_y.

LeRobot's side is the loop docs/lerobot.md gives: one ``lerobot-eval --env.type=indgen --env.level=k`` per level
(the same episodes and seeds as indgen's), then ``indgen import lerobot-eval`` of every output into one run
directory with k*. indgen's side is one ``indgen evaluate --levels`` (at --workers 1 and 2). Per run: wall time
from process start to exit; for lerobot-eval also its own rollout seconds (eval_info.json ``overall.eval_s``), so
start-up = wall - rollout. Checks that the imported episodes equal indgen's, episode by episode.

lerobot-eval renders a video of its first 10 episodes unless --eval.recording=true (then it records a dataset
instead, and only one batch works: its recorder re-creates the dataset per batch). The ladder runs with
--eval.recording=true --eval.batch_size=EPISODES (no video); --video-level K adds one default run (videos on) at K.

    .venv/bin/python scripts/bench_lerobot_ladder.py --levels -3:3 --episodes 5 --video-level 0
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CHECKPOINT = ROOT / "checkpoints" / "act_pick_place_human"


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    env.update(HF_HUB_OFFLINE="1", MUJOCO_GL=env.get("MUJOCO_GL", "egl"), OMP_NUM_THREADS="1")
    return env


def _run(cmd: list[str]) -> float:
    t = time.perf_counter()
    proc = subprocess.run(cmd, env=_env(), cwd=ROOT, capture_output=True, text=True)
    if proc.returncode not in (0, 5):
        sys.exit(f"failed ({proc.returncode}): {' '.join(cmd)}\n{proc.stderr[-2000:]}")
    return time.perf_counter() - t


def lerobot_eval(out: Path, level: int, episodes: int, video: bool) -> dict:
    cmd = [sys.executable, "-m", "lerobot.scripts.lerobot_eval", f"--policy.path={CHECKPOINT}", "--policy.device=cpu",
           "--env.type=indgen", "--env.scene=pick_place", "--env.axis=pick_y", f"--env.level={level}",
           f"--eval.n_episodes={episodes}", f"--output_dir={out}"]  # fmt: skip
    cmd += (
        []
        if video
        else [f"--eval.batch_size={episodes}", "--eval.use_async_envs=false", "--eval.recording=true"]
    )
    wall = _run(cmd)
    rollout = json.loads((out / "eval_info.json").read_text())["overall"]["eval_s"]
    return {"level": level, "video": video, "wall_s": wall, "rollout_s": rollout, "startup_s": wall - rollout}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", default="-3:3")
    ap.add_argument("--episodes", type=int, default=5)
    ap.add_argument("--video-level", type=int, default=None)
    ap.add_argument("--out", default="/tmp/bench_lerobot_ladder")
    a = ap.parse_args()
    lo, hi = (int(x) for x in a.levels.split(":"))
    out = Path(a.out)
    shutil.rmtree(out, ignore_errors=True)
    cli = [sys.executable, "-m", "indgen_vla.app.cli"]
    res: dict = {"machine": f"{platform.node()} {os.cpu_count()} cores", "load_1m": os.getloadavg()[0],
                 "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "levels": a.levels,
                 "episodes": a.episodes}  # fmt: skip
    for w in (1, 2):
        res[f"indgen_evaluate_workers{w}_s"] = _run([*cli, "evaluate", "--policy", f"lerobot:{CHECKPOINT}", "--scene",
                                                    "pick_place", "--axis", "pick_y", "--levels", a.levels,
                                                    "--episodes", str(a.episodes), "--workers", str(w),
                                                    "--out", str(out / f"indgen_w{w}")])  # fmt: skip
    runs = [lerobot_eval(out / f"le_L{k}", k, a.episodes, False) for k in range(lo, hi + 1)]
    res["lerobot_eval"] = runs
    res["lerobot_eval_total_s"] = sum(r["wall_s"] for r in runs)
    res["import_s"] = _run([*cli, "import", "lerobot-eval", *(str(out / f"le_L{k}") for k in range(lo, hi + 1)),
                            "--out", str(out / "imported"), "--policy", "act"])  # fmt: skip
    if a.video_level is not None:
        res["lerobot_eval_video"] = lerobot_eval(out / "le_video", a.video_level, a.episodes, True)
    import pandas as pd

    cols = ["level", "episode", "seed", "success"]
    ours = pd.read_parquet(out / "indgen_w1" / "episodes.parquet")[cols].sort_values(["level", "episode"])
    theirs = pd.read_parquet(out / "imported" / "episodes.parquet")[cols].sort_values(["level", "episode"])
    res["episodes_equal"] = int((ours.to_numpy() == theirs.to_numpy()).all(axis=1).sum())
    res["episodes_total"] = len(ours)
    summary = json.loads((out / "imported" / "summary.json").read_text())["axes"]["pick_y"]
    res["imported_kstar"] = summary.get("kstar") or summary.get("break_level")
    print(json.dumps(res, indent=2, default=str))


if __name__ == "__main__":
    main()
