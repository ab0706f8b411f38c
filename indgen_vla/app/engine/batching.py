"""One round of the local backend's coordinator: which workers have replied (``Ready``), how long a batched round
waits for the rest (``Gather``), and the actions for every waiting environment (``act``)."""

from __future__ import annotations

import selectors
import time

import numpy as np

from indgen_vla.core.protocol.interface import act_padded, validate_chunk


class Ready:
    """Which busy workers have a reply, through one selector kept for the whole run.

    ``multiprocessing.connection.wait`` (and ``Connection.poll``) build and register a new selector per call, once
    per worker and round; here the registered set changes only when the busy workers do. Workers without a pipe
    (the in-process worker) are asked by ``poll()``.
    """

    def __init__(self, pool: list) -> None:
        self._pool = pool
        self._sel = selectors.DefaultSelector()
        self._watched: set[int] = set()

    def _watch(self, workers: list[int]) -> None:
        """Register exactly ``workers``' pipes (a reply stays readable until received, so an idle or already
        ready worker must not stay registered while we wait for others)."""
        want = {w for w in workers if getattr(self._pool[w], "conn", None) is not None}
        if want == self._watched:
            return
        for w in self._watched - want:
            self._sel.unregister(self._pool[w].conn)
        for w in want - self._watched:
            self._sel.register(self._pool[w].conn, selectors.EVENT_READ, w)
        self._watched = want

    def _select(self, workers: list[int], timeout: float | None) -> list[int]:
        self._watch(workers)
        ready = [w for w in workers if w not in self._watched and self._pool[w].poll()]
        if self._watched and not ready:
            ready = [key.data for key, _ in self._sel.select(timeout)]
        return sorted(ready)

    def now(self, busy_workers: list[int]) -> list[int]:
        """The busy workers whose reply is already there (no waiting)."""
        return self._select(busy_workers, 0)

    def wait(self, busy_workers: list[int], timeout: float | None) -> list[int]:
        """Block until at least one busy worker replies (or ``timeout`` seconds pass: then [])."""
        return self._select(busy_workers, timeout)

    def gather(self, busy_workers: list[int], ready: list[int], window_s: float) -> list[int]:
        """``ready`` plus the busy workers that reply within ``window_s`` (all of them: no waiting at all)."""
        if window_s <= 0:
            return ready
        deadline = time.monotonic() + window_s
        ready = list(ready)
        rest = [w for w in busy_workers if w not in ready]
        while rest:
            left = deadline - time.monotonic()
            if left <= 0:
                break
            ready += self._select(rest, left)
            rest = [w for w in rest if w not in ready]
        return sorted(ready)

    def close(self) -> None:
        self._sel.close()


class Gather:
    """How long a round waits for the workers still stepping once the first has replied: up to half a forward
    (running of its recent cost). A forward costs the same at 1 or W rows, so acting on the first replies alone makes
    the rest wait a whole forward (pi0.5 on an H100: 2 forwards per cycle instead of 1). Per-episode instances
    (``per_episode``: a policy server's clients) are called from threads, so one round's calls overlap only if they
    start together; but a cheap in-process one (the oracle) is better called alone, beside the other workers' steps
    (gathering cost the oracle 25 % of its episodes/s on 2 workers), so they wait only for forwards of
    ``PER_EPISODE_MIN_S`` or more."""

    CAP_S = 0.5  # never hold replies longer than this
    PER_EPISODE_MIN_S = 0.005

    def __init__(self, per_episode: bool = False) -> None:
        self.cost = 0.0
        self.per_episode = per_episode

    def observe(self, seconds: float) -> None:
        self.cost = seconds if not self.cost else 0.8 * self.cost + 0.2 * seconds

    def window(self) -> float:
        if self.per_episode and self.cost < self.PER_EPISODE_MIN_S:
            return 0.0
        return min(self.CAP_S, 0.5 * self.cost)


def act(
    policies, spec, waiting, who: str, threads, pad_to: int = 1, dim: int = 7
) -> list[tuple[int, np.ndarray | Exception]]:
    """Actions for every waiting environment: (slot index, (T, 7) chunk) or (index, the exception).

    A batched policy always gets ``pad_to`` rows (the worker count; see ``act_padded``).
    """
    if not waiting:
        return []
    if spec.batched:
        try:
            chunks = act_padded(policies[0], [t.obs for _, t in waiting], pad_to, who, dim)
        except Exception as e:
            return [(i, e) for i, _ in waiting]
        return [(i, chunks[j]) for j, (i, _) in enumerate(waiting)]

    def one(item):
        i, t = item
        try:
            return i, validate_chunk(policies[i].act([t.obs]), 1, who, dim)[0]
        except Exception as e:
            return i, e

    return (
        list(threads.map(one, waiting))
        if threads is not None and len(waiting) > 1
        else [one(x) for x in waiting]
    )
