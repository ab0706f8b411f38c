"""``SceneEnv``: one level of the tabletop family, built into this package's robosuite scene (``scenes.sim``) from
the level's ``SceneSpec`` and its ``Layout`` (``scenes.tabletop.builders``); the gym plumbing is ``BaseSceneEnv``'s."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from indgen_vla.core.errors import SceneError
from indgen_vla.core.protocol.interface import Observation
from scenes.axes import Successor, axis_param, check_progression, spec_at_level
from scenes.base_env import CAMERA_NAMES, BaseSceneEnv
from scenes.privileged import PrivilegedState

if TYPE_CHECKING:
    from scenes.family import Scene


class SceneEnv(BaseSceneEnv):
    """One level of one task of one scene; ``reset(seed=...)`` fixes the initial state completely."""

    _state: PrivilegedState | None = None  # privileged state after the last step (None right after a reset)

    def _load(self, scene: Scene, task: str, successor: Successor) -> None:
        self.instruction = scene.instruction(task)
        base = scene.base(task)
        # a step below the T0 jitter would not leave the easier levels' support
        check_progression(base, successor)
        self.spec = spec_at_level(base, successor, self.level)  # the frozen scene spec of this level
        self.axis_param = axis_param(self.spec, successor, self.level)
        self.success_predicate = scene.success_predicate
        layout = scene.layout(self.spec)
        try:
            from scenes.sim import IndgenRobosuiteEnv  # lazy: optional robosuite (the listings never build)

            self._sim_env = IndgenRobosuiteEnv(layout)
        except Exception as e:  # robosuite raises bare assertions and mujoco errors
            raise SceneError(f"scene {scene.name}/{task} level {self.level} failed to build: {e}") from e

    # ---- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[Observation, dict]:
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, 2**31 - 1))
        self.episode_seed = int(seed)
        self._rs.seed_placement(self.episode_seed)
        self._rs.reset()
        self._t, self._done, self._state = 0, False, None
        return self._observation(), {"success": False, "step": 0, "seed": self.episode_seed}

    # ---- extras for the engine and the oracle ----------------------------------------------------
    def privileged_state(self) -> PrivilegedState:
        """Object/receptacle poses, contacts and placement targets (for oracles only)."""
        return self._rs.privileged_state()

    # ---- the robosuite backend -------------------------------------------------------------------
    @property
    def _rs(self):
        """The robosuite env (None once closed)."""
        return self._sim_env

    def _advance(self, action: np.ndarray) -> bool:
        self._rs.step(action)
        self._state = self._rs.privileged_state()  # read again by _failure_signals, once per step
        return bool(self.success_predicate(self._state))

    def _failure_signals(self) -> tuple[bool, float]:
        s = self._state if self._state is not None else self._rs.privileged_state()
        return bool(s.pick.touching_gripper), float(s.pick.bottom)

    def _over_goal(self) -> bool | None:
        over = getattr(self.success_predicate, "over_goal", None)
        if over is None:
            return None
        return over(self._state if self._state is not None else self._rs.privileged_state())

    def _observation(self) -> Observation:
        images = {c: self._render(CAMERA_NAMES[c], self.image_size) for c in self.cameras}
        return Observation(
            images=images,
            state=self._rs.robot_state(),
            instruction=self.instruction,
            extras={"step": self._t},
        )

    def _observation_without_images(self) -> Observation:
        return Observation(images={}, state=self._rs.robot_state(), instruction=self.instruction,
                           extras={"step": self._t})  # fmt: skip
