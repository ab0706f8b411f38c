"""Start-up of ``indgen evaluate``: one 1-step episode of the shipped tiny ACT, split into its parts.

Each repeat runs ``indgen evaluate --policy lerobot:checkpoints/act_pick_place_human --scene pick_place --axis
pick_y --levels 0 --episodes 1 --max-steps 1`` in a fresh process whose functions are wrapped by timers (exclusive
seconds: a part nested in another counts only in the inner one), plus the interpreter start and the process exit as
the parent sees them. A scene built by a worker process (started while the policy loads, when its files say which
cameras it reads: ``local.EarlyWorkers``) is not timed here; the wait for it is ``early_wait`` plus the first
reset's reply (in ``rollout_other``). The machine is shared, so it reports the min and the median over ``--repeats`` runs and the
1-minute load average at each run's start. Prints one JSON object on its last line (docs/results/benchmarks/startup.md).

    .venv/bin/python scripts/bench_startup.py [--repeats 5] [--policy SPEC] [--workers N]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def shipped(root: Path) -> str:
    """The shipped tiny ACT of checkout ``root``."""
    return f"lerobot:{root / 'checkpoints' / 'act_pick_place_human'}"


# (part, module, attribute): attribute is "func" or "Class.method"; wrapped in the child before the CLI runs
PARTS = (
    ("plan", "indgen_vla.app.engine.run", "build_plan"),
    ("policy_load", "policy_wrappers.specs", "load_policy"),
    ("manifest", "indgen_vla.app.engine.run", "build_manifest"),
    ("run_dir_create", "indgen_vla.core.runs.records", "RunDir.create_or_resume"),
    ("fingerprint", "indgen_vla.app.engine.run", "_fingerprint"),
    ("forkserver", "indgen_vla.app.engine.local", "_context"),
    # in this process only (1 worker and no preview); a worker's build is not timed
    ("scene_build", "indgen_vla.app.engine.rollout", "EnvRunner._env_for"),
    # waiting for the workers started during the policy load
    ("early_wait", "indgen_vla.app.engine.local", "EarlyWorkers.take"),
    ("scene_reset", "indgen_vla.app.engine.rollout", "EnvRunner.reset"),
    ("steps", "indgen_vla.app.engine.rollout", "EnvRunner.execute"),
    ("act", "indgen_vla.app.engine.scheduler", "act"),  # the coordinator's call (batching.act, bound there)
    (
        "act",
        "indgen_vla.app.engine.local",
        "_act",
    ),  # the same before the scheduler split (--compare with older checkouts)
    ("records", "indgen_vla.core.runs.records", "RunDir.append"),
    ("rollout_other", "indgen_vla.app.engine.local", "run_local"),
    ("report", "indgen_vla.core.reporting.report", "write_run_report"),
    ("report", "indgen_vla.report", "write_run_report"),  # before the two-layer layout (--compare 944c1c4)
    ("tables", "indgen_vla.core.reporting.report", "print_tables"),
)

CHILD = r"""
import importlib, json, os, sys, time
T0 = time.time()
parts, stack = {}, []

cpu = {}

def wrap(name, fn):
    def timed(*a, **k):
        t, c = time.perf_counter(), time.process_time()
        stack.append([0.0, 0.0])
        try:
            return fn(*a, **k)
        finally:
            inner = stack.pop()
            dt, dc = time.perf_counter() - t, time.process_time() - c
            parts[name] = parts.get(name, 0.0) + dt - inner[0]
            cpu[name] = cpu.get(name, 0.0) + dc - inner[1]
            if stack:
                stack[-1][0] += dt
                stack[-1][1] += dc
    return timed

t = time.perf_counter()
def here(module):  # in this checkout (the venv's editable install would find another's modules this one lacks)
    base = os.path.join(os.getcwd(), *module.split("."))
    return os.path.isfile(base + ".py") or os.path.isfile(os.path.join(base, "__init__.py"))

if here("indgen_vla.app.cli"):
    import indgen_vla.app.cli as cli
    import indgen_vla.app.engine  # what cli._resolve imports first
    import indgen_vla.app.cli.evaluate
else:  # a checkout from before the two-layer layout (--compare 944c1c4)
    import indgen_vla.cli as cli
parts["cli_import"] = time.perf_counter() - t
for name, module, attr in json.loads(os.environ["BENCH_PARTS"]):
    if not here(module):  # e.g. a module an older checkout lacks (--compare)
        continue
    mod = importlib.import_module(module)
    owner, _, leaf = attr.rpartition(".")
    obj = getattr(mod, owner, None) if owner else mod
    if obj is None:  # a class an older checkout lacks (--compare)
        continue
    raw = vars(obj).get(leaf)
    if isinstance(raw, (classmethod, staticmethod)):
        setattr(obj, leaf, type(raw)(wrap(name, raw.__func__)))
    elif raw is not None:
        setattr(obj, leaf, wrap(name, raw))
parts["bench_wrap"] = time.perf_counter() - t - parts["cli_import"]
t = time.perf_counter()
sys.argv = ["indgen", *sys.argv[1:]]
rc = cli.main()  # as the console script calls it
parts["main_total"] = time.perf_counter() - t
with open(os.environ["BENCH_OUT"], "w") as f:
    json.dump({"parts": parts, "cpu": cpu, "cpu_main_process": time.process_time(), "t_start": T0,
               "t_main_end": time.time(), "rc": rc}, f)
sys.stdout.flush()
"""


def one_run(root: Path, policy: str, workers: int, episodes: int, out_dir: Path, max_steps: int = 1) -> dict:
    """One evaluate of checkout ``root`` in a fresh interpreter: {part: seconds} with interpreter start, exit
    and total, and CPU seconds (``cpu_*``)."""
    out_dir.mkdir(parents=True)
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), "HF_HUB_OFFLINE": "1",
           "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep),
           "BENCH_PARTS": json.dumps(PARTS), "BENCH_OUT": str(out_dir / "parts.json")}  # fmt: skip
    cmd = [sys.executable, "-c", CHILD, "evaluate", "--policy", policy, "--scene", "pick_place", "--axis", "pick_y",
           "--levels", "0", "--episodes", str(episodes), "--workers", str(workers), "--out", str(out_dir / "run"),
           *(["--max-steps", str(max_steps)] if max_steps else [])]  # fmt: skip
    load = os.getloadavg()[0]
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_before = usage.ru_utime + usage.ru_stime
    t0 = time.time()
    proc = subprocess.run(cmd, env=env, cwd=root, capture_output=True, text=True)
    t_end = time.time()
    if proc.returncode != 0:
        sys.exit(f"bench run failed (exit {proc.returncode}):\n{proc.stderr[-3000:]}")
    child = json.loads((out_dir / "parts.json").read_text())
    parts = dict(child["parts"])
    parts["interpreter_start"] = child["t_start"] - t0
    parts["exit"] = t_end - child["t_main_end"]
    parts["main_other"] = parts.pop("main_total") - sum(
        v for k, v in child["parts"].items() if k not in ("main_total", "cli_import", "bench_wrap")
    )
    parts["total"] = t_end - t0
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    parts["cpu_reaped_children"] = usage.ru_utime + usage.ru_stime - cpu_before
    parts["cpu_main_process"] = child["cpu_main_process"]
    parts.update({f"cpu_{k}": v for k, v in child["cpu"].items()})
    return {"load_avg": load, **{k: round(v, 3) for k, v in parts.items()}}


def summarize(runs: list[dict]) -> dict:
    """Min and median of every part over the repeats (parts ordered by their median, largest first)."""
    keys = [k for k in runs[0] if k != "load_avg"]
    order = sorted(keys, key=lambda k: -statistics.median(r.get(k, 0.0) for r in runs))
    return {
        "total_min_s": min(r["total"] for r in runs),
        "total_median_s": round(statistics.median(r["total"] for r in runs), 3),
        "load_avg": [round(r["load_avg"], 2) for r in runs],
        "parts_min_s": {k: min(r.get(k, 0.0) for r in runs) for k in order},
        "parts_median_s": {k: round(statistics.median(r.get(k, 0.0) for r in runs), 3) for k in order},
    }


def paired(this: list[dict], other: list[dict]) -> dict:
    """This ÷ other per pair of runs made in turn (same load): median and [min, max] of the wall and CPU ratios."""
    out = {"n_pairs": len(this)}
    for key, name in (("total", "wall"), ("cpu_reaped_children", "cpu")):
        r = sorted(a[key] / b[key] for a, b in zip(this, other, strict=True))
        out[name] = {"median": round(statistics.median(r), 3), "min": round(r[0], 3), "max": round(r[-1], 3)}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--policy", default=None, help="policy spec (default: the checkout's shipped tiny ACT)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--episodes", type=int, default=1)
    ap.add_argument(
        "--max-steps",
        type=int,
        default=1,
        help="steps per episode (0: the scene's own limit, whole "
        "episodes: the end-to-end run of issue 56 is --episodes 6 --workers 2 --max-steps 0)",
    )
    ap.add_argument("--compare", metavar="CHECKOUT", default=None,
                    help="another checkout (e.g. a worktree of the previous commit): runs alternate between the "
                    "two, so both see the same load")  # fmt: skip
    a = ap.parse_args()
    roots = {"this": ROOT, **({"other": Path(a.compare).resolve()} if a.compare else {})}
    runs: dict[str, list[dict]] = {name: [] for name in roots}
    with tempfile.TemporaryDirectory() as tmp:

        def run_in(root: Path, out: str) -> dict:
            return one_run(
                root, a.policy or shipped(root), a.workers, a.episodes, Path(tmp) / out, a.max_steps
            )

        for name, root in roots.items():  # caches, .pyc, page cache
            run_in(root, f"warmup-{name}")
        for i in range(a.repeats):
            for name, root in roots.items():
                row = run_in(root, f"{name}{i}")
                runs[name].append(row)
                print(json.dumps({"checkout": name, **row}), flush=True)
    out = {
        "bench": "startup", "machine": f"{platform.node()} {platform.machine()} {os.cpu_count()} cores",
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "policy": a.policy or "shipped tiny ACT",
        "workers": a.workers, "episodes": a.episodes, "max_steps": a.max_steps, "repeats": a.repeats,
        **summarize(runs["this"]),
        **({"other": {"checkout": str(roots["other"]), **summarize(runs["other"])}} if a.compare else {}),
        **({"paired": paired(runs["this"], runs["other"])} if a.compare else {}),
    }  # fmt: skip
    print(json.dumps(out))


if __name__ == "__main__":
    main()
