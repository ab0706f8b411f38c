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
        "--axis", "fixture_x", "--levels", "0:1", "--episodes", "1", "--workers", "1", "--max-steps", "120"]  # fmt: skip


def _outcomes(run):
    df = pd.read_parquet(run / "episodes.parquet")
    cols = ["seed", "param", "success", "steps", "status", "failure", "progress"]
    df = df.astype(object).where(df.notna(), None)  # progress is missing (NaN) on RoboCasa; NaN != NaN
    return {(r.level, r.episode): tuple(getattr(r, c) for c in cols) for r in df.itertuples()}


def _cli(out):
    return [sys.executable, "-m", "indgen_vla.app.cli", *ARGS, "--out", str(out)]


@pytest.mark.slow  # 40 s (two RoboCasa runs and a kill); the default suite keeps test_engine's resume after SIGKILL
@needs_venv
def test_a_killed_robocasa_run_resumes_to_the_uninterrupted_episodes(placeholders, tmp_path):
    from indgen_vla.app.cli import main

    ref = tmp_path / "ref"
    assert main([*ARGS, "--out", str(ref)]) == 0  # the uninterrupted run, in this process
    killed = tmp_path / "killed"
    assert kill_midway(ARGS, killed, total=2, timeout_s=300) == 1  # level 0 done, level 1 not
    subprocess.run(_cli(killed), check=True, capture_output=True)
    want = _outcomes(ref)
    assert len(want) == 2 and _outcomes(killed) == want
    # the oracle closes the head within the limit: the step counts are the episodes' own, not the limit
    assert all(v[2] and v[3] < 120 for v in want.values()), want
