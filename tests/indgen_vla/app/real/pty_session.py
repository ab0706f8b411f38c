"""Drive a command in a pseudo-terminal the way a person at a keyboard does: wait for text, type a line."""

from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[4]
ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


class PtySession:
    """A child process whose stdin, stdout and stderr are a terminal (``os.openpty``)."""

    def __init__(self, argv: list[str], cwd: Path, rows: int = 50, cols: int = 120):
        import fcntl
        import struct
        import termios

        self.master, slave = os.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", rows, cols, 0, 0))
        env = {
            **os.environ,
            "PYTHONPATH": str(ROOT),
            "TERM": "xterm",
            "COLUMNS": str(cols),
            "PYTHONUNBUFFERED": "1",
        }
        self.proc = subprocess.Popen(argv, stdin=slave, stdout=slave, stderr=slave, cwd=cwd, env=env,
                                     start_new_session=True, close_fds=True)  # fmt: skip
        os.close(slave)
        self.transcript = ""  # everything the terminal showed, typed echo included
        self._seen = 0

    def _read(self, timeout: float) -> bool:
        r, _, _ = select.select([self.master], [], [], timeout)
        if not r:
            return False
        try:
            data = os.read(self.master, 65536)
        except OSError:  # EIO: the child closed the terminal
            return False
        if not data:
            return False
        self.transcript += ANSI.sub("", data.decode(errors="replace")).replace("\r\n", "\n")
        return True

    def expect(self, text: str, timeout: float = 20.0) -> str:
        """Wait until ``text`` appears after what was already consumed; return the output up to it."""
        deadline = time.monotonic() + timeout
        while True:
            at = self.transcript.find(text, self._seen)
            if at >= 0:
                chunk = self.transcript[self._seen : at + len(text)]
                self._seen = at + len(text)
                return chunk
            left = deadline - time.monotonic()
            if left <= 0 or (
                not self._read(min(left, 0.5)) and self.proc.poll() is not None and not self._read(0)
            ):
                raise AssertionError(
                    f"did not see {text!r}; the terminal showed:\n{self.transcript[self._seen :]}"
                )

    def type(self, line: str) -> None:
        """Type a line and press Enter."""
        os.write(self.master, (line + "\n").encode())

    def kill9(self) -> None:
        os.killpg(self.proc.pid, signal.SIGKILL)
        self.proc.wait(timeout=10)
        self.close()

    def wait(self, timeout: float = 20.0) -> int:
        deadline = time.monotonic() + timeout
        while self.proc.poll() is None and time.monotonic() < deadline:
            self._read(0.2)
        while self._read(0.05):
            pass
        rc = self.proc.wait(timeout=max(0.1, deadline - time.monotonic()))
        self.close()
        return rc

    def close(self) -> None:
        try:
            os.close(self.master)
        except OSError:
            pass


def indgen(*args: str) -> list[str]:
    return [sys.executable, "-m", "indgen_vla.app.cli", *args]
