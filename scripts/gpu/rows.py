"""Issue 28's GPU rows in one device call: installs the carried kit, runs each row under a time budget, and
writes one JSON line per row to ``$OUT/rows.jsonl`` (with the tail of every row's output in ``$OUT/log.txt``),
so a lent GPU's 15 minutes go to measuring, not to setting up.

On the device machine (a bare box with torch but no lerobot, MuJoCo or robosuite; run ``kit.py pack`` here
first, which fills the git-ignored ``.whl/`` and ``.gl/``)::

    python3 scripts/gpu/rows.py a --budget 360   # carry [".whl", ".gl"]; env, scaling, vs lerobot-eval, pinned
    python3 scripts/gpu/rows.py b --budget 540   # env, real-size pi0.5: build, alone eager and compiled,
                                                 # compiled and eager in the engine (b0: 2026-11-26's call b)
    python3 scripts/gpu/rows.py i56 --budget 500 # issue 56 in one call: 1,000 episodes at 8 and 16 workers,
                                                 # 3 pairs vs lerobot-eval, pi0.5 eager vs compiled (GPU busy %)
    python3 scripts/gpu/rows.py ray16 --budget 200  # carry [".ray", ".gl"] (``kit.py pack-ray``), in any call
                                                    # of a lease: Ray / local with 15 simulators, both policies,
                                                    # 3 pairs

Rows run in the order given and each gets the smaller of its cap and what ``--budget`` leaves (a row that would
start with under 20 s is skipped and says so), so the most wanted rows come first in each group; docs/benchmarks.md
("Running the GPU rows") sizes the two calls to a 15-minute lease.

Here, on a CPU machine, the same commands at tiny sizes (what ``tests/scripts/test_gpu_kit.py`` runs)::

    .venv/bin/python scripts/gpu/rows.py --rehearsal all

Python's standard library only: it runs under the box's own ``python3`` before anything is installed.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shlex
import subprocess
import sys
import sysconfig
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
VENV_PY = ROOT / ".venv" / "bin" / "python"
KIT = ROOT / ".whl" / "kit.tar.xz"
RAY_KIT = (
    ROOT / ".ray" / "ray.tar.xz"
)  # the ray16 call's own kit: Ray does not fit beside the GPU kit in 64 MiB
LOG_TAIL = 80  # lines of each row's output kept in log.txt
NVIDIA_VENDOR_FILES = {
    "__EGL_VENDOR_LIBRARY_FILENAMES": "/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json",
    "VK_DRIVER_FILES": "/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json",
}
MIN_ROW_S = 20  # a row with less time left than this is skipped, not started


@dataclasses.dataclass(frozen=True)
class Ctx:
    """What a row's command depends on: the device, rehearsal sizes, the work folder, earlier rows' results."""

    python: str
    device: str
    rehearsal: bool
    work: Path
    results: dict


@dataclasses.dataclass(frozen=True)
class Row:
    """One measurement: a command (None when an earlier row it needs failed) and the most seconds it may take."""

    name: str
    cap_s: int
    argv: Callable[[Ctx], list[str] | None]
    about: str


# Sizes of each row: on the GPU box, and in a CPU rehearsal (the same code paths, seconds instead of minutes).
SIZES = {
    "scaling": ("--workers 8,15,16 --episodes 64 --seconds 2",
                "--workers 1,2 --episodes 2 --max-steps 10 --seconds 0.2"),
    "vs_lerobot": ("--cores 8 --episodes 64 --sizes 256 --tools indgen,lerobot-eval-novideo",
                   "--cores 2 --episodes 2 --max-steps 12 --sizes 64 --tools indgen,lerobot-eval-novideo"),
    "pi05_build": ("", "--reduced"),
    "pi05_scaling": ("--precision bf16 --workers 8,16 --episodes 32 --max-steps 50 --seconds 3",
                     "--workers 2 --episodes 2 --max-steps 10 --seconds 0.2"),
    "pi05_model": ("--precision bf16 --batches 1,16 --seconds 3", "--batches 1,2 --seconds 0.2"),
    "pi05_compile": ("--precision bf16 --compile reduce-overhead --batches 1,16 --seconds 3",
                     "--batches 1,2 --seconds 0.2"),
    "pi05_wide": ("--precision bf16 --workers 32,48 --episodes 96 --max-steps 50 --seconds 3",
                  "--workers 3 --episodes 3 --max-steps 10 --seconds 0.2"),
    "pi05_compiled_scaling": ("--precision bf16 --compile reduce-overhead --workers 16 --episodes 32 "
                              "--max-steps 50 --seconds 3",
                              "--workers 2 --episodes 2 --max-steps 10 --seconds 0.2"),
    # issue 56: one call under 10 minutes
    "scaling_1k": ("--workers 8,16 --episodes 1000 --max-steps 20 --seconds 1",
                   "--workers 1,2 --episodes 6 --max-steps 5 --seconds 0.2"),
    "vs_lerobot_paired": ("--cores 8 --episodes 8 --repeats 3 --sizes 256 --tools indgen,lerobot-eval-novideo",
                          "--cores 1 --episodes 1 --repeats 2 --max-steps 8 --sizes 64 "
                          "--tools indgen,lerobot-eval-novideo"),
    "pi05_model16": ("--precision bf16 --batches 16 --seconds 3", "--batches 2 --seconds 0.2"),
    "pi05_compile16": ("--precision bf16 --compile reduce-overhead --batches 16 --seconds 3",
                       "--batches 2 --seconds 0.2"),
    # issue 56's 16-core Ray row: as many simulators as the scaling rows' 15 workers, 4 episodes each
    "ray_vs_local": ("--sims 15 --episodes 60 --max-steps 40 --repeats 3 --forward-ms 0,50 --calls 300",
                     "--sims 2 --episodes 3 --max-steps 8 --repeats 1 --forward-ms 0,50 --calls 20"),
}  # fmt: skip


def _sizes(ctx: Ctx, row: str) -> list[str]:
    return SIZES[row][ctx.rehearsal].split()


def _bench_engine(ctx: Ctx, *args: str) -> list[str]:
    return [ctx.python, "scripts/bench_engine.py", "--device", ctx.device, *args]


def _pi05_spec(ctx: Ctx) -> str | None:
    """The built pi0.5's policy spec, replanning every 5 steps (openpi's LIBERO setting)."""
    spec = (ctx.results.get("pi05_build") or {}).get("spec")
    return None if spec is None else spec + ("&" if "?" in spec else "?") + "replan=5"


def _env(ctx: Ctx) -> list[str]:
    code = (
        "import json, importlib.metadata as m, torch\n"
        "from scenes.render_info import gl_renderer\n"
        "v = {d: m.version(d) for d in ('lerobot', 'mujoco', 'robosuite', 'transformers', 'numpy')}\n"
        "gpu = torch.cuda.get_device_name(0) if torch.cuda.is_available() else None\n"
        "print(json.dumps({'torch': torch.__version__, 'gpu': gpu, 'gl': gl_renderer(), **v}))\n"
    )
    return [ctx.python, "-c", code]


def _scaling(ctx: Ctx, *extra: str) -> list[str]:
    return _bench_engine(ctx, "--only", "scaling", *_sizes(ctx, "scaling"), *extra)


def _vs_lerobot(ctx: Ctx, row: str = "vs_lerobot") -> list[str]:
    out = str(ctx.work / f"{row}.json")
    sizes = _sizes(ctx, row)
    repeats = [] if "--repeats" in sizes else ["--repeats", "1"]
    return [ctx.python, "scripts/bench_vs_lerobot.py", "--device", ctx.device, "--miniature", *repeats,
            "--json", out, *sizes]  # fmt: skip


def _pi05_build(ctx: Ctx) -> list[str]:
    out = str(ctx.work / "pi05")
    return [
        ctx.python,
        "scripts/build_real_size.py",
        "pi05",
        out,
        "--device",
        ctx.device,
        *_sizes(ctx, "pi05_build"),
    ]


def _pi05(ctx: Ctx, part: str, row: str, *extra: str) -> list[str] | None:
    spec = _pi05_spec(ctx)
    return (
        None
        if spec is None
        else _bench_engine(ctx, "--only", part, "--policy", spec, *_sizes(ctx, row), *extra)
    )


ROWS = {
    r.name: r
    for r in [
        Row("env", 120, _env, "versions, the GPU, the GL renderer MuJoCo's EGL gets"),
        Row("scaling", 200, _scaling, "engine steps/s at 8, 15, 16 workers (cameras on): is 16 >= 8?"),
        Row("scaling_pin", 200, lambda c: _scaling(c, "--pin"), "the same, coordinator on core 0, a core per worker"),
        Row("vs_lerobot", 330, _vs_lerobot, "episodes/min vs lerobot-eval, 8 processes, policies on the device"),
        Row("pi05_build", 240, _pi05_build, "pi0.5 at its real size (4.1 B parameters), random init, offline"),
        Row("pi05_scaling", 150, lambda c: _pi05(c, "scaling", "pi05_scaling"),
            "pi0.5 in the engine at 8 and 16 workers: share_of_model_alone (goal >= 0.8), gpu_busy_pct (>= 70)"),
        Row("pi05_pipeline", 150, lambda c: _pi05(c, "scaling", "pi05_scaling", "--pipeline"),
            "the same with two lanes per worker"),
        Row("pi05_model", 120, lambda c: _pi05(c, "model", "pi05_model"),
            "pi0.5 alone, eager, batches 1 and 16: this machine's baseline for the compiled rows"),
        Row("pi05_wide", 150, lambda c: _pi05(c, "scaling", "pi05_wide"),
            "pi0.5 with more workers than cores (32, 48): a GPU-bound model leaves workers idle; bigger batches?"),
        Row("pi05_compile", 240, lambda c: _pi05(c, "model", "pi05_compile"),
            "--compile reduce-overhead (CUDA graphs on one flow step) on pi0.5; first_call_s holds the compile"),
        Row("pi05_compiled_scaling", 200, lambda c: _pi05(c, "scaling", "pi05_compiled_scaling"),
            "pi0.5 compiled in the engine at 16 workers (the batch-16 compile cached by pi05_compile): GPU busy"),
        Row("scaling_1k", 150, lambda c: _bench_engine(c, "--only", "scaling", *_sizes(c, "scaling_1k")),
            "engine steps/s at 8 and 16 workers on a 1,000-episode run, start included (steps_per_s)"),
        Row("vs_lerobot_paired", 230, lambda c: _vs_lerobot(c, "vs_lerobot_paired"),
            "indgen / lerobot-eval episodes/min, 3 interleaved pairs: geometric mean with its 95 % t-interval"),
        Row("pi05_model16", 90, lambda c: _pi05(c, "model", "pi05_model16"),
            "pi0.5 alone, eager, batch 16: forward ms and GPU busy % (the compiled row's baseline)"),
        Row("pi05_compile16", 200, lambda c: _pi05(c, "model", "pi05_compile16"),
            "pi0.5 alone, --compile reduce-overhead, batch 16: forward ms and GPU busy %, first_call_s the compile"),
        Row("ray_vs_local", 190, lambda c: [c.python, "scripts/bench_ray.py", *_sizes(c, "ray_vs_local")],
            "Ray / local wall time with 15 simulators, cheap and 50 ms policies, 3 pairs (goal <= 1.10); a call's ms"),
    ]
}  # fmt: skip
GROUPS = {
    "a": ["env", "scaling", "vs_lerobot", "scaling_pin"],
    "b": [
        "env",
        "pi05_build",
        "pi05_model",
        "pi05_wide",
        "pi05_compile",
        "pi05_compiled_scaling",
        "pi05_scaling",
    ],
    "b0": ["env", "pi05_build", "pi05_scaling", "pi05_pipeline", "pi05_compile"],  # 2026-11-26's call b
    # issue 56 in one call of < 10 minutes (--budget 500): the engine at scale, the paired comparison with a CI,
    # pi0.5 compiled against eager with GPU busy %
    "i56": ["env", "scaling_1k", "vs_lerobot_paired", "pi05_build", "pi05_model16", "pi05_compile16"],
    "ray16": ["ray_vs_local"],  # a call of its own, carrying .ray (its own kit, Ray included) and .gl
    "all": list(ROWS),
}
GROUPS["kit"] = [r for r in ROWS if r not in GROUPS["ray16"]]  # what kit.py trace measures the GPU kit on


def last_json(text: str) -> dict | None:
    """The last line of ``text`` that parses as a JSON object (the benches print their result there)."""
    for line in reversed(text.splitlines()):
        line = line.strip()
        if line.startswith("{"):
            try:
                return json.loads(line)
            except json.JSONDecodeError:
                continue
    return None


def install_kits(venv: Path, kits: list[Path], log: Path) -> dict:
    """A venv that sees the box's own packages (torch, CUDA), with the carried kits' wheels and this checkout on
    top: made once, each kit installed once (a warm box keeps ``.venv`` from an earlier call: ``ray16`` after ``a``).

    The box's ``python3`` is itself a venv, and a venv made from a venv gets the base interpreter's site-packages
    as its system site, not the parent venv's: a ``.pth`` adds the parent's site-packages (and its own .pth files)
    behind the new venv's, so carried versions win and torch stays the box's."""
    todo = [k for k in kits if not _marker(venv, k).exists()]
    made = (venv / "bin" / "python").exists()
    if made and not todo:
        return {"venv": "installed earlier"}
    if not made and not kits:
        raise OSError("no kit carried: carry .whl and .gl (kit.py pack) or .ray and .gl (kit.py pack-ray)")
    t0 = time.perf_counter()
    py = venv / "bin" / "python"
    if not made:
        _checked([sys.executable, "-m", "venv", "--without-pip", str(venv)], log)
        new_site = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                                  capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
        parents = dict.fromkeys(sysconfig.get_paths()[k] for k in ("purelib", "platlib"))
        (Path(new_site) / "_box_site.pth").write_text(
            "".join(f"import site; site.addsitedir({p!r})\n" for p in parents)
        )
    for kit in todo:
        with tempfile.TemporaryDirectory() as tmp:
            _checked(["tar", "-xJf", str(kit), "-C", tmp], log)
            _checked([*_pip(py), *sorted(str(p) for p in Path(tmp).glob("*.whl"))], log)
    if not made:
        _checked([*_pip(py), "--no-build-isolation", "-e", str(ROOT)], log)
    for kit in todo:
        _marker(venv, kit).touch()
    return {"venv": "added to" if made else "created", "kits": [k.name for k in todo],
            "install_s": round(time.perf_counter() - t0, 1)}  # fmt: skip


def _marker(venv: Path, kit: Path) -> Path:
    """``.kit`` once ``kit.tar.xz`` is installed, ``.ray`` once ``ray.tar.xz`` is."""
    return venv / f".{kit.name.split('.')[0]}"


def _pip(py: Path) -> list[str]:
    """Install into the new venv even what the box's site already has at that version (pip would skip it)."""
    return [
        str(py),
        "-m",
        "pip",
        "install",
        "-q",
        "--no-index",
        "--no-deps",
        "--no-compile",
        "--ignore-installed",
    ]


def unpack_gl() -> int:
    """The EGL/GL loader packages ``kit.py pack`` downloaded, unpacked over / (the device README's recipe)."""
    debs = sorted((ROOT / ".gl").glob("*.deb"))
    for deb in debs:
        subprocess.run(["dpkg", "-x", str(deb), "/"], check=True)
    if debs:
        subprocess.run(["ldconfig"], check=True)
    return len(debs)


def _checked(argv: list[str], log: Path) -> None:
    with log.open("a") as f:
        f.write(f"$ {shlex.join(argv)}\n")
        f.flush()
        subprocess.run(argv, check=True, stdout=f, stderr=subprocess.STDOUT, cwd=ROOT)


def run_row(row: Row, ctx: Ctx, budget_end: float, out: Path) -> dict:
    """Run one row with the smaller of its cap and what the budget leaves; its record (rc, wall, result)."""
    argv = row.argv(ctx)
    rec: dict = {"row": row.name, "about": row.about}
    left = int(budget_end - time.monotonic()) - 10
    if argv is None:
        return rec | {"skipped": "an earlier row it needs failed"}
    if min(row.cap_s, left) < MIN_ROW_S:
        return rec | {"skipped": f"budget ({left} s left)", "cmd": shlex.join(argv)}
    timeout = min(row.cap_s, left)
    t0 = time.perf_counter()
    try:
        p = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=timeout)
        rc, text = p.returncode, p.stdout + p.stderr
    except subprocess.TimeoutExpired as e:
        rc, text = "timeout", _text(e.stdout) + _text(e.stderr)
    rec |= {
        "rc": rc,
        "wall_s": round(time.perf_counter() - t0, 1),
        "timeout_s": timeout,
        "cmd": shlex.join(argv),
    }
    rec["result"] = last_json(text) if rc == 0 else None
    if rc == "timeout" and (part := last_json(text)) is not None:  # what a bench printed before its cap: kept
        rec["partial"] = part
    tail = "\n".join(text.splitlines()[-LOG_TAIL:])
    with (out / "log.txt").open("a") as f:
        f.write(f"== {row.name} rc={rc} {rec['wall_s']} s\n$ {rec['cmd']}\n{tail}\n")
    return rec


def _text(b) -> str:
    return b.decode(errors="replace") if isinstance(b, bytes) else (b or "")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("rows", nargs="+", help=f"row names or groups: {', '.join([*GROUPS, *ROWS])}")
    ap.add_argument("--rehearsal", action="store_true", help="CPU, tiny sizes: the same commands, for tests")
    ap.add_argument("--budget", type=float, default=540, help="seconds for the whole call (default 540)")
    ap.add_argument(
        "--out", default=os.environ.get("OUT") or "/tmp/gpu_rows_out", help="results folder ($OUT)"
    )
    a = ap.parse_args(argv)
    names = [n for x in a.rows for n in GROUPS.get(x, [x])]
    if unknown := [n for n in names if n not in ROWS]:
        print(
            f"error: unknown row {unknown[0]!r}; choose from {', '.join([*GROUPS, *ROWS])}", file=sys.stderr
        )
        return 2
    budget_end = time.monotonic() + a.budget
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    os.environ.update(
        MUJOCO_GL="egl", HF_HUB_OFFLINE="1", TOKENIZERS_PARALLELISM="false", PYTHONUNBUFFERED="1"
    )
    for var, path in NVIDIA_VENDOR_FILES.items():  # the device README: where the loaders find no driver
        if Path(path).is_file():
            os.environ.setdefault(var, path)
    head = {
        "row": "setup",
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "cores": os.cpu_count(),
    }
    try:
        if not a.rehearsal:  # here the project's own .venv runs the rows; never unpack packages over /
            kits = [k for k in (KIT, RAY_KIT) if k.is_file()]
            head |= {"gl_debs": unpack_gl(), **install_kits(ROOT / ".venv", kits, out / "log.txt")}
    except (subprocess.CalledProcessError, OSError) as e:
        _write(out, head | {"error": f"set-up failed: {e}; see log.txt"})
        return 1
    _write(out, head)
    with tempfile.TemporaryDirectory(prefix="gpu_rows_") as work:
        py, device = (sys.executable, "cpu") if a.rehearsal else (str(VENV_PY), "cuda")
        ctx = Ctx(py, device, a.rehearsal, Path(work), {})
        for name in dict.fromkeys(names):
            rec = run_row(ROWS[name], ctx, budget_end, out)
            ctx.results[name] = rec.get("result")
            _write(out, rec)
    return 0


def _write(out: Path, rec: dict) -> None:
    line = json.dumps(rec)
    print(line, flush=True)
    with (out / "rows.jsonl").open("a") as f:
        f.write(line + "\n")


if __name__ == "__main__":
    sys.exit(main())
