"""The local backend's coordinator loop: which episode runs in which slot, its retries and connection-fault pauses,
and one round (collect replies, reset policies for new episodes, act, send the next chunk slices).

Slot ``i`` is lane ``i // W`` of worker ``i % W`` (one lane unless pipelined).
"""

from __future__ import annotations

import time
from collections import defaultdict, deque
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

from indgen_vla.app.engine import timing
from indgen_vla.app.engine.batching import Gather, Ready, act
from indgen_vla.app.engine.reconnect import Outage
from indgen_vla.app.engine.rollout import RunMeta, Transition, _describe, make_record
from indgen_vla.core.errors import PolicyConnectionError
from indgen_vla.core.protocol.plan import EpisodeJob
from indgen_vla.core.runs.records import EpisodeRecord

POISON_FAULTS = 5  # after this many, a connection drop that only this episode triggers is an episode fault


@dataclass
class _Slot:
    job: EpisodeJob
    attempt: int = 0
    fresh: bool = True
    last_error: str = ""
    acts: int = 0  # successful policy calls in the current try of the episode
    faults: int = 0  # connection faults of this episode in the current outage (backoff exponent)
    wake: float = 0.0  # > 0: paused by a connection fault until this monotonic time
    fault_at: float = 0.0  # when the last connection fault happened
    fault_acts: int = -1  # ``acts`` at the last connection fault
    poison: int = 0  # consecutive faults at the same point while the server answered others


@dataclass(frozen=True)
class Limits:
    """What a run fixes for every episode: retries, the executed slice of a chunk, the action size."""

    max_retries: int
    replan_steps: int
    action_dim: int


class JobQueue:
    """The episodes still to start, served so that a slot keeps its scene.

    A slot's environment holds one cell's scene (task, axis, level: ``EnvRunner`` rebuilds it when the cell
    changes, 0.5-3 s). A slot takes the next episode of the cell it holds while that cell has any, else the first
    episode of the cell the fewest slots are running (plan order breaks ties). W workers then build about one scene
    per cell, where taking the plan's order would spread every cell over all W (W builds per cell). Seeds belong
    to episodes, so which slot runs an episode changes no outcome.
    """

    def __init__(self, jobs: Sequence[EpisodeJob], held: dict[int, tuple] | None = None) -> None:
        self._cells: dict[tuple, deque[EpisodeJob]] = {}
        for job in jobs:
            self._cells.setdefault(cell_of(job), deque()).append(job)
        self._running: dict[tuple, int] = defaultdict(int)  # cell -> slots running one of its episodes
        self._held: dict[int, tuple] = dict(held or {})  # slot -> the cell its environment holds
        for cell in self._held.values():
            self._running[cell] += 1

    def __bool__(self) -> bool:
        return bool(self._cells)

    def take(self, slot: int) -> EpisodeJob | None:
        """The next episode for ``slot``, whose previous one (if any) is done; None when the queue is empty."""
        held = self._held.pop(slot, None)
        if held is not None:
            self._running[held] -= 1
        if not self._cells:
            return None
        cell = held if held in self._cells else min(self._cells, key=self._running.__getitem__)
        queue = self._cells[cell]
        job = queue.popleft()
        if not queue:
            del self._cells[cell]
        self._held[slot] = cell
        self._running[cell] += 1
        return job

    def put_back(self, slot: int, job: EpisodeJob) -> None:
        """``slot`` is gone (a Ray actor that died) with ``job`` unfinished: the job runs next in its cell."""
        self.release(slot)
        self._cells.setdefault(cell_of(job), deque()).appendleft(job)

    def release(self, slot: int) -> None:
        """``slot`` is gone: its environment no longer counts for the cell it held."""
        held = self._held.pop(slot, None)
        if held is not None:
            self._running[held] -= 1


def cell_of(job: EpisodeJob) -> tuple:
    """What an environment is built for (``EnvRunner._env_for``'s key)."""
    return (job.task, job.axis, job.level)


def first_jobs(jobs: Sequence[EpisodeJob], n: int) -> list[EpisodeJob]:
    """The episodes slots 0..n-1 start with (``Slots`` starts them in that order): what early workers prepare."""
    queue = JobQueue(jobs)
    return [job for job in (queue.take(i) for i in range(n)) if job is not None]


class Slots:
    """Episodes in flight, one per slot: starting, retrying and pausing them (no policy, no waiting).

    ``n_slots``: the slots the run uses; a worker handed over from an earlier run starts each of its lanes' slots
    on the cell that lane's environment holds (the worker's ``held``)."""

    def __init__(self, jobs: Sequence[EpisodeJob], pool: list, meta: RunMeta, limits: Limits,
                 on_record: Callable[[EpisodeRecord], None], outage: Outage,
                 notify: Callable[[str], None], n_slots: int) -> None:  # fmt: skip
        self.pool, self.n = pool, len(pool)
        self.meta, self.limits, self.on_record = meta, limits, on_record
        self.outage, self.notify = outage, notify
        held = {i: self.pool[i % self.n].held.get(i // self.n) for i in range(n_slots)}
        self.queue = JobQueue(jobs, {i: cell for i, cell in held.items() if cell is not None})
        self.active: dict[int, _Slot] = {}

    def send(self, i: int, op: str, arg) -> None:
        self.pool[i % self.n].send((op, i // self.n, arg))

    def start(self, i: int, slot: _Slot | None = None) -> None:
        """Reset slot ``i`` for ``slot``'s episode (a retry or resume), else the next queued one (none: free it)."""
        if slot is None:
            job = self.queue.take(i)
            if job is None:
                self.active.pop(i, None)
                return
            slot = _Slot(job)
        slot.fresh, slot.acts, slot.wake = True, 0, 0.0
        self.active[i] = slot
        self.pool[i % self.n].held[i // self.n] = cell_of(slot.job)
        self.send(i, "reset", slot.job)

    def fail(self, i: int, error: str, t: Transition | None = None) -> None:
        """An episode fault: retry from the seed, or record the error once the retries are spent (at once when the
        seed decides it: ``Transition.final``)."""
        slot = self.active[i]
        slot.attempt += 1
        slot.last_error = f"attempt {slot.attempt}: {error}"
        if slot.attempt <= self.limits.max_retries and not (t is not None and t.final):
            self.start(i, slot)
        else:
            t = t or Transition(slot.job.key, None)
            self.on_record(make_record(self.meta, slot.job, t, "error", slot.last_error))
            self.start(i)

    def conn_fault(self, i: int, e: Exception) -> None:
        """Pause the episode and schedule a fresh try from its seed (never a half-episode record)."""
        slot, now, error = self.active[i], time.monotonic(), _describe(e)
        same_point = slot.acts == slot.fault_acts and self.outage.last_ok > slot.fault_at
        slot.poison = slot.poison + 1 if same_point else 0
        if slot.poison + 1 >= POISON_FAULTS:  # the server answers others but drops this episode
            slot.poison, slot.faults, slot.fault_acts = 0, 0, -1
            self.fail(
                i, f"{error} (the connection dropped {POISON_FAULTS} times at this point of the episode)"
            )
            return
        slot.faults += 1
        slot.wake = now + self.outage.fault(slot.faults, error)
        slot.fault_at, slot.fault_acts = now, slot.acts
        self.notify(self.outage.describe(min(s.wake for s in self.active.values() if s.wake)))

    def wake_due(self, now: float) -> list[float]:
        """Re-run the paused episodes whose backoff is over (the server may be back); the wake times left."""
        for i in [i for i, s in self.active.items() if s.wake and s.wake <= now]:
            self.start(i, self.active[i])
        paused = [s.wake for s in self.active.values() if s.wake]
        if paused:
            self.notify(self.outage.describe(min(paused)))
        return paused

    def finish(self, i: int, t: Transition) -> bool:
        """Handle a worker's reply for slot ``i``: True when its episode waits for actions."""
        if t.error:
            self.fail(i, t.error, t)
        elif t.done:
            timing.CLOCK.note_episode(t)
            self.on_record(make_record(self.meta, self.active[i].job, t))
            self.start(i)
        else:
            return True
        return False

    def acted(self, i: int, result) -> None:
        """Send slot ``i`` its chunk slice, or handle the policy's fault."""
        if isinstance(result, PolicyConnectionError):
            self.conn_fault(i, result)
        elif isinstance(result, Exception):
            self.fail(i, _describe(result))
        else:
            if self.outage.ok():
                self.notify("")
            slot = self.active[i]
            slot.acts += 1
            slot.faults = 0
            self.send(i, "step", result[: self.limits.replan_steps])


class Policies:
    """The policy instances of a run: one batched instance, or one per slot (remote ones called from threads)."""

    def __init__(self, make_policy: Callable[[], object], n_slots: int) -> None:
        self.items: list = []
        first = make_policy()
        self.items.append(first)
        self.spec = first.spec
        if not self.spec.batched:
            self.items += [make_policy() for _ in range(n_slots - 1)]
        self.threads = (
            ThreadPoolExecutor(max_workers=n_slots) if not self.spec.batched and n_slots > 1 else None
        )

    def of(self, i: int):
        return self.items[0] if self.spec.batched else self.items[i]

    def shutdown(self) -> None:
        if self.threads is not None:
            self.threads.shutdown(wait=False, cancel_futures=True)


def coordinate(slots: Slots, policies: Policies, lanes: int) -> None:
    """Serve rounds until every episode is recorded: one reply per ready worker, fresh episodes reset their
    policy, one ``act`` per lane (batched policies: over every waiting environment of the lane)."""
    n, pool = slots.n, slots.pool
    ready_now = Ready(pool)
    # per-episode instances are called from threads, all at once only when their replies are there together:
    # acting on the first alone serialises a policy server's calls (W forwards a cycle instead of 1)
    per_episode = not policies.spec.batched
    gather = Gather(per_episode) if n > 1 and (not per_episode or policies.threads is not None) else None
    clock = timing.CLOCK
    try:
        while slots.active:
            now = time.monotonic()
            paused = slots.wake_due(now)
            busy_workers = sorted({i % n for i, s in slots.active.items() if not s.wake})
            ready = ready_now.now(busy_workers)
            if not ready:
                timeout = min(1.0, max(0.0, min(paused) - now)) if paused else None
                if not busy_workers:
                    time.sleep(timeout or 0.0)
                    continue
                ready = ready_now.wait(busy_workers, timeout)
                clock.wait_s += time.monotonic() - now
            if gather and lanes == 1 and ready and len(ready) < len(busy_workers):
                ready = ready_now.gather(busy_workers, ready, gather.window())
            waiting = _collect(slots, ready)
            waiting = _reset_fresh(slots, policies, waiting)
            for lane in sorted({i // n for i, _ in waiting}):  # a lane's chunk leaves once computed
                group = [(i, t) for i, t in waiting if i // n == lane]
                t_act = time.monotonic()
                results = act(policies.items, policies.spec, group, slots.meta.policy, policies.threads,
                              pad_to=n, dim=slots.limits.action_dim)  # fmt: skip
                spent = time.monotonic() - t_act
                clock.note_act(len(group), spent)
                if gather:
                    gather.observe(spent)
                for i, result in results:
                    slots.acted(i, result)
            clock.rounds, clock.replies = clock.rounds + 1, clock.replies + len(ready)
            clock.loop_s += time.monotonic() - now
    finally:
        ready_now.close()


def _collect(slots: Slots, ready: list[int]) -> list[tuple[int, Transition]]:
    """One reply per ready worker (a pipelined worker's other lane: next round); the episodes waiting for actions."""
    waiting = []
    for w in ready:
        lane, t = slots.pool[w].recv()
        i = lane * slots.n + w
        if slots.finish(i, t):
            waiting.append((i, t))
    return waiting


def _reset_fresh(slots: Slots, policies: Policies, waiting: list) -> list[tuple[int, Transition]]:
    """A new episode (or a retry) resets the policy it will use; the waiting episodes whose reset succeeded."""
    for i, t in waiting:
        slot = slots.active[i]
        if slot.fresh:
            try:
                policies.of(i).reset(t.obs.instruction, seed=slot.job.seed)
            except PolicyConnectionError as e:
                slots.conn_fault(i, e)
                continue
            except Exception as e:
                slots.fail(i, _describe(e))
                continue
            slot.fresh = False
    return [(i, t) for i, t in waiting if i in slots.active and not slots.active[i].fresh]
