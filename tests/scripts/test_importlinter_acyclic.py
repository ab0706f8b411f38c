"""scripts/importlinter_acyclic.py: the ``acyclic`` import-linter contract that ``make lint`` runs."""

import subprocess
import sys
import textwrap
from pathlib import Path

import grimp
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(
    0, str(ROOT)
)  # ``scripts`` is a namespace package at the repository root, as lint-imports sees it
from scripts.importlinter_acyclic import find_cycles  # noqa: E402

CONFIG = """\
[importlinter]
root_packages =
    cyc
contract_types =
    acyclic: scripts.importlinter_acyclic.AcyclicContract

[importlinter:contract:no-cycles]
name = no cycles
type = acyclic
"""


def _package(tmp_path: Path, files: dict[str, str]) -> Path:
    for name, text in {"__init__.py": "", **files}.items():
        path = tmp_path / "cyc" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text))
    return tmp_path


def _cycles(tmp_path: Path, files: dict[str, str], monkeypatch) -> list[str]:
    monkeypatch.syspath_prepend(str(_package(tmp_path, files)))
    return find_cycles(grimp.build_graph("cyc", cache_dir=None))


def _lint(project: Path) -> subprocess.CompletedProcess:
    (project / ".importlinter").write_text(CONFIG)
    env = {"PYTHONPATH": f"{ROOT}:{project}", "PATH": "/usr/bin:/bin"}
    code = "import sys; from importlinter.cli import lint_imports_command; sys.exit(lint_imports_command())"
    return subprocess.run(
        [sys.executable, "-c", code, "--no-cache"],
        cwd=project,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_a_function_level_import_closes_a_cycle(tmp_path, monkeypatch):
    cycles = _cycles(
        tmp_path,
        {
            "a.py": "from cyc.b import g\n",
            "b.py": "def g():\n    from cyc.a import x\n",
            "c.py": "import cyc.a\n",
        },
        monkeypatch,
    )
    assert cycles == ["cyc.a -> cyc.b (line 1 of cyc.a) -> cyc.a (line 2 of cyc.b)"]


@pytest.mark.parametrize("statement", ["from cyc import b\n", "from . import b\n"])
def test_reading_the_package_namespace_imports_the_package(tmp_path, monkeypatch, statement):
    """``from pkg import submodule`` runs and reads ``pkg/__init__``: a cycle when that ``__init__`` imports the
    importer (grimp itself records only ``pkg.submodule``)."""
    files = {"__init__.py": "from cyc.a import x\n", "a.py": statement + "x = 1\n", "b.py": ""}
    cycles = _cycles(tmp_path, files, monkeypatch)
    assert cycles == ["cyc -> cyc.a (line 1 of cyc) -> cyc (line 1 of cyc.a)"]


def test_importing_the_submodule_itself_is_acyclic(tmp_path, monkeypatch):
    files = {"__init__.py": "from cyc.a import x\n", "a.py": "import cyc.b as b\nx = 1\n", "b.py": ""}
    assert _cycles(tmp_path, files, monkeypatch) == []


def test_lint_imports_fails_on_a_cycle_and_passes_once_it_is_broken(tmp_path):
    project = _package(tmp_path, {"a.py": "from cyc.b import g\n", "b.py": "from cyc.a import x\ng = 1\n"})
    broken = _lint(project)
    assert broken.returncode == 1, broken.stdout + broken.stderr
    assert "cyc.a -> cyc.b (line 1 of cyc.a) -> cyc.a (line 1 of cyc.b)" in " ".join(broken.stdout.split())
    (project / "cyc" / "b.py").write_text("g = 1\n")
    kept = _lint(project)
    assert kept.returncode == 0 and "1 kept, 0 broken" in kept.stdout, kept.stdout + kept.stderr


def test_the_repository_has_no_import_cycles():
    cycles = find_cycles(grimp.build_graph("indgen_vla", "scenes", "policy_wrappers", cache_dir=None))
    assert cycles == [], "\n".join(cycles)
