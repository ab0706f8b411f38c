"""The workers' fork server leaves with ``os._exit`` when its coordinator has gone: it holds the simulator's imports
and caches, whose interpreter teardown kept a piped caller waiting 0.6-0.9 s after ``indgen`` itself had exited.

The last module the fork server preloads (``local._context``); importing it anywhere else does nothing."""

from __future__ import annotations

import atexit
import os
import sys


def _in_fork_server() -> bool:
    """Whether this import runs inside ``multiprocessing.forkserver.main`` (its preload), not in a coordinator."""
    frame = sys._getframe()
    while frame is not None:
        code = frame.f_code
        if code.co_name == "main" and code.co_filename.endswith(
            os.path.join("multiprocessing", "forkserver.py")
        ):
            return True
        frame = frame.f_back
    return False


if _in_fork_server():  # atexit runs first what registered last: nothing of the teardown after this
    atexit.register(os._exit, 0)
