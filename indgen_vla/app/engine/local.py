"""The local backend: W worker processes own scene instances; the main process holds the policy and
serves one batched forward per round across every environment that is waiting for actions.

With ``pipeline=True`` every worker owns two environments (lanes) and the policy computes one lane's chunk while
the worker steps the other's, so simulation and inference overlap (docs/results/benchmarks/engine.md, "Pipelining").
"""

from __future__ import annotations

import json
import logging
import multiprocessing as mp
import os
import pickle
import threading
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from indgen_vla.app.engine.main_guard import check_main_guard
from indgen_vla.app.engine.reconnect import DEFAULT_PATIENCE_S, Outage
from indgen_vla.app.engine.rollout import EnvRunner, RunMeta, RunnerConfig, Transition, action_dim
from indgen_vla.app.engine.scheduler import Limits, Policies, Slots, cell_of, coordinate, first_jobs
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.plan import WARM_CELL_ENV, EpisodeJob
from indgen_vla.core.runs.records import EpisodeRecord

LANES = 2  # environments per worker when pipelined: one steps while the policy computes the other's chunk


def _dumps(msg) -> bytes:
    """Requests and replies cross the pipe as plain pickles (protocol 5): ``Connection.send`` goes through
    ``ForkingPickler``, which is 7x slower on an observation with two 128-px images (0.37 vs 0.05 ms here);
    they carry no handles or connections that would need its reducers."""
    return pickle.dumps(msg, protocol=pickle.HIGHEST_PROTOCOL)


_loads = pickle.loads


def _handle(runners: dict[int, EnvRunner], cfg: RunnerConfig, msg: tuple) -> tuple[int, Transition] | None:
    """One request; ``prepare`` (build and reset a job's scene before it is asked for) has no reply."""
    op, lane, arg = msg
    runner = runners.get(lane)
    if runner is None:
        runner = runners[lane] = EnvRunner(cfg)
    if op == "prepare":
        runner.prepare(arg)
        return None
    if op == "reset":
        return lane, runner.reset(arg)
    if op == "step":
        return lane, runner.execute(arg)
    raise ValueError(f"unknown worker op {op!r}")


def _adopt_environment(env: dict[str, str]) -> None:
    """Take the coordinator's environment as of this worker's start. The fork server's is that of its own start,
    and the caller may have changed it since (asset paths, e.g. ``INDGEN_ROBOCASA_ASSETS``, read when a scene is
    built); a worker keeps only what the fork server set for itself: the thread limits and the GL platform its
    preload chose (``FORKSERVER_OWN_ENV``)."""
    own = {k: os.environ[k] for k in FORKSERVER_OWN_ENV if k in os.environ and k not in env}
    os.environ.clear()
    os.environ.update(env)
    os.environ.update(own)


def init_worker_process(render_threads: int, egl_device: int | None = None, env: dict | None = None) -> None:
    """What a worker forked from the fork server does first (here, and as ``indgen demos``'s pool initializer):
    leave Ctrl-C to the main process, take its environment (``env``), render with ``render_threads`` threads."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the main process handles Ctrl-C and closes us
    if env is not None:
        _adopt_environment(env)
    os.environ.setdefault("MUJOCO_GL", "egl")
    if egl_device is not None:  # several GPUs: workers render round-robin on them (read at context creation)
        os.environ.setdefault("MUJOCO_EGL_DEVICE_ID", str(egl_device))
    # llvmpipe starts one render thread per core in every process: W workers would oversubscribe the cores
    # (pixels do not depend on the thread count; docs/results/benchmarks/render.md)
    os.environ.setdefault("LP_NUM_THREADS", str(render_threads))
    logging.getLogger("robosuite").setLevel(logging.ERROR)


def _worker_main(
    conn, cfg: RunnerConfig, render_threads: int, egl_device: int | None = None, env: dict | None = None
) -> None:
    """Worker process loop: build scenes lazily, answer reset/step requests until told to close."""
    init_worker_process(render_threads, egl_device, env)
    runners: dict[int, EnvRunner] = {}
    try:
        while True:
            try:
                msg = _loads(conn.recv_bytes())
            except (EOFError, OSError):
                break
            if msg[0] == "close":
                break
            reply = _handle(runners, cfg, msg)
            if reply is not None:
                try:
                    conn.send_bytes(_dumps(reply))
                except OSError:  # the main process is gone (killed): no one to answer, no traceback
                    break
    finally:
        for runner in runners.values():
            runner.close()


class _InProcessWorker:
    """W = 1, unpipelined: the same request/reply protocol without a subprocess (cheaper start, easier
    debugging)."""

    def __init__(self, cfg: RunnerConfig):
        self.cfg = cfg
        self.held: dict[int, tuple] = {}  # lane -> the cell its environment was last asked for (scheduler)
        self.runners: dict[int, EnvRunner] = {}
        self._replies: deque[tuple[int, Transition]] = deque()

    def send(self, msg: tuple) -> None:
        reply = _handle(self.runners, self.cfg, msg)
        if reply is not None:
            self._replies.append(reply)

    def poll(self) -> bool:
        return bool(self._replies)

    def recv(self) -> tuple[int, Transition]:
        return self._replies.popleft()

    def close(self) -> None:
        for runner in self.runners.values():
            runner.close()


class _ProcessWorker:
    def __init__(self, ctx, cfg: RunnerConfig, render_threads: int, egl_device: int | None = None):
        self.cfg = cfg
        self.held: dict[int, tuple] = {}  # lane -> the cell its environment was last asked for (scheduler)
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(
            target=_worker_main, args=(child, cfg, render_threads, egl_device, dict(os.environ)), daemon=True
        )
        self.proc.start()
        child.close()

    def send(self, msg: tuple) -> None:
        self.conn.send_bytes(_dumps(msg))

    def poll(self) -> bool:
        return self.conn.poll()

    def recv(self) -> tuple[int, Transition]:
        try:
            return _loads(self.conn.recv_bytes())
        except (EOFError, OSError):
            raise RuntimeError(
                f"worker process {self.proc.pid} died (exit code {self.proc.exitcode})"
            ) from None

    def close(self) -> None:
        try:
            self.conn.send_bytes(_dumps(("close", None, None)))
        except (BrokenPipeError, OSError):
            pass
        self.proc.join(timeout=10)
        if self.proc.is_alive():
            self.proc.terminate()
            self.proc.join(timeout=5)


# Each worker is one single-threaded simulator: BLAS/OpenMP pools sized to the whole machine in each of W
# processes oversubscribe the cores (16 workers on 16 cores: +45 % worker CPU per step, docs/results/benchmarks/gpu.md).
WORKER_THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
# what a worker keeps of the fork server's own environment when the coordinator's lacks it (``_adopt_environment``)
FORKSERVER_OWN_ENV = (*WORKER_THREAD_ENV, "MUJOCO_GL", "PYOPENGL_PLATFORM")


def _context(levels, task: str | None = None):
    """A forkserver that has imported the simulator once (the preload of ``levels``, the plan's builder), so W
    workers start fast and clean (no threads inherited from the main process, no EGL context shared across
    processes). It starts with one BLAS/OpenMP thread per process (``WORKER_THREAD_ENV``, unless the user set
    them; the main process keeps its own) and names ``task``, the first the workers build, to the preload
    (``WARM_CELL_ENV``: a family may warm its caches with it; callers name one only when two or more workers
    will share what the fork server warmed). A script's unguarded top level is refused first (``main_guard``)."""
    check_main_guard()
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(
        ["indgen_vla.app.engine.local", *levels.preload, "indgen_vla.app.engine.forkserver_exit"]
    )
    from multiprocessing import forkserver

    if (
        getattr(forkserver._forkserver, "_forkserver_pid", None) is None
    ):  # not started yet: its env is ours now
        saved = {k: os.environ.get(k) for k in (*WORKER_THREAD_ENV, WARM_CELL_ENV)}
        for k in WORKER_THREAD_ENV:
            os.environ.setdefault(k, "1")
        os.environ.pop(WARM_CELL_ENV, None)
        if task is not None:
            os.environ[WARM_CELL_ENV] = json.dumps({"scene": levels.scene, "task": task})
        try:
            _spawn_ignoring_ctrl_c(forkserver.ensure_running)
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
    return ctx


def _spawn_ignoring_ctrl_c(start) -> None:
    """Call ``start`` (which spawns the fork server) with SIGINT ignored, a disposition the new interpreter inherits:
    a Ctrl-C during its seconds of preload printed a KeyboardInterrupt traceback beside the coordinator's one line
    (the fork server ignores SIGINT itself only after its preload; its workers ignore it too). SIGINT is blocked
    meanwhile, so a Ctrl-C that comes during the spawn reaches the coordinator afterwards instead of being lost."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        start()
        return
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        start()
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler if previous is None else previous)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def worker_processes(n_jobs: int, workers: int, pipeline: bool) -> int:
    """How many worker processes ``run_local`` starts for ``n_jobs`` episodes (0: it steps the one environment
    in this process)."""
    n = max(1, min(workers, n_jobs))
    return 0 if n == 1 and not (pipeline and n_jobs > n) else n


def start_forkserver(levels, task: str | None = None):
    """Start the workers' forkserver now, so its preload (the simulator's imports; ``task``: the first the
    workers build) runs while this process does something else, e.g. load the policy; ``run_local`` then forks
    its workers from it at once. Returns its multiprocessing context (``indgen demos`` starts its pool in it)."""
    return _context(levels, task)


def egl_devices() -> int:
    """GPUs visible to this process (``CUDA_VISIBLE_DEVICES``, else /dev/nvidiaN), 0 without any; no CUDA import."""
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    if visible is not None:
        return len([d for d in visible.split(",") if d.strip() and d.strip() != "-1"])
    import glob

    return len([p for p in glob.glob("/dev/nvidia[0-9]*") if p[len("/dev/nvidia") :].isdigit()])


@dataclass(frozen=True)
class LocalOptions:
    """How ``run_local`` runs its jobs: worker processes, actions executed per chunk, tries again of an episode that
    raised, seconds to wait for an unreachable policy server, two lanes per worker (``pipeline``), and whether it
    closes the policies it made (a caller that runs rounds keeps them)."""

    workers: int = 1
    replan_steps: int = 1
    max_retries: int = 2
    server_patience_s: float = DEFAULT_PATIENCE_S
    pipeline: bool = False
    close_policies: bool = True


@dataclass
class Handoff:
    """Worker processes passed between ``run_local`` calls. ``early``: workers to use instead of starting new ones
    (``EarlyWorkers``, or an earlier call's ``keep``), made for its ``runner_cfg``; as many as the call needs are used,
    more are started if it needs more. ``keep``: after a run that ends normally the workers are appended to it instead
    of closed, with the scenes they hold, for the caller's next call (adaptive rounds); the caller closes them."""

    early: list | None = None
    keep: list | None = None


def run_local(
    jobs: Sequence[EpisodeJob],
    runner_cfg: RunnerConfig,
    make_policy: Callable[[], object],
    meta: RunMeta,
    on_record: Callable[[EpisodeRecord], None],
    options: LocalOptions = LocalOptions(),
    on_wait: Callable[[str], None] | None = None,
    handoff: Handoff | None = None,
) -> None:
    """Run ``jobs`` and hand each finished episode to ``on_record`` as soon as it ends.

    Batched policies get one ``act`` per round over all waiting environments; per-episode-stateful
    policies get one instance per environment (remote ones are called concurrently from threads). A connection
    fault pauses the episode, waits with backoff (``on_wait`` gets the progress line, "" when it clears)
    and re-runs it from its seed; past ``options.server_patience_s`` it raises ``ServerUnreachableError``.

    ``options.pipeline``: two environments per worker (slot ``i`` is lane ``i // W`` of worker ``i % W``), and each
    lane gets its own ``act``, so a worker steps one lane while the policy computes the other's chunk. Every
    episode still runs from its own seed with its own actions: the records equal the unpipelined run's.

    ``handoff``: the workers passed between calls (``Handoff``).
    """
    o, h = options, handoff or Handoff()
    early, keep = h.early, h.keep
    n = max(1, min(o.workers, len(jobs)))
    if not jobs:
        if keep is not None:
            keep.extend(early or [])
        return
    lanes = LANES if o.pipeline and len(jobs) > n else 1
    n_slots = min(n * lanes, len(jobs))
    pool: list = []
    spare: list = []
    policies: Policies | None = None
    try:
        n_proc = worker_processes(len(jobs), o.workers, o.pipeline)
        pool, spare = _reuse(early or [], runner_cfg, n_proc, jobs[0].task)
        limits = Limits(o.max_retries, o.replan_steps, action_dim(runner_cfg.levels))
        outage = Outage(patience_s=o.server_patience_s)
        slots = Slots(jobs, pool, meta, limits, on_record, outage, on_wait or (lambda text: None), n_slots)
        for i in range(n_slots):
            slots.start(i)  # the workers start and build their scenes while the policy loads
        policies = Policies(make_policy, n_slots)
        coordinate(slots, policies, lanes)
        if keep is not None:  # a normal end: the next call gets the workers and the scenes they hold
            keep.extend(pool + spare)
            pool, spare = [], []
    finally:
        if policies is not None:
            policies.shutdown()
        for w in pool + spare:
            w.close()
        # the caller may keep the policies for its next call (close_policies=False)
        for p in policies.items if policies is not None and o.close_policies else []:
            close = getattr(p, "close", None)
            if close is not None:
                try:
                    close()
                except Exception:  # closing must not mask the run's own outcome
                    logging.getLogger(__name__).debug("policy close failed", exc_info=True)


def _reuse(early: list, runner_cfg: RunnerConfig, n_proc: int, task: str) -> tuple[list, list]:
    """(pool, spare): the first workers of ``early`` this run needs (``n_proc``: 0 = one in-process worker, which
    a worker process also serves), more started if it needs more, the rest spare; workers made for another
    config, or an in-process worker where processes are needed, are closed and replaced."""
    want = max(1, n_proc)
    if any(w.cfg != runner_cfg for w in early) or (
        want > 1 and any(isinstance(w, _InProcessWorker) for w in early)
    ):
        for w in early:
            w.close()
        early = []
    if not early:
        return _start_pool(runner_cfg, n_proc, task), []
    pool, spare = early[:want], early[want:]
    if len(pool) < want:
        _spawn(_context(runner_cfg.levels, task), runner_cfg, want - len(pool), into=pool)
    return pool, spare


def _start_pool(runner_cfg: RunnerConfig, n: int, task: str) -> list:
    """``n`` worker processes forked from the fork server (``worker_processes``; ``task``: the first they build),
    or with ``n`` = 0 one in-process worker and no fork server; rendering on the GPUs round-robin when there are
    several."""
    if n == 0:
        return [_InProcessWorker(runner_cfg)]
    return _spawn(_context(runner_cfg.levels, task if n > 1 else None), runner_cfg, n)


def _spawn(ctx, runner_cfg: RunnerConfig, n: int, into: list | None = None) -> list:
    """``n`` worker processes from the fork server ``ctx``, appended to ``into`` one by one (a failure part-way
    leaves the started ones there to close); rendering on the GPUs round-robin when there are several."""
    pool = [] if into is None else into
    render_threads = max(1, (os.cpu_count() or 1) // n)
    gpus = egl_devices()
    for w in range(n):
        pool.append(_ProcessWorker(ctx, runner_cfg, render_threads, w % gpus if gpus > 1 else None))
    return pool


class EarlyWorkers:
    """Worker processes started, and their first scenes built and reset, while the policy loads (start-up, issue 28).

    ``evaluate`` makes them from a ``RunnerConfig`` built on the policy's ``ScenePreview``; ``take`` hands them
    to ``run_local`` when the loaded policy asks for exactly that config, and closes them otherwise. They start
    from a thread: a fork server answers only once its preload (the simulator's imports) is done, and the
    policy load should not wait for that.
    """

    def __init__(self, runner_cfg: RunnerConfig, jobs: Sequence[EpisodeJob], n: int):
        self.runner_cfg = runner_cfg
        self.pool: list = []
        self._failed: BaseException | None = None
        self._thread: threading.Thread | None = None
        # the fork server starts here, not in the thread: starting it sets this process's env briefly
        try:
            ctx = _context(runner_cfg.levels, jobs[0].task if jobs and n > 1 else None)
        except ConfigError:
            raise  # an unguarded script (main_guard): no worker would start, now or later
        except (ValueError, OSError) as e:
            self._failed = e  # no fork server on this platform: the run starts as without a preview
            return
        self._thread = threading.Thread(
            target=self._start, args=(ctx, first_jobs(jobs, n), n), name="indgen-early-workers", daemon=True
        )
        self._thread.start()

    def _start(self, ctx, jobs: list[EpisodeJob], n: int) -> None:
        try:
            _spawn(ctx, self.runner_cfg, n, into=self.pool)
            for w, job in zip(self.pool, jobs, strict=False):  # slot i is lane 0 of worker i (scheduler)
                w.send(("prepare", 0, job))
                w.held[0] = cell_of(job)
        except BaseException as e:  # e.g. a fork server that died: run_local starts its own workers
            self._failed = e

    def _join(self) -> None:
        if self._thread is not None:
            self._thread.join()

    def take(self, runner_cfg: RunnerConfig) -> list | None:
        """The workers, if the loaded policy's scenes are the previewed ones; else None (and they are closed)."""
        self._join()
        if self._failed is None and runner_cfg == self.runner_cfg:
            pool, self.pool = self.pool, []
            return pool
        if self._failed is not None:
            logging.getLogger(__name__).debug("early workers failed to start", exc_info=self._failed)
        self.close()
        return None

    def close(self) -> None:
        """Close the workers not handed out (a refused policy, an interrupted load)."""
        self._join()
        for w in self.pool:
            w.close()
        self.pool = []
