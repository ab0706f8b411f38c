"""The worker process of an external scene family (``scenes.runtime``): closing one never raises, whatever it does."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from scenes.runtime import ExternalRuntime, WorkerProcess

SLOW_BACKEND = """
import os
import time


class Env:
    def close(self):
        os.closerange(3, 1024)  # the reply pipe closes first (as at interpreter shutdown)...
        time.sleep(30)  # ...and the simulator is slow to let go: the worker exits long after


def build(config):
    return Env()


def versions():
    return {"slow": "1"}
"""


def test_closing_a_worker_slow_to_exit_kills_it_and_raises_nothing(tmp_path, monkeypatch):
    """A worker whose simulator takes longer than ``EXIT_WAIT_S`` to close after "close" (a RoboCasa env, under
    load) is killed: ``TimeoutExpired`` used to escape ``close`` from the wait after the pipe closed, and a worker
    that kept its pipe open held ``close`` until it exited."""
    import scenes.runtime

    monkeypatch.setattr(scenes.runtime, "EXIT_WAIT_S", 0.5)
    backend = tmp_path / "slow_backend.py"
    backend.write_text(SLOW_BACKEND)
    w = WorkerProcess(ExternalRuntime("slow", lambda: Path(sys.executable), backend))
    assert w.request("versions") == {"slow": "1"}
    w.request("build", {})
    started = time.monotonic()
    w.close()  # raises nothing
    assert not w.alive and time.monotonic() - started < 10
