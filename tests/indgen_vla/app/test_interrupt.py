"""SIGTERM (what a cluster scheduler or ``kill PID`` sends) stops ``indgen`` as Ctrl-C does: workers closed, finished
work kept, one line, exit 143; before, Python's default ended the process at once with no cleanup."""

from __future__ import annotations

import signal
import sys

import pytest

from indgen_vla.app.cli import main
from indgen_vla.app.interrupts import sigterm_raises
from indgen_vla.core.errors import EXIT_SIGTERM, Terminated
from indgen_vla.core.runs.records import JOURNAL
from tests.fixtures.kill import episodes_on_disk, stop_midway

ARGS = ["evaluate", "--policy", "standin:random", "--scene", "pick_place", "--axis", "pick_y", "--levels", "0:1",
        "--episodes", "4", "--workers", "2", "--max-steps", "8"]  # fmt: skip


def test_sigterm_closes_the_workers_and_says_one_line(tmp_path):
    """A ``kill PID`` of a run with two worker processes; that a stopped run resumes exactly is
    ``test_engine.test_resume_after_sigkill``'s (SIGTERM keeps the same journal, and flushes it too)."""
    out = tmp_path / "run"
    stopped = stop_midway([*ARGS, "--out", str(out)], signal.SIGTERM, lambda: episodes_on_disk(out) >= 1)
    assert stopped.returncode == EXIT_SIGTERM, stopped.stderr
    assert "Traceback" not in stopped.stderr  # the workers may not print one either
    assert stopped.stderr.strip().splitlines()[-1] == (
        "terminated (SIGTERM): finished episodes are saved; re-run the same command to resume"
    )
    assert stopped.survivors == []  # the fork server and its workers ended with the run
    assert 0 < episodes_on_disk(out) < 8
    assert (out / "episodes.parquet").is_file() and not (out / JOURNAL).exists()  # flushed on the way out


def test_a_terminated_command_exits_143_with_one_line(monkeypatch, capsys):
    import indgen_vla.app.cli as cli

    def terminated(args):
        raise Terminated

    monkeypatch.setattr(cli, "_resolve", lambda command: terminated)
    assert main(["certify", "--scene", "pick_place", "--axis", "pick_y"]) == EXIT_SIGTERM
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "terminated (SIGTERM): the levels finished so far are saved (a level in progress starts over); "
        "re-run the same command to resume"
    ]


def test_sigterm_raises_only_while_a_command_runs_and_a_second_one_is_ignored():
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(Terminated), sigterm_raises():
        signal.raise_signal(signal.SIGTERM)
    assert signal.getsignal(signal.SIGTERM) is before  # put back, so the handler does not outlive the command
    with pytest.raises(Terminated), sigterm_raises():
        try:
            signal.raise_signal(signal.SIGTERM)
        except Terminated:
            signal.raise_signal(signal.SIGTERM)  # in the shutdown: ignored, not a second Terminated
            raise


def test_ray_init_does_not_take_over_sigterm():
    """``ray.init`` installs a handler that exits with status 15 (and Ray's C++ one prints a stack dump)."""
    from indgen_vla.app.engine.ray_backend import _keeping_sigterm

    with sigterm_raises():
        ours = signal.getsignal(signal.SIGTERM)
        _keeping_sigterm(lambda: signal.signal(signal.SIGTERM, lambda *_: sys.exit(15)))
        assert signal.getsignal(signal.SIGTERM) is ours


@pytest.mark.slow  # 20-30 s: a local Ray cluster starts
def test_sigterm_stops_a_ray_run_as_a_local_one(tmp_path):
    pytest.importorskip("ray")
    out = tmp_path / "run"
    stopped = stop_midway([*ARGS, "--backend", "ray", "--out", str(out)], signal.SIGTERM,
                          lambda: episodes_on_disk(out) >= 1, timeout_s=180)  # fmt: skip
    assert stopped.returncode == EXIT_SIGTERM, stopped.stderr[-2000:]
    assert "SIGTERM received" not in stopped.stderr  # Ray's C++ handler's stack dump
    last = stopped.stderr.strip().splitlines()[-1]
    assert last.startswith("terminated (SIGTERM): finished episodes are saved")
    assert stopped.survivors == [] and 0 < episodes_on_disk(out) < 8


RAY_SIGTERM_SCRIPT = """
import os, signal, sys, threading
import ray
from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.app.engine.ray_cluster import join, keeping_sigterm
from indgen_vla.app.interrupts import by_sigterm, sigterm_raises
from indgen_vla.core.errors import Terminated
from tests.fixtures.resolved import evaluate

with sigterm_raises():  # a SIGTERM while ray.get waits
    join(1, keeping_sigterm)
    nap = ray.remote(num_cpus=0)(lambda: __import__("time").sleep(60))
    threading.Timer(3.0, os.kill, (os.getpid(), signal.SIGTERM)).start()
    try:
        ray.get(nap.remote())
    except KeyboardInterrupt as e:
        print("in ray.get:", by_sigterm(e), flush=True)
    keeping_sigterm(ray.shutdown)
with sigterm_raises():  # a SIGTERM once a Ray run's rollouts are done (its report being written)
    evaluate(EvalConfig.from_flat(policy="standin:random", scene="pick_place", axes=("pick_y",), levels="0",
             episodes=1, workers=1, max_steps=4, backend="ray", out=sys.argv[1]), quiet=True)
    try:
        signal.raise_signal(signal.SIGTERM)
    except Terminated:
        print("after the run: Terminated", flush=True)
"""


@pytest.mark.slow  # 20-40 s: two local Ray instances start
def test_sigterm_inside_ray_get_and_after_a_ray_run_still_stops_as_sigterm(tmp_path):
    """Two ways a Ray run lost SIGTERM's exit 143 and one line: ``ray.get`` re-raises the handler's ``Terminated`` as
    a plain KeyboardInterrupt (exit 130, "interrupted"), and ``ray.shutdown`` left SIGTERM at SIG_DFL under
    Python's handler, so a SIGTERM while the report was written killed the run (status -15, no line)."""
    import subprocess

    pytest.importorskip("ray")
    proc = subprocess.run([sys.executable, "-c", RAY_SIGTERM_SCRIPT, str(tmp_path / "run")], capture_output=True,
                          text=True, timeout=300)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.splitlines() == ["in ray.get: True", "after the run: Terminated"], proc.stderr[-2000:]
