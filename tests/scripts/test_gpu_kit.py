"""scripts/gpu/: the kit a bare GPU box needs (kit.py) and the driver that runs issue 28's rows there (rows.py).

No GPU here: the driver's rows run as a CPU rehearsal (the same commands at tiny sizes; the whole set is slow),
and the kit's pieces are checked on wheels built in tmp_path and installed with the real pip."""

from __future__ import annotations

import importlib.metadata as md
import importlib.util
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _load(name: str):
    spec = importlib.util.spec_from_file_location(f"gpu_{name}", ROOT / "scripts" / "gpu" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses resolve their module by name
    spec.loader.exec_module(mod)
    return mod


rows = _load("rows")
kit = _load("kit")


def _ctx(tmp_path: Path, **results) -> object:
    return rows.Ctx(sys.executable, "cpu", True, tmp_path, results)


def test_last_json_takes_the_last_object_line():
    text = 'progress {"not": json\n{"a": 1}\nnoise\n{"b": 2}\n{broken\n'
    assert rows.last_json(text) == {"b": 2}
    assert rows.last_json("no json here") is None


def test_run_row_records_rc_result_and_log_tail(tmp_path):
    row = rows.Row("t", 60, lambda c: [c.python, "-c", "print('x'); print('{\"v\": 3}')"], "a tiny row")
    rec = rows.run_row(row, _ctx(tmp_path), rows.time.monotonic() + 100, tmp_path)
    assert rec["rc"] == 0 and rec["result"] == {"v": 3} and rec["timeout_s"] == 60
    assert "== t rc=0" in (tmp_path / "log.txt").read_text()


def test_run_row_fails_skips_and_times_out(tmp_path, monkeypatch):
    failing = rows.Row("f", 60, lambda c: [c.python, "-c", "print('{\"v\": 1}'); raise SystemExit(3)"], "")
    rec = rows.run_row(failing, _ctx(tmp_path), rows.time.monotonic() + 100, tmp_path)
    assert rec["rc"] == 3 and rec["result"] is None  # a failed row's output is not a result
    needs = rows.Row("n", 60, lambda c: None, "")
    assert rows.run_row(needs, _ctx(tmp_path), rows.time.monotonic() + 100, tmp_path)["skipped"].startswith(
        "an earlier"
    )
    over = rows.run_row(failing, _ctx(tmp_path), rows.time.monotonic() + 25, tmp_path)
    assert over["skipped"].startswith("budget") and "rc" not in over
    monkeypatch.setattr(rows, "MIN_ROW_S", 1)
    code = 'import time; print(\'{"pairs": 1, "partial": true}\', flush=True); time.sleep(30)'
    slow = rows.Row("s", 2, lambda c: [c.python, "-c", code], "")
    rec = rows.run_row(slow, _ctx(tmp_path), rows.time.monotonic() + 100, tmp_path)
    assert rec["rc"] == "timeout" and rec["timeout_s"] == 2 and rec["wall_s"] < 10
    assert rec["result"] is None and rec["partial"] == {
        "pairs": 1,
        "partial": True,
    }  # what it measured in time
    assert "partial" not in rows.run_row(failing, _ctx(tmp_path), rows.time.monotonic() + 100, tmp_path)


def test_pi05_rows_take_the_built_spec_and_wait_for_it(tmp_path):
    assert rows.ROWS["pi05_scaling"].argv(_ctx(tmp_path)) is None  # the build failed or did not run
    built = _ctx(tmp_path, pi05_build={"spec": "lerobot:/m/pi05?tokenizer=/m/tok"})
    argv = rows.ROWS["pi05_pipeline"].argv(built)
    assert (
        argv[argv.index("--policy") + 1] == "lerobot:/m/pi05?tokenizer=/m/tok&replan=5"
        and "--pipeline" in argv
    )
    assert rows._pi05_spec(_ctx(tmp_path, pi05_build={"spec": "lerobot:/m"})) == "lerobot:/m?replan=5"
    gpu = rows.Ctx("python3", "cuda", False, tmp_path, built.results)
    argv = rows.ROWS["pi05_compile"].argv(gpu)
    assert (
        argv[argv.index("--compile") + 1] == "reduce-overhead" and argv[argv.index("--device") + 1] == "cuda"
    )


def test_issue_56_call_measures_what_it_promises_within_its_budget(tmp_path):
    # one call: 1,000 episodes at 8 and 16 workers, 3 interleaved pairs against lerobot-eval (a CI needs n >= 3),
    # pi0.5 at batch 16 eager and compiled; --budget 500 cuts the last rows, not the first
    gpu = rows.Ctx("python3", "cuda", False, tmp_path, {"pi05_build": {"spec": "lerobot:/m/pi05"}})
    argv = {name: rows.ROWS[name].argv(gpu) for name in rows.GROUPS["i56"]}
    scaling = argv["scaling_1k"]
    assert (
        scaling[scaling.index("--workers") + 1] == "8,16"
        and int(scaling[scaling.index("--episodes") + 1]) >= 1000
    )
    paired = argv["vs_lerobot_paired"]
    assert paired.count("--repeats") == 1 and int(paired[paired.index("--repeats") + 1]) >= 3
    assert "--compile" not in argv["pi05_model16"] and "reduce-overhead" in argv["pi05_compile16"]
    assert all(a is not None for a in argv.values())
    engine = [
        n for n in rows.GROUPS["i56"] if not n.startswith("pi05")
    ]  # at their caps, pi0.5 still has time
    assert sum(rows.ROWS[n].cap_s for n in engine) <= 500 and rows.GROUPS["i56"][: len(engine)] == engine
    rehearsal = rows.ROWS["vs_lerobot_paired"].argv(_ctx(tmp_path))
    assert rehearsal.count("--repeats") == 1 and "--max-steps" in rehearsal


def test_ray16_call_measures_the_16_core_ray_row_within_its_budget(tmp_path):
    # issue 56: Ray / local at the same number of simulators on the box's 16 cores, both policies, n >= 3 pairs,
    # in a call of its own (Ray's wheel does not fit beside the GPU kit in one call's 64 MiB)
    argv = rows.ROWS["ray_vs_local"].argv(rows.Ctx("python3", "cuda", False, tmp_path, {}))
    opt = {k: argv[argv.index(k) + 1] for k in ("--sims", "--episodes", "--repeats", "--forward-ms")}
    assert argv[1] == "scripts/bench_ray.py" and opt["--forward-ms"] == "0,50" and int(opt["--repeats"]) >= 3
    assert int(opt["--sims"]) == 15 and int(opt["--episodes"]) >= 4 * 15  # the scaling rows' 15 workers
    assert rows.GROUPS["ray16"] == ["ray_vs_local"] and rows.ROWS["ray_vs_local"].cap_s <= 200 - 10
    assert "ray_vs_local" not in rows.GROUPS["kit"] and {*rows.GROUPS["kit"], "ray_vs_local"} == set(
        rows.ROWS
    )


def test_a_call_with_no_kit_on_a_fresh_box_says_what_to_carry(tmp_path):
    with pytest.raises(OSError, match=r"no kit carried: carry .whl and .gl .* or .ray and .gl"):
        rows.install_kits(tmp_path / "venv", [], tmp_path / "log.txt")
    assert not (tmp_path / "venv").exists()


def test_ray_kit_carries_what_its_rows_open_and_ray_requires():
    """carry_ray.txt (``kit.py trace ray16``) names Ray, the simulator and what the dashboard's processes import;
    Ray's declared requirements the box lacks come too; none of it is on the box or this checkout's own."""
    measured = kit.RAY_CARRY.read_text().split()
    assert {"ray", "mujoco", "robosuite", "pyopengl"} <= set(measured)
    assert kit.ray_carry() == ["jsonschema", "jsonschema-specifications", "ray", "referencing", "rpds-py"]
    assert not set(measured) & kit.BOX and not any(kit.NEVER.match(n) for n in measured)
    assert all(md.version(n) for n in measured)
    site = Path(md.distribution("robosuite").locate_file(""))
    assert [a for a in kit.RAY_ASSETS.read_text().split() if not (site / a).is_file()] == []


def test_startup_files_do_not_make_a_distribution_carried():
    assert kit._startup_file("/v/site-packages/__editable__.lerobot_env_indgen-0.1.0.pth")
    assert kit._startup_file("/v/site-packages/distutils-precedence.pth")
    assert not kit._startup_file("/v/site-packages/mujoco/__init__.py")


@pytest.mark.slow  # ~4 min: 19 wheels from the package registry, packed (xz), installed, and the ray16 row run
def test_packed_ray_kit_fits_one_call_and_runs_the_ray16_row_alone(tmp_path):
    res = kit.pack_ray(tmp_path / ".ray", None)
    assert res["carried_mib"] <= 64 and res["dropped_files"] > 1000, res
    venv = (
        tmp_path / "venv"
    )  # a fresh box: the Ray kit alone makes the venv, over this venv (which has Ray) here
    made = rows.install_kits(venv, [tmp_path / ".ray" / "ray.tar.xz"], tmp_path / "log.txt")
    assert made["venv"] == "created" and made["kits"] == ["ray.tar.xz"] and (venv / ".ray").exists()
    py = str(venv / "bin" / "python")
    code = ("import os, ray, robosuite; d = os.path.dirname(ray.__file__); "
            "print(d, os.path.isdir(d + '/jars'), robosuite.__file__)")  # fmt: skip
    where, jars, rs = subprocess.run(
        [py, "-c", code], capture_output=True, text=True, check=True
    ).stdout.split()
    assert where.startswith(str(venv)) and jars == "False" and rs.startswith(str(venv))  # the kit's, not ours
    proc = subprocess.run([py, "scripts/gpu/rows.py", "--rehearsal", "ray16", "--out", str(tmp_path / "out")],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)  # fmt: skip
    recs = [json.loads(x) for x in (tmp_path / "out" / "rows.jsonl").read_text().splitlines()]
    assert proc.returncode == 0 and recs[-1]["rc"] == 0, (tmp_path / "out" / "log.txt").read_text()[-3000:]
    result = recs[-1]["result"]
    assert [p["forward_ms"] for p in result["policies"]] == [0.0, 50.0] and result["sims"] == 2


def test_unknown_row_is_one_line_and_exit_2(tmp_path, capsys):
    assert rows.main(["scalling", "--rehearsal", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown row 'scalling'" in err[0] and "scaling" in err[0]


@pytest.mark.slow  # ~6 s: the GPU kit's env row through its command line
def test_rehearsal_env_row_through_the_command_line(tmp_path):
    proc = subprocess.run([sys.executable, "scripts/gpu/rows.py", "--rehearsal", "env", "--out", str(tmp_path)],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    recs = [json.loads(x) for x in (tmp_path / "rows.jsonl").read_text().splitlines()]
    assert [r["row"] for r in recs] == ["setup", "env"] and "venv" not in recs[0]  # nothing installed here
    env = recs[1]["result"]
    assert env["gpu"] is None and env["lerobot"] == md.version("lerobot") and env["robosuite"] == "1.4.0"


@pytest.mark.slow
def test_rehearsal_of_every_row(tmp_path):
    proc = subprocess.run([sys.executable, "scripts/gpu/rows.py", "--rehearsal", "all", "--budget", "1500",
                           "--out", str(tmp_path)], cwd=ROOT, capture_output=True, text=True, timeout=1600)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    recs = {r["row"]: r for r in map(json.loads, (tmp_path / "rows.jsonl").read_text().splitlines())}
    assert set(recs) == {"setup", *rows.ROWS}
    failed = {k: r.get("rc", r.get("skipped")) for k, r in recs.items() if k != "setup" and r.get("rc") != 0}
    assert not failed, (tmp_path / "log.txt").read_text()[-4000:]
    assert recs["pi05_scaling"]["result"]["scaling_policy"].endswith("replan=5")


def _wheel(path: Path, files: dict[str, bytes], requires: tuple[str, ...] = ()) -> Path:
    """A minimal valid wheel (METADATA, WHEEL, RECORD) holding ``files``."""
    name, version = path.name.split("-")[:2]
    info = f"{name}-{version}.dist-info"
    meta = f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n" + "".join(
        f"Requires-Dist: {r}\n" for r in requires
    )
    members = {**files, f"{info}/METADATA": meta.encode(),
               f"{info}/WHEEL": b"Wheel-Version: 1.0\nGenerator: test\nRoot-Is-Purelib: true\nTag: py3-none-any\n"}  # fmt: skip
    import base64
    import hashlib

    record = [
        f"{n},sha256={base64.urlsafe_b64encode(hashlib.sha256(d).digest()).rstrip(b'=').decode()},{len(d)}"
        for n, d in members.items()
    ]
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for n, d in members.items():
            z.writestr(n, d)
        z.writestr(f"{info}/RECORD", "\n".join([*record, f"{info}/RECORD,,"]) + "\n")
    return path


def test_trim_wheel_drops_unopened_assets_and_pip_installs_the_rest(tmp_path):
    src = _wheel(tmp_path / "robosim-1.0-py3-none-any.whl", {
        "robosim/__init__.py": b"X = 1\n", "robosim/models/assets/a.stl": b"a" * 100,
        "robosim/models/assets/b.stl": b"b" * 100, "robosim/models/assets/c.xml": b"<c/>"})  # fmt: skip
    out = tmp_path / "trimmed"
    out.mkdir()
    dst = out / src.name
    keep = {"robosim/models/assets/a.stl"}
    assert kit.trim_wheel(src, dst, lambda n: n.startswith("robosim/models/assets/") and n not in keep) == 2
    with zipfile.ZipFile(dst) as z:
        names = set(z.namelist())
        record = z.read("robosim-1.0.dist-info/RECORD").decode()
        assert all(i.compress_type == zipfile.ZIP_STORED for i in z.infolist())
    assert "robosim/models/assets/a.stl" in names and "robosim/models/assets/b.stl" not in names
    assert "b.stl" not in record and "c.xml" not in record and "robosim/__init__.py" in record
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-index", "--no-deps", "--target",
                    str(target), str(dst)], check=True, capture_output=True)  # fmt: skip
    assert (target / "robosim/models/assets/a.stl").read_bytes() == b"a" * 100
    assert not (target / "robosim/models/assets/b.stl").exists()


def test_carry_set_keeps_what_the_box_lacks_and_its_pinned_versions():
    opened = {"lerobot", "MuJoCo", "robosuite", "numpy", "scipy", "torch", "nvidia_cublas", "transformers",
              "tokenizers", "indgen_vla", "Farama.Notifications", "opencv-python"}  # fmt: skip
    assert kit.carry_set(opened) == ["farama-notifications", "lerobot", "mujoco", "robosuite", "tokenizers",
                                     "transformers"]  # fmt: skip


def test_opened_files_reads_successful_opens_only(tmp_path):
    log = tmp_path / "strace.log"
    log.write_text(
        '101 openat(AT_FDCWD, "/usr/lib/a.so", O_RDONLY|O_CLOEXEC) = 3\n'
        '101 openat(AT_FDCWD, "/nope/b.py", O_RDONLY) = -1 ENOENT (No such file or directory)\n'
        '102 open("/tmp/c.xml", O_RDONLY) = 7\n'
    )
    assert kit.opened_files(log) == {str(Path("/usr/lib/a.so").resolve()), str(Path("/tmp/c.xml").resolve())}


def test_check_names_requirements_nothing_provides(tmp_path):
    import tarfile

    wheels = [_wheel(tmp_path / "alpha-1.0-py3-none-any.whl", {"alpha/__init__.py": b""},
                     ("beta>=1", "numpy", "gamma; extra == 'dev'", "delta; python_version < '3.10'", "epsilon",
                      "opencv-python")),
              _wheel(tmp_path / "beta-2.0-py3-none-any.whl", {"beta/__init__.py": b""})]  # fmt: skip
    with tarfile.open(tmp_path / "kit.tar.xz", "w:xz") as tar:
        for w in wheels:
            tar.add(w, arcname=w.name)
    assert kit.check(tmp_path / "kit.tar.xz") == [("alpha-1.0-py3-none-any.whl", "epsilon")]


def test_the_measured_lists_name_installed_distributions():
    """carry.txt and robosuite_assets.txt (written by ``kit.py trace``) still match this venv: pack can fetch
    every carried distribution at its installed version, and every listed asset exists."""
    carried = kit.CARRY.read_text().split()
    assert {"lerobot", "mujoco", "robosuite", "hf-libero", "transformers"} <= set(carried)
    for name in carried:
        md.version(name)  # raises PackageNotFoundError when the venv no longer has it
    site = Path(md.distribution("robosuite").locate_file(""))
    assets = kit.ROBOSUITE_ASSETS.read_text().split()
    assert any("robots/panda" in a for a in assets)
    assert [a for a in assets if not (site / a).is_file()] == []


@pytest.mark.slow  # ~9 s: a venv made and wheels installed
def test_install_kit_makes_a_venv_over_a_venv_where_carried_wheels_win(tmp_path):
    """The box's python3 is a venv (torch in it); here the project's .venv plays it: the new venv must import
    torch from it, a carried wheel before the parent's copy of the same distribution, and this checkout."""
    import tarfile

    parent_termcolor = md.version("termcolor")
    whl = _wheel(tmp_path / "termcolor-99.0-py3-none-any.whl", {"termcolor/__init__.py": b"CARRIED = True\n"})
    with tarfile.open(tmp_path / "kit.tar.xz", "w:xz") as tar:
        tar.add(whl, arcname=whl.name)
    venv = tmp_path / "venv"
    res = rows.install_kits(venv, [tmp_path / "kit.tar.xz"], tmp_path / "log.txt")
    assert res["venv"] == "created", (tmp_path / "log.txt").read_text()
    code = ("import importlib.metadata as m, termcolor, torch, indgen_vla, sys; "
            "print(termcolor.CARRIED, m.version('termcolor'), torch.__file__, indgen_vla.__file__, sys.prefix)")  # fmt: skip
    out = subprocess.run(
        [str(venv / "bin" / "python"), "-c", code], capture_output=True, text=True, cwd=tmp_path
    )
    assert out.returncode == 0, out.stderr[-2000:]
    carried, version, torch_file, pkg_file, prefix = out.stdout.split()
    assert carried == "True" and version == "99.0" != parent_termcolor
    assert torch_file.startswith(sys.prefix) and pkg_file == str(ROOT / "indgen_vla" / "__init__.py")
    assert prefix == str(venv)
    assert rows.install_kits(venv, [tmp_path / "kit.tar.xz"], tmp_path / "log.txt") == {
        "venv": "installed earlier"
    }
    # a later call of the same lease (the warm box keeps .venv) adds its own kit, and only it
    other = _wheel(tmp_path / "tinypkg-1.0-py3-none-any.whl", {"tinypkg/__init__.py": b""})
    with tarfile.open(tmp_path / "ray.tar.xz", "w:xz") as tar:
        tar.add(other, arcname=other.name)
    added = rows.install_kits(venv, [tmp_path / "kit.tar.xz", tmp_path / "ray.tar.xz"], tmp_path / "log.txt")
    assert added["venv"] == "added to" and added["kits"] == ["ray.tar.xz"] and (venv / ".ray").exists()
    check = [str(venv / "bin" / "python"), "-c", "import tinypkg, termcolor; print(termcolor.CARRIED)"]
    assert subprocess.run(check, capture_output=True, text=True, cwd=tmp_path).stdout.strip() == "True"
