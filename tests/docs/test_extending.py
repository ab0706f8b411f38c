"""docs/extending.md's example is a script a user copies: it runs as it is and evaluates its policy."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[2]


def test_the_own_policy_example_runs_as_written(tmp_path):
    """The page's one Python block, saved as a file and run by the interpreter (its workers import it), writes a run
    of 4 episodes of its policy."""
    (code,) = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "extending.md").read_text(), re.S)
    (tmp_path / "descend.py").write_text(code)
    r = subprocess.run(
        [sys.executable, "descend.py"], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert r.returncode == 0, r.stderr[-3000:]
    eps = pd.read_parquet(tmp_path / "runs" / "descend" / "episodes.parquet")
    assert len(eps) == 4 and set(eps["status"]) == {"ok"} and set(eps["policy"]) == {"object:Descend"}
