"""Waiting out a policy server outage: exponential backoff with jitter under a total patience.

A connection fault (``PolicyConnectionError``) is not an episode failure: the engine pauses the episode,
waits, and re-runs it from its seed once the server answers again. ``Outage`` holds the shared clock.
"""

from __future__ import annotations

import random
import time
from dataclasses import dataclass, field

from indgen_vla.core.errors import ServerUnreachableError

BACKOFF_START_S = 1.0
BACKOFF_CAP_S = 30.0
DEFAULT_PATIENCE_S = 600.0


def _clock(seconds: float) -> str:
    s = max(0, int(round(seconds)))
    return f"{s // 60}:{s % 60:02d}"


@dataclass
class Outage:
    """Backoff state shared by every worker of one run (they all talk to the same server)."""

    patience_s: float = DEFAULT_PATIENCE_S
    start_s: float = BACKOFF_START_S
    cap_s: float = BACKOFF_CAP_S
    since: float | None = None  # monotonic time of the first fault of the current outage
    last_ok: float = 0.0  # monotonic time of the last successful call
    last_error: str = ""
    rng: random.Random = field(default_factory=random.Random)

    def ok(self) -> bool:
        """Record a successful call; True when this ends an outage."""
        ended = self.since is not None
        self.since, self.last_ok = None, time.monotonic()
        return ended

    def fault(self, n: int, error: str) -> float:
        """The delay before retry ``n`` (1-based) of one episode; raises when patience is spent."""
        now = time.monotonic()
        if self.since is None:
            self.since = now
        self.last_error = error
        left = self.left(now)
        if left <= 0:
            raise ServerUnreachableError(
                f"policy server unreachable for {now - self.since:.0f} s (--server-patience "
                f"{self.patience_s:g}): {error}; finished episodes are saved, re-run the same command to resume"
            )
        delay = min(self.cap_s, self.start_s * 2 ** (n - 1)) * self.rng.uniform(0.75, 1.25)
        return min(delay, left)

    def left(self, now: float | None = None) -> float:
        """Seconds of patience left in the current outage."""
        if self.since is None:
            return self.patience_s
        return self.patience_s - ((time.monotonic() if now is None else now) - self.since)

    def describe(self, wake: float) -> str:
        """The progress line while waiting, e.g. ``server unreachable, retrying in 4 s (patience 9:30 left)``."""
        now = time.monotonic()
        return (
            f"[yellow]server unreachable, retrying in {max(0.0, wake - now):.0f} s "
            f"(patience {_clock(self.left(now))} left)[/]"
        )
