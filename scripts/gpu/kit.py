"""The wheels and GL loaders a bare GPU box needs to run ``rows.py``, packed here within the device tool's 64 MiB.

The box has torch, transformers and the scientific stack but no lerobot, MuJoCo or robosuite, and no network.
What to carry is measured, not guessed: ``trace`` runs ``rows.py --rehearsal kit`` (every row but Ray's, which a
second call carries) under strace and keeps every distribution whose files were opened and that the box lacks
(``carry.txt``), and every robosuite asset file opened (``robosuite_assets.txt``: 0.3 % of robosuite's 590 MB).
``pack`` downloads those wheels at this venv's versions, drops robosuite's unopened assets, and writes
``.whl/kit.tar.xz`` (stored zips, one xz stream) and ``.gl/*.deb``::

    .venv/bin/python scripts/gpu/kit.py pack          # then: device run "python3 scripts/gpu/rows.py a",
                                                      #       carry [".whl", ".gl"]
    .venv/bin/python scripts/gpu/kit.py trace         # after a dependency or scene change (needs strace)
    .venv/bin/python scripts/gpu/kit.py check [KIT]   # declared requirements left behind (never opened here)
    .venv/bin/python scripts/gpu/kit.py pack-ray      # .ray/ray.tar.xz and .gl/: the ray16 call's own kit (Ray with
                                                      #   the simulator): device run "python3 scripts/gpu/rows.py
                                                      #   ray16", carry [".ray", ".gl"]
    .venv/bin/python scripts/gpu/kit.py trace ray16   # its lists, carry_ray.txt and robosuite_assets_ray.txt
"""

from __future__ import annotations

import argparse
import importlib.metadata as md
import io
import json
import re
import shutil
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
CARRY = HERE / "carry.txt"
ROBOSUITE_ASSETS = HERE / "robosuite_assets.txt"
# the Ray call's own lists (``trace ray16``): it carries everything its rows open, so it runs on a fresh box too
RAY_CARRY, RAY_ASSETS = HERE / "carry_ray.txt", HERE / "robosuite_assets_ray.txt"
LISTS = {
    "kit": (CARRY, ROBOSUITE_ASSETS),
    "ray16": (RAY_CARRY, RAY_ASSETS),
}  # rows.py group -> what trace writes
LIMIT = 64 * 2**20  # what the device tool carries per call, the repository included
PLATFORMS = ["manylinux_2_28_x86_64", "manylinux_2_27_x86_64", "manylinux_2_24_x86_64", "manylinux_2_17_x86_64",
             "manylinux2014_x86_64", "manylinux1_x86_64", "linux_x86_64"]  # fmt: skip
# Never loaded by a local Ray instance, its actors and ray.cluster_utils (checked by running the ray16 rows on it):
# the Java jars (31 of Ray's 76 MiB), the dashboard's web page, and the libraries on top of Ray core.
RAY_DROP = ("ray/jars/", "ray/dashboard/client/", "ray/rllib/", "ray/data/", "ray/serve/", "ray/tune/",
            "ray/train/", "ray/llm/")  # fmt: skip
GL_DEBS = ["libvulkan1", "libegl1", "libglvnd0", "libopengl0", "libgl1", "libglx0", "libgles2"]

# The device image's packages as listed in the device tool's KINDS.md (read 2026-11-17).
BOX = set(
    """absl-py accelerate aiofiles aiohappyeyeballs aiohttp aiosignal annotated-doc anyio attrs botorch build
certifi charset-normalizer chex click cloudpickle cmake colorama contourpy coverage cuda-bindings cuda-core
cuda-pathfinder cuda-toolkit cupy-cuda13x cycler cython diffrax e3nn einops equinox etils execnet filelock flatbuffers
flax fonttools formulaic frozenlist fsspec gpytorch grpcio h11 h5py hf-xet httpcore httpx huggingface-hub humanize
hypothesis idna imageio iniconfig interface-meta jax jax-cuda13-pjrt jax-cuda13-plugin jaxlib jaxtyping jinja2 joblib
kiwisolver lazy-loader lightning lightning-utilities linear-operator lineax llvmlite lxml markdown markdown-it-py
markupsafe matplotlib mdurl meson ml-dtypes mpi4py mpmath msgpack multidict multipledispatch mypy-extensions nanobind
narwhals networkx ninja numba numba-cuda numpy numpyro nvidia-cublas nvidia-cuda-cupti nvidia-cuda-nvrtc
nvidia-cuda-runtime nvidia-cudnn-cu13 nvidia-cufft nvidia-cufile nvidia-curand nvidia-cusolver nvidia-cusparse
nvidia-cusparselt-cu13 nvidia-ml-py nvidia-nccl-cu13 nvidia-nvjitlink nvidia-nvshmem-cu13 nvidia-nvtx onnx onnx-ir
onnxruntime onnxscript opencv-python-headless optax opt-einsum opt-einsum-fx optimistix orbax-checkpoint packaging
pandas pathspec patsy peft pillow pip pluggy portalocker prometheus-client propcache protobuf psutil pyarrow pybind11
py-cpuinfo pygments pyparsing pyproject-hooks pyre-extensions pytest pytest-benchmark pytest-cov pytest-mock
pytest-timeout pytest-xdist python-dateutil pytorch-lightning pyyaml regex requests rich sacrebleu safetensors
scikit-build-core scikit-image scikit-learn scipy seaborn sentencepiece sentence-transformers setuptools shellingham
simplejson six sortedcontainers statsmodels sympy tabulate tensorboard tensorboard-data-server tensorstore
threadpoolctl tifffile tiktoken timm tokenizers toolz torch torchaudio torchdiffeq torch-geometric torchmetrics
torchvision tqdm transformers treescope triton typer typing-extensions typing-inspect urllib3 uvloop wadler-lindig
werkzeug wheel wrapt xarray xxhash yarl zipp""".split()
)
# On the box at other versions than lerobot 0.6.1 was resolved with here (transformers 5.17.0, tokenizers 0.23.2):
ALWAYS = {"transformers", "tokenizers"}
# The box's CUDA stack: never replaced (its torch is the CUDA build); and this checkout's own distributions.
NEVER = re.compile(
    r"^(torch|torchvision|torchaudio|triton|nvidia-.*|cuda-.*|indgen-vla|lerobot-env-indgen|pip|setuptools|wheel)$"
)


def norm(name: str) -> str:
    """PEP 503 name: what pip and the box's list agree on."""
    return re.sub(r"[-_.]+", "-", name).lower()


# Another distribution of the same modules is on the box (both install cv2).
SAME_MODULES = {"opencv-python": "opencv-python-headless"}


def carry_set(opened_dists: set[str]) -> list[str]:
    """The distributions to carry: opened in the rehearsal, and missing on the box or pinned differently there."""
    on_box = BOX | {d for d, twin in SAME_MODULES.items() if twin in BOX}
    return sorted(
        d for d in map(norm, opened_dists) if not NEVER.match(d) and (d not in on_box or d in ALWAYS)
    )


def file_owners() -> dict[str, str]:
    """Absolute path of every installed file -> its distribution (from each distribution's RECORD)."""
    owners = {}
    for dist in md.distributions():
        for f in dist.files or ():
            owners[str(Path(dist.locate_file(f)).resolve())] = norm(dist.metadata["Name"])
    return owners


def opened_files(strace_log: Path) -> set[str]:
    """Files a traced process tree opened successfully (``openat(...) = fd``)."""
    pat = re.compile(r'open(?:at)?\((?:AT_FDCWD, )?"([^"]+)".*\) = \d+')
    with strace_log.open(errors="replace") as f:
        raw = {m.group(1) for line in f if (m := pat.search(line))}
    return {str((ROOT / p).resolve()) for p in raw}  # relative paths: the rehearsal runs in ROOT


def trace(out_dir: Path, group: str = "kit") -> dict:
    """Run ``group``'s rehearsal under strace; write its carry list and robosuite asset list (``LISTS``) from what
    it opened."""
    if not shutil.which("strace"):
        raise SystemExit("error: strace not found; install it (apt-get install strace) and re-run")
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "strace.log"  # about 100 MB
        argv = ["strace", "-f", "-qq", "-e", "trace=open,openat", "-o", str(log), sys.executable,
                str(HERE / "rows.py"), "--rehearsal", group, "--out", str(Path(tmp) / "out")]  # fmt: skip
        subprocess.run(argv, check=True, cwd=ROOT)
        rows = [json.loads(x) for x in (Path(tmp) / "out" / "rows.jsonl").read_text().splitlines()]
        if failed := [r["row"] for r in rows if r.get("rc", 0) != 0 or r.get("skipped")]:
            raise SystemExit(f"error: rehearsal rows failed: {', '.join(failed)}; see {tmp}/out/log.txt")
        files = opened_files(log)
    owners = file_owners()
    # metadata scans read every dist-info, and every interpreter start reads every .pth (editable finders too)
    dists = {owners[f] for f in files if f in owners and ".dist-info/" not in f and not _startup_file(f)}
    rs_root = Path(md.distribution("robosuite").locate_file("robosuite")).resolve()
    assets = sorted(
        str(Path(f).relative_to(rs_root.parent))
        for f in files
        if f.startswith(str(rs_root / "models" / "assets"))
    )
    carry = carry_set(dists)
    carry_file, assets_file = LISTS[group]
    (out_dir / carry_file.name).write_text("".join(f"{d}\n" for d in carry))
    (out_dir / assets_file.name).write_text("".join(f"{a}\n" for a in assets))
    return {"carry": len(carry), "robosuite_assets": len(assets)}


def _startup_file(path: str) -> bool:
    """A file every interpreter start opens, whether or not its distribution is used."""
    name = Path(path).name
    return name.endswith(".pth") or name.startswith("__editable__")


def trim_wheel(src: Path, dst: Path, drop: Callable[[str], bool]) -> int:
    """Copy ``src`` without the members ``drop`` names, uncompressed (one xz over the tar compresses better),
    RECORD rewritten to match; returns the number of members dropped."""
    dropped = 0
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_STORED) as zout:
        names = [n for n in zin.namelist() if n.endswith("/") or not drop(n)]
        dropped = len(zin.namelist()) - len(names)
        kept = set(names)
        for name in names:
            data = zin.read(name)
            if name.endswith(".dist-info/RECORD"):
                lines = [x for x in data.decode().splitlines() if x.split(",", 1)[0] in kept or not x.strip()]
                data = ("\n".join(lines) + "\n").encode()
            zout.writestr(zin.getinfo(name), data, compress_type=zipfile.ZIP_STORED)
    return dropped


def fetch_wheel(name: str, version: str, dest: Path) -> Path:
    """This venv's version of ``name`` as a wheel for CPython 3.12 x86-64 (built here when only an sdist exists)."""
    before = set(dest.iterdir())
    plats = [x for p in PLATFORMS for x in ("--platform", p)]
    cmd = [sys.executable, "-m", "pip", "download", "-q", "--no-deps", "--only-binary=:all:", "--python-version",
           "3.12", "--implementation", "cp", *plats, "-d", str(dest), f"{name}=={version}"]  # fmt: skip
    if subprocess.run(cmd, capture_output=True).returncode != 0:  # sdist only: build the wheel here (x86-64)
        cmd = [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(dest), f"{name}=={version}"]
        subprocess.run(cmd, check=True, capture_output=True)
    (new,) = set(dest.iterdir()) - before
    return new


def pack(whl_dir: Path, gl_dir: Path | None) -> dict:
    """Download and trim the carried wheels into ``whl_dir/kit.tar.xz``; the GL loader debs into ``gl_dir``."""
    return _pack(CARRY.read_text().split(), ROBOSUITE_ASSETS, whl_dir / "kit.tar.xz", gl_dir)


def pack_ray(ray_dir: Path, gl_dir: Path | None) -> dict:
    """The Ray call's kit, ``ray_dir/ray.tar.xz``: everything its rows open that the box lacks (``carry_ray.txt``)
    and Ray's declared requirements, Ray without what a local instance and its actors never load (``RAY_DROP``:
    its wheel alone is 76 MiB), so it runs on a fresh box as on one an earlier call set up."""
    names = sorted({*RAY_CARRY.read_text().split(), *ray_carry()})
    return _pack(names, RAY_ASSETS, ray_dir / "ray.tar.xz", gl_dir)


def _pack(names: list[str], assets: Path, out: Path, gl_dir: Path | None) -> dict:
    """``names`` at this venv's versions, robosuite's assets cut to those listed in ``assets`` and Ray's by
    ``RAY_DROP``, as one tar.xz at ``out``; the GL loader debs into ``gl_dir``; refused over one call's 64 MiB."""
    keep = set(assets.read_text().split())
    drops = {"robosuite": lambda n: n.startswith("robosuite/models/assets/") and n not in keep,
             "ray": lambda n: n.startswith(RAY_DROP)}  # fmt: skip
    out.parent.mkdir(exist_ok=True)
    dropped = 0
    with tempfile.TemporaryDirectory() as tmp:
        raw, stored = Path(tmp) / "raw", Path(tmp) / "stored"
        raw.mkdir()
        stored.mkdir()
        for name in names:
            w = fetch_wheel(name, md.version(name), raw)
            dropped += trim_wheel(w, stored / w.name, drops.get(name, lambda n: False))
        data = _tar_xz(stored)
    out.write_bytes(data)
    res = {"wheels": len(names), "dropped_files": dropped, "kit_mib": round(len(data) / 2**20, 1)}
    if gl_dir is not None:
        res["gl_debs"] = download_gl(gl_dir)
    return res | _carried(len(data) + sum(p.stat().st_size for p in (gl_dir or out.parent).glob("*.deb")))


def _tar_xz(folder: Path) -> bytes:
    """The wheels in ``folder`` as one xz-compressed tar (what ``rows.py`` unpacks on the box)."""
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:xz", preset=9) as tar:
        for w in sorted(folder.iterdir()):
            tar.add(w, arcname=w.name)
    return buf.getvalue()


def _carried(kit_bytes: int) -> dict:
    """What one device call carries (the kit and the checkout), refused over the device tool's limit."""
    tracked = sum(p.stat().st_size for p in map(ROOT.joinpath, _git_files()) if p.is_file())
    total = kit_bytes + tracked
    if total > LIMIT:
        raise SystemExit(
            f"error: the kit and the checkout are {total / 2**20:.1f} MiB, over the device tool's 64"
        )
    return {"carried_mib": round(total / 2**20, 1)}


def ray_carry() -> list[str]:
    """Ray and what it requires, transitively, that the box lacks (jsonschema and its kin), at this venv's versions."""
    todo, found = ["ray"], []
    while todo:
        name = todo.pop()
        if name in found:
            continue
        found.append(name)
        todo += [r for r in _requires(md.requires(name) or []) if r not in BOX]
    return sorted(found)


def download_gl(gl_dir: Path) -> int:
    """The EGL/GL loaders for amd64 (the device README's list), with apt-get into ``gl_dir``."""
    gl_dir.mkdir(exist_ok=True)
    lists = Path(tempfile.mkdtemp(prefix="apt_amd64_"))
    (lists / "partial").mkdir()
    o = ["-oAPT::Architecture=amd64", "-oAPT::Architectures=amd64", f"-oDir::State::Lists={lists}"]
    subprocess.run(["apt-get", *o, "-qq", "update"], check=True)
    subprocess.run(["apt-get", *o, "-qq", "download", *GL_DEBS], check=True, cwd=gl_dir)
    return len(list(gl_dir.glob("*.deb")))


def _git_files() -> list[str]:
    out = subprocess.run(
        ["git", "ls-files", "-co", "--exclude-standard"], cwd=ROOT, capture_output=True, text=True
    )
    return out.stdout.split()


def requires(whl: Path) -> list[str]:
    """The names a wheel requires outside extras, for Python 3.12 on Linux."""
    with zipfile.ZipFile(whl) as z:
        meta = next(n for n in z.namelist() if n.endswith(".dist-info/METADATA"))
        head = "Requires-Dist: "
        return _requires([x[len(head) :] for x in z.read(meta).decode().splitlines() if x.startswith(head)])


def _requires(lines: list[str]) -> list[str]:
    """The names in Requires-Dist lines that apply outside extras, for Python 3.12 on Linux."""
    from packaging.requirements import Requirement

    reqs = map(Requirement, lines)
    env = {"python_version": "3.12", "sys_platform": "linux", "platform_system": "Linux", "extra": ""}
    return sorted({norm(r.name) for r in reqs if r.marker is None or r.marker.evaluate(env)})


def check(kit: Path) -> list[tuple[str, str]]:
    """(wheel, requirement) pairs that neither the kit nor the box provides."""
    with tempfile.TemporaryDirectory() as tmp:
        with tarfile.open(kit) as tar:
            tar.extractall(tmp, filter="data")
        wheels = sorted(Path(tmp).glob("*.whl"))
        have = (
            BOX
            | {d for d, twin in SAME_MODULES.items() if twin in BOX}
            | {norm(w.name.split("-")[0]) for w in wheels}
        )
        return [(w.name, r) for w in wheels for r in requires(w) if r not in have]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("trace", help="re-measure carry.txt and robosuite_assets.txt (needs strace)")
    t.add_argument("group", nargs="?", default="kit", choices=list(LISTS),
                   help="kit (default): the GPU kit's lists; ray16: the Ray call's (carry_ray.txt, ...)")  # fmt: skip
    p = sub.add_parser("pack", help="fill .whl/kit.tar.xz and .gl/")
    p.add_argument("--no-gl", action="store_true", help="skip the GL loader debs")
    r = sub.add_parser(
        "pack-ray", help="fill .ray/ray.tar.xz and .gl/ (the Ray call's kit, for the ray16 rows)"
    )
    r.add_argument("--no-gl", action="store_true", help="skip the GL loader debs")
    c = sub.add_parser(
        "check", help="requirements the carried wheels declare that are neither carried nor on the box"
    )
    c.add_argument("kit", nargs="?", default=str(ROOT / ".whl" / "kit.tar.xz"),
                   help="the kit to read (default .whl/kit.tar.xz; the Ray call's: .ray/ray.tar.xz)")  # fmt: skip
    a = ap.parse_args(argv)
    if a.cmd == "trace":
        print(json.dumps(trace(HERE, a.group)))
    elif a.cmd == "pack":
        print(json.dumps(pack(ROOT / ".whl", None if a.no_gl else ROOT / ".gl")))
    elif a.cmd == "pack-ray":
        print(json.dumps(pack_ray(ROOT / ".ray", None if a.no_gl else ROOT / ".gl")))
    else:  # information for whoever reads an ImportError from the box: declared, but never opened here
        for whl, req in check(Path(a.kit)):
            print(f"{whl}: declares {req}; not carried (the rehearsal never opened it) and not on the box")
    return 0


if __name__ == "__main__":
    sys.exit(main())
