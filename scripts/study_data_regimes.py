"""The paper's data-regime experiment on a CPU, with a policy that sees the object (docs/results/data_regimes.md).

    .venv/bin/python scripts/study_data_regimes.py [--work runs/study_data_regimes] [--episodes 30] [--quick]

One set of 50 noisy-oracle T0 demos with object poses (``indgen demos --objects``) → 50 MimicGen episodes from
them → a low-dimensional ACT (state + object poses, ``indgen train --objects``) per regime (h-only, h+mg) and
training seed (0, 1, 2), same budget → ``indgen evaluate`` of every checkpoint on the same episodes along
``pick_y`` (then ``scale``) → ``indgen compare --a RUN... --b RUN...`` (paired, stratified by training seed) →
``docs/results/data_regimes.md`` with the wall time. Every stage resumes: re-run the same command after a stop.
``--quick`` is a smoke run of the same path that writes under ``--work`` only.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("HF_DATASETS_DISABLE_PROGRESS_BARS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
SCENE = "pick_place"
REGIMES = ("h-only", "h+mg")


def log(msg: str) -> None:
    print(f"[study {time.strftime('%H:%M:%S')}] {msg}", flush=True)


def _run(cmd: list[str]) -> None:
    log(" ".join(cmd))
    subprocess.run(cmd, check=True, cwd=ROOT)


class StudyClock:
    """The study's wall time summed over its invocations, saved every 30 s and at exit, so an invocation that is
    killed or stops early (``--stop-after``) still counts. ``study_wall.json``: {"invocations": [{"start", "s"}],
    "unrecorded": bool} (true when earlier invocations predate this accounting, so the total is a lower bound)."""

    def __init__(self, work: Path, every_s: float = 30.0):
        self.path, self.every_s, self.t0 = work / "study_wall.json", every_s, time.perf_counter()
        data = json.loads(self.path.read_text()) if self.path.is_file() else {"invocations": []}
        if isinstance(data, list):  # the old format kept only invocations that reached the document
            data = {"invocations": [{"start": None, "s": s} for s in data], "unrecorded": True}
        self.data = data
        self.data["invocations"].append({"start": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "s": 0.0})
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, daemon=True)
        self._thread.start()
        self.save()

    def save(self) -> None:
        from indgen_vla.core.runs.records import atomic_write_json

        self.data["invocations"][-1]["s"] = round(time.perf_counter() - self.t0, 1)
        atomic_write_json(self.path, self.data)

    def _beat(self) -> None:
        while not self._stop.wait(self.every_s):
            self.save()

    def close(self) -> None:
        self._stop.set()
        self.save()

    def total(self) -> tuple[float, int, bool]:
        """(seconds over every invocation, invocations, whether some earlier ones were not recorded)."""
        self.save()
        inv = self.data["invocations"]
        return sum(i["s"] for i in inv), len(inv), bool(self.data.get("unrecorded"))


def build_data(work: Path, n_demos: int, n_mg: int) -> dict[str, list[Path]]:
    """The human demos and the MimicGen episodes made from them, once for every checkpoint."""
    from indgen_vla.app import api
    from indgen_vla.app.regimes.demos import DemosConfig
    from indgen_vla.app.regimes.mimicgen import STATS_FILE, MimicGenConfig

    demos, mg = work / "data" / "human", work / "data" / "mimicgen"
    if not (demos / ".done").is_file():
        shutil.rmtree(demos, ignore_errors=True)
        log(f"recording {n_demos} T0 demos with object poses into {demos}")
        api.demos(DemosConfig(scene=SCENE, out=demos, n=n_demos, seed=0, cameras=(), objects=True, workers=1))
        (demos / ".done").touch()
    if not (mg / STATS_FILE).is_file():  # a generation killed half way resumes
        log(f"generating {n_mg} MimicGen T0 episodes from the demos into {mg}")
        api.mimicgen(MimicGenConfig(source=demos, out=mg, n=n_mg, seed=0, guarantee=True))
    return {"h-only": [demos], "h+mg": [demos, mg]}


def train(
    work: Path, data: dict[str, list[Path]], seeds: list[int], steps: int
) -> dict[tuple[str, int], Path]:
    """One object-observing ACT per (regime, training seed), same budget; finished ones are kept."""
    from indgen_vla.app.regimes.train import INFO_FILE, TrainConfig, TrainRecipe, train_policy

    ckpts = {}
    for regime in REGIMES:
        for seed in seeds:
            out = work / "ckpt" / f"{regime.replace('+', '_')}_s{seed}"
            if not (out / INFO_FILE).is_file():  # a training run killed half way resumes
                log(f"training {regime} seed {seed} ({steps} updates)")
                cfg = TrainRecipe(steps=steps, seed=seed, objects=True, log_every=max(steps // 5, 1))
                train_policy(TrainConfig(datasets=data[regime], out=out, recipe=cfg, data_regime=regime))
            ckpts[(regime, seed)] = out
    return ckpts


def evaluate(work: Path, ckpts: dict, axis: str, episodes: int, workers: int) -> dict[str, list[Path]]:
    """Every checkpoint on the same episodes (evaluation seed 0) along ``axis``; evaluate resumes itself."""
    indgen = str(Path(sys.executable).with_name("indgen"))
    runs: dict[str, list[Path]] = {r: [] for r in REGIMES}
    for (regime, seed), ckpt in ckpts.items():
        out = work / "runs" / axis / ckpt.name
        _run([indgen, "evaluate", "--policy", f"lerobot:{ckpt}", "--scene", SCENE, "--axis", axis,
              "--levels", "-3:3", "--episodes", str(episodes), "--seed", "0", "--workers", str(workers),
              "--data-regime", f"{regime} seed {seed}", "--out", str(out)])  # fmt: skip
        runs[regime].append(out)
    return runs


def compare(work: Path, axis: str, runs: dict[str, list[Path]]) -> tuple[dict, str]:
    """``indgen compare --a h-only runs --b h+mg runs``: paired within a seed, stratified across seeds."""
    indgen = str(Path(sys.executable).with_name("indgen"))
    out = work / f"compare_{axis}"
    _run([indgen, "compare", "--a", *map(str, runs["h-only"]), "--b", *map(str, runs["h+mg"]),
          "--label-a", "h-only", "--label-b", "h+mg", "--out", str(out)])  # fmt: skip
    return json.loads((out / "compare.json").read_text()), (out / "compare.md").read_text()


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", default="runs/study_data_regimes", help="data, checkpoints and runs go here")
    p.add_argument(
        "--episodes", type=int, default=30, help="episodes per level (same episodes for every checkpoint)"
    )
    p.add_argument("--seeds", type=int, default=3, help="training seeds per regime")
    p.add_argument("--steps", type=int, default=3000, help="training updates per checkpoint")
    p.add_argument("--axes", default="pick_y,scale", help="primary axis first; later ones are secondary")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--stop-after", choices=("data", "train", "evaluate"), default=None,
                   help="stop after this stage (re-run later to continue)")  # fmt: skip
    p.add_argument("--quick", action="store_true", help="tiny smoke run; results are not written to docs/")
    a = p.parse_args()
    if a.quick:
        a.episodes, a.seeds, a.steps = 1, 2, 20
    work = (ROOT / a.work).resolve()
    work.mkdir(parents=True, exist_ok=True)
    clock = StudyClock(work)
    try:
        return _stages(a, work, clock)
    finally:
        clock.close()


def _stages(a, work: Path, clock: StudyClock) -> int:
    data = build_data(work, 3 if a.quick else 50, 2 if a.quick else 50)
    if a.stop_after == "data":
        return 0
    ckpts = train(work, data, list(range(a.seeds)), a.steps)
    if a.stop_after == "train":
        return 0
    axes = [x for x in a.axes.split(",") if x]
    runs = {axis: evaluate(work, ckpts, axis, a.episodes, a.workers) for axis in axes}
    if a.stop_after == "evaluate":
        return 0
    results = {axis: compare(work, axis, r) for axis, r in runs.items()}
    wall, invocations, unrecorded = clock.total()
    from study_regimes_doc import render  # scripts/study_regimes_doc.py: the document from the comparisons

    text = render(results, axes, a, wall, invocations, unrecorded)
    dest = work / "data_regimes.md" if a.quick else ROOT / "docs" / "results" / "data_regimes.md"
    dest.write_text(text)
    log(f"wrote {dest} ({wall / 60:.1f} min)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
