"""The paper's data-regime experiment on a CPU: does MimicGen T0 data improve inductive generalization?

    .venv/bin/python scripts/study_data_regimes.py [--work runs/study] [--episodes 10] [--quick]

demos → mimicgen → train a state-only ACT on human-only and on human+MimicGen data (``build_standin.py``, which
also records the demos and generates the MimicGen episodes) → ``indgen evaluate`` both along ``pick_y`` and
``scale`` (k = −3..3) → ``indgen compare`` per axis → ``docs/results/data_regimes.md`` with the wall time.
Slow (tens of minutes on 2 cores); ``--quick`` is a smoke run of the same path that writes under ``--work`` only.
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
AXES = ("pick_y", "scale")


def _run(cmd: list[str]) -> None:
    print(f"[study {time.strftime('%H:%M:%S')}] {' '.join(cmd)}", flush=True)
    subprocess.run(cmd, check=True, cwd=ROOT)


def _build(ckpt: Path, args: list[str]) -> None:
    """Build a stand-in unless an earlier (interrupted) invocation already finished it: re-running resumes."""
    if (ckpt / "train_info.json").is_file():
        print(f"[study] {ckpt} exists (train_info.json); skipping its build", flush=True)
        return
    _run(args)


def _wall(work: Path, seconds: float) -> tuple[float, int]:
    """Add this invocation's seconds to the study's running total; return (total seconds, invocations)."""
    path = work / "study_wall.json"
    runs = json.loads(path.read_text()) if path.is_file() else []
    runs.append(round(seconds, 1))
    path.write_text(json.dumps(runs))
    return sum(runs), len(runs)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", default="runs/study_data_regimes", help="demos, checkpoints and runs go here")
    p.add_argument("--mimicgen", type=int, default=50, help="MimicGen episodes added for the h+mg regime")
    p.add_argument("--episodes", type=int, default=10, help="episodes per level in the axis sweeps")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--quick", action="store_true", help="tiny smoke run; results are not written to docs/")
    a = p.parse_args()
    work = (ROOT / a.work).resolve()
    py, indgen = sys.executable, str(Path(sys.executable).with_name("indgen"))
    start = time.perf_counter()
    quick = ["--quick"] if a.quick else []
    n_mg = 2 if a.quick else a.mimicgen
    ckpts = {"h-only": work / "ckpt_h_only", "h+mg": work / "ckpt_h_mg"}
    _build(ckpts["h-only"], [py, "scripts/build_standin.py", "--out", str(ckpts["h-only"]),
                             "--work", str(work / "h_only"), *quick])  # fmt: skip
    _build(ckpts["h+mg"], [py, "scripts/build_standin.py", "--mimicgen", str(n_mg), "--out", str(ckpts["h+mg"]),
                           "--work", str(work / "h_mg"), *quick])  # fmt: skip
    episodes = 1 if a.quick else a.episodes
    sections, verdicts = [], []
    for axis in AXES:
        runs = {}
        for regime, ckpt in ckpts.items():
            runs[regime] = work / f"eval_{axis}_{regime.replace('+', '_')}"
            _run([indgen, "evaluate", "--policy", f"lerobot:{ckpt}", "--scene", "pick_place", "--axis", axis,
                  "--levels", "-3:3", "--episodes", str(episodes), "--workers", str(a.workers),
                  "--data-regime", regime, "--out", str(runs[regime])])  # fmt: skip
        out = work / f"compare_{axis}"
        _run([indgen, "compare", str(runs["h-only"]), str(runs["h+mg"]), "--out", str(out)])
        verdicts.append(json.loads((out / "compare.json").read_text())["verdict"])
        # one document: each comparison's headings go one level down
        sections.append(
            "\n".join(
                "#" + ln if ln.startswith("#") else ln for ln in (out / "compare.md").read_text().splitlines()
            )
        )
    wall, invocations = _wall(work, time.perf_counter() - start)
    cards = {r: json.loads((c / "train_info.json").read_text()) for r, c in ckpts.items()}
    text = "\n".join([
        "# Data regimes: human-only vs human+MimicGen (pick_place, state-only ACT)", "",
        f"`scripts/study_data_regimes.py`, {time.strftime('%Y-%m-%d')}, wall time {wall / 60:.1f} min"
        + (f" over {invocations} invocations (resumed)" if invocations > 1 else "") + ", "
        f"{episodes} episodes per level, MimicGen episodes added: {n_mg}. Training set sizes: "
        + ", ".join(f"{r}: {c.get('episodes')} episodes" for r, c in cards.items()) + ".", "",
        "**Result.** " + " ".join(verdicts), "",
        *sections,
    ])  # fmt: skip
    dest = work / "data_regimes.md" if a.quick else ROOT / "docs" / "results" / "data_regimes.md"
    dest.parent.mkdir(parents=True, exist_ok=True)
    dest.write_text(text + "\n")
    print(f"wrote {dest} ({wall / 60:.1f} min)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
