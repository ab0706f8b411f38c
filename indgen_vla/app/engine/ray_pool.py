"""The Ray backend's supervisor: starts simulator and policy actors where the cluster has room, hands out episodes,
and keeps the run going while actors and nodes die or join. An episode whose simulator (or its node) died goes back
in the queue and runs again from its seed; a dead policy actor is replaced and its simulators reconnect; nodes that
join get actors. The run stops with one line only when no episode could run for ``--server-patience`` seconds."""

from __future__ import annotations

import sys
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from indgen_vla.app.engine.ray_cluster import Need, Node, capacity, describe, first_fit, live_nodes, place
from indgen_vla.app.engine.ray_files import FileRoute, deliver, not_shared, write_probe
from indgen_vla.app.engine.rollout import RunMeta, Transition, make_record
from indgen_vla.app.engine.scheduler import JobQueue
from indgen_vla.core.errors import ClusterStalledError, ConfigError, ServerUnreachableError
from indgen_vla.core.protocol.plan import EpisodeJob
from indgen_vla.core.runs.records import EpisodeRecord

REFRESH_S = 1.0  # how often the supervisor looks at the cluster's nodes


@dataclass(frozen=True)
class Interrupted:
    """A simulator actor's reply when its policy actor died mid-episode: not the episode's fault, so it runs again
    from its seed (no attempt spent) once the simulator is connected to a live policy actor."""

    why: str


@dataclass
class _Actor:
    """One actor of the run: its handle, node, and the reply that says it started (None once it has)."""

    handle: object
    node: str
    starting: object | None
    since: float = field(default_factory=time.monotonic)
    policy: int | None = None  # a simulator: the policy actor it talks to
    job: EpisodeJob | None = None  # a simulator: the episode it runs
    # a simulator: the episode it prepared and runs next (taken from the queue)
    ahead: EpisodeJob | None = None
    clients: set[int] = field(default_factory=set)  # a policy actor: its simulators
    spec: object = None  # a policy actor: its policy's PolicySpec
    watch: object = None  # a policy actor: a call that fails when it dies (``_PolicyActor.watch``)


@dataclass(frozen=True)
class Settings:
    """What the supervisor is told: the run's episodes and limits, the actors' classes and arguments."""

    meta: RunMeta
    replan: int
    max_retries: int
    patience_s: float
    workers: int | None  # None: ``--workers auto`` (as many simulators as the CPUs hold)
    need: Need
    sim_cls: object
    sim_args: tuple
    policy_cls: object
    policy_args: tuple
    files: FileRoute | None = None  # where episode files go (None: the run writes none)


class Supervisor:
    """The driver's loop over the actors of one run (``run``); ``faults`` counts what it survived."""

    def __init__(self, ray, jobs: Sequence[EpisodeJob], s: Settings, on_record: Callable[[EpisodeRecord], None],
                 on_fault: Callable[[Counter, Counter], None] | None = None) -> None:  # fmt: skip
        self.ray, self.s, self.on_record, self.on_fault = ray, s, on_record, on_fault
        self.queue, self.left = JobQueue(jobs), len(jobs)
        self.sims: dict[int, _Actor] = {}
        self.policies: dict[int, _Actor] = {}
        self.running: dict[object, int] = {}  # an episode's reply -> its simulator
        self.crashes: Counter = (
            Counter()
        )  # episode key -> simulator crashes while running it (spend attempts)
        self.faults: Counter = Counter()
        self.per_node: Counter = Counter()  # node id -> episodes its simulators finished
        self.prepared = 0  # simulators that built their first scene on starting (``_started``)
        self.nodes: dict[str, Node] = {}
        self._ids = 0
        self._refreshed = 0.0
        self._stalled_since: float | None = None
        self._probe = write_probe(s.files.run_dir) if s.files is not None and s.files.shared else None

    # ----------------------------------------------------------------- the loop
    def run(self) -> None:
        self._start_fit()
        while self.left:
            if time.monotonic() - self._refreshed >= REFRESH_S:
                self._refresh()
            self._dispatch()
            waiting = list(self.running) + [a.starting for a in self._all() if a.starting is not None]
            waiting += [p.watch for p in self.policies.values() if p.watch is not None]
            if waiting:
                first, _ = self.ray.wait(waiting, num_returns=1, timeout=REFRESH_S)
                if first:
                    ready, _ = self.ray.wait(waiting, num_returns=len(waiting), timeout=0)
                    for ref in ready:
                        self._handle(ref)
            else:
                time.sleep(REFRESH_S / 4)
            self._check_stall()

    def _all(self) -> list[_Actor]:
        return [*self.policies.values(), *self.sims.values()]

    # ----------------------------------------------------------------- placement
    def _start_fit(self) -> None:
        nodes = live_nodes(self.ray)
        self.nodes = {n.node_id: n for n in nodes}
        plan, note = first_fit(nodes, self.s.need, self.s.workers, self.left)
        if note:
            print(f"[indgen] {note}", file=sys.stderr)
        self._start(plan.policies, plan.sims)
        self._refreshed = time.monotonic()

    def _refresh(self) -> None:
        """Look at the nodes: count those that joined or left, and start the actors there is now room for."""
        nodes = live_nodes(self.ray)
        now = {n.node_id: n for n in nodes}
        self.faults["nodes_joined"] += len(set(now) - set(self.nodes))
        gone = set(self.nodes) - set(now)
        self.faults["nodes_lost"] += len(gone)
        self.nodes = now
        self._refreshed = time.monotonic()
        if (
            gone
        ):  # idle actors there are lost now; a running episode's reply still comes (a result or an error)
            for pool, kind in ((self.sims, "simulator"), (self.policies, "policy")):
                for k, a in list(pool.items()):
                    if a.node in gone and a.job is None:
                        self._lost(pool, kind, k)
            self._report()
        free_sims = sum(1 for a in self.sims.values() if a.job is None)
        queued = self.left - len(self.running)
        target = self.s.workers if self.s.workers is not None else capacity(nodes, self.s.need)
        want = max(0, min(target - sum(a.node in now for a in self.sims.values()), queued - free_sims))
        held: dict[str, tuple[int, int]] = {}
        for a in self.sims.values():
            held[a.node] = (held.get(a.node, (0, 0))[0] + 1, held.get(a.node, (0, 0))[1])
        for a in self.policies.values():
            held[a.node] = (held.get(a.node, (0, 0))[0], held.get(a.node, (0, 0))[1] + 1)
        plan = place(nodes, held, want, self.s.need)
        self._start(plan.policies, plan.sims)

    def _start(self, policy_nodes: Sequence[str], sim_nodes: Sequence[str]) -> None:
        from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy as OnNode

        for (
            node
        ) in policy_nodes:  # first: a policy actor's CPU is never taken by a simulator placed meanwhile
            h = self.s.policy_cls.options(scheduling_strategy=OnNode(node, soft=False)).remote(
                *self.s.policy_args
            )
            self.policies[self._next()] = _Actor(h, node, h.hello.remote())
            self.faults["policy_actors_started"] += 1
        for node in sim_nodes:
            h = self.s.sim_cls.options(scheduling_strategy=OnNode(node, soft=False)).remote(*self.s.sim_args)
            self.sims[self._next()] = _Actor(h, node, h.hello.remote(self._probe))
            self.faults["simulator_actors_started"] += 1

    def _next(self) -> int:
        self._ids += 1
        return self._ids

    # ----------------------------------------------------------------- handing out episodes
    def _dispatch(self) -> None:
        ready_policies = [k for k, p in self.policies.items() if p.starting is None and p.node in self.nodes]
        for i, sim in self.sims.items():
            if sim.starting is not None or sim.job is not None or sim.node not in self.nodes:
                continue
            if sim.policy is None:
                if not ready_policies:
                    continue
                local = [k for k in ready_policies if self.policies[k].node == sim.node] or ready_policies
                k = min(local, key=lambda k: len(self.policies[k].clients))
                pol = self.policies[k]
                pol.clients.add(i)
                sim.policy = k
                sim.handle.connect.remote(pol.handle, i, pol.spec)
                pol.handle.set_clients.remote(len(pol.clients))
            job, sim.ahead = sim.ahead or self.queue.take(i), None
            if job is None:
                continue
            sim.job = job
            s = self.s
            ref = sim.handle.run.remote(
                job, s.meta, s.replan, s.max_retries, s.patience_s
            )  # after connect: in order
            self.running[ref] = i

    def _handle(self, ref) -> None:
        if ref in self.running:
            self._finished(ref, self.running.pop(ref))
            return
        for k, p in list(self.policies.items()):
            if p.watch is ref:  # a policy actor died (its watch returns only when it is closed, at the end)
                self._policy_died(k)
                return
        for pool, kind in ((self.policies, "policy"), (self.sims, "simulator")):
            for k, a in list(pool.items()):
                if a.starting is ref:
                    self._started(pool, kind, k, a)
                    return

    def _started(self, pool: dict[int, _Actor], kind: str, k: int, a: _Actor) -> None:
        try:
            reply = self.ray.get(a.starting)
        except self.ray.exceptions.RayActorError as e:
            if getattr(e, "actor_init_failed", False):  # a node without the package, a scene that cannot load
                raise ConfigError(f"a {kind} actor failed to start on node {self._where(a.node)}: "
                                  f"{_first_line(e)}") from None  # fmt: skip
            self._lost(pool, kind, k)
            return
        except self.ray.exceptions.RayError:  # e.g. its node left before it was placed
            self._lost(pool, kind, k)
            return
        a.starting = None
        if kind == "policy":
            a.spec, a.watch = reply, a.handle.watch.remote()
        elif reply is False:  # the simulator does not see the shared run directory
            raise not_shared(self.s.files.run_dir, self._where(a.node))
        elif (ahead := self.queue.take(k)) is not None:
            a.ahead = ahead  # its first scene is built while the policy actor loads
            a.handle.prepare.remote(ahead)
            self.prepared += 1

    def _finished(self, ref, i: int) -> None:
        sim = self.sims[i]
        job, sim.job = sim.job, None
        try:
            result = self.ray.get(ref)
        except (
            self.ray.exceptions.RayTaskError
        ) as e:  # the episode loop gave up on the policy server: one line
            if isinstance(getattr(e, "cause", None), ServerUnreachableError):
                raise ServerUnreachableError(str(e.cause)) from None
            raise
        except self.ray.exceptions.RayError as e:  # the simulator (or its node) died with the episode
            self._sim_died(i, job, e)
            return
        if isinstance(
            result, Interrupted
        ):  # its policy actor died: the episode runs again, elsewhere if need be
            self._put_back(i, job, "episodes_requeued")
            self._policy_died(sim.policy)
            return
        record, files = result
        if files and self.s.files is not None:
            deliver(self.s.files.run_dir, files)
        self.on_record(record)
        self.left -= 1
        self.per_node[sim.node] += 1

    # ----------------------------------------------------------------- faults
    def _sim_died(self, i: int, job: EpisodeJob, error: Exception) -> None:
        """Put the episode back (its seed decides its outcome wherever it runs); a simulator that died on a live node
        spends one of the episode's attempts, so an episode that crashes its simulator every time ends ``error``."""
        sim = self.sims[i]
        node_gone = sim.node not in {n.node_id for n in live_nodes(self.ray)}
        self._lost(self.sims, "simulator", i)
        if node_gone:
            self._put_back(i, job, "episodes_requeued")
            return
        self.crashes[job.key] += 1
        if self.crashes[job.key] <= self.s.max_retries:
            self._put_back(i, job, "episodes_requeued")
            return
        why = f"attempt {self.crashes[job.key]}: simulator actor died ({type(error).__name__})"
        self.on_record(make_record(self.s.meta, job, Transition(job.key, None), "error", why))
        self.left -= 1

    def _put_back(self, i: int, job: EpisodeJob, counter: str) -> None:
        self.queue.put_back(i, job)
        self.faults[counter] += 1
        self._report()

    def _policy_died(self, k: int | None) -> None:
        """Policy actor ``k`` is gone: its simulators reconnect to another, and a replacement starts where there is
        room (at the next look at the cluster, which is now)."""
        if k is not None and k in self.policies:
            self._lost(self.policies, "policy", k)

    def _lost(self, pool: dict[int, _Actor], kind: str, k: int) -> None:
        a = pool.pop(k)
        self._kill(a.handle)
        self.faults[f"{kind}_actors_lost"] += 1
        if kind == "simulator":
            if a.policy in self.policies:
                self.policies[a.policy].clients.discard(k)
            if a.ahead is not None:  # prepared, never started: it runs elsewhere, spending no attempt
                self.queue.put_back(k, a.ahead)
            else:
                self.queue.release(k)
        else:
            for i in a.clients:
                if i in self.sims:
                    self.sims[i].policy = None
        self._refreshed = 0.0
        self._report()

    def _kill(self, handle) -> None:
        try:
            self.ray.kill(handle)
        except Exception:  # noqa: BLE001 - already gone
            pass

    def _report(self) -> None:
        if self.on_fault is not None:
            self.on_fault(self.faults, self.per_node)

    def _check_stall(self) -> None:
        """No episode running while some wait: allowed for ``patience_s`` (actors starting, nodes joining)."""
        if self.running or not self.left:
            self._stalled_since = None
            return
        now = time.monotonic()
        if self._stalled_since is None:
            self._stalled_since = now
        elif now - self._stalled_since > self.s.patience_s:
            ready_sims = sum(1 for a in self.sims.values() if a.starting is None)
            ready_pol = sum(1 for a in self.policies.values() if a.starting is None)
            raise ClusterStalledError(
                f"no episode could run on the Ray cluster for {self.s.patience_s:g} s (--server-patience): "
                f"{ready_sims} simulator actor(s) and {ready_pol} policy actor(s) running, "
                f"{len(self.sims) - ready_sims + len(self.policies) - ready_pol} waiting for room "
                f"({describe(list(self.nodes.values()), self.s.need)}); finished episodes are saved, re-run the same "
                "command to resume"
            )

    def _where(self, node: str) -> str:
        n = self.nodes.get(node)
        return f"{n.address} ({node[:8]})" if n is not None and n.address else node[:8]

    # ----------------------------------------------------------------- the end
    def close(self) -> None:
        """Close every started actor (a policy server's connections, the simulators' scenes), then kill them all
        (one still waiting for room would answer a close never)."""
        live = self._all()
        calls = [a.handle.close.remote() for a in live if a.starting is None]
        try:
            self.ray.wait(calls, num_returns=len(calls), timeout=60)
        finally:
            for a in live:
                self._kill(a.handle)

    def batch_sizes(self) -> list[int]:
        ready = [a for a in self.policies.values() if a.starting is None]
        return [b for sizes in self.ray.get([a.handle.batch_sizes.remote() for a in ready]) for b in sizes]

    def policy_calls(self) -> dict[str, int]:
        """The live policy actors' calls served, by road (``_PolicyActor.calls``)."""
        ready = [a for a in self.policies.values() if a.starting is None]
        return dict(
            sum((Counter(c) for c in self.ray.get([a.handle.calls.remote() for a in ready])), Counter())
        )


def _first_line(e: Exception) -> str:
    cause = getattr(e, "cause", None) or e
    lines = [x.strip() for x in str(cause).splitlines() if x.strip()]
    return lines[-1] if lines else type(e).__name__
