"""The Ray backend: simulator actors on CPUs, one batched policy actor per GPU (per node without GPUs).

A VLA is loaded once per GPU, not once per simulator: each simulator actor runs episodes with a thin client
that sends its observation to a policy actor, which coalesces concurrent requests into one batched ``act``
(up to ``INDGEN_RAY_MAX_BATCH`` observations, waiting at most ``INDGEN_RAY_BATCH_WAIT_MS`` for more).
Per-episode-stateful policies (``batched=False``: history policies, remote openpi/GR00T/OFT servers) get one
instance per simulator actor inside the policy actor, so connections and weights live there too. Seeds come
from the plan and each episode runs ``run_episode``, so results equal the local backend's.

Joins the cluster in ``RAY_ADDRESS`` when set, else starts a local Ray instance (``ray_cluster``). Which actor
runs where, and what happens when actors or nodes die or join, is the supervisor's (``ray_pool``); episode files
travel back with their records (``ray_files``). Each simulator actor waits out a policy server outage on its own
(``run_episode``'s backoff), with the same ``--server-patience``.
"""

from __future__ import annotations

import dataclasses
import os
import queue
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future
from pathlib import Path

from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.app.engine.ray_channel import (
    SOCKET_ENV,
    Address,
    ChannelClient,
    ChannelLost,
    ChannelServer,
    available,
)
from indgen_vla.app.engine.ray_channel import connect as channel_connect
from indgen_vla.app.engine.ray_cluster import Need, join, keeping_sigterm, local_cpus
from indgen_vla.app.engine.ray_files import FileRoute, Scratch, sees, shared_out
from indgen_vla.app.engine.ray_files import route as files_route
from indgen_vla.app.engine.ray_pool import Interrupted, Settings, Supervisor
from indgen_vla.app.engine.rollout import EnvRunner, RunMeta, RunnerConfig, _describe, run_episode
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import ACTION_DIM, act_padded, validate_chunk
from indgen_vla.core.protocol.plan import EpisodeJob
from indgen_vla.core.runs.records import EpisodeRecord, RunDir
from policy_wrappers.specs import load_policy

ENV_KNOBS = {  # environment variable: (default, what it sets)
    "INDGEN_RAY_CPUS_PER_SIM": (1.0, "CPUs reserved per simulator actor"),
    "INDGEN_RAY_CPUS_PER_POLICY": (
        1.0,
        "CPUs reserved per policy actor (0 allowed: e.g. clients of a server)",
    ),
    "INDGEN_RAY_GPUS_PER_POLICY": (1.0, "GPUs per policy actor (device cuda); one actor per that many GPUs"),
    "INDGEN_RAY_MAX_BATCH": (32, "most observations in one batched act"),
    "INDGEN_RAY_BATCH_WAIT_MS": (5.0, "how long a policy actor waits to fill a batch"),
    SOCKET_ENV: (1, "how simulators call the policy actor on their node (1: a Unix socket, 0: through Ray)"),
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
        zero_ok = name == "INDGEN_RAY_CPUS_PER_POLICY"
        if name == SOCKET_ENV:
            if value not in (0, 1):
                raise ConfigError(f"{name}={raw!r}: {what} must be 0 or 1 (default {default})")
        elif not (value >= 0 if zero_ok else value > 0) or (
            name == "INDGEN_RAY_BATCH_WAIT_MS" and value > 10_000
        ):
            kind = "a number >= 0" if zero_ok else "a positive number"
            if isinstance(default, int):  # int('1.5') fails: say so, not 'positive'
                kind = "a positive whole number"
            raise ConfigError(f"{name}={raw!r}: {what} must be {kind} (default {default})")
        out[name] = value
    shared_out(environ)  # checked here although only --video writes files: a bad value is never ignored
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
        self.pad_to = min(int(pad_to), self.max_batch)
        self.clients: int | None = None  # simulators served, once the supervisor says (``pad``)
        self._queue: queue.Queue = queue.Queue()
        self.batch_sizes: list[int] = []  # what was served (benchmarks and tests read it)
        self._thread = threading.Thread(target=self._loop, name="indgen-batcher", daemon=True)
        self._thread.start()

    def pad(self, rows: int) -> None:
        """Pad every batch to ``rows`` (at most ``max_batch``): the number of simulators this batcher serves, each with
        at most one request in flight, so a batch holding that many is served at once."""
        self.pad_to = min(int(rows), self.max_batch)
        self.clients = int(rows)

    def act(self, obs):
        """One observation's (T, 7) chunk, computed in a batch with whatever else arrived meanwhile."""
        fut: Future = Future()
        self._queue.put((obs, fut))
        return fut.result()

    def close(self) -> None:
        self._queue.put(None)
        self._thread.join(timeout=10)

    def _loop(self) -> None:
        while (item := self._queue.get()) is not None:
            batch, deadline = [item], time.monotonic() + self.max_wait_s
            # every simulator served has a request in: none can come, so waiting out max_wait_s is lost time
            # (5 ms a call, an oracle's every control step); requests already queued are still taken
            while len(batch) < self.max_batch and (
                self.clients is None or len(batch) < self.clients or not self._queue.empty()
            ):
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
        self._closed = threading.Event()
        self._channel: ChannelServer | None = None
        self._channel_lock = threading.Lock()
        # policy calls by the road they came (benchmarks and tests read it); calls arrive on many threads
        self._served, self._served_lock = {"socket": 0, "ray": 0}, threading.Lock()

    def get_spec(self):
        return self.spec

    def hello(self):
        """The first reply, once the policy is loaded: its spec."""
        return self.spec

    def channel(self) -> Address | None:
        """Where simulators on this node call this actor without Ray (``ray_channel``); None where that is not
        available. The socket opens at the first request."""
        with self._channel_lock:
            if self._channel is None and available():
                self._channel = ChannelServer(_node(), self._on_call)
        return self._channel.address if self._channel is not None else None

    def _on_call(self, op: str, client: int, args: tuple):
        if op not in ("reset", "act"):
            return ValueError(f"unknown policy call {op!r}")
        return getattr(self, op)(client, *args, road="socket")

    def calls(self) -> dict[str, int]:
        """Policy calls served so far, by road: ``socket`` (the channel) or ``ray`` (an actor call)."""
        return dict(self._served)

    def watch(self) -> None:
        """Returns only when the actor closes: the supervisor learns of its death from this call failing, even when no
        simulator is calling it (one of the actor's threads waits here)."""
        self._closed.wait()

    def set_clients(self, count: int) -> None:
        """How many simulators this actor serves: every batch is padded to that many rows (see Batcher)."""
        if self._batcher is not None:
            self._batcher.pad(count)

    def node_id(self) -> str:
        return _node()

    def pid(self) -> int:
        return os.getpid()

    def _instance(self, client: int):
        if self._batcher is not None:
            return self._batcher.policy
        with self._lock:
            if client not in self._instances:
                first, self._first = self._first, None
                self._instances[client] = first if first is not None else self._make()
            return self._instances[client]

    def reset(self, client: int, instruction: str, seed: int | None, road: str = "ray"):
        with self._served_lock:
            self._served[road] += 1
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

    def act(self, client: int, obs, road: str = "ray"):
        with self._served_lock:
            self._served[road] += 1
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
        self._closed.set()
        if self._channel is not None:
            self._channel.close()
        if self._batcher is not None:
            self._batcher.close()
        held = (
            [self._batcher.policy] if self._batcher is not None else [*self._instances.values(), self._first]
        )
        for p in held:
            if p is not None:
                p.close()


class _PolicyActorLost(BaseException):  # noqa: N818 - a signal to the simulator actor, not an error
    """The policy actor went away mid-episode. A ``BaseException``: ``run_episode`` must not retry the episode
    against a dead actor or record it as an episode fault; the simulator actor replies ``Interrupted``."""


class _PolicyClient:
    """What ``run_episode`` sees in a simulator actor: a policy whose calls go to the shared policy actor, over its
    channel when one was opened (``channel``: same node), else through Ray."""

    def __init__(self, actor, client: int, spec, channel: ChannelClient | None = None):
        self.actor, self.client, self.spec, self.channel = actor, client, spec, channel

    def _call(self, method: str, *args):
        import ray

        try:
            if self.channel is not None:
                result = self.channel.call(method, self.client, *args)
            else:
                result = ray.get(getattr(self.actor, method).remote(self.client, *args))
        except ChannelLost as e:
            raise _PolicyActorLost(f"policy actor lost ({e})") from None
        except ray.exceptions.RayActorError as e:
            raise _PolicyActorLost(f"policy actor lost ({type(e).__name__})") from None
        if isinstance(result, Exception):
            raise result  # PolicyConnectionError stays itself, so run_episode's backoff sees it
        return result

    def reset(self, instruction: str, seed: int | None = None) -> None:
        self._call("reset", instruction, seed)

    def act(self, observations):
        import numpy as np

        return np.stack([self._call("act", o) for o in observations])

    def close(self) -> None:
        """The policy actor owns the policy; only the socket to it is this client's."""
        if self.channel is not None:
            self.channel.close()


class _SimActor:
    """Holds one EnvRunner for the actor's lifetime and runs whole episodes against a policy actor; files an
    episode writes go back with its record unless the run directory is shared (``ray_files``)."""

    def __init__(
        self,
        runner_cfg: RunnerConfig,
        render_threads: int,
        route: FileRoute | None = None,
        socket: bool = True,
    ):
        import dataclasses
        import logging

        os.environ.setdefault("MUJOCO_GL", "egl")
        os.environ.setdefault("LP_NUM_THREADS", str(render_threads))
        logging.getLogger("robosuite").setLevel(logging.ERROR)

        self.route = route
        self.scratch = Scratch() if route is not None and not route.shared and runner_cfg.video_dir else None
        if self.scratch is not None:
            runner_cfg = dataclasses.replace(
                runner_cfg, video_dir=self.scratch.video_dir(runner_cfg.video_dir)
            )
        self.runner = EnvRunner(runner_cfg)
        self.policy: _PolicyClient | None = None
        self.socket = socket

    def hello(self, token: str | None = None) -> bool:
        """The first reply, once the simulator is ready: False when it does not see the shared run directory."""
        return token is None or sees(self.route.run_dir, token)

    def node_id(self) -> str:
        return _node()

    def pid(self) -> int:
        return os.getpid()

    def connect(self, policy_actor, client: int, spec) -> None:
        """Talk to ``policy_actor`` from now on: over its channel when it is on this node, else through Ray. A policy
        actor gone meanwhile leaves the Ray road, whose first call then says so (``Interrupted``)."""
        import ray

        if self.policy is not None:
            self.policy.close()
        channel = None
        if self.socket:
            try:
                channel = channel_connect(ray.get(policy_actor.channel.remote()), _node())
            except ray.exceptions.RayError:
                pass
        self.policy = _PolicyClient(policy_actor, client, spec, channel)

    def prepare(self, job: EpisodeJob) -> None:
        """Build and reset ``job``'s scene now, while the policy actor may still be loading; ``run(job)`` then starts
        from that reset (the same state: nothing runs on this simulator between the two)."""
        self.runner.prepare(job)

    def run(self, job: EpisodeJob, meta: RunMeta, replan: int, max_retries: int, patience: float):
        """``(record, files)``, or ``Interrupted`` when the policy actor died mid-episode."""
        try:
            record = run_episode(self.runner, self.policy, job, meta, replan, max_retries, patience)
        except _PolicyActorLost as e:
            if self.scratch is not None:
                self.scratch.collect()  # a half episode's files go nowhere
            return Interrupted(str(e))
        return record, self.scratch.collect() if self.scratch is not None else {}

    def close(self) -> None:
        if self.policy is not None:
            self.policy.close()
        self.runner.close()
        if self.scratch is not None:
            self.scratch.close()


def _policy_factory(cfg: EvalConfig, scene: str) -> Callable[[], object]:
    from functools import partial

    extra = cfg.policy_options()  # precision/compile, for families that take them
    p = cfg.policy
    return partial(load_policy, p.spec, trust_remote_code=p.trust_remote_code, device=p.device, scene=scene,
                   **extra)  # fmt: skip


def sim_options(levels) -> dict:
    """A simulator actor's ``runtime_env``: the plan's choices its scene would otherwise read from the environment
    (the builder's ``worker_environment``: RoboCasa365's split), so an actor on a node that sets them otherwise
    builds, and says, what the manifest records (the builder it is handed carries the same choice)."""
    env = levels.worker_environment() if hasattr(levels, "worker_environment") else {}
    return {"runtime_env": {"env_vars": env}} if env else {}


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
    """Run ``jobs`` on up to ``cfg.run.workers`` simulator actors (``auto``: as many as the cluster's CPUs hold)
    served by shared policy actors, recording each episode as it finishes; survives actors and nodes that die or
    join (``ray_pool``). ``make_policy`` (picklable) replaces loading ``cfg.policy.spec``; ``stats`` gets the policy
    actors' batch sizes and the faults survived."""
    try:
        import ray
    except ImportError:
        raise ConfigError("--backend ray needs the 'ray' extra: pip install 'indgen-vla[ray]'") from None
    if not jobs:
        return
    knobs = ray_knobs()
    gpu = cfg.policy.device.startswith("cuda")
    need = Need(knobs["INDGEN_RAY_CPUS_PER_SIM"], knobs["INDGEN_RAY_CPUS_PER_POLICY"],
                knobs["INDGEN_RAY_GPUS_PER_POLICY"] if gpu else 0.0)  # fmt: skip
    workers = None if cfg.run.workers == "auto" else max(1, min(int(cfg.run.workers), len(jobs)))
    route = None
    if runner_cfg.video_dir:  # the run directory is where the videos folder is
        route = files_route(Path(runner_cfg.video_dir).parent)
        if route.shared:  # the simulators write there directly: the same absolute path on every node
            video_dir = str(Path(route.run_dir) / Path(runner_cfg.video_dir).name)
            runner_cfg = dataclasses.replace(runner_cfg, video_dir=video_dir)
    started_here = join(local_cpus(workers, need), keeping_sigterm)
    run_dir = Path(cfg.run.out)
    before = _manifest(run_dir).get("ray", {})

    def on_fault(faults, per_node) -> None:
        """The faults survived so far (added to those of earlier invocations of this run) into the manifest."""
        if (run_dir / "manifest.json").exists():
            entry = {**(route.manifest() if route else {}), "faults": _added(before.get("faults", {}), faults),
                     "episodes_per_node": _added(before.get("episodes_per_node", {}), per_node)}  # fmt: skip
            RunDir(run_dir).update_manifest(ray=entry)

    factory = make_policy or _policy_factory(cfg, runner_cfg.scene)
    most = max(
        16, 2 * (workers or int(ray.cluster_resources().get("CPU", 1))) + 4
    )  # a policy actor's clients
    policy_opts = {"num_gpus": need.gpus_per_policy} if gpu else {}
    settings = Settings(
        meta=meta, replan=replan, max_retries=cfg.run.max_retries, patience_s=cfg.policy.server_patience,
        workers=workers, need=need, files=route,
        sim_cls=ray.remote(num_cpus=need.cpus_per_sim, **sim_options(runner_cfg.levels))(_SimActor),
        sim_args=(runner_cfg, max(1, int(need.cpus_per_sim)), route, bool(knobs[SOCKET_ENV])),
        policy_cls=ray.remote(max_concurrency=most, num_cpus=need.cpus_per_policy, **policy_opts)(_PolicyActor),
        policy_args=(factory, knobs["INDGEN_RAY_MAX_BATCH"], knobs["INDGEN_RAY_BATCH_WAIT_MS"] / 1000.0),
    )  # fmt: skip
    sup, stopped = None, False
    try:
        sup = Supervisor(ray, jobs, settings, on_record, on_fault)
        sup.run()
        on_fault(sup.faults, sup.per_node)
        if stats is not None:
            stats["batch_sizes"] = sup.batch_sizes()
            stats["policy_calls"] = sup.policy_calls()
            stats["scenes_prepared"] = sup.prepared
            stats["policy_actors"] = len(sup.policies)
            stats["faults"] = dict(sup.faults)
            stats["episodes_per_node"] = dict(sup.per_node)
    except KeyboardInterrupt:
        # Ctrl-C or SIGTERM: a scheduler's SIGTERM reaches Ray's own processes too, and a call that waits on a
        # GCS gone with them hangs 60 s, then Ray aborts with status 1
        stopped = True
        raise
    finally:
        if (
            sup is not None and not stopped
        ):  # the actors are not detached: they end with this driver in any case
            sup.close()
        if started_here:  # ray.shutdown puts SIGTERM back to SIG_DFL underneath Python's handler: a SIGTERM
            keeping_sigterm(ray.shutdown)  # while the report is written then killed the run with no line


def _added(a: dict, b: dict) -> dict[str, int]:
    return {k: int(a.get(k, 0)) + int(b.get(k, 0)) for k in sorted({*a, *b})}


def _manifest(run_dir: Path) -> dict:
    import json

    try:
        return json.loads((run_dir / "manifest.json").read_text())
    except (OSError, ValueError):
        return {}


_keeping_sigterm = keeping_sigterm  # the name tests and older callers use


def _carried(e: Exception) -> Exception:
    """The exception as a reply value, its error line described here (the traceback does not cross processes),
    so an ``error`` row reads as the local backend's."""
    try:
        e.remote_description = _describe(e)
    except AttributeError:  # an exception type that refuses attributes keeps its plain description
        pass
    return e


def _node() -> str:
    import ray

    return ray.get_runtime_context().get_node_id()
