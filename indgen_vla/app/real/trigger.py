"""Optional episode triggers of ``indgen real record``: start each episode from the session; the operator judges.

The robot still runs in the user's own stack. ``EpisodeCommand`` runs the user's command once per episode (a
template filled with the episode's level, seed, instruction, ...; no shell), streams its output to the terminal,
keeps a log in ``RUN/real_logs/`` and returns its exit code and the video path it printed; the journal records
them beside the verdict. A check that the user's policy server answers (``indgen_vla.app.real_policy``, which may
import ``policy_wrappers``) plugs in through the same ``Trigger`` protocol, so this package stays policy-free.
"""

from __future__ import annotations

import os
import select
import shlex
import shutil
import signal
import string
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Protocol

from indgen_vla.core.errors import ConfigError, IndgenError

LOGS = "real_logs"
VIDEO_SUFFIXES = (".mp4", ".mkv", ".avi", ".webm", ".mov", ".h264")
STOP_GRACE_S = 5.0  # after Ctrl-C, how long the command may take to exit before it is killed


class TriggerError(IndgenError):
    """A trigger that could not start the episode (server unreachable, command missing); the operator decides."""


@dataclass(frozen=True)
class EpisodeContext:
    """What a trigger knows of the episode about to run (the fields of ``--episode-command`` templates)."""

    run: str
    axis: str
    task: str
    level: int
    param: float
    unit: str
    episode: int
    attempt: int  # 0 for the first run, n after n voids
    seed: int
    instruction: str
    placement: str
    policy: str
    video: str  # the --video-pattern path for this episode, or ""

    def env(self) -> dict[str, str]:
        """The same fields as ``INDGEN_*`` environment variables for the command."""
        return {
            f"INDGEN_{k.upper()}": f"{v:g}" if isinstance(v, float) else str(v)
            for k, v in asdict(self).items()
        }


FIELDS = tuple(EpisodeContext.__dataclass_fields__)


def check_template(template: str, what: str, fields: tuple[str, ...] = FIELDS) -> None:
    """Raise a one-line ``ConfigError`` when ``template`` uses a field outside ``fields`` or bad braces."""
    try:
        names = [f for _, f, _, _ in string.Formatter().parse(template) if f is not None]
    except ValueError as e:
        raise ConfigError(f"{what} {template!r}: {e}; write braces as {{{{ and }}}}") from None
    for name in names:
        base = name.split(".")[0].split("[")[0]
        if base not in fields:
            import difflib

            close = difflib.get_close_matches(base, fields, 1)
            hint = f" (did you mean {{{close[0]}}}?)" if close else ""
            raise ConfigError(
                f"{what} {template!r}: unknown field {{{name}}}{hint}; fields: {', '.join(fields)}"
            )


def fill(template: str, values: dict, what: str) -> str:
    """``template.format(**values)`` with a one-line error for a bad format spec."""
    try:
        return template.format(**values)
    except (ValueError, KeyError, IndexError, AttributeError) as e:
        raise ConfigError(f"{what} {template!r}: cannot fill it ({type(e).__name__}: {e})") from None


def video_in(output: str) -> str:
    """The video path a command printed: its last ``video=PATH`` line, else its last line that is a video path."""
    lines = [s.strip() for s in output.splitlines()]
    tagged = [s[len("video=") :].strip() for s in lines if s.startswith("video=")]
    bare = [s for s in lines if s and " " not in s and s.lower().endswith(VIDEO_SUFFIXES)]
    return (tagged or bare or [""])[-1]


class Trigger(Protocol):
    """Something the session runs when the operator starts an episode; it never judges success."""

    name: str

    def describe(self, ctx: EpisodeContext) -> str:
        """The line shown in the episode block (what will happen when the operator presses Enter)."""

    def start(self, ctx: EpisodeContext, write: Callable[[str], None]) -> dict:
        """Start the episode; return what the journal keeps (raise ``TriggerError`` when it cannot start)."""

    def close(self) -> None: ...


@dataclass(frozen=True)
class EpisodeCommand:
    """``--episode-command``: the user's per-episode command, e.g. ``python eval.py --seed {seed}``.

    The template is split like a shell line (``shlex``) and each word is then filled in, so ``{instruction}``
    stays one argument whatever it contains; no shell runs (write ``sh -c '...'`` to get one).
    It runs in the directory ``indgen real record`` was started from.
    """

    template: str
    run_dir: str
    name: str = "command"

    def __post_init__(self) -> None:
        try:
            words = shlex.split(self.template)
        except ValueError as e:
            raise ConfigError(f"--episode-command {self.template!r}: {e}; check its quotes") from None
        if not words:
            raise ConfigError("--episode-command is empty; give the command that runs one episode")
        for w in words:
            check_template(w, "--episode-command")
        program = words[0]
        if "{" not in program and shutil.which(program) is None:
            raise ConfigError(f"--episode-command: program {program!r} not found on PATH; give its full path")

    def argv(self, ctx: EpisodeContext) -> list[str]:
        values = asdict(ctx)
        return [fill(w, values, "--episode-command") for w in shlex.split(self.template)]

    def describe(self, ctx: EpisodeContext) -> str:
        return f"  run    : {shlex.join(self.argv(ctx))}"

    def log_path(self, ctx: EpisodeContext) -> Path:
        return Path(self.run_dir) / LOGS / f"L{ctx.level}_e{ctx.episode}_a{ctx.attempt}.log"

    def start(self, ctx: EpisodeContext, write: Callable[[str], None]) -> dict:
        """Run the command to its end, its output shown as it comes and kept in the log. Ctrl-C reaches the
        command (it shares the terminal's process group); it gets STOP_GRACE_S to exit, then it is killed."""
        argv = self.argv(ctx)
        log = self.log_path(ctx)
        log.parent.mkdir(parents=True, exist_ok=True)
        t0 = time.monotonic()
        chunks: list[bytes] = []
        with log.open("ab") as f, _sigint_noted() as interrupted:
            f.write(f"# {time.strftime('%Y-%m-%dT%H:%M:%S')} $ {shlex.join(argv)}\n".encode())
            try:  # stdin stays the terminal: an eval script may ask the operator things itself
                proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                        env={**os.environ, **ctx.env()})  # fmt: skip
            except OSError as e:
                raise TriggerError(
                    f"--episode-command could not start {argv[0]!r}: {e.strerror or e}"
                ) from None
            try:
                _relay(proc, f, write, interrupted, chunks)
            except BaseException:  # SIGTERM to the session (``Terminated``) or a fault of ours: the robot's
                _stop(proc)  # command must not run on with nobody watching it, orphaned
                raise
            rc = proc.wait()
            proc.stdout.close()
            f.write(f"# exit {rc}\n".encode())
        output = b"".join(chunks).decode(errors="replace")
        if output and not output.endswith("\n"):
            write("\n")
        return {"argv": argv, "exit_code": rc, "seconds": round(time.monotonic() - t0, 3),
                "log": str(log.relative_to(self.run_dir)), "video": video_in(output),
                **({"interrupted": True} if interrupted else {})}  # fmt: skip

    def close(self) -> None:
        pass


def _relay(proc: subprocess.Popen, log, write: Callable[[str], None], interrupted: list[float],
           chunks: list[bytes]) -> None:  # fmt: skip
    """Copy the command's output to the log, ``write`` and ``chunks`` until it ends; kill it ``STOP_GRACE_S`` after
    a Ctrl-C (``interrupted``) if it has not exited by then."""
    assert proc.stdout is not None
    fd = proc.stdout.fileno()
    while True:
        if interrupted and time.monotonic() - interrupted[0] > STOP_GRACE_S and proc.poll() is None:
            proc.send_signal(signal.SIGKILL)
        if not select.select([fd], [], [], 0.2)[0]:
            continue
        data = os.read(fd, 65536)
        if not data:
            return
        chunks.append(data)
        log.write(data)
        log.flush()
        write(data.decode(errors="replace"))


def _stop(proc: subprocess.Popen) -> None:
    """SIGTERM, then SIGKILL after ``STOP_GRACE_S``: the grace Ctrl-C gives a command to exit on its own."""
    if proc.poll() is not None:
        return
    proc.terminate()
    try:
        proc.wait(timeout=STOP_GRACE_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


@contextmanager
def _sigint_noted() -> Iterator[list[float]]:
    """While a command runs, Ctrl-C is noted (the list gets its time) instead of raising in this process."""
    noted: list[float] = []
    if threading.current_thread() is not threading.main_thread():
        yield noted
        return
    old = signal.signal(signal.SIGINT, lambda *_: noted.append(time.monotonic()))
    try:
        yield noted
    finally:
        signal.signal(signal.SIGINT, old)


def summary_line(info: dict) -> str:
    """One line after the triggers ran: what the command returned, what the policy check found."""
    parts = []
    if "policy" in info:
        p = info["policy"]
        parts.append(f"policy {p['spec']} answered and was reset ({p['seconds']:.1f} s)")
    if "command" in info:
        c = info["command"]
        how = "was stopped (Ctrl-C)" if c.get("interrupted") else f"exited {c['exit_code']}"
        parts.append(f"episode command {how} after {c['seconds']:.1f} s"
                     + (f"; video {c['video']}" if c["video"] else "") + f"; log {c['log']}")  # fmt: skip
    return "; ".join(parts)


def echo(text: str) -> None:
    """Write a command's output straight to the terminal."""
    sys.stdout.write(text)
    sys.stdout.flush()
