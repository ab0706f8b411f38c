"""indgen_vla.core.resources finds the top-level configs/ in a checkout and inside an installed wheel."""

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tomllib
from pathlib import Path

import pytest

from indgen_vla.core.resources import CONFIG_KINDS, config_dir

ROOT = Path(__file__).resolve().parents[3]
PRESETS = {kind: sorted(p.name for p in (ROOT / "configs" / kind).glob("*.yaml")) for kind in CONFIG_KINDS}


def test_config_dir_is_the_top_level_configs_of_a_checkout():
    for kind in CONFIG_KINDS:
        assert config_dir(kind) == ROOT / "configs" / kind
    assert "libero_object.yaml" in PRESETS["paper"] and PRESETS["axes"] == ["paper.yaml", "quick.yaml"]
    assert not (
        ROOT / "indgen_vla" / "configs"
    ).exists()  # one copy: the wheel maps configs/ into the package
    with pytest.raises(ValueError, match="unknown config kind 'nope'"):
        config_dir("nope")


def test_the_wheel_lists_every_package_folder():
    """pyproject lists packages explicitly (for the configs/ mapping): a new package folder must be added there."""
    tool = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    folders = {
        ".".join(init.parent.relative_to(ROOT).parts)
        for top in ("indgen_vla", "scenes", "policy_wrappers")
        for init in (ROOT / top).rglob("__init__.py")
    }
    assert set(tool["packages"]) == folders | {"indgen_vla.configs"}
    assert tool["package-dir"] == {"indgen_vla.configs": "configs"}


def _run(*cmd, cwd, **kw) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=300, **kw)


@pytest.mark.slow  # ~12 s: a wheel built and unpacked
def test_an_installed_wheel_carries_the_presets(tmp_path):
    """Build the wheel from a copy of the checkout, install it (no deps) into a fresh venv that sees this venv's
    packages through a .pth line, and use it from outside any checkout (~6 s: no build isolation, no pip in the venv)."""
    src = tmp_path / "src"
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in ("indgen_vla", "scenes", "policy_wrappers", "configs"):
        shutil.copytree(ROOT / name, src / name, ignore=ignore)
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    pip = (sys.executable, "-m", "pip", "--disable-pip-version-check", "-q")
    build = (*pip, "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-w", "dist", str(src))
    built = _run(*build, cwd=tmp_path)
    assert built.returncode == 0, built.stderr
    (wheel,) = (tmp_path / "dist").glob("indgen_vla-*.whl")

    venv = tmp_path / "venv"
    assert _run(sys.executable, "-m", "venv", "--without-pip", str(venv), cwd=tmp_path).returncode == 0
    python = str(venv / "bin" / "python")
    installed = _run(*pip, "--python", python, "install", "--no-deps", "--no-index", str(wheel), cwd=tmp_path)
    assert installed.returncode == 0, installed.stderr
    purelib = "import sysconfig; print(sysconfig.get_paths()['purelib'])"
    site = Path(_run(python, "-c", purelib, cwd=tmp_path).stdout.strip())
    (site / "deps_from_dev_venv.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")

    code = (
        "import json, indgen_vla, scenes.axes; from indgen_vla.core.resources import config_dir; "
        "from indgen_vla.app.engine.config import load_config_preset; "
        "print(json.dumps({'pkg': indgen_vla.__file__, 'dirs': {k: str(config_dir(k)) for k in ('paper', 'axes', 'real')}, "
        "'paper': sorted(p.name for p in config_dir('paper').glob('*.yaml')), "
        "'axes': sorted(p.name for p in config_dir('axes').glob('*.yaml')), "
        "'scene': load_config_preset('libero_object')['scene'], 'quick': scenes.axes.load_preset('quick')}))"
    )
    out = _run(python, "-c", code, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout)
    assert Path(got["pkg"]).parent == site / "indgen_vla"  # the installed wheel, not this checkout
    assert got["dirs"] == {k: str(site / "indgen_vla" / "configs" / k) for k in CONFIG_KINDS}
    assert (got["paper"], got["axes"]) == (PRESETS["paper"], PRESETS["axes"])
    assert got["scene"] == "libero_object" and got["quick"]["pick_y"] == {"max_level": 1}

    indgen = str(venv / "bin" / "indgen")
    helped = _run(indgen, "evaluate", "--config", "libero_object", "--help", cwd=tmp_path)
    assert helped.returncode == 0 and "--config" in helped.stdout, helped.stderr
    missing = _run(indgen, "evaluate", "--config", "nope", cwd=tmp_path)
    shipped = ", ".join(Path(p).stem for p in PRESETS["paper"])
    assert missing.returncode == 2, missing.stderr
    assert missing.stderr.strip() == f"error: --config nope: no such file; presets shipped: {shipped}"
    bad_axes = _run(indgen, "evaluate", "--scene", "stack", "--axis", "stack", "--policy", "standin:random",
                    "--axes-preset", "nope", "--out", str(tmp_path / "run"), cwd=tmp_path)  # fmt: skip
    assert (
        bad_axes.returncode == 2 and "unknown --axes-preset 'nope' (known: paper, quick)" in bad_axes.stderr
    ), bad_axes.stderr
    assert not (tmp_path / "run").exists()
