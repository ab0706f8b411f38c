"""indgen evaluate vs lerobot-eval side by side: the same tiny LeRobot ACT checkpoint (random init, LIBERO's
feature names, built offline), the same LIBERO-Object task, episodes, episode length, cameras and image size, at
equal core counts, interleaved repeats in one run. Per tool: episodes/min, env steps/s, peak memory of the process
tree, MuJoCo steps and renders counted in every process (identical work), and with --profile where the time goes.

    .venv/bin/python scripts/bench_vs_lerobot.py --sizes 128,256 --episodes 2 --repeats 2 --fill-missing

lerobot-eval finds LIBERO's assets through hf-libero's ``get_assets_path()`` (``~/.cache/libero/assets``; the
``assets`` key of LIBERO's config.yaml is not read), so its runs get a temporary HOME holding that link and a
LIBERO_CONFIG_PATH with a written config.yaml; indgen gets INDGEN_LIBERO_ASSETS. lerobot-eval always writes
videos of the first 10 episodes (only --eval.recording=true drops them, recording a dataset instead): the ``lerobot-eval-novideo`` rows run its own ``main()``
with ``eval_policy_all(max_episodes_rendered=0)``, nothing else changed.

Per run: episodes/min and env steps/s end to end (start to exit), the rollout window (first to last ``mj_step``:
its env steps/s, and startup = wall - rollout), a 280-step projection for shorter --max-steps, and per control
step the wall ms inside MuJoCo's render and physics calls. Paired ratios (indgen / lerobot) come with a 95 %
t-interval over the repeats. Results in docs/results/benchmarks/vs_lerobot.md.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
SUBSTEPS = 25  # MuJoCo steps per 20 Hz control step (LIBERO: timestep 0.002 s)
SETTLE = 10  # no-op settling steps after each reset, in both tools
FULL_STEPS = 280  # LIBERO-Object's episode length (lerobot's LiberoEnv), for the projection of shorter runs
TOOLS = ("indgen", "lerobot-eval", "lerobot-eval-novideo")

# Counts MuJoCo physics steps and renders in every Python process of a run (PYTHONPATH puts it first).
COUNTER_SITE = """
import os
if os.environ.get("BENCH_COUNT_DIR"):
    os.environ.setdefault("MUJOCO_GL", "egl")  # without it, importing mujoco here can hang
    import atexit, json, multiprocessing.util as _mu
    import mujoco as _mj
    from time import perf_counter as _pc, time as _now
    _c = {"mj_step": 0, "mjr_render": 0, "render_s": 0.0, "physics_s": 0.0, "first": None, "last": None}
    _GROUP = {"mj_step": "physics_s", "mj_forward": "physics_s", "mjr_render": "render_s",
              "mjr_readPixels": "render_s", "mjv_updateScene": "render_s"}
    def _reset(*_):
        _c.update(mj_step=0, mjr_render=0, render_s=0.0, physics_s=0.0, first=None, last=None)
    def _dump():
        if _c["mj_step"] or _c["mjr_render"]:
            p = os.path.join(os.environ["BENCH_COUNT_DIR"], f"{os.getpid()}.json")
            with open(p + ".tmp", "w") as f:
                json.dump(_c, f)
            os.replace(p + ".tmp", p)
    def _wrap(name, group):
        fn = getattr(_mj, name)
        def timed(*a, **k):
            t0 = _pc()
            try:
                return fn(*a, **k)
            finally:
                _c[group] += _pc() - t0
                if name in ("mj_step", "mjr_render"):
                    _c[name] += 1
                    if name == "mj_step":
                        _c["last"] = _now()
                        _c["first"] = _c["first"] or _c["last"]
                    if _c[name] % (50 if name == "mjr_render" else 2500) == 0:
                        _dump()
        setattr(_mj, name, timed)
    for _n, _g in _GROUP.items():
        _wrap(_n, _g)
    class _Key:
        pass
    _key = _Key()
    def _child(_):  # multiprocessing children clear the finalizers and skip atexit: register again
        _reset()
        _mu.Finalize(None, _dump, exitpriority=100)
    os.register_at_fork(after_in_child=_reset)
    _mu.register_after_fork(_key, _child)
    atexit.register(_dump)
"""

# lerobot-eval exactly, minus its videos: eval_main() passes max_episodes_rendered=10 with no flag to change it.
NOVIDEO_DRIVER = """
import os
import sys
import lerobot.scripts.lerobot_eval as le
_orig = le.eval_policy_all
def _no_video(*a, **k):
    k["max_episodes_rendered"], k["videos_dir"] = 0, None
    return _orig(*a, **k)
le.eval_policy_all = _no_video
for _arg in sys.argv[1:]:  # lerobot-eval's output dir is created by its video writer; without videos, here
    if _arg.startswith("--output_dir="):
        os.makedirs(_arg.split("=", 1)[1], exist_ok=True)
sys.argv = ["lerobot-eval", *sys.argv[1:]]
sys.exit(le.main())
"""

# Profile categories: the first rule (in this order) with a key ("|"-separated) in any frame of a stack names it.
PROFILE_RULES = (
    ("video (lerobot's extra frames + mp4)", "render (lerobot/envs/libero.py|write_video|render_frame ("),
    ("startup (imports)", "_find_and_load"),
    (
        "env build / hard reset",
        "_load_model|_destroy_sim|from_xml_string|_initialize_sim|_reset_internal|hard_reset|_build (",
    ),
    (
        "policy (pre/post-processing + forward)",
        "select_action|predict_action_chunk|torch/|processor|policy_wrappers/",
    ),
    ("render", "mjr_|read_pixels|render (robosuite|MjRenderContext|_render (|egl"),
    (
        "physics (OSC control + mj_step)",
        "mj_step|mj_forward|run_controller|fast_step|_pre_action|step (robosuite",
    ),
    (
        "transport (pickle, pipes, shared memory)",
        "pickle|_send|_recv|send (|recv (|dumps|loads|shared_memory",
    ),
)


def parse_sizes(text: str) -> list[int]:
    """'128,256' -> [128, 256]; one clear line when a size is not a positive integer."""
    try:
        sizes = [int(s) for s in text.split(",") if s.strip()]
    except ValueError:
        sys.exit(f"--sizes must be a comma list of integers like 128,256, got {text!r}")
    if not sizes or min(sizes) <= 0:
        sys.exit(f"--sizes must list positive pixel sizes like 128,256, got {text!r}")
    return sizes


def lerobot_libero_env(work: Path, assets: Path) -> dict:
    """HOME and LIBERO_CONFIG_PATH under which hf-libero (as lerobot-eval imports it) uses ``assets``."""
    import yaml

    from scenes.libero.assets import libero_root

    home, cfg_dir = work / "lerobot_home", work / "lerobot_libero_config"
    link = home / ".cache" / "libero" / "assets"
    link.parent.mkdir(parents=True, exist_ok=True)
    if link.is_symlink():
        link.unlink()
    link.symlink_to(assets.resolve())
    cfg_dir.mkdir(parents=True, exist_ok=True)
    root = libero_root()
    cfg = {"benchmark_root": str(root), "bddl_files": str(root / "bddl_files"),
           "init_states": str(root / "init_files"), "datasets": str(root.parent / "datasets"),
           "assets": str(assets.resolve())}  # fmt: skip
    (cfg_dir / "config.yaml").write_text(yaml.safe_dump(cfg))
    return {"HOME": str(home), "LIBERO_CONFIG_PATH": str(cfg_dir)}


def tool_command(tool: str, a, ckpt: Path, size: int, task_id: int, out: Path) -> list[str]:
    """The command line one tool runs for one size (the same episodes, steps, cameras, image size, cores)."""
    py = str(ROOT / ".venv" / "bin" / "python") if (ROOT / ".venv").is_dir() else sys.executable
    if tool == "indgen":
        return [str(Path(py).parent / "indgen"), "evaluate", "--policy", f"lerobot:{ckpt}", "--scene", "libero_object",
                "--task", a.task, "--axis", "pick_y", "--levels", "0", "--episodes", str(a.episodes),
                "--workers", str(a.cores), "--max-steps", str(a.max_steps), "--image-size", str(size),
                "--seed", "0", "--device", a.device, "--out", str(out),
                *(["--smoke"] if a.miniature else [])]  # boxes: a timing, not a measurement  # fmt: skip
    args = [f"--policy.path={ckpt}", f"--policy.device={a.device}", "--env.type=libero", "--env.task=libero_object",
            f"--env.task_ids=[{task_id}]", f"--env.observation_height={size}", f"--env.observation_width={size}",
            f"--env.episode_length={a.max_steps}", f"--eval.n_episodes={a.episodes}",
            f"--eval.batch_size={a.lerobot_batch or min(a.cores, a.episodes)}", "--eval.use_async_envs=true",
            "--seed=0", f"--output_dir={out}"]  # fmt: skip
    if tool == "lerobot-eval":
        return [str(Path(py).parent / "lerobot-eval"), *args]
    return [py, "-c", NOVIDEO_DRIVER, *args]


class TreeMemory(threading.Thread):
    """Samples the summed RSS of a process and all its descendants every ``period`` s; keeps the peak."""

    def __init__(self, pid: int, period: float = 0.5):
        super().__init__(daemon=True)
        self.pid, self.period, self.peak, self.stop = pid, period, 0, threading.Event()

    def run(self) -> None:
        import psutil

        def rss(p) -> int:
            try:
                return p.memory_info().rss
            except psutil.Error:
                return 0

        while not self.stop.is_set():
            try:
                procs = [psutil.Process(self.pid)]
                procs += procs[0].children(recursive=True)
            except psutil.Error:
                return
            self.peak = max(self.peak, sum(rss(p) for p in procs))
            self.stop.wait(self.period)


def read_counts(d: Path) -> dict:
    """MuJoCo steps and renders summed over the run's processes."""
    tot = {"mj_step": 0, "mjr_render": 0, "render_s": 0.0, "physics_s": 0.0, "processes": 0}
    tot.update(first=math.inf, last=-math.inf)
    for f in d.glob("*.json"):
        c = json.loads(f.read_text())
        for k in ("mj_step", "mjr_render", "render_s", "physics_s"):
            tot[k] += c.get(k, 0)
        tot["processes"] += 1
        if c.get("first"):
            tot["first"], tot["last"] = min(tot["first"], c["first"]), max(tot["last"], c["last"])
    return tot


def run_one(tool: str, a, ckpt: Path, size: int, task_id: int, work: Path, tag: str,
            profile: Path | None = None) -> dict:  # fmt: skip
    """Run one tool once; wall time, peak tree memory, counted work, load average before/after."""
    out = work / "runs" / tag
    counts = out / "counts"
    shutil.rmtree(out, ignore_errors=True)
    counts.mkdir(parents=True)
    env = {**os.environ, "BENCH_COUNT_DIR": str(counts),
           "PYTHONPATH": os.pathsep.join([str(work / "site"), str(ROOT)])}  # fmt: skip
    if tool != "indgen":
        env.update(lerobot_libero_env(work, Path(env["INDGEN_LIBERO_ASSETS"])))
    cmd = tool_command(tool, a, ckpt, size, task_id, out / "run")
    if profile is not None:
        cmd = [a.py_spy, "record", "--subprocesses", "-r", "25", "-f", "raw", "-o", str(profile), "--", *cmd]
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    with open(out / "log.txt", "w") as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env, cwd=str(ROOT))
        mem = TreeMemory(proc.pid)
        mem.start()
        rc = proc.wait()
        mem.stop.set()
    wall = time.perf_counter() - t0
    if rc != 0:
        tail = (out / "log.txt").read_text(errors="ignore").strip().splitlines()[-3:]
        raise SystemExit(
            f"{tool} failed (exit {rc}) at {size}px: {' | '.join(tail)}; full log {out / 'log.txt'}"
        )
    c = read_counts(counts)
    control = c["mj_step"] / SUBSTEPS
    steps_per_ep = control / a.episodes - SETTLE
    return {"tool": tool, "size": size, "wall_s": round(wall, 2), "episodes": a.episodes,
            "episodes_per_min": round(60 * a.episodes / wall, 3),
            "env_steps_per_s": round(a.episodes * a.max_steps / wall, 2),
            "rollout_s": round(c["last"] - c["first"], 2) if c["processes"] else None,
            "startup_s": round(wall - (c["last"] - c["first"]), 2) if c["processes"] else None,
            "rollout_env_steps_per_s": round(a.episodes * a.max_steps / (c["last"] - c["first"]), 2)
            if c["processes"] else None,
            "peak_tree_rss_mib": round(mem.peak / 2**20), "steps_per_episode": round(steps_per_ep, 2),
            "renders_per_control_step": round(c["mjr_render"] / control, 3) if control else None,
            # per control step of one env, wall ms: inside MuJoCo's render calls / physics calls / the whole
            # rollout window (the rest is policy, transport, robosuite's Python and waiting for a core)
            "render_ms_per_step": round(1000 * c["render_s"] / control, 1) if control else None,
            "physics_ms_per_step": round(1000 * c["physics_s"] / control, 1) if control else None,
            "rollout_ms_per_step": round(1000 * (c["last"] - c["first"]) * c["processes"] / control, 1)
            if control else None,
            "processes_counted": c["processes"], "load_before": round(load0, 2),
            "load_after": round(os.getloadavg()[0], 2)}  # fmt: skip


def categorize(raw: Path) -> dict[str, float]:
    """Share of py-spy samples (all processes, idle excluded) per category of PROFILE_RULES."""
    tally: dict[str, int] = {}
    for line in raw.read_text(errors="ignore").splitlines():
        stack, _, n = line.rpartition(" ")
        if not n.isdigit():
            continue
        cat = next(
            (name for name, keys in PROFILE_RULES if any(k in stack for k in keys.split("|"))), "other"
        )
        tally[cat] = tally.get(cat, 0) + int(n)
    total = sum(tally.values()) or 1
    return {k: round(100 * v / total, 1) for k, v in sorted(tally.items(), key=lambda kv: -kv[1])}


def t975(df: int) -> float:
    """Student's t 97.5 % quantile (exact table to 10 degrees of freedom, then a 1/df expansion; no scipy)."""
    table = (12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228)
    return table[df - 1] if df <= 10 else 1.96 + 2.37 / df


def paired_ratio(num: list[float], den: list[float]) -> dict:
    """Geometric-mean ratio of paired rates (same repeat) with a 95% t-interval on the log ratios."""
    logs = [math.log(x / y) for x, y in zip(num, den, strict=True)]
    n = len(logs)
    m = statistics.fmean(logs)
    if n < 2:
        return {"ratio": round(math.exp(m), 3), "n": n, "ci95": None, "paired": True}
    half = t975(n - 1) * statistics.stdev(logs) / math.sqrt(n)
    return {"ratio": round(math.exp(m), 3), "n": n,
            "ci95": [round(math.exp(m - half), 3), round(math.exp(m + half), 3)], "paired": True}  # fmt: skip


MEDIANS = ("wall_s", "startup_s", "episodes_per_min", "env_steps_per_s", "rollout_env_steps_per_s",
           "projected_280_episodes_per_min",
           "peak_tree_rss_mib", "steps_per_episode", "renders_per_control_step", "render_ms_per_step",
           "physics_ms_per_step", "rollout_ms_per_step")  # fmt: skip


def summarize(rows: list[dict], tools: list[str]) -> dict:
    """Per size and tool: median rates over repeats; indgen's paired episodes/min ratio to each lerobot row."""
    out = {}
    for r in rows:  # startup = wall - rollout window; 280-step projection = startup + rollout scaled by steps
        if r.get("rollout_s"):
            r["startup_s"] = round(r["wall_s"] - r["rollout_s"], 2)
            scale = (FULL_STEPS + SETTLE) / (r["steps_per_episode"] + SETTLE)
            r["projected_280_episodes_per_min"] = round(
                60 * r["episodes"] / (r["startup_s"] + r["rollout_s"] * scale), 3
            )
    for size in sorted({r["size"] for r in rows}):
        per = {t: [r for r in rows if r["size"] == size and r["tool"] == t] for t in tools}
        s = {t: {k: statistics.median(v) if (v := [r[k] for r in rs if r.get(k) is not None]) else None
                 for k in MEDIANS} | {"n_repeats": len(rs)} for t, rs in per.items() if rs}  # fmt: skip
        for t in tools:
            if t != "indgen" and per.get(t) and per.get("indgen") and len(per[t]) == len(per["indgen"]):
                for k in ("episodes_per_min", "rollout_env_steps_per_s", "projected_280_episodes_per_min"):
                    if all(r[k] for r in per["indgen"] + per[t]):
                        s[f"indgen_vs_{t}:{k}"] = paired_ratio(
                            [r[k] for r in per["indgen"]], [r[k] for r in per[t]]
                        )
        out[str(size)] = s
    return out


def build_checkpoint(size: int, out: Path) -> Path:
    """The tiny random-init ACT whose two cameras take ``size`` px images (so neither tool resizes)."""
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

    if not (out / "config.json").is_file():
        build_tiny_checkpoint("act", out, size=size)
    return out


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--sizes", default="128,256", help="camera image sides in px, comma list (default 128,256)"
    )
    ap.add_argument("--task", default="alphabet_soup", help="LIBERO-Object task (default alphabet_soup)")
    ap.add_argument("--episodes", type=int, default=2, help="episodes per tool per repeat (default 2)")
    ap.add_argument(
        "--max-steps", type=int, default=280, help="episode length (default 280, LIBERO-Object's)"
    )
    ap.add_argument(
        "--repeats", type=int, default=2, help="interleaved timed repeats (default 2; 0: --profile only)"
    )
    ap.add_argument("--cores", type=int, default=os.cpu_count() or 1,
                    help="indgen --workers and lerobot-eval's env count (default: all cores)")  # fmt: skip
    ap.add_argument("--lerobot-batch", type=int, default=0,
                    help="lerobot-eval --eval.batch_size (default min(cores, episodes), async envs)")  # fmt: skip
    ap.add_argument("--device", default="cpu", help="both tools' policy device (cpu, cuda): equal terms")
    ap.add_argument("--tools", default=",".join(TOOLS), help=f"comma list of {', '.join(TOOLS)}")
    ap.add_argument(
        "--assets", default=None, help="LIBERO asset tree (default: $INDGEN_LIBERO_ASSETS or found)"
    )
    ap.add_argument("--fill-missing", action="store_true",
                    help="run on a symlink copy of --assets with a tiny placeholder for every referenced but "
                         "missing file (partial copies of LIBERO's tree); the list is in the results")  # fmt: skip
    ap.add_argument("--miniature", action="store_true", help="use the miniature asset tree (boxes) instead")
    ap.add_argument(
        "--profile", action="store_true", help="after the timed runs, one py-spy run per tool/size"
    )
    ap.add_argument(
        "--py-spy", default=shutil.which("py-spy") or "py-spy", help="py-spy binary for --profile"
    )
    ap.add_argument(
        "--work",
        default=None,
        help="working folder (default: a new temp folder; with --summarize: the run's)",
    )
    ap.add_argument("--json", default=None, help="also write the results JSON here")
    ap.add_argument("--summarize", default=None, metavar="LOG",
                    help="only re-summarize the per-run JSON lines a previous run printed to LOG")  # fmt: skip
    a = ap.parse_args(argv)
    if a.summarize:
        rows = [json.loads(x) for x in Path(a.summarize).read_text().splitlines() if x.startswith('{"tool"')]
        tools = [t for t in TOOLS if any(r["tool"] == t for r in rows)]
        for r in rows:  # with --work: the time split from the run's counter files (rows of older versions)
            d = Path(a.work or "/nonexistent") / "runs" / f"{r['tool']}_{r['size']}_r{r['repeat']}" / "counts"
            if d.is_dir() and (c := read_counts(d))["mj_step"]:
                control = c["mj_step"] / SUBSTEPS
                for k in ("render", "physics"):
                    r[f"{k}_ms_per_step"] = round(1000 * c[f"{k}_s"] / control, 1) if c[f"{k}_s"] else None
                r["rollout_ms_per_step"] = round(
                    1000 * (c["last"] - c["first"]) * c["processes"] / control, 1
                )
        print(json.dumps(summarize(rows, tools), indent=1))
        return {"rows": rows}
    sizes = parse_sizes(a.sizes)
    tools = [t for t in a.tools.split(",") if t]
    if bad := [t for t in tools if t not in TOOLS]:
        sys.exit(f"--tools: unknown {bad}; choose from {', '.join(TOOLS)}")
    if min(a.episodes, a.max_steps, a.cores) <= 0 or a.repeats < (0 if a.profile else 1):
        sys.exit(
            "--episodes, --max-steps, --cores and --repeats must be positive (--repeats 0 only with --profile)"
        )
    if a.profile and not shutil.which(a.py_spy):
        sys.exit(f"--profile needs py-spy ({a.py_spy} not found): pip install py-spy, or pass --py-spy PATH")
    os.environ.setdefault("MUJOCO_GL", "egl")
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from scenes.family import get_scene

    work = Path(a.work) if a.work else Path(tempfile.mkdtemp(prefix="bench_vs_lerobot_"))
    work.mkdir(parents=True, exist_ok=True)
    (work / "site").mkdir(exist_ok=True)
    (work / "site" / "sitecustomize.py").write_text(COUNTER_SITE)
    tasks = get_scene("libero_object").tasks
    if a.task not in tasks:
        sys.exit(f"--task {a.task!r} is not a LIBERO-Object task; choose from {', '.join(tasks)}")
    placeholders: list[str] = []
    if a.miniature:
        from scenes.libero.miniature import write_miniature_assets

        assets = write_miniature_assets(work / "miniature_assets")
    else:
        from scenes.libero.assets import find_assets

        assets = Path(a.assets).expanduser() if a.assets else find_assets()
        if a.fill_missing:
            from scenes.libero.overlay import overlay_assets

            placeholders = overlay_assets(assets.resolve(), work / "assets_overlay")
            assets = work / "assets_overlay"
    os.environ["INDGEN_LIBERO_ASSETS"] = str(assets)
    ckpts = {s: build_checkpoint(s, work / f"ckpt{s}") for s in sizes}
    rows = []
    for rep in range(a.repeats):
        for size in sizes:
            order = tools[rep % len(tools) :] + tools[: rep % len(tools)]  # rotate who goes first
            for tool in order:
                r = run_one(tool, a, ckpts[size], size, tasks.index(a.task), work, f"{tool}_{size}_r{rep}")
                r["repeat"] = rep
                rows.append(r)
                print(json.dumps(r), flush=True)
    profiles = {}
    if a.profile:
        for size in sizes:
            for tool in tools:
                raw = work / f"profile_{tool}_{size}.txt"
                run_one(tool, a, ckpts[size], size, tasks.index(a.task), work, f"prof_{tool}_{size}", raw)
                profiles[f"{tool}@{size}"] = categorize(raw)
                print(json.dumps({"profile": f"{tool}@{size}", **profiles[f"{tool}@{size}"]}), flush=True)
    result = {
        "machine": f"{platform.machine()} {os.cpu_count()} cores, {platform.platform()}",
        "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
        "task": a.task, "episodes": a.episodes, "max_steps": a.max_steps, "cores": a.cores,
        "repeats": a.repeats, "assets": str(assets), "placeholder_files": placeholders,
        "summary": summarize(rows, tools), "profiles": profiles, "rows": rows,
    }  # fmt: skip
    if a.json:
        Path(a.json).write_text(json.dumps(result, indent=1))
    print(json.dumps({k: result[k] for k in ("machine", "date_utc", "summary", "profiles")}))
    return result


if __name__ == "__main__":
    main()
