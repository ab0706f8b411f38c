"""``PrivilegedState``: the simulator facts an oracle, a success predicate and the failure trace read.

Every scene env's ``privileged_state()`` returns one; learned policies never see it. The engine attaches it to
an oracle's observation with ``with_privileged`` (``Observation.extras["privileged"]``), and the oracle reads
it back with ``privileged_of``. Scene-specific facts a scene lacks are ``None``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from indgen_vla.core.errors import PolicyError, SceneError
from indgen_vla.core.protocol.interface import Observation

PRIVILEGED_KEY = "privileged"  # the Observation.extras key the engine fills for privileged policies


def _check_shape(what: str, value, shape: tuple[int, ...]) -> None:
    if getattr(value, "shape", None) != shape:  # read every control step: no np.shape dispatch
        raise SceneError(
            f"privileged state: {what} must be a NumPy array of shape {shape}, got {type(value).__name__} "
            f"of shape {np.shape(value)}"
        )


@dataclass(frozen=True, slots=True)
class PickState:
    """The object to pick: world pose (quaternion wxyz), linear velocity and world-AABB extents."""

    pos: np.ndarray
    quat_wxyz: np.ndarray
    linvel: np.ndarray
    bottom: float  # lowest z of its collision geoms
    top: float  # highest z of its collision geoms
    half_width: float  # horizontal half extent
    touching_gripper: bool  # a finger touches it
    half_extents: np.ndarray | None = (
        None  # half sizes along its own axes (x, y, z), where the scene knows them
    )

    def __post_init__(self) -> None:
        _check_shape("pick.pos", self.pos, (3,))
        _check_shape("pick.quat_wxyz", self.quat_wxyz, (4,))
        _check_shape("pick.linvel", self.linvel, (3,))


@dataclass(frozen=True, slots=True)
class GoalState:
    """The receptacle or target body: world pose (quaternion wxyz) and the top of its geoms."""

    pos: np.ndarray
    quat_wxyz: np.ndarray
    top: float

    def __post_init__(self) -> None:
        _check_shape("goal.pos", self.pos, (3,))
        _check_shape("goal.quat_wxyz", self.quat_wxyz, (4,))


@dataclass(frozen=True, slots=True)
class Targets:
    """Where the scene wants the pick object: the grasp height, the height to clear, where to put it down."""

    place_xy: np.ndarray  # world xy the object is carried to
    place_bottom: float  # the object's bottom z when put down there
    clear_z: float  # highest obstacle between the pick object and the place point
    grasp_z: float  # grip-site height for the grasp
    floor_z: float | None = None  # the receptacle's inner floor (scenes with a receptacle)
    grasp_xy: np.ndarray | None = (
        None  # world xy to grasp at, where not the object's centre (LIBERO's neighbours)
    )

    def __post_init__(self) -> None:
        _check_shape("target.place_xy", self.place_xy, (2,))


@dataclass(frozen=True, slots=True)
class SceneFacts:
    """Constant geometry a scene's success predicate reads (``None`` where the scene has no such thing)."""

    receptacle_inner: tuple[float, float] | None = None  # interior half extents (x, y) of the receptacle
    fixture_centre: np.ndarray | None = None  # world xy of the fixture the object must leave
    fixture_half: tuple[float, float] | None = None  # its footprint's half extents (x, y)
    button: bool = False  # a press task's part is a button: one touch counts, at its release (RoboCasa)
    base_room: tuple[float, ...] | None = None  # m a mobile base may drive ahead, back, left, right
    ceiling: float | None = None  # z of the underside of what hangs over a fixture part to push (RoboCasa)
    # the hinged part (goal: its hinge) is lifted from under its free edge, not swept shut: "opens" (the mixer's
    # head) or "shuts" (the toaster oven's door, lying open toward the robot); None: swept shut (a kettle's lid)
    lift: str | None = None
    lever: bool = False  # the part is a lever beside the fixture, pressed down at its free end (RoboCasa)
    # a carry drives the mobile base twice: the pick object, then (held) the place point, straight ahead (RoboCasa)
    carry_drives: bool = False
    reach_drives: bool = False  # ... only where the pick object lies beyond the arm's reach (RoboCasa)

    def __post_init__(self) -> None:
        if self.lift not in (None, "opens", "shuts"):
            raise ValueError(
                f"SceneFacts.lift is {self.lift!r}: give 'opens', 'shuts' or None (swept, not lifted)"
            )


NO_FACTS = SceneFacts()


@dataclass(frozen=True, slots=True)
class PrivilegedState:
    """One instant of privileged simulator state: the arm, the pick object, the goal body and the targets."""

    eef_pos: np.ndarray  # grip site, world
    eef_mat: np.ndarray  # grip site orientation, 3x3
    gripper_qpos: np.ndarray  # finger joint positions
    pick: PickState
    goal: GoalState | None  # None in scenes without a free receptacle body (cabinet_pick)
    target: Targets
    table_top: float | None = None  # z of the table surface (built-in scenes)
    facts: SceneFacts = NO_FACTS
    bddl_success: bool | None = (
        None  # the benchmark's own goal check (LIBERO's BDDL, RoboCasa's _check_success)
    )
    robot_base: np.ndarray | None = (
        None  # (x, y, yaw) of a mobile base (RoboCasa's PandaOmron: arm actions are
    )
    # in its frame); None on the fixed-base tabletop arms

    def __post_init__(self) -> None:
        _check_shape("eef_pos", self.eef_pos, (3,))
        _check_shape("eef_mat", self.eef_mat, (3, 3))


def with_privileged(obs: Observation, env) -> Observation:
    """``obs`` with ``env``'s privileged state in ``extras["privileged"]`` (for privileged policies only)."""
    return dataclasses.replace(obs, extras={**obs.extras, PRIVILEGED_KEY: env.privileged_state()})


def privileged_of(obs: Observation, who: str) -> PrivilegedState:
    """The privileged state ``with_privileged`` attached to ``obs``; a one-line ``PolicyError`` without it."""
    state = obs.extras.get(PRIVILEGED_KEY)
    if not isinstance(state, PrivilegedState):
        raise PolicyError(
            f"{who} needs the env's privileged state in Observation.extras['{PRIVILEGED_KEY}'] "
            "(the engine attaches it for policies whose spec says privileged=True)"
        )
    return state
