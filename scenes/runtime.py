"""The worker process of a scene family whose simulator runs in another Python environment (``scenes.external``).

Importing this is cheap (no simulator, no gymnasium): a family module names its ``ExternalRuntime`` at import time.
"""

from __future__ import annotations

import os
import pickle
import struct
import subprocess
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from indgen_vla.core.errors import EpisodeUnavailableError, SceneError

WORKER = Path(__file__).with_name("external_worker.py")
EXIT_WAIT_S = 10.0  # how long a worker may take to exit (its simulator's close) before it is killed


@dataclass(frozen=True)
class ExternalRuntime:
    """Where a family's simulator runs: ``python()`` finds the interpreter (raising the one-line set-up hint when
    it is missing), ``backend`` is the file the worker loads, ``env`` extra environment variables for it."""

    name: str
    python: Callable[[], Path]
    backend: Path
    env: Callable[[], dict[str, str]] = field(default=lambda: {})


class WorkerDied(SceneError):
    """The worker process exited (crash, kill, out of memory): the episode is retried on a fresh worker."""


class WorkerProcess:
    """One worker of an ``ExternalRuntime``: request/reply over its stdin/stdout."""

    def __init__(self, runtime: ExternalRuntime):
        self.runtime = runtime
        self.log = tempfile.TemporaryFile(prefix=f"indgen-{runtime.name}-")  # the worker's stderr, for errors
        env = {**os.environ, **runtime.env(), "PYTHONNOUSERSITE": "1"}
        env.pop("PYTHONPATH", None)  # the other venv must not see our packages (robosuite 1.4, numpy, ...)
        self.proc = subprocess.Popen(
            [str(runtime.python()), "-u", str(WORKER), str(runtime.backend)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.log, env=env, cwd=tempfile.gettempdir(),
        )  # fmt: skip

    @property
    def alive(self) -> bool:
        return self.proc.poll() is None

    def request(self, op: str, arg: Any = None) -> Any:
        """Send one request and return its value; ``SceneError`` carries the worker's one-line error
        (``EpisodeUnavailableError`` when the worker says the episode's seed rules the level out)."""
        try:
            self._send(op, arg)
            head = self.proc.stdout.read(4)
            if len(head) < 4:
                raise EOFError
            (n,) = struct.unpack("<I", head)
            status, value = pickle.loads(self.proc.stdout.read(n))
        except (BrokenPipeError, EOFError, OSError):
            self._reap()
            raise WorkerDied(
                f"the {self.runtime.name} worker (pid {self.proc.pid}) died with exit code {self.proc.returncode}"
                f"{self._last_log_line()}"
            ) from None
        if status == "unavailable":
            raise EpisodeUnavailableError(value)
        if status == "error":
            raise SceneError(value)
        return value

    def _last_log_line(self) -> str:
        try:
            self.log.seek(0)
            lines = [ln for ln in self.log.read().decode(errors="replace").splitlines() if ln.strip()]
        except OSError:
            return ""
        return f" (last output: {lines[-1].strip()[:200]})" if lines else ""

    def _send(self, op: str, arg: Any = None) -> None:
        data = pickle.dumps((op, arg), protocol=pickle.HIGHEST_PROTOCOL)
        self.proc.stdin.write(struct.pack("<I", len(data)) + data)
        self.proc.stdin.flush()

    def _reap(self) -> None:
        """Wait for the worker to exit; one slower than ``EXIT_WAIT_S`` (a simulator slow to close) is killed."""
        try:
            self.proc.wait(timeout=EXIT_WAIT_S)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()

    def close(self) -> None:
        """Ask the worker to exit and reap it, whatever state it is in: never raises for a slow or dead worker."""
        if self.alive:
            try:
                self._send("close")  # the worker exits without a reply
            except OSError:
                pass
            self._reap()
        for s in (self.proc.stdin, self.proc.stdout):
            try:
                s.close()
            except OSError:
                pass
        self.log.close()


def worker_versions(runtime: ExternalRuntime) -> dict[str, str]:
    """The worker environment's package versions (for the run manifest)."""
    w = WorkerProcess(runtime)
    try:
        return w.request("versions")
    finally:
        w.close()
