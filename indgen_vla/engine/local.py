"""The local backend: W worker processes own scene instances; the main process holds the policy and
serves one batched forward per round across every environment that is waiting for actions.

With ``pipeline=True`` every worker owns two environments (lanes) and the policy computes one lane's chunk while
the worker steps the other's, so simulation and inference overlap (docs/benchmarks.md, "Pipelining").
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
import time
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from multiprocessing.connection import wait

import numpy as np

from indgen_vla.engine.reconnect import DEFAULT_PATIENCE_S, Outage
from indgen_vla.engine.rollout import (
    EnvRunner,
    RunMeta,
    RunnerConfig,
    Transition,
    _describe,
    action_dim,
    make_record,
)
from indgen_vla.errors import PolicyConnectionError
from indgen_vla.interface import act_padded, validate_chunk
from indgen_vla.plan import EpisodeJob
from indgen_vla.records import EpisodeRecord

LANES = 2  # environments per worker when pipelined: one steps while the policy computes the other's chunk


def _handle(runners: dict[int, EnvRunner], cfg: RunnerConfig, msg: tuple) -> tuple[int, Transition]:
    op, lane, arg = msg
    runner = runners.get(lane)
    if runner is None:
        runner = runners[lane] = EnvRunner(cfg)
    if op == "reset":
        return lane, runner.reset(arg)
    if op == "step":
        return lane, runner.execute(arg)
    raise ValueError(f"unknown worker op {op!r}")


def _worker_main(conn, cfg: RunnerConfig, render_threads: int, egl_device: int | None = None) -> None:
    """Worker process loop: build scenes lazily, answer reset/step requests until told to close."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the main process handles Ctrl-C and closes us
    os.environ.setdefault("MUJOCO_GL", "egl")
    if egl_device is not None:  # several GPUs: workers render round-robin on them (read at context creation)
        os.environ.setdefault("MUJOCO_EGL_DEVICE_ID", str(egl_device))
    # llvmpipe starts one render thread per core in every process: W workers would oversubscribe the cores
    # (pixels do not depend on the thread count; docs/benchmarks.md "Where a CPU frame goes")
    os.environ.setdefault("LP_NUM_THREADS", str(render_threads))
    logging.getLogger("robosuite").setLevel(logging.ERROR)
    runners: dict[int, EnvRunner] = {}
    try:
        while True:
            try:
                msg = conn.recv()
            except (EOFError, OSError):
                break
            if msg[0] == "close":
                break
            conn.send(_handle(runners, cfg, msg))
    finally:
        for runner in runners.values():
            runner.close()


class _InProcessWorker:
    """W = 1, unpipelined: the same request/reply protocol without a subprocess (cheaper start, easier
    debugging)."""

    def __init__(self, cfg: RunnerConfig):
        self.cfg = cfg
        self.runners: dict[int, EnvRunner] = {}
        self._replies: deque[tuple[int, Transition]] = deque()

    def send(self, msg: tuple) -> None:
        self._replies.append(_handle(self.runners, self.cfg, msg))

    def poll(self) -> bool:
        return bool(self._replies)

    def recv(self) -> tuple[int, Transition]:
        return self._replies.popleft()

    def close(self) -> None:
        for runner in self.runners.values():
            runner.close()


class _ProcessWorker:
    def __init__(self, ctx, cfg: RunnerConfig, render_threads: int, egl_device: int | None = None):
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(
            target=_worker_main, args=(child, cfg, render_threads, egl_device), daemon=True
        )
        self.proc.start()
        child.close()

    def send(self, msg: tuple) -> None:
        self.conn.send(msg)

    def poll(self) -> bool:
        return self.conn.poll()

    def recv(self) -> tuple[int, Transition]:
        try:
            return self.conn.recv()
        except (EOFError, OSError):
            raise RuntimeError(
                f"worker process {self.proc.pid} died (exit code {self.proc.exitcode})"
            ) from None

    def close(self) -> None:
        try:
            self.conn.send(("close", None, None))
        except (BrokenPipeError, OSError):
            pass
        self.proc.join(timeout=10)
        if self.proc.is_alive():
            self.proc.terminate()
            self.proc.join(timeout=5)


# Each worker is one single-threaded simulator: BLAS/OpenMP pools sized to the whole machine in each of W
# processes oversubscribe the cores (16 workers on 16 cores: +45 % worker CPU per step, docs/benchmarks.md).
WORKER_THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


def _context(preload: Sequence[str]):
    """A forkserver that has imported the simulator once (``preload``: the scene family's modules, from the
    plan's builder), so W workers start fast and clean (no threads inherited from the main process, no EGL
    context shared across processes). It starts with one
    BLAS/OpenMP thread per process (``WORKER_THREAD_ENV``, unless the user set them); the main process keeps its own."""
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(["indgen_vla.engine.local", *preload])
    from multiprocessing import forkserver

    if (
        getattr(forkserver._forkserver, "_forkserver_pid", None) is None
    ):  # not started yet: its env is ours now
        saved = {k: os.environ.get(k) for k in WORKER_THREAD_ENV}
        for k in WORKER_THREAD_ENV:
            os.environ.setdefault(k, "1")
        try:
            forkserver.ensure_running()
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
    return ctx


def worker_processes(n_jobs: int, workers: int, pipeline: bool) -> int:
    """How many worker processes ``run_local`` starts for ``n_jobs`` episodes (0: it steps the one environment
    in this process)."""
    n = max(1, min(workers, n_jobs))
    return 0 if n == 1 and not (pipeline and n_jobs > n) else n


def start_forkserver(preload: Sequence[str]) -> None:
    """Start the workers' forkserver now, so its preload (the simulator's imports) runs while this process does
    something else, e.g. load the policy; ``run_local`` then forks its workers from it at once."""
    _context(preload)


def egl_devices() -> int:
    """GPUs visible to this process (``CUDA_VISIBLE_DEVICES``, else /dev/nvidiaN), 0 without any; no CUDA import."""
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    if visible is not None:
        return len([d for d in visible.split(",") if d.strip() and d.strip() != "-1"])
    import glob

    return len([p for p in glob.glob("/dev/nvidia[0-9]*") if p[len("/dev/nvidia") :].isdigit()])


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


POISON_FAULTS = 5  # after this many, a connection drop that only this episode triggers is an episode fault


def run_local(
    jobs: Sequence[EpisodeJob],
    runner_cfg: RunnerConfig,
    make_policy: Callable[[], object],
    meta: RunMeta,
    on_record: Callable[[EpisodeRecord], None],
    workers: int = 1,
    replan_steps: int = 1,
    max_retries: int = 2,
    server_patience_s: float = DEFAULT_PATIENCE_S,
    on_wait: Callable[[str], None] | None = None,
    close_policies: bool = True,
    pipeline: bool = False,
) -> None:
    """Run ``jobs`` and hand each finished episode to ``on_record`` as soon as it ends.

    Batched policies get one ``act`` per round over all waiting environments; per-episode-stateful
    policies get one instance per environment (remote ones are called concurrently from threads). A connection
    fault pauses the episode, waits with backoff (``on_wait`` gets the progress line, "" when it clears)
    and re-runs it from its seed; past ``server_patience_s`` it raises ``ServerUnreachableError``.

    ``pipeline``: two environments per worker (slot ``i`` is lane ``i // W`` of worker ``i % W``), and each
    lane gets its own ``act``, so a worker steps one lane while the policy computes the other's chunk. Every
    episode still runs from its own seed with its own actions: the records equal the unpipelined run's.
    """
    n = max(1, min(workers, len(jobs)))
    if not jobs:
        return
    lanes = LANES if pipeline and len(jobs) > n else 1
    n_slots = min(n * lanes, len(jobs))
    in_process = worker_processes(len(jobs), workers, pipeline) == 0  # one env here: no forkserver to wait on
    ctx = None if in_process else _context(runner_cfg.levels.preload)
    pool: list = []
    policies: list = []
    threads: ThreadPoolExecutor | None = None
    outage = Outage(patience_s=server_patience_s)
    notify = on_wait or (lambda text: None)
    try:
        render_threads = max(1, (os.cpu_count() or 1) // n)
        gpus = egl_devices()
        pool = (
            [_InProcessWorker(runner_cfg)]
            if in_process
            else [
                _ProcessWorker(ctx, runner_cfg, render_threads, w % gpus if gpus > 1 else None)
                for w in range(n)
            ]
        )
        queue = deque(jobs)
        slots: dict[int, _Slot] = {}

        def send(i: int, op: str, arg) -> None:
            pool[i % n].send((op, i // n, arg))

        def start(i: int, slot: _Slot | None = None) -> None:
            if slot is None:
                if not queue:
                    slots.pop(i, None)
                    return
                slot = _Slot(queue.popleft())
            slot.fresh, slot.acts, slot.wake = True, 0, 0.0
            slots[i] = slot
            send(i, "reset", slot.job)

        def fail(i: int, error: str, t: Transition | None = None) -> None:
            slot = slots[i]
            slot.attempt += 1
            slot.last_error = f"attempt {slot.attempt}: {error}"
            if slot.attempt <= max_retries:
                start(i, slot)
            else:
                on_record(
                    make_record(meta, slot.job, t or Transition(slot.job.key, None), "error", slot.last_error)
                )
                start(i)

        def conn_fault(i: int, e: Exception) -> None:
            """Pause the episode and schedule a fresh try from its seed (never a half-episode record)."""
            slot, now, error = slots[i], time.monotonic(), _describe(e)
            same_point = slot.acts == slot.fault_acts and outage.last_ok > slot.fault_at
            slot.poison = slot.poison + 1 if same_point else 0
            if slot.poison + 1 >= POISON_FAULTS:  # the server answers others but drops this episode
                slot.poison, slot.faults, slot.fault_acts = 0, 0, -1
                fail(
                    i, f"{error} (the connection dropped {POISON_FAULTS} times at this point of the episode)"
                )
                return
            slot.faults += 1
            slot.wake = now + outage.fault(slot.faults, error)
            slot.fault_at, slot.fault_acts = now, slot.acts
            notify(outage.describe(min(s.wake for s in slots.values() if s.wake)))

        for i in range(n_slots):
            start(i)  # the workers start and build their scenes while the policy loads
        first = make_policy()
        spec = first.spec
        policies = [first] if spec.batched else [first] + [make_policy() for _ in range(n_slots - 1)]
        threads = ThreadPoolExecutor(max_workers=n_slots) if not spec.batched and n_slots > 1 else None
        gather = _Gather() if spec.batched and n > 1 else None
        while slots:
            now = time.monotonic()
            for i in [i for i, s in slots.items() if s.wake and s.wake <= now]:
                start(i, slots[i])  # the server may be back: re-run the paused episode from its seed
            busy = [i for i, s in slots.items() if not s.wake]
            paused = [s.wake for s in slots.values() if s.wake]
            if paused:
                notify(outage.describe(min(paused)))
            busy_workers = sorted({i % n for i in busy})
            ready = [w for w in busy_workers if pool[w].poll()]
            if not ready:
                timeout = min(1.0, max(0.0, min(paused) - now)) if paused else None
                if not busy:
                    time.sleep(timeout or 0.0)
                    continue
                conns = {pool[w].conn: w for w in busy_workers}
                ready = [conns[c] for c in wait(list(conns), timeout)]
            if gather and lanes == 1 and ready and len(ready) < len(busy_workers):
                ready = _gather(pool, busy_workers, ready, gather.window())
            waiting: list[tuple[int, Transition]] = []
            for w in ready:  # one reply per worker and round (a pipelined worker's other lane: next round)
                lane, t = pool[w].recv()
                i = lane * n + w
                slot = slots[i]
                if t.error:
                    fail(i, t.error, t)
                elif t.done:
                    on_record(make_record(meta, slot.job, t))
                    start(i)
                else:
                    waiting.append((i, t))
            if not waiting:
                continue
            for i, t in waiting:  # a new episode (or a retry) resets the policy it will use
                if slots[i].fresh:
                    policy = policies[0] if spec.batched else policies[i]
                    try:
                        policy.reset(t.obs.instruction, seed=slots[i].job.seed)
                    except PolicyConnectionError as e:
                        conn_fault(i, e)
                        continue
                    except Exception as e:
                        fail(i, _describe(e))
                        continue
                    slots[i].fresh = False
            waiting = [(i, t) for i, t in waiting if i in slots and not slots[i].fresh]  # drop failed resets
            for lane in sorted({i // n for i, _ in waiting}):  # a lane's chunk leaves once computed
                group = [(i, t) for i, t in waiting if i // n == lane]
                t_act = time.monotonic()
                acted = _act(
                    policies, spec, group, meta.policy, threads, pad_to=n, dim=action_dim(runner_cfg.levels)
                )
                if gather:
                    gather.observe(time.monotonic() - t_act)
                for i, result in acted:
                    if isinstance(result, PolicyConnectionError):
                        conn_fault(i, result)
                    elif isinstance(result, Exception):
                        fail(i, _describe(result))
                    else:
                        if outage.ok():
                            notify("")
                        slots[i].acts += 1
                        slots[i].faults = 0
                        send(i, "step", result[:replan_steps])
    finally:
        if threads is not None:
            threads.shutdown(wait=False, cancel_futures=True)
        for w in pool:
            w.close()
        for p in policies if close_policies else ():  # the caller may keep them for its next call
            close = getattr(p, "close", None)
            if close is not None:
                try:
                    close()
                except Exception:  # closing must not mask the run's own outcome
                    logging.getLogger(__name__).debug("policy close failed", exc_info=True)


class _Gather:
    """How long a batched round waits for the workers still stepping once the first has replied: up to half a
    forward (running of its recent cost). A forward costs the same at 1 or W rows, so acting on the first replies
    alone makes the rest wait a whole forward (pi0.5 on an H100: 2 forwards per cycle instead of 1)."""

    CAP_S = 0.5  # never hold replies longer than this

    def __init__(self) -> None:
        self.cost = 0.0

    def observe(self, seconds: float) -> None:
        self.cost = seconds if not self.cost else 0.8 * self.cost + 0.2 * seconds

    def window(self) -> float:
        return min(self.CAP_S, 0.5 * self.cost)


def _gather(pool, busy_workers: list[int], ready: list[int], window_s: float) -> list[int]:
    """``ready`` plus the busy workers that reply within ``window_s`` (all of them: no waiting at all)."""
    if window_s <= 0:
        return ready
    deadline = time.monotonic() + window_s
    ready = list(ready)
    rest = {pool[w].conn: w for w in busy_workers if w not in ready}
    while rest:
        left = deadline - time.monotonic()
        if left <= 0:
            break
        for c in wait(list(rest), left):
            ready.append(rest.pop(c))
    return sorted(ready)


def _act(
    policies, spec, waiting, who: str, threads, pad_to: int = 1, dim: int = 7
) -> list[tuple[int, np.ndarray | Exception]]:
    """Actions for every waiting environment: (worker index, (T, 7) chunk) or (index, the exception).

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
