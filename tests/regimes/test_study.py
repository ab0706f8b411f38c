"""The data-regime study end to end in its --quick form (slow: several minutes of simulation)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_study_quick_runs_end_to_end(tmp_path):
    work = tmp_path / "study"
    subprocess.run([sys.executable, "scripts/study_data_regimes.py", "--quick", "--work", str(work)],
                   check=True, cwd=ROOT, timeout=1800)  # fmt: skip
    text = (work / "data_regimes.md").read_text()
    assert "pick_y" in text and "scale" in text
    assert (work / "compare_pick_y" / "compare.json").exists()
