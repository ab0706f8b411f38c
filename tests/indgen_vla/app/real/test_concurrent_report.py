"""``indgen report RUN`` and ``indgen real status RUN`` while ``indgen real record`` writes the same run: every read
sees a consistent snapshot (never more than was journaled), nothing is corrupted, and when the recorder completes
the run and writes its own report beside ours, the files (plots included) are whole."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import pyarrow.parquet as pq
import pytest

from indgen_vla.app.cli import main
from indgen_vla.app.real.design import RealRun
from indgen_vla.app.real.status import status
from indgen_vla.app.real.store import read_journal, replay
from tests.indgen_vla.app.real.pty_session import ROOT

# 3 per level over levels 0..1 (6 counted) and 2 voids, recorded through the CLI, the last one writing the report
OUTCOMES = ["success", "failure:dropped", "void:e-stop", "success", "failure:misplaced", "void:camera bumped",
            "success", "success"]  # fmt: skip
WRITER = """\
import sys
from indgen_vla.app.cli import main
import time
for outcome in sys.argv[2:]:
    rc = main(["real", "record", sys.argv[1], "--outcome", outcome])
    if rc:
        sys.exit(rc)
    time.sleep(0.15)  # an operator is slower still; leaves the reports room to overlap several verdicts
"""


def _png_whole(path) -> bool:
    data = path.read_bytes()
    return data.startswith(b"\x89PNG\r\n\x1a\n") and data[-8:-4] == b"IEND"


@pytest.mark.slow  # ~8 s: a recording session read while it runs; test_dry_run covers the real-robot road by default
def test_report_and_status_while_recording(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["real", "plan", "--setup", "stack", "--levels", "0:1", "--episodes", "3", "--adaptive", "off",
                 "--policy", "pi05-droid", "--out", str(run)]) == 0  # fmt: skip
    writer = subprocess.Popen([sys.executable, "-c", WRITER, str(run), *OUTCOMES], cwd=tmp_path,
                              env={**os.environ, "PYTHONPATH": str(ROOT)}, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE)  # fmt: skip
    overlapped, seen = 0, []
    while writer.poll() is None:
        before = len(replay(read_journal(run), "stack").counted)
        st = status(RealRun.open(run))  # the journal, read while it grows
        rc = main(["report", str(run)])
        out, err = capsys.readouterr()
        after = len(replay(read_journal(run), "stack").counted)
        assert st["queued"] + sum(r["n"] for r in st["levels"]) >= 6
        if rc == 2:  # before the first verdict reached episodes.parquet
            assert err.strip().endswith("has no finished episodes yet; run or resume 'indgen evaluate' first")
            time.sleep(0.1)  # the recorder is still starting: leave it the CPU
            continue
        assert rc == 0, err
        summary = json.loads((run / "summary.json").read_text())
        n = sum(r["n"] for r in summary["axes"]["stack"]["levels"])
        assert n <= after and (writer.poll() is not None or n >= min(before, 1))  # a snapshot of the journal
        assert "## Real-robot run (`indgen real`)" in (run / "report.md").read_text()
        assert all(_png_whole(p) for p in (run / "plots").glob("*.png"))
        overlapped += writer.poll() is None
        seen.append(n)
    assert writer.wait() == 0, writer.stderr.read().decode()
    assert overlapped >= 2, "the reports did not overlap the recording; the test proved nothing"
    assert seen == sorted(seen)  # never went backwards

    entries = read_journal(run)
    assert len(entries) == len(OUTCOMES) and [e.seq for e in entries] == list(range(1, len(OUTCOMES) + 1))
    state = replay(entries, "stack")
    rows = pq.read_table(run / "episodes.parquet").to_pylist()
    assert {(r["level"], r["episode"]) for r in rows} == set(state.counted) and len(rows) == 6
    assert all(_png_whole(p) for p in (run / "plots").glob("*.png"))
    assert main(["report", str(run)]) == 0  # and the run reports as a whole, voids listed
    summary = json.loads((run / "summary.json").read_text())
    assert sum(r["n"] for r in summary["axes"]["stack"]["levels"]) == 6
    assert sum(r["successes"] for r in summary["axes"]["stack"]["levels"]) == OUTCOMES.count("success")
    assert "2, 0 episode(s) still pending a re-run" in (run / "report.md").read_text()
