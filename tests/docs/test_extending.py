"""docs/extending.md's examples are scripts a user copies: each runs as it is (its own policy, its own scene)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pandas as pd

from tests.docs.fences import code_blocks

ROOT = Path(__file__).resolve().parents[2]


def _blocks() -> list[str]:
    """The page's Python blocks: its own policy, then its own scene."""
    blocks = code_blocks((ROOT / "docs" / "extending.md").read_text(), "python")
    assert len(blocks) == 2, len(blocks)
    return blocks


def test_the_own_policy_example_runs_as_written(tmp_path):
    """The page's first Python block, saved as a file and run by the interpreter (its workers import it), writes a run
    of 4 episodes of its policy."""
    code = _blocks()[0]
    (tmp_path / "descend.py").write_text(code)
    r = subprocess.run(
        [sys.executable, "descend.py"], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert r.returncode == 0, r.stderr[-3000:]
    eps = pd.read_parquet(tmp_path / "runs" / "descend" / "episodes.parquet")
    assert len(eps) == 4 and set(eps["status"]) == {"ok"} and set(eps["policy"]) == {"object:Descend"}


def test_the_own_scene_example_registers_and_evaluates_its_family(tmp_path):
    """The page's second block, saved and run as a script: its family is registered, resolved by name and built in
    the workers (which import the script), and the oracle's 4 episodes land in the run."""
    (tmp_path / "near_pick.py").write_text(_blocks()[1])
    r = subprocess.run(
        [sys.executable, "near_pick.py"], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert r.returncode == 0, r.stderr[-3000:]
    eps = pd.read_parquet(tmp_path / "runs" / "near_pick" / "episodes.parquet")
    assert len(eps) == 4 and set(eps["status"]) == {"ok"} and set(eps["scene"]) == {"near_pick"}
    assert set(eps["level"]) == {0, 1} and eps["success"].all()  # the tabletop oracle solves its levels
