"""``BaseSceneEnv``: the gymnasium-compatible scene every policy and the rollout engine talk to, whichever family.

One env is one (scene, task, axis, level) of a family (``scenes.tabletop.env.SceneEnv``,
``scenes.libero.env.LiberoSceneEnv``); it renders only the requested cameras (MuJoCo's own offscreen renderer,
images kept in the simulator's raw upside-down orientation) and judges success with the family's single success
predicate. The arguments every env checks, its observation space and the dict-observation wrapper live here too.
"""

from __future__ import annotations

from collections.abc import Sequence

import gymnasium as gym
import numpy as np

from indgen_vla.core.errors import ConfigError, SceneError
from indgen_vla.core.protocol.interface import CAMERAS, STATE_DIM, TABLETOP, Observation
from scenes.axes import Successor
from scenes.failure import FailureTrace
from scenes.family import Scene
from scenes.poses import object_poses, object_vector
from scenes.privileged import PrivilegedState, with_privileged

# interface camera -> MuJoCo camera of the robosuite tabletop scenes (scenes.sim.CAMERA_NAMES; kept here so that
# importing scenes.base_env does not import robosuite: an external family's proxy env must not load robosuite 1.4)
CAMERA_NAMES = {"agentview": "agentview", "wrist": "robot0_eye_in_hand"}


def _check_size(size: tuple[int, int], what: str) -> tuple[int, int]:
    try:
        h, w = (int(size[0]), int(size[1]))
    except (TypeError, ValueError, IndexError):
        raise ConfigError(f"{what} must be (height, width), got {size!r}") from None
    if not (8 <= h <= 2048 and 8 <= w <= 2048):
        raise ConfigError(f"{what} {size!r} must lie in 8..2048 pixels per side")
    return h, w


def check_env_args(
    cameras: Sequence[str], max_steps: int | None, known: Sequence[str] = CAMERAS
) -> tuple[str, ...]:  # fmt: skip
    """Validate the camera names (``known``: the family's ``EnvSpec.cameras``) and step limit every scene env
    accepts; returns the cameras as a tuple."""
    cams = tuple(cameras)
    bad = [c for c in cams if c not in known]
    if bad:
        raise ConfigError(f"unknown camera(s) {bad}; cameras are {list(known)}")
    if max_steps is not None and int(max_steps) < 1:
        raise ConfigError(f"max_steps must be >= 1, got {max_steps}")
    return cams


class ObservationSpace(gym.spaces.Space):
    """What a scene env's ``reset``/``step`` return: an ``Observation`` with one uint8 HxWx3 image per requested
    camera and the float32 robot state (``DictObservation`` gives the same as a ``spaces.Dict``)."""

    def __init__(
        self, cameras: tuple[str, ...], image_size: tuple[int, int], seed: int | None = None,
        state_dim: int = STATE_DIM,
    ):  # fmt: skip
        h, w = image_size
        self.images = {c: gym.spaces.Box(0, 255, (h, w, 3), np.uint8) for c in cameras}
        self.state = gym.spaces.Box(-np.inf, np.inf, (state_dim,), np.float32)
        super().__init__(seed=seed)

    def as_dict(self) -> gym.spaces.Dict:
        """The same observations as ``{camera: image, "state": state}`` (``DictObservation``'s space)."""
        return gym.spaces.Dict({**self.images, "state": self.state})

    def contains(self, x) -> bool:
        return (
            isinstance(x, Observation)
            and set(x.images) == set(self.images)
            and all(self.images[c].contains(x.images[c]) for c in self.images)
            and self.state.contains(np.asarray(x.state))
        )

    def sample(self, mask=None, probability=None) -> Observation:
        return Observation(
            images={c: b.sample() for c, b in self.images.items()}, state=self.state.sample(), instruction=""
        )

    def seed(self, seed: int | None = None) -> list[int]:
        seeds = super().seed(seed)
        for i, b in enumerate([*self.images.values(), self.state]):
            b.seed(None if seed is None else seed + 1 + i)
        return seeds

    def __eq__(self, other) -> bool:
        return isinstance(other, ObservationSpace) and self.as_dict() == other.as_dict()

    def __repr__(self) -> str:
        return f"ObservationSpace({self.as_dict()!r})"


class BaseSceneEnv(gym.Env):
    """The gym plumbing every scene env shares: arguments, spaces, the step contract, video frames, closing."""

    # A backend implements _load (build the level; put its simulator env, anything with .sim and .close(),
    # in _sim_env), reset (setting _t/_done), _advance (one simulator step; returns success) and _observation.

    _sim_env = None  # the backend's robosuite-style env; None before it is built and once closed
    _trace: FailureTrace | None = None  # this episode's contacts and lifts (privileged; never observed)
    _observing: bool = True  # whether the step in progress must produce camera images (``step(observe=...)``)
    # the last reset's own axis parameter where a backend sets one per episode (RoboCasa's pick_x: the offset in its
    # kitchen); None: the level's ``axis_param``
    episode_param: float | None = None
    has_progress: bool = (
        True  # the failure trace's signals are real (external proxies have none: no progress)
    )

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}
    render_mode = "rgb_array"  # render() returns an upright agentview frame (``render_frame``)

    def __init__(
        self,
        scene: Scene,
        task: str,
        successor: Successor,
        level: int,
        cameras: Sequence[str] = CAMERAS,
        image_size: tuple[int, int] = (128, 128),
        max_steps: int | None = None,
    ):
        self.env_spec = getattr(scene, "env_spec", TABLETOP)
        if tuple(cameras) == CAMERAS and self.env_spec.cameras != CAMERAS:
            cameras = self.env_spec.cameras  # the default camera set is the family's own
        self.cameras = check_env_args(cameras, max_steps, self.env_spec.cameras)
        self.scene, self.task, self.level = scene.name, task, int(level)
        self.axis = successor.axis
        self.image_size = _check_size(image_size, "image_size")
        self.max_steps = int(max_steps) if max_steps is not None else scene.task_max_steps(task)
        self._renderers: dict[tuple[int, int], object] = {}
        self._scene_option = None
        self._t = 0
        self._done = True
        self.episode_seed: int | None = None
        self._load(scene, task, successor)
        self.observation_space = ObservationSpace(
            self.cameras, self.image_size, state_dim=self.env_spec.state_dim
        )
        self.action_space = gym.spaces.Box(-1.0, 1.0, (self.env_spec.action_dim,), np.float32)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.scene}/{self.task} axis={self.axis.name} level={self.level}>"

    __str__ = __repr__

    # ---- gymnasium API -------------------------------------------------------------------------
    def step(self, action, observe: bool = True) -> tuple[Observation, float, bool, bool, dict]:
        """Gymnasium's step; ``observe=False`` (the engine, for steps whose observation nobody reads) skips the
        camera renders where the scene can: the returned observation then has no images, all else is the same."""
        if self._done:
            raise SceneError("step() after the episode ended; call reset() first")
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        dim = self.action_space.shape[0]
        if a.shape != (dim,) or not np.all(np.isfinite(a)):
            raise SceneError(f"action must be {dim} finite numbers, got shape {np.shape(action)}")
        if self._t == 0:  # the episode's first step: the trace starts from the reset state
            self._trace = FailureTrace(start_bottom=self._failure_signals()[1])
        self._observing = observe
        success = self._advance(np.clip(a, -1.0, 1.0))
        self._trace.update(
            *self._failure_signals(), gripper_closed=self._gripper_closed(a), over_goal=self._over_goal
        )
        self._t += 1
        terminated = success
        truncated = (not success) and self._t >= self.max_steps
        self._done = terminated or truncated
        return (
            self._observation() if observe else self._observation_without_images(),
            float(success),
            terminated,
            truncated,
            {"success": success, "step": self._t},
        )

    def render(self) -> np.ndarray:
        return self.render_frame()

    def close(self) -> None:
        renderers = getattr(self, "_renderers", {})
        for r in renderers.values():
            r.close()
        renderers.clear()
        if self._sim_env is not None:
            self._sim_env.close()
            self._sim_env = None

    @property
    def steps(self) -> int:
        return self._t

    def object_observation(self) -> np.ndarray:
        """The pick object's and the target's pose (``Observation.objects``) for low-dim policies that declare it."""
        return object_vector(object_poses(self.privileged_state()))

    def failure_mode(self, success: bool) -> str:
        """Why the episode so far failed (``scenes.failure``); ``none`` on success or before any step."""
        return "none" if success or self._trace is None or self._t == 0 else self._trace.classify(success)

    def progress(self, success: bool) -> int | None:
        """The episode's ordinal progress 0..5 so far (``scenes.failure``); None where the family has no
        contact signals (``has_progress``) or before any step."""
        if not self.has_progress or self._trace is None or self._t == 0:
            return 5 if success and self.has_progress else None
        return self._trace.progress(success)

    def render_frame(self, camera: str = "agentview", size: tuple[int, int] = (256, 256)) -> np.ndarray:
        """One upright (human-viewable) uint8 HxWx3 frame from ``camera`` for videos, whatever ``cameras`` is.

        Unlike observation images (raw simulator orientation, upside down), video frames are flipped upright.
        """
        names = self._camera_names()
        if camera not in names:
            raise ConfigError(f"unknown camera {camera!r}; cameras are {list(names)}")
        return self.upright(self._render(names[camera], _check_size(size, "frame size")))

    def upright(self, image: np.ndarray) -> np.ndarray:
        """An observation image as a person views it (videos, ``indgen preview``): robosuite renders upside down."""
        return np.ascontiguousarray(image[::-1])

    def _render(self, camera: str, size: tuple[int, int]) -> np.ndarray:
        """MuJoCo camera ``camera`` at ``size`` in robosuite's raw (OpenGL, upside-down) orientation."""
        import mujoco

        renderer = self._renderers.get(size)
        if renderer is None:
            model = self._mj_model()
            model.vis.global_.offwidth = max(model.vis.global_.offwidth, size[1])
            model.vis.global_.offheight = max(model.vis.global_.offheight, size[0])
            renderer = mujoco.Renderer(model, height=size[0], width=size[1])
            self._renderers[size] = renderer
        if self._scene_option is None:
            self._scene_option = mujoco.MjvOption()
            self._scene_option.geomgroup[0] = 0  # like robosuite: draw visual meshes, not collision geoms
        renderer.update_scene(self._mj_data(), camera=camera, scene_option=self._scene_option)
        return np.ascontiguousarray(renderer.render()[::-1])

    # ---- what a backend provides ---------------------------------------------------------------
    def _load(self, scene: Scene, task: str, successor: Successor) -> None:
        """Build this level's simulator into ``_sim_env`` (and whatever else the backend needs)."""
        raise NotImplementedError

    def _camera_names(self) -> dict[str, str]:
        """Interface camera name -> MuJoCo camera name."""
        return CAMERA_NAMES

    def _advance(self, action: np.ndarray) -> bool:
        """Apply one clipped action to the simulator; return the success predicate after it."""
        raise NotImplementedError

    def _failure_signals(self) -> tuple[bool, float]:
        """(a finger touches the pick object, the pick object's lowest z) now, for the failure trace."""
        raise NotImplementedError

    def _gripper_closed(self, action: np.ndarray) -> bool:
        """Whether ``action`` commands the gripper closed (the 7-d/8-d tabletop action: its last entry > 0)."""
        return bool(action[-1] > 0)

    def _over_goal(self) -> bool | None:
        """Whether the pick object's centre is over the goal region now (progress stage 4); None: no such region."""
        return None

    def _observation(self) -> Observation:
        raise NotImplementedError

    def _observation_without_images(self) -> Observation:
        """The observation minus the camera images (scenes whose images come with the physics step: all of it)."""
        return self._observation()

    def privileged_state(self) -> PrivilegedState:
        """The simulator facts oracles and the success predicate read, now (``scenes.privileged``)."""
        raise NotImplementedError

    def with_privileged(self, obs: Observation) -> Observation:
        """``obs`` with this env's privileged state attached, for privileged policies only (the engine's call)."""
        return with_privileged(obs, self)

    def _mj_model(self):
        return self._sim_env.sim.model._model

    def _mj_data(self):
        return self._sim_env.sim.data._data


class DictObservation(gym.ObservationWrapper):
    """A scene env with plain dict observations (``{camera: image, "state": state}``) in a ``spaces.Dict``, for
    gymnasium tooling such as ``gymnasium.utils.env_checker``."""

    def __init__(self, env: BaseSceneEnv):
        super().__init__(env)
        self.observation_space = env.observation_space.as_dict()

    def observation(self, observation: Observation) -> dict[str, np.ndarray]:
        return {**observation.images, "state": observation.state}
