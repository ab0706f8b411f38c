"""The data-regime study end to end in its --quick form (slow: several minutes of simulation)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[4]


@pytest.mark.slow
def test_study_quick_runs_end_to_end(tmp_path):
    work = tmp_path / "study"
    subprocess.run([sys.executable, "scripts/study_data_regimes.py", "--quick", "--work", str(work)],
                   check=True, cwd=ROOT, timeout=1800)  # fmt: skip
    text = (work / "data_regimes.md").read_text()
    assert "pick_y" in text and "scale" in text
    assert (work / "compare_pick_y" / "compare.json").exists()


def _script(name: str):
    import importlib.util

    sys.path.insert(0, str(ROOT / "scripts"))
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_study_clock_counts_every_invocation_even_a_killed_one(tmp_path):
    """The study's wall time is the sum over invocations, saved while running (a kill loses < one beat)."""
    import json
    import time

    study = _script("study_data_regimes")
    (tmp_path / "study_wall.json").write_text("[100.0]")  # the old format: only invocations that finished
    first = study.StudyClock(tmp_path, every_s=0.05)
    time.sleep(0.3)
    saved = json.loads((tmp_path / "study_wall.json").read_text())  # as a kill would leave it: no close()
    assert saved["unrecorded"] is True and saved["invocations"][0]["s"] == 100.0
    assert 0.1 <= saved["invocations"][1]["s"] <= 5
    first.close()
    second = study.StudyClock(tmp_path, every_s=60)
    total, n, unrecorded = second.total()
    second.close()
    assert n == 3 and unrecorded and 100.2 <= total <= 110
    doc = _script("study_regimes_doc")
    assert doc.wall_text(total, n, unrecorded).startswith("at least 1.7 min over 3 invocations")
    assert doc.wall_text(90.0, 1) == "1.5 min, on a 2-core CPU machine shared with other jobs."
