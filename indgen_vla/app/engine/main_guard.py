"""Refuse to start worker processes from a script's unguarded top level: each worker imports the script to start
(multiprocessing's forkserver), so it would run the script's evaluation again and die, and the run would end in
"worker process died" after the script's other top-level work (files written, runs imported) ran once per worker."""

from __future__ import annotations

import ast
import functools
import sys
import threading
from pathlib import Path

from indgen_vla.core.errors import ConfigError


def check_main_guard() -> None:
    """One ``ConfigError`` line when the main thread is running the ``__main__`` script's top level outside
    ``if __name__ == "__main__":``; a notebook, ``python -c``, ``python -m package`` and a guarded call pass."""
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    spec_name = getattr(getattr(main, "__spec__", None), "name", None) or ""
    if not path or spec_name == "__main__" or spec_name.endswith(".__main__"):
        return  # nothing the workers import (multiprocessing skips a package's __main__)
    frame = sys._current_frames().get(threading.main_thread().ident)
    while frame is not None and not (frame.f_code.co_name == "<module>" and frame.f_globals is vars(main)):
        frame = frame.f_back
    if frame is None:
        return  # the script's top level is done (an atexit hook, a thread left running)
    guards = guard_lines(str(Path(path).resolve()))
    if guards is None or any(first <= frame.f_lineno <= last for first, last in guards):
        return
    raise ConfigError(f"{Path(path).name} line {frame.f_lineno} starts indgen's worker processes from the script's "
                      "top level, and each worker imports the script to start (it would run again); put the call "
                      "under 'if __name__ == \"__main__\":' (docs/api.md)")  # fmt: skip


@functools.lru_cache(maxsize=8)
def guard_lines(path: str) -> tuple[tuple[int, int], ...] | None:
    """The line ranges of the file's top-level ``if`` blocks that test ``__name__`` (None: unreadable source)."""
    try:
        tree = ast.parse(Path(path).read_text(), path)
    except (OSError, SyntaxError, ValueError):
        return None
    return tuple(
        (node.lineno, node.end_lineno or node.lineno)
        for node in tree.body
        if isinstance(node, ast.If)
        and any(isinstance(n, ast.Name) and n.id == "__name__" for n in ast.walk(node.test))
    )
