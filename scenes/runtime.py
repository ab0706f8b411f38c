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
        data = pickle.dumps((op, arg), protocol=pickle.HIGHEST_PROTOCOL)
        try:
            self.proc.stdin.write(struct.pack("<I", len(data)) + data)
            self.proc.stdin.flush()
            head = self.proc.stdout.read(4)
            if len(head) < 4:
                raise EOFError
            (n,) = struct.unpack("<I", head)
            status, value = pickle.loads(self.proc.stdout.read(n))
        except (BrokenPipeError, EOFError, OSError):
            self.proc.wait(timeout=10)
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

    def close(self) -> None:
        if self.alive:
            try:
                self.request("close")
            except SceneError:
                pass
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
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
