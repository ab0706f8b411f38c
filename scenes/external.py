"""Scene families whose simulator runs in another Python environment, driven over a pipe.

A family declares ``runtime`` (an ``ExternalRuntime``: the interpreter of its own venv and the backend file that
worker loads) and its own ``EnvSpec`` (cameras, state and action sizes). ``ExternalSceneEnv`` is the proxy
``BaseSceneEnv`` in our process: it starts ``scenes/external_worker.py`` with that interpreter and sends it
``build`` / ``reset`` / ``step`` / ``privileged`` requests (length-prefixed pickles, numpy arrays inside). A worker
error reaches the caller as a one-line ``SceneError`` naming the task, level and cause; a worker that died is
restarted on the next ``reset`` (the engine retries the episode like any other episode error).
"""

from __future__ import annotations

import atexit
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from indgen_vla.core.errors import SceneError
from indgen_vla.core.protocol.interface import Observation
from scenes.base_env import BaseSceneEnv
from scenes.runtime import ExternalRuntime, WorkerDied, WorkerProcess

if TYPE_CHECKING:
    from scenes.axes import Successor
    from scenes.family import Scene

# One idle worker per runtime, kept by ``close`` for the next env of this process: the next level skips the
# simulator's import and reuses the worker's T0 cache (RoboCasa: one reset per episode instead of two).
# Keyed by (pid, runtime): a forked child never reuses (or stops) its parent's worker.
_IDLE: dict[tuple[int, str], WorkerProcess] = {}


@atexit.register
def close_idle_workers() -> None:
    """Stop this process's idle workers (at exit; tests call it to start from a cold worker)."""
    for key in [k for k in _IDLE if k[0] == os.getpid()]:
        _IDLE.pop(key).close()


class ExternalSceneEnv(BaseSceneEnv):
    """The proxy env of a family with ``runtime``: one level of one task, simulated in the family's own venv.

    The family provides ``level_config(task, successor, level, cameras, image_size) -> dict`` (what the backend's
    ``build`` receives) and ``env_spec`` (its cameras and state/action sizes); images and state arrive as numpy.
    """

    _worker: WorkerProcess | None = None
    _last: dict | None = None
    has_progress = False  # set at each reset: the worker sends contact facts for this task (``_facts``)

    def _load(self, scene: Scene, task: str, successor: Successor) -> None:
        self._scene = scene
        self.runtime: ExternalRuntime = scene.runtime
        self.config = scene.level_config(task, successor, self.level, self.cameras, self.image_size)
        self.spec = self.config.get("spec")
        self.axis_param = float(self.config.get("axis_param", self.level))
        self.instruction = scene.instruction(task)
        self.success_predicate = scene.success_predicate
        self._build()

    def _where(self) -> str:
        return f"scene {self.scene}/{self.task} axis {self.axis.name} level {self.level}"

    def _call(self, op: str, arg: Any = None) -> Any:
        try:
            return self._worker.request(op, arg)
        except WorkerDied as e:
            self._worker.close()
            self._worker = None
            raise WorkerDied(f"{self._where()}: {e}") from None
        except SceneError as e:  # EpisodeUnavailableError stays itself: the engine does not retry it
            raise type(e)(f"{self._where()}: {e}") from None

    def _build(self) -> None:
        if self._worker is None or not self._worker.alive:
            idle = _IDLE.pop((os.getpid(), self.runtime.name), None)
            self._worker = idle if idle is not None and idle.alive else WorkerProcess(self.runtime)
        self._call("build", {k: v for k, v in self.config.items() if k != "spec"})

    # ---- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[Observation, dict]:
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, 2**31 - 1))
        self.episode_seed = int(seed)
        if self._worker is None or not self._worker.alive:  # a worker that died: a fresh one, rebuilt
            self._worker = None
            self._build()
        self._last = self._call("reset", self.episode_seed)
        # a backend may send the episode's own axis parameter (RoboCasa's pick_x: the offset in its kitchen)
        self.episode_param = float(self._last.get("axis_param", self.axis_param))
        self.has_progress = bool(self._facts())  # a task without a pick object: failures unknown, no progress
        self.instruction = self._last.get("instruction") or self.instruction
        self._t, self._done = 0, False
        return self._observation(), {"success": False, "step": 0, "seed": self.episode_seed}

    def _advance(self, action: np.ndarray) -> bool:
        self._last = self._call("step", action.astype(np.float64))
        return bool(self._last.get("success", False))

    def _facts(self) -> dict:
        """The worker's failure facts after the last reset or step (``touching``, ``bottom``, ``placed``,
        ``gripper_closed``; e.g. ``scenes/robocasa/backend.py failure_facts``); empty: none for this task."""
        return (self._last or {}).get("facts") or {}

    def _failure_signals(self) -> tuple[bool, float]:
        f = self._facts()
        return bool(f.get("touching", False)), float(f.get("bottom", 0.0))

    def _gripper_closed(self, action: np.ndarray) -> bool:
        return bool(self._facts().get("gripper_closed", False))  # the worker knows its action layout

    def _over_goal(self) -> bool | None:
        """The backend's placement predicate (RoboCasa: its success with the gripper's release ignored)."""
        placed = self._facts().get("placed")
        return None if placed is None else bool(placed)

    def failure_mode(self, success: bool) -> str:
        """As every scene's, but ``unknown`` (never a guessed class) when the worker sends no contact facts, or
        when the object lies where the task counts it yet the episode did not succeed (RoboCasa also wants the
        gripper 0.25 m away: released, not misplaced, and no mode names that)."""
        mode = super().failure_mode(success)
        if mode == "none" or self._trace is None or self._t == 0:
            return mode
        if not self.has_progress or (mode == "misplaced" and self._facts().get("placed")):
            return "unknown"
        return mode

    def _observation(self) -> Observation:
        last = self._last or {}
        return Observation(
            images=dict(last.get("images", {})),
            state=np.asarray(last["state"], dtype=np.float32),
            instruction=self.instruction,
            extras={"step": self._t},
        )

    def privileged_state(self):
        """The family's ``PrivilegedState`` of the worker's privileged facts (``SceneEnvironment.privileged_from``)."""
        return self._scene.environment.privileged_from(self._call("privileged"))

    def call(self, name: str, **kwargs) -> Any:
        """A backend extra by name (e.g. ``ep_meta``), for tests and the oracle."""
        return self._call("call", (name, kwargs))

    def kill_worker(self) -> None:
        """Make the worker exit now (tests: the worker dying mid-episode)."""
        try:
            self._worker.request("exit", 9)
        except WorkerDied:
            pass

    def render_frame(self, camera: str | None = None, size: Sequence[int] = (256, 256)) -> np.ndarray:
        last = self._last or {}
        images = last.get("images", {})
        if not images:
            raise SceneError(f"{self._where()}: no camera was rendered; request cameras to record video")
        return images[camera] if camera in images else next(iter(images.values()))

    def upright(self, image: np.ndarray) -> np.ndarray:
        """The worker's images are upright already (``render_frame`` shows them as they come)."""
        return image

    def close(self) -> None:
        """Free the level; its live worker is kept idle for the next env of this runtime (one per runtime)."""
        if self._worker is not None:
            worker, self._worker = self._worker, None
            key = (os.getpid(), self.runtime.name)
            if worker.alive and key not in _IDLE:
                try:
                    worker.request("drop")  # the simulator env goes; the interpreter and T0 cache stay
                    _IDLE[key] = worker
                    return
                except SceneError:
                    pass
            worker.close()
