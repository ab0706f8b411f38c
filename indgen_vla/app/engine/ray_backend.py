"""The Ray backend: simulator actors on CPUs, one batched policy actor per GPU (per node without GPUs).

A VLA is loaded once per GPU, not once per simulator: each simulator actor runs episodes with a thin client
that sends its observation to a policy actor, which coalesces concurrent requests into one batched ``act``
(up to ``INDGEN_RAY_MAX_BATCH`` observations, waiting at most ``INDGEN_RAY_BATCH_WAIT_MS`` for more).
Per-episode-stateful policies (``batched=False``: history policies, remote openpi/GR00T/OFT servers) get one
instance per simulator actor inside the policy actor, so connections and weights live there too. Seeds come
from the plan and each episode runs ``run_episode``, so results equal the local backend's.

Connects to the cluster in ``RAY_ADDRESS`` when set, else starts a local Ray instance. Each simulator actor
waits out a policy server outage on its own (``run_episode``'s backoff), with the same ``--server-patience``.
"""

from __future__ import annotations

import os
import queue
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future

from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig
from indgen_vla.app.engine.scheduler import JobQueue
from indgen_vla.core.errors import ConfigError, ServerUnreachableError
from indgen_vla.core.protocol.plan import EpisodeJob
from indgen_vla.core.runs.records import EpisodeRecord

ENV_KNOBS = {  # environment variable: (default, what it sets)
    "INDGEN_RAY_CPUS_PER_SIM": (1.0, "CPUs reserved per simulator actor"),
    "INDGEN_RAY_GPUS_PER_POLICY": (1.0, "GPUs per policy actor (device cuda); one actor per that many GPUs"),
    "INDGEN_RAY_MAX_BATCH": (32, "most observations in one batched act"),
    "INDGEN_RAY_BATCH_WAIT_MS": (5.0, "how long a policy actor waits to fill a batch"),
}


def ray_knobs(environ=os.environ) -> dict[str, float]:
    """The backend's resource and batching settings from the environment, each checked (one line if bad)."""
    out = {}
    for name, (default, what) in ENV_KNOBS.items():
        raw = environ.get(name)
        try:
            value = type(default)(raw) if raw not in (None, "") else default
        except ValueError:
            value = -1
        if not value > 0 or (name == "INDGEN_RAY_BATCH_WAIT_MS" and value > 10_000):
            raise ConfigError(f"{name}={raw!r}: {what} must be a positive number (default {default})")
        out[name] = value
    return out


class Batcher:
    """Coalesces ``act`` requests from many threads into batched calls of one stateless policy.

    Every call gets at least ``pad_to`` rows (``act_padded``; the local engine pads to its worker count the same
    way), never more than ``max_batch``.
    """

    def __init__(self, policy, who: str, max_batch: int, max_wait_s: float, pad_to: int = 1):
        self.policy, self.who, self.max_batch, self.max_wait_s = (
            policy,
            who,
            int(max_batch),
            float(max_wait_s),
        )
        self.pad(pad_to)
        self._queue: queue.Queue = queue.Queue()
        self.batch_sizes: list[int] = []  # what was served (benchmarks and tests read it)
        self._thread = threading.Thread(target=self._loop, name="indgen-batcher", daemon=True)
        self._thread.start()

    def pad(self, rows: int) -> None:
        """Pad every batch to ``rows`` (at most ``max_batch``): the number of simulators this batcher serves."""
        self.pad_to = min(int(rows), self.max_batch)

    def act(self, obs):
        """One observation's (T, 7) chunk, computed in a batch with whatever else arrived meanwhile."""
        fut: Future = Future()
        self._queue.put((obs, fut))
        return fut.result()

    def close(self) -> None:
        self._queue.put(None)
        self._thread.join(timeout=10)

    def _loop(self) -> None:
        from indgen_vla.core.protocol.interface import ACTION_DIM, act_padded

        while (item := self._queue.get()) is not None:
            batch, deadline = [item], time.monotonic() + self.max_wait_s
            while len(batch) < self.max_batch:
                try:
                    nxt = self._queue.get(timeout=max(0.0, deadline - time.monotonic()))
                except queue.Empty:
                    break
                if nxt is None:
                    self._queue.put(None)  # stop after serving this batch
                    break
                batch.append(nxt)
            try:
                dim = self.policy.spec.action_dim or ACTION_DIM  # the scene family's (12 on RoboCasa365)
                chunks = act_padded(self.policy, [o for o, _ in batch], self.pad_to, self.who, dim)
            except Exception as e:  # every waiting request sees the failure, as in the local engine
                for _, fut in batch:
                    fut.set_exception(e)
                continue
            self.batch_sizes.append(len(batch))
            for j, (_, fut) in enumerate(batch):
                fut.set_result(chunks[j])


class _PolicyActor:
    """Holds the policy (once) for every simulator actor that talks to it; replies carry exceptions as values."""

    def __init__(self, make_policy: Callable[[], object], max_batch: int, max_wait_s: float):
        self._make = make_policy
        first = make_policy()
        self.spec = first.spec
        self._lock = threading.Lock()
        self._instances: dict[int, object] = {}
        self._first: object | None = first
        self._batcher = Batcher(first, first.spec.name, max_batch, max_wait_s) if first.spec.batched else None

    def get_spec(self):
        return self.spec

    def set_clients(self, count: int) -> None:
        """How many simulators this actor serves: every batch is padded to that many rows (see Batcher)."""
        if self._batcher is not None:
            self._batcher.pad(count)

    def node_id(self) -> str:
        return _node()

    def _instance(self, client: int):
        if self._batcher is not None:
            return self._batcher.policy
        with self._lock:
            if client not in self._instances:
                first, self._first = self._first, None
                self._instances[client] = first if first is not None else self._make()
            return self._instances[client]

    def reset(self, client: int, instruction: str, seed: int | None):
        try:
            policy = self._instance(client)
            if self._batcher is not None:
                with self._lock:
                    policy.reset(instruction, seed=seed)
            else:
                policy.reset(instruction, seed=seed)
        except Exception as e:
            return _carried(e)
        return None

    def act(self, client: int, obs):
        from indgen_vla.core.protocol.interface import ACTION_DIM, validate_chunk

        try:
            if self._batcher is not None:
                return self._batcher.act(obs)
            dim = self.spec.action_dim or ACTION_DIM
            return validate_chunk(self._instance(client).act([obs]), 1, self.spec.name, dim)[0]
        except Exception as e:
            return _carried(e)

    def batch_sizes(self) -> list[int]:
        return list(self._batcher.batch_sizes) if self._batcher is not None else []

    def close(self) -> None:
        if self._batcher is not None:
            self._batcher.close()
        held = (
            [self._batcher.policy] if self._batcher is not None else [*self._instances.values(), self._first]
        )
        for p in held:
            if p is not None:
                p.close()


class _PolicyClient:
    """What ``run_episode`` sees in a simulator actor: a policy whose calls go to the shared policy actor."""

    def __init__(self, actor, client: int, spec):
        self.actor, self.client, self.spec = actor, client, spec

    def _call(self, method, *args):
        import ray

        result = ray.get(method.remote(self.client, *args))
        if isinstance(result, Exception):
            raise result  # PolicyConnectionError stays itself, so run_episode's backoff sees it
        return result

    def reset(self, instruction: str, seed: int | None = None) -> None:
        self._call(self.actor.reset, instruction, seed)

    def act(self, observations):
        import numpy as np

        return np.stack([self._call(self.actor.act, o) for o in observations])

    def close(self) -> None:
        pass  # the policy actor owns the policy


class _SimActor:
    """Holds one EnvRunner for the actor's lifetime and runs whole episodes against a policy actor."""

    def __init__(self, runner_cfg: RunnerConfig, render_threads: int):
        import logging

        os.environ.setdefault("MUJOCO_GL", "egl")
        os.environ.setdefault("LP_NUM_THREADS", str(render_threads))
        logging.getLogger("robosuite").setLevel(logging.ERROR)
        from indgen_vla.app.engine.rollout import EnvRunner

        self.runner = EnvRunner(runner_cfg)
        self.policy: _PolicyClient | None = None

    def node_id(self) -> str:
        return _node()

    def connect(self, policy_actor, client: int, spec) -> None:
        self.policy = _PolicyClient(policy_actor, client, spec)

    def run(
        self, job: EpisodeJob, meta: RunMeta, replan: int, max_retries: int, patience: float
    ) -> EpisodeRecord:
        from indgen_vla.app.engine.rollout import run_episode

        return run_episode(self.runner, self.policy, job, meta, replan, max_retries, patience)

    def close(self) -> None:
        self.runner.close()


def _policy_factory(cfg: EvalConfig, scene: str) -> Callable[[], object]:
    from functools import partial

    from policy_wrappers.registry import load_policy

    extra = cfg.policy_options()  # precision/compile, for families that take them
    return partial(load_policy, cfg.policy, trust_remote_code=cfg.trust_remote_code, device=cfg.device,
                   scene=scene, **extra)  # fmt: skip


def run_ray(
    jobs: Sequence[EpisodeJob],
    runner_cfg: RunnerConfig,
    cfg: EvalConfig,
    meta: RunMeta,
    on_record: Callable[[EpisodeRecord], None],
    replan: int,
    make_policy: Callable[[], object] | None = None,
    stats: dict | None = None,
) -> None:
    """Run ``jobs`` on ``cfg.workers`` simulator actors served by shared policy actors, recording each
    episode as it finishes. ``make_policy`` (picklable) replaces loading ``cfg.policy``; ``stats`` gets the
    policy actors' batch sizes."""
    try:
        import ray
    except ImportError:
        raise ConfigError("--backend ray needs the 'ray' extra: pip install 'indgen-vla[ray]'") from None
    if not jobs:
        return
    knobs = ray_knobs()
    n = max(1, min(cfg.workers, len(jobs)))
    started_here = not ray.is_initialized()
    if started_here:
        import math

        cpus = math.ceil(n * knobs["INDGEN_RAY_CPUS_PER_SIM"]) + 1  # the simulators and one policy actor
        _keeping_sigterm(lambda: ray.init(num_cpus=cpus, include_dashboard=False, log_to_driver=False,
                                          ignore_reinit_error=True))  # fmt: skip
    gpu = cfg.device.startswith("cuda")
    gpus_per = knobs["INDGEN_RAY_GPUS_PER_POLICY"]
    resources = ray.cluster_resources()
    if gpu:
        if resources.get("GPU", 0) < gpus_per:
            raise ConfigError(f"--device {cfg.device} but the Ray cluster has {resources.get('GPU', 0):g} GPUs "
                              f"(< INDGEN_RAY_GPUS_PER_POLICY={gpus_per:g}); use --device cpu or add GPU nodes")  # fmt: skip
        n_policy = max(1, min(n, int(resources["GPU"] // gpus_per)))
        policy_opts = {"num_gpus": gpus_per, "num_cpus": 1}
    else:
        n_policy = max(1, min(n, len([x for x in ray.nodes() if x.get("Alive")])))
        policy_opts = {"num_cpus": 1}
    factory = make_policy or _policy_factory(cfg, runner_cfg.scene)
    policy_cls = ray.remote(max_concurrency=n + 4, **policy_opts)(_PolicyActor)
    wait_s = knobs["INDGEN_RAY_BATCH_WAIT_MS"] / 1000.0
    servers = [
        policy_cls.options(scheduling_strategy="SPREAD").remote(
            factory, knobs["INDGEN_RAY_MAX_BATCH"], wait_s
        )
        for _ in range(n_policy)
    ]
    sim_cls = ray.remote(num_cpus=knobs["INDGEN_RAY_CPUS_PER_SIM"])(_SimActor)
    render_threads = max(1, int(knobs["INDGEN_RAY_CPUS_PER_SIM"]))
    actors = [sim_cls.remote(runner_cfg, render_threads) for _ in range(n)]
    stopped = False
    try:
        specs = ray.get([s.get_spec.remote() for s in servers])
        _connect(ray, actors, servers, specs)
        todo = JobQueue(jobs)  # an actor keeps the scene it holds (one build per cell, as the local backend)
        running: dict = {}  # a running episode's future -> its actor

        def submit(i: int) -> None:
            job = todo.take(i)
            if job is not None:
                running[actors[i].run.remote(job, meta, replan, cfg.max_retries, cfg.server_patience)] = i

        for i in range(n):
            submit(i)
        try:
            while running:
                (done,), _ = ray.wait(list(running), num_returns=1)
                i = running.pop(done)
                on_record(ray.get(done))
                submit(i)
        except ray.exceptions.RayTaskError as e:  # an actor gave up on the server: one clear line
            if isinstance(getattr(e, "cause", None), ServerUnreachableError):
                raise ServerUnreachableError(str(e.cause)) from None
            raise
        if stats is not None:
            stats["batch_sizes"] = [b for s in ray.get([s.batch_sizes.remote() for s in servers]) for b in s]
            stats["policy_actors"] = len(servers)
    except KeyboardInterrupt:
        # Ctrl-C or SIGTERM: a scheduler's SIGTERM reaches Ray's own processes too, and a call that waits on a
        # GCS gone with them hangs 60 s, then Ray aborts with status 1
        stopped = True
        raise
    finally:
        if not stopped:  # the actors are not detached: they end with this driver in any case
            ray.get([a.close.remote() for a in actors + servers], timeout=60)
            for a in actors + servers:
                ray.kill(a)
        if started_here:
            ray.shutdown()


def _keeping_sigterm(start: Callable[[], object]) -> None:
    """Call ``start`` (``ray.init``) and put back the SIGTERM handler it replaces: Ray's exits with status 15 and a
    C++ stack dump instead of the one-line stop and exit 143 of ``indgen`` (``interrupts.sigterm_raises``)."""
    import signal

    if threading.current_thread() is not threading.main_thread():
        start()
        return
    previous = signal.getsignal(signal.SIGTERM)
    start()
    if previous is not None:
        signal.signal(signal.SIGTERM, previous)


def _connect(ray, actors: list, servers: list, specs: list) -> None:
    """Pair every simulator actor with a policy actor on its own node when there is one (round robin)."""
    server_nodes = ray.get([s.node_id.remote() for s in servers])
    sim_nodes = ray.get([a.node_id.remote() for a in actors])
    turn: dict[str, int] = {}
    clients: dict[int, int] = {}
    calls = []
    for client, (actor, node) in enumerate(zip(actors, sim_nodes, strict=True)):
        local = [k for k, sn in enumerate(server_nodes) if sn == node] or list(range(len(servers)))
        k = local[turn.get(node, 0) % len(local)]
        turn[node] = turn.get(node, 0) + 1
        calls.append(actor.connect.remote(servers[k], client, specs[k]))
        clients[k] = clients.get(k, 0) + 1
    calls += [servers[k].set_clients.remote(count) for k, count in clients.items()]
    ray.get(calls)


def _carried(e: Exception) -> Exception:
    """The exception as a reply value, its error line described here (the traceback does not cross processes),
    so an ``error`` row reads as the local backend's."""
    from indgen_vla.app.engine.rollout import _describe

    try:
        e.remote_description = _describe(e)
    except AttributeError:  # an exception type that refuses attributes keeps its plain description
        pass
    return e


def _node() -> str:
    import ray

    return ray.get_runtime_context().get_node_id()
