"""A RoboCasa365 run killed with SIGKILL resumes to exactly the episodes an uninterrupted run writes: level k's
episode i rebuilds T0's kitchen from its seed in a fresh worker, so nothing depends on which process ran it."""

from __future__ import annotations

import subprocess
import sys

import pandas as pd
import pytest

from tests.fixtures.kill import kill_midway
from tests.scenes.robocasa.test_robocasa import needs_venv

ARGS = ["evaluate", "--policy", "standin:oracle", "--scene", "robocasa", "--task", "CloseStandMixerHead",
        "--axis", "fixture_x", "--levels", "0:1", "--episodes", "2", "--workers", "1", "--max-steps", "120"]  # fmt: skip


def _outcomes(run):
    df = pd.read_parquet(run / "episodes.parquet")
    cols = ["seed", "param", "success", "steps", "status", "failure", "progress"]
    return {(r.level, r.episode): tuple(getattr(r, c) for c in cols) for r in df.itertuples()}


def _cli(out):
    return [sys.executable, "-m", "indgen_vla.cli", *ARGS, "--out", str(out)]


@needs_venv
@pytest.mark.slow  # three cold RoboCasa runs (~40 s); the worker's death and retry: test_robocasa.py (default)
def test_a_killed_robocasa_run_resumes_to_the_uninterrupted_episodes(placeholders, tmp_path):
    ref = tmp_path / "ref"
    subprocess.run(_cli(ref), check=True, capture_output=True)
    killed = tmp_path / "killed"
    assert 0 < kill_midway(ARGS, killed, total=4, timeout_s=300) < 4
    subprocess.run(_cli(killed), check=True, capture_output=True)
    want = _outcomes(ref)
    assert len(want) == 4 and _outcomes(killed) == want
    # the oracle closes the head within the limit: the step counts are the episodes' own, not the limit
    assert all(v[2] and v[3] < 120 for v in want.values()), want
