"""Where the Ray backend's actors go: joining the cluster (or starting a local one), which node holds which actor,
and the one line that says what a cluster lacks for a run. The placement is a pure function of the nodes, so a
cluster that is too small is refused (or used as far as it goes) before anything waits on Ray."""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from indgen_vla.core.errors import ConfigError

EPS = 1e-9  # Ray's resources are fractional; a sum of quarters must still fit


@dataclass(frozen=True)
class Need:
    """What one actor of each kind reserves on its node (the ``INDGEN_RAY_*`` knobs): simulators take CPUs, policy
    actors a CPU each and, with ``--device cuda``, ``gpus_per_policy`` GPUs (0: CPU policy actors, one per node)."""

    cpus_per_sim: float
    cpus_per_policy: float
    gpus_per_policy: float = 0.0

    def __post_init__(self) -> None:
        if not self.cpus_per_sim > 0 or self.cpus_per_policy < 0 or self.gpus_per_policy < 0:
            raise ConfigError(f"bad Ray actor resources {self}: CPUs per simulator > 0, the rest >= 0")

    @property
    def gpu(self) -> bool:
        return self.gpus_per_policy > 0


@dataclass(frozen=True)
class Node:
    """A live node as the placement sees it: its id, its logical CPUs and GPUs, its address (for messages)."""

    node_id: str
    cpus: float
    gpus: float
    address: str = ""

    def __post_init__(self) -> None:
        if self.cpus < 0 or self.gpus < 0:
            raise ConfigError(f"node {self.node_id}: negative resources")


@dataclass(frozen=True)
class Placement:
    """The nodes of the actors to start now: one entry per new policy actor, one per new simulator actor."""

    policies: tuple[str, ...]
    sims: tuple[str, ...]


def live_nodes(ray) -> list[Node]:
    """The cluster's live nodes (``ray.nodes()``), in a stable order."""
    out = []
    for n in ray.nodes():
        if n.get("Alive"):
            res = n.get("Resources", {})
            out.append(Node(n["NodeID"], float(res.get("CPU", 0)), float(res.get("GPU", 0)),
                            n.get("NodeManagerAddress", "")))  # fmt: skip
    return sorted(out, key=lambda n: n.node_id)


def place(
    nodes: Sequence[Node], held: Mapping[str, tuple[int, int]], want_sims: int, need: Need
) -> Placement:
    """Where to start up to ``want_sims`` more simulator actors and the policy actors they need, given the
    simulators and policy actors this run already holds on each node (``held``: node -> (sims, policies)).

    With GPUs, policy actors come first: one per ``gpus_per_policy`` GPUs of every node (never more than there are
    simulators), so a simulator never takes the CPU one needs. On CPU, every node that runs simulators gets a policy
    actor where there is room for it (at least one in all). Simulators go one at a time to the node with the most
    free CPUs, so they spread over the nodes."""
    free = {}
    for n in nodes:
        sims, pols = held.get(n.node_id, (0, 0))
        free[n.node_id] = [n.cpus - sims * need.cpus_per_sim - pols * need.cpus_per_policy,
                           n.gpus - pols * need.gpus_per_policy]  # fmt: skip
    has_policy = {n.node_id for n in nodes if held.get(n.node_id, (0, 0))[1]}
    runs_sims = {n.node_id for n in nodes if held.get(n.node_id, (0, 0))[0]}
    cap = max(1, sum(held.get(n.node_id, (0, 0))[0] for n in nodes) + want_sims)  # policies <= simulators
    policies: list[str] = []
    sims: list[str] = []

    def fits(node: str, cpus: float, gpus: float = 0.0) -> bool:
        return free[node][0] + EPS >= cpus and free[node][1] + EPS >= gpus

    def add_policy(node: str) -> None:
        free[node][0] -= need.cpus_per_policy
        free[node][1] -= need.gpus_per_policy
        policies.append(node)
        has_policy.add(node)

    def n_policies() -> int:
        return sum(held.get(n.node_id, (0, 0))[1] for n in nodes) + len(policies)

    order = [n.node_id for n in nodes]
    if need.gpu:
        for k in order:
            while n_policies() < cap and fits(k, need.cpus_per_policy, need.gpus_per_policy):
                add_policy(k)
    else:
        for k in order:  # a node that runs simulators but lost its policy actor
            if k in runs_sims and k not in has_policy and fits(k, need.cpus_per_policy):
                add_policy(k)
        if not n_policies() and (roomy := [k for k in order if fits(k, need.cpus_per_policy)]):
            add_policy(max(roomy, key=lambda k: free[k][0]))
    while len(sims) < want_sims:
        room = [k for k in order if fits(k, need.cpus_per_sim)]
        if not room:
            break
        best = max(room, key=lambda k: free[k][0])  # ties: the first node
        if not need.gpu and best not in has_policy and fits(best, need.cpus_per_policy + need.cpus_per_sim):
            add_policy(best)
        free[best][0] -= need.cpus_per_sim
        sims.append(best)
    return Placement(tuple(policies), tuple(sims))


def capacity(nodes: Sequence[Node], need: Need) -> int:
    """How many simulator actors the cluster holds once its policy actors are placed (``--workers auto``)."""
    return len(place(nodes, {}, 1 << 16, need).sims)


def describe(nodes: Sequence[Node], need: Need) -> str:
    """The cluster in a few words, with what each actor takes (for the lines that say what it lacks)."""
    cpus, gpus = sum(n.cpus for n in nodes), sum(n.gpus for n in nodes)
    policy = f"{need.cpus_per_policy:g} CPU" + (f" + {need.gpus_per_policy:g} GPU" if need.gpu else "")
    return (f"{len(nodes)} live node{'s' if len(nodes) != 1 else ''}, {cpus:g} CPUs, {gpus:g} GPUs; each simulator "
            f"actor takes {need.cpus_per_sim:g} CPU (INDGEN_RAY_CPUS_PER_SIM), each policy actor {policy} "
            f"(INDGEN_RAY_CPUS_PER_POLICY{', INDGEN_RAY_GPUS_PER_POLICY' if need.gpu else ''})")  # fmt: skip


def first_fit(nodes: Sequence[Node], need: Need, workers: int | None, jobs: int) -> tuple[Placement, str]:
    """The run's first placement and, when it holds fewer simulators than asked for, the one line that says so;
    a cluster that cannot hold one policy actor and one simulator is refused in one line (``ConfigError``).
    ``workers``: ``--workers`` (None: ``auto``, as many as the CPUs hold)."""
    want = min(jobs, workers if workers is not None else max(1, capacity(nodes, need)))
    plan = place(nodes, {}, want, need)
    if need.gpu and sum(n.gpus for n in nodes) + EPS < need.gpus_per_policy:
        raise ConfigError(f"--device cuda but the Ray cluster has {sum(n.gpus for n in nodes):g} GPUs (one policy "
                          f"actor takes INDGEN_RAY_GPUS_PER_POLICY={need.gpus_per_policy:g}); use --device cpu or "
                          "add GPU nodes")  # fmt: skip
    if not plan.policies or not plan.sims:
        missing = "a policy actor" if not plan.policies else "a simulator actor beside its policy actor"
        raise ConfigError(f"the Ray cluster has no room for {missing} ({describe(nodes, need)}); add nodes or lower "
                          "those settings (docs/cluster.md)")  # fmt: skip
    note = ""
    if len(plan.sims) < want:
        short = (want - len(plan.sims)) * need.cpus_per_sim
        cpus = f"{short:g} CPU{'s' if short != 1 else ''}"
        note = (f"the Ray cluster holds {len(plan.sims)} of the {want} simulator actors asked for (--workers) beside "
                f"{len(plan.policies)} policy actor(s) ({describe(nodes, need)}): it lacks {cpus}; running "
                f"{len(plan.sims)}, more as nodes join")  # fmt: skip
    return plan, note


# Ray starts its workers at nice 15 (``worker_niceness``), so beside any process at the default priority (the driver,
# a build, another job) the simulator actors starve: beside two busy processes on 2 cores, 8 oracle episodes took
# 122-136 s through Ray against 6-7 s locally, 9-11 s at nice 0 (``scripts/bench_ray.py --busy 2``;
# docs/results/benchmarks/speed.md). A local instance runs them at the driver's priority; a joined cluster keeps its own.
LOCAL_SYSTEM_CONFIG = {"worker_niceness": 0}


def join(local_cpus: int, start: Callable[[Callable[[], object]], None] | None = None) -> bool:
    """Join the Ray cluster this process already joined or ``RAY_ADDRESS`` names (``ray.init`` then takes no
    resource counts: the cluster has its own), else start a local Ray instance of ``local_cpus`` CPUs. True when
    this call connected (the caller disconnects with ``ray.shutdown()``, which leaves a joined cluster running).
    The local instance is always a new one (``address="local"``): a bare ``ray.init`` would join a cluster some
    ``ray start`` left on this machine, and refuse the CPU count.
    ``start`` wraps the ``ray.init`` call (keeping the SIGTERM handler)."""
    import ray

    if ray.is_initialized():
        return False
    start = start or (lambda init: init())
    address = os.environ.get("RAY_ADDRESS", "").strip()
    if address:
        if address.startswith(("http://", "https://")):  # Ray's own message ends in 'To fix this, either:'
            raise ConfigError(f"RAY_ADDRESS={address} is the dashboard's (job API) address, which 'ray job submit "
                              "--address' takes; indgen joins the head's GCS address HOST:PORT (6379 unless "
                              "'ray start --head --port' said otherwise; docs/cluster.md)")  # fmt: skip
        if silent := unanswered(address):
            raise ConfigError(f"RAY_ADDRESS={address}: no Ray cluster answers there ({silent}); start one with "
                              "'ray start --head' (docs/cluster.md), or unset RAY_ADDRESS for a local Ray "
                              "instance")  # fmt: skip
        try:
            start(lambda: ray.init(address=address, log_to_driver=False))
        except (ConnectionError, RuntimeError, ValueError, TimeoutError) as e:
            first = (str(e).strip().splitlines() or [type(e).__name__])[0]
            raise ConfigError(f"RAY_ADDRESS={address}: cannot join a Ray cluster there ({first}); start one with "
                              "'ray start --head' (docs/cluster.md), or unset RAY_ADDRESS for a local Ray "
                              "instance") from None  # fmt: skip
        return True
    start(
        lambda: ray.init(
            address="local",
            num_cpus=local_cpus,
            include_dashboard=False,
            log_to_driver=False,
            _system_config=LOCAL_SYSTEM_CONFIG,
        )
    )
    return True


def unanswered(address: str, timeout_s: float = 5.0) -> str:
    """Why nothing can be reached at a ``HOST:PORT`` (or ``ray://HOST:PORT``) address, '' when something does or the
    address is another form (``auto``; Ray checks those): ``ray.init`` retries an address where no GCS answers
    for many minutes (> 8 with Ray 2.60) instead of failing."""
    import socket

    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not host or not port.isdigit() or "/" in host:
        return ""
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s).close()
    except OSError as e:
        return f"cannot connect to {host}:{port}: {e.strerror or e or type(e).__name__}"
    return ""


def local_cpus(workers: int | None, need: Need) -> int:
    """CPUs of a local Ray instance: the simulators and one policy actor (``auto``: this machine's cores)."""
    if workers is None:
        return os.cpu_count() or 1
    return max(1, math.ceil(workers * need.cpus_per_sim + need.cpus_per_policy))


def keeping_sigterm(start: Callable[[], object]) -> None:
    """Call ``start`` (``ray.init``, ``ray.shutdown``) and put back the SIGTERM handler it replaces: Ray's exits with
    status 15 and a C++ stack dump, ``ray.shutdown`` leaves SIG_DFL (Python still reports its own handler), instead
    of the one-line stop and exit 143 of ``indgen`` (``interrupts.sigterm_raises``)."""
    import signal

    if threading.current_thread() is not threading.main_thread():
        start()
        return
    previous = signal.getsignal(signal.SIGTERM)
    start()
    if previous is not None:
        signal.signal(signal.SIGTERM, previous)
