"""How ``indgen`` stops on Ctrl-C and SIGTERM: the one line each command prints (whether a re-run resumes), and
SIGTERM turned into the same orderly stop as Ctrl-C (a cluster scheduler's kill)."""

from __future__ import annotations

import argparse
import contextlib
import signal
import threading
from collections.abc import Iterator

from indgen_vla.core.errors import Terminated


def interrupted_message(args: argparse.Namespace) -> str:
    """The Ctrl-C line: only the commands that keep their progress say "resume" (``blockenv train`` writes its
    output only when complete, so a re-run starts over)."""
    rest = getattr(args, "rest", None) or []
    if args.command in ("evaluate", "demos"):
        return "interrupted: finished episodes are saved; re-run the same command to resume"
    if args.command == "train":
        return "interrupted: the last saved training state is kept; re-run the same command to resume"
    if args.command == "mimicgen":
        return "interrupted: every finished attempt is saved; re-run the same command to resume"
    if args.command == "certify":
        return ("interrupted: the levels finished so far are saved (a level in progress starts over); "
                "re-run the same command to resume")  # fmt: skip
    if args.command == "real":
        return "interrupted: every verdict shown as saved is kept; re-run 'indgen real record RUN'"
    if args.command == "blockenv" and rest[:1] == ["ablate"]:
        return ("interrupted: each finished ablation is saved in the results JSON (one in progress starts over); "
                "re-run the ablations not yet done")  # fmt: skip
    if args.command == "blockenv" and "--resume" in rest:
        return "interrupted: finished (method, seed) jobs are saved; re-run the same command to resume"
    name = " ".join([args.command] + rest[:1]) if args.command == "blockenv" and rest else args.command
    return f"interrupted: 'indgen {name}' keeps no partial output; re-run it to start over"


_SIGTERM_SEEN = threading.Event()  # set by ``sigterm_raises``'s handler until the next command starts


def by_sigterm(exc: BaseException) -> bool:
    """Whether an interrupt came from SIGTERM: ``Terminated``, or the plain ``KeyboardInterrupt`` a library raised in
    its place (Ray's ``ray.get`` turns any exception of a signal handler into one), so the exit is still 143."""
    return isinstance(exc, Terminated) or _SIGTERM_SEEN.is_set()


@contextlib.contextmanager
def sigterm_raises() -> Iterator[None]:
    """While a command runs, SIGTERM raises ``Terminated`` (a ``KeyboardInterrupt``) so that it stops as on Ctrl-C:
    workers closed, finished work saved, one line. A second SIGTERM is ignored so it cannot cut that shutdown short
    (SIGKILL still can). Signal handlers belong to the main thread: elsewhere this does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminate(signum, frame):
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        _SIGTERM_SEEN.set()
        raise Terminated

    _SIGTERM_SEEN.clear()
    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
