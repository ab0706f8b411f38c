"""A small exception hierarchy: every user-facing failure is an ``IndgenError`` with one clear line."""

from __future__ import annotations


class IndgenError(Exception):
    """Base class; the CLI prints ``error: <message>`` and exits non-zero instead of a traceback."""

    exit_code = 2


class ConfigError(IndgenError, ValueError):
    """A bad argument, preset or level range: the message names the value and the fix."""


class UnknownNameError(ConfigError, KeyError):
    """An unregistered scene, axis, policy or task; carries close matches for "did you mean"."""

    def __init__(self, kind: str, name: str, choices: list[str] | tuple[str, ...], note: str = ""):
        import difflib

        self.kind, self.name, self.choices = kind, name, sorted(choices)
        close = difflib.get_close_matches(name, self.choices, n=3, cutoff=0.5)
        hint = f"did you mean {', '.join(repr(c) for c in close)}?" if close else ""
        listing = f"known: {', '.join(self.choices)}" if self.choices else "none registered"
        head = (
            f"unknown {kind} {name!r}; {hint} ({listing})" if hint else f"unknown {kind} {name!r} ({listing})"
        )
        super().__init__(head + (f"; {note}" if note else ""))

    def __str__(self) -> str:  # KeyError would otherwise repr() the message
        return self.args[0]


class RunDirError(IndgenError):
    """A run directory that is missing, corrupt, unwritable or made by a different plan."""


class PolicyError(IndgenError):
    """A policy that cannot be loaded, reached, or returned a malformed action."""


class EpisodeErrorsWarning(UserWarning):
    """``indgen_vla.evaluate`` finished with episodes that ended ``error`` (the command's exit 3): a re-run retries
    them; ``warnings.simplefilter("error", EpisodeErrorsWarning)`` makes it raise."""


# Exit codes of ``indgen evaluate`` (docs/cli.md "Exit codes"): 0 every planned episode ok, 2 bad input,
# EXIT_EPISODE_ERRORS the run finished but some episodes ended ``error`` (a re-run retries them), EXIT_STOPPED the run
# stopped early (policy server unreachable past --server-patience; Ctrl-C gives the conventional 130),
# EXIT_UNAVAILABLE every episode that could run finished, and some were ruled out by their level (``unavailable``:
# their initial state cannot hold it; nothing to retry).
EXIT_EPISODE_ERRORS = 3
EXIT_STOPPED = 4
EXIT_UNAVAILABLE = 6
EXIT_SIGTERM = 143  # 128 + SIGTERM, as a shell reports a process that SIGTERM ended


class Terminated(KeyboardInterrupt):
    """SIGTERM (a cluster scheduler's stop, ``kill PID``) raised in the main thread, so a run shuts its workers down
    and keeps what it finished exactly as on Ctrl-C; Python's default would end the process with no cleanup,
    leaving workers and ``pip`` children running on."""


class PolicyConnectionError(PolicyError):
    """A fault of the connection to a policy server (refused, reset, closed mid-reply, timed out, HTTP 5xx),
    not of the episode: the engine pauses and reconnects instead of recording an ``error`` episode."""

    exit_code = EXIT_STOPPED


class ServerUnreachableError(PolicyConnectionError):
    """The policy server stayed unreachable past ``--server-patience``; finished episodes are on disk."""


class ClusterStalledError(IndgenError):
    """No episode could run on the Ray cluster for ``--server-patience`` (no room for a simulator or policy actor);
    finished episodes are on disk."""

    exit_code = EXIT_STOPPED


class SceneError(IndgenError):
    """A scene that cannot be built or stepped."""


class EpisodeUnavailableError(SceneError):
    """A level this episode's initial state cannot hold (a RoboCasa kitchen too narrow for pick_x's levels): its
    seed decides it, so the engine records the episode once as an error, never retried."""


class InfeasibleLevelError(IndgenError):
    """A level the privileged oracle does not certify (Assumption 2 of the paper)."""
