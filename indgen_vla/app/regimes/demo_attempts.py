"""The noisy-oracle attempts ``indgen demos`` keeps: attempt ``a`` of a (task, level) cell always starts from the same
seed, and a cell keeps its first ``n`` successes in attempt order, whether the attempts run in this process or in
worker processes (forked from the engine's fork server) and whether the run was interrupted or not."""

from __future__ import annotations

import dataclasses
import os
import queue
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from indgen_vla.app.config_fields import check_types, option
from indgen_vla.app.engine.local import init_worker_process, start_forkserver
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import Observation
from indgen_vla.core.protocol.seeding import fresh_seed, held_out_seeds
from scenes.poses import object_poses
from scenes.privileged import privileged_of, with_privileged
from scenes.tabletop.oracle import OraclePolicy


@dataclass(frozen=True)
class HumanNoise:
    """Teleoperator-like imperfections layered on the oracle: jittery motion and short hesitations.

    Attributes:
        sigma: std of Gaussian noise added to the 6 motion dims (action units, [-1, 1] range).
        pause_prob: chance per step of starting a pause (zero motion, gripper held).
        pause_steps: (min, max) length of a pause in control steps.
    """

    sigma: float = option(0.1, "std of motion noise (action units)", name="noise", type=float)
    pause_prob: float = option(0.02, "per-step probability of a human-like pause", type=float)
    pause_steps: tuple[int, int] = option((2, 8))  # API only

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        if self.sigma < 0 or not 0 <= self.pause_prob < 1:
            raise ConfigError(f"noise sigma must be >= 0 and pause probability in [0, 1); got {self}")
        if not 1 <= self.pause_steps[0] <= self.pause_steps[1]:
            raise ConfigError(f"pause_steps must be 1 <= min <= max, got {self.pause_steps}")


def noisy_oracle_episode(env, seed: int, noise: HumanNoise) -> Iterator[tuple[Observation, np.ndarray, dict]]:
    """Yield (observation, executed action, info) for one episode of the noisy oracle, seeded."""
    rng = np.random.default_rng(seed)
    oracle = OraclePolicy()
    obs, _ = env.reset(seed=seed)
    oracle.reset(obs.instruction, seed=seed)
    pause = 0
    for _ in range(env.max_steps):
        obs = with_privileged(obs, env)  # yielded too, so recorders can keep object poses
        a = oracle.act([obs])[0, 0].astype(np.float64)
        if pause == 0 and rng.random() < noise.pause_prob:
            pause = int(rng.integers(noise.pause_steps[0], noise.pause_steps[1] + 1))
        if pause > 0:
            pause -= 1
            a[:6] = 0.0
        else:
            a[:6] = np.clip(a[:6] + rng.normal(0.0, noise.sigma, 6), -1.0, 1.0)
        a = a.astype(np.float32)
        next_obs, _, terminated, truncated, info = env.step(a)
        yield obs, a, info
        obs = next_obs
        if terminated or truncated:
            return


@dataclass(frozen=True)
class DemoCell:
    """One (task, level) ``indgen demos`` records: ``axis`` None is T0 as recorded without ``--axis``."""

    task: str
    level: int = 0
    axis: str | None = None
    param: float | None = None

    @property
    def label(self) -> str:
        return self.task if self.axis is None else f"{self.task} {self.axis} level {self.level}"

    def seed_key(self, scene: str) -> tuple:
        """The seed key of its episodes: level 0 keeps T0's key, so it holds the same episodes on every axis."""
        if self.level == 0:
            return ("demos", scene, self.task)
        return ("demos", scene, self.task, self.axis, self.level)

    def attempt_seeds(self, scene: str, seed: int, attempts: int) -> list[int]:
        """The seed of each attempt, in order; none of them an evaluation seed (``held_out_seeds``)."""
        avoid = held_out_seeds(scene, self.task, also=(seed,))
        return [fresh_seed(seed, *self.seed_key(scene), a, avoid=avoid) for a in range(attempts)]


@dataclass(frozen=True)
class EnvMaker:
    """Builds a cell's scene in whichever process records it (picklable: it travels to the workers).

    Attributes:
        scene, cameras, image_size: as ``indgen demos`` got them.
        builder: the ``LevelBuilder`` every cell is built with (``scenes.planning``): the plan's with ``--axis``.
        t0_axis: the axis a T0 cell (``axis`` None) is built along, at level 0: T0 on every axis.
    """

    scene: str
    cameras: tuple[str, ...]
    image_size: int
    builder: Any
    t0_axis: str = ""

    @property
    def preload(self) -> tuple[str, ...]:
        """The modules the workers' fork server imports first (the engine's ``LevelBuilder.preload``)."""
        return tuple(self.builder.preload)

    def __call__(self, cell: DemoCell):
        size = (self.image_size, self.image_size)
        return self.builder.make_env(cell.task, cell.axis or self.t0_axis, cell.level, cameras=self.cameras,
                                     image_size=size, max_steps=None)  # fmt: skip


_OPEN: dict = {}  # this process's one open scene: {"for": (maker, cell), "env": env}


def _env_for(maker: EnvMaker, cell: DemoCell):
    """The scene of ``cell``, built once per process and cell (attempts of a cell arrive together)."""
    if _OPEN.get("for") != (maker, cell):
        close_env()
        _OPEN.update({"for": (maker, cell), "env": maker(cell)})
    return _OPEN["env"]


def close_env() -> None:
    """Close this process's open scene, if any."""
    env = _OPEN.pop("env", None)
    _OPEN.pop("for", None)
    if env is not None:
        env.close()


def record_attempt(maker: EnvMaker, cell: DemoCell, seed: int, noise: HumanNoise) -> list | None:
    """One noisy-oracle episode from ``seed``: its (observation, executed action, object poses) frames if it
    succeeded (the observations without their privileged state), else None."""
    frames, success = [], False
    for obs, a, info in noisy_oracle_episode(_env_for(maker, cell), seed, noise):
        frames.append(
            (dataclasses.replace(obs, extras={}), a, object_poses(privileged_of(obs, "indgen demos")))
        )
        success = bool(info.get("success", False))
    return frames if success else None


@dataclass
class AttemptPlan:
    """Which attempts to run: per cell its attempt seeds (the allowed attempts, in order) and where it stands.

    Attributes:
        maker, noise: the scenes and the noise every attempt uses.
        cells: the cells, in recording order.
        seeds: per cell, the seed of each allowed attempt.
        n: successes to keep per cell.
        kept, next_attempt: per cell, successes already kept and the first attempt not yet run (a resumed run).
    """

    maker: EnvMaker
    noise: HumanNoise
    cells: list[DemoCell]
    seeds: list[list[int]]
    n: int
    kept: list[int]
    next_attempt: list[int]

    def exhausted(self, c: int) -> ConfigError:
        return ConfigError(f"only {self.kept[c]}/{self.n} noisy oracle demos of {self.maker.scene}/"
                           f"{self.cells[c].label} succeeded in {len(self.seeds[c])} attempts; lower the noise "
                           "(the episodes recorded so far stay in --out; record into a new one)")  # fmt: skip

    def remaining(self) -> int:
        return sum(max(0, self.n - k) for k in self.kept)


def kept_episodes(plan: AttemptPlan, workers: int = 1) -> Iterator[tuple[int, int, list]]:
    """Yield (cell index, attempt, frames) of every episode to keep, in cell then attempt order (the same
    sequence for any ``workers``); raise ``AttemptPlan.exhausted`` when a cell runs out of attempts."""
    if min(workers, plan.remaining()) <= 1:
        yield from _in_process(plan)
    else:
        yield from _OrderedPool(plan, min(workers, plan.remaining())).run()


def _in_process(plan: AttemptPlan) -> Iterator[tuple[int, int, list]]:
    try:
        for c, cell in enumerate(plan.cells):
            while plan.kept[c] < plan.n:
                a = plan.next_attempt[c]
                if a >= len(plan.seeds[c]):
                    raise plan.exhausted(c)
                frames = record_attempt(plan.maker, cell, plan.seeds[c][a], plan.noise)
                plan.next_attempt[c] += 1
                if frames is not None:
                    plan.kept[c] += 1
                    yield c, a, frames
    finally:
        close_env()


class _OrderedPool:
    """Attempts in ``workers`` processes; results are taken in attempt order, so the episodes kept are the
    in-process run's. A cell gets only the attempts it may still need if every running one succeeds (a failure
    starts another), so no attempt is wasted except where a run ends early."""

    def __init__(self, plan: AttemptPlan, workers: int):
        self.plan, self.workers = plan, workers
        self.dispatched = list(plan.next_attempt)  # per cell: the next attempt to start
        self.running: dict[tuple[int, int], Any] = {}
        self.results: queue.SimpleQueue = queue.SimpleQueue()
        self.done: dict[tuple[int, int], Any] = {}

    def run(self) -> Iterator[tuple[int, int, list]]:
        from concurrent.futures import ProcessPoolExecutor

        plan = self.plan
        first = next(c for c in range(len(plan.cells)) if plan.kept[c] < plan.n)
        ctx = start_forkserver(plan.maker, plan.cells[first].task)
        threads = max(1, (os.cpu_count() or 1) // self.workers)
        alive, self.alive = ctx.Pipe(duplex=False)  # only this process holds the write end
        pool = ProcessPoolExecutor(self.workers, mp_context=ctx, initializer=_init_worker,
                                   initargs=(threads, dict(os.environ), alive))  # fmt: skip
        try:
            for c in range(first, len(plan.cells)):
                yield from self._cell(pool, c)
        finally:
            _stop(pool, busy=bool(self.running))
            self.alive.close()

    def _cell(self, pool, c: int) -> Iterator[tuple[int, int, list]]:
        plan = self.plan
        while plan.kept[c] < plan.n:
            a = plan.next_attempt[c]
            if a >= len(plan.seeds[c]):
                raise plan.exhausted(c)
            self._submit(pool, c)
            while (c, a) not in self.done:
                key, future = self.results.get()
                del self.running[key]
                self.done[key] = future.result()  # a worker's error raises here
                self._submit(pool, c)
            frames = self.done.pop((c, a))
            plan.next_attempt[c] += 1
            if frames is not None:
                plan.kept[c] += 1
                yield c, a, frames
        for key in [k for k in self.done if k[0] == c]:  # attempts past the n-th success: not kept
            del self.done[key]

    def _submit(self, pool, current: int) -> None:
        """Keep ``2 * workers`` attempts going (two per worker: one runs while the next waits for it)."""
        plan = self.plan
        for c in range(current, len(plan.cells)):
            while len(self.running) < 2 * self.workers:
                a = self.dispatched[c]
                pending = a - plan.next_attempt[c]  # started or finished, not yet taken
                if plan.kept[c] + pending >= plan.n or a >= len(plan.seeds[c]):
                    break
                future = pool.submit(record_attempt, plan.maker, plan.cells[c], plan.seeds[c][a], plan.noise)
                self.running[(c, a)] = future
                future.add_done_callback(lambda f, key=(c, a): self.results.put((key, f)))
                self.dispatched[c] += 1


def _init_worker(render_threads: int, env: dict, alive) -> None:
    """The engine's worker setup, and an exit once the main process is gone: a pool worker waits on a queue whose
    write end it holds itself, so after a SIGKILL of the main process it would wait (with its scene) forever."""
    import threading

    init_worker_process(render_threads, None, env)

    def watch() -> None:
        try:
            alive.recv()
        except (EOFError, OSError):
            os._exit(0)

    threading.Thread(target=watch, name="indgen-demos-parent", daemon=True).start()


def _stop(pool, busy: bool) -> None:
    """Stop the pool; with attempts still running (Ctrl-C, an error) at once, without waiting for their episodes."""
    if not busy:
        pool.shutdown()
        return
    procs = list((getattr(pool, "_processes", None) or {}).values())  # Python 3.14: pool.terminate_workers()
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in procs:
        if proc.is_alive():
            proc.terminate()
        proc.join(timeout=10)
