"""The one observation/action interface every policy and scene shares (docs/contracts.md)."""

from __future__ import annotations

import numbers
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from indgen_vla.core.errors import ConfigError, PolicyError
from indgen_vla.core.protocol.policy_options import (  # noqa: F401  (re-exported: --precision, --compile)
    COMPILE_MODES,
    CUDA_GRAPH_COMPILE_MODES,
    PRECISIONS,
)
from indgen_vla.core.protocol.training_support import TrainedCell

CAMERAS = ("agentview", "wrist")
STATE_DIM = 8  # eef pos (3) + eef axis-angle (3) + gripper qpos (2): the LIBERO convention
ACTION_DIM = 7  # delta eef pos (3) + delta rotation (3) + gripper (-1 open, +1 close)
# what ``Policy.act`` returns: a (B, T, ACTION_DIM) float32 chunk, one row per observation, T actions each
type Action = np.ndarray
# robomimic's "object" observation for low-dim policies that declare it: pick then target, pos + quat (xyzw, w >= 0)
OBJECT_NAMES = tuple(f"{o}_{c}" for o in ("pick", "goal") for c in ("x", "y", "z", "qx", "qy", "qz", "qw"))
OBJECT_DIM = len(OBJECT_NAMES)
# robosuite OSC_POSE's default output range: one unit of action moves this far (what scripted controllers invert)
POS_SCALE = 0.05  # metres per unit action
ROT_SCALE = 0.5  # radians per unit action
NOOP_ACTION = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0)  # no motion, gripper open
# Observation.extras key the engine fills with (episode seed, control steps taken) of each query: a sampling policy
# draws that query's noise from it, so an episode's noise does not depend on the episodes it shares a batch with
QUERY_KEY = "indgen/query"
# why an episode failed (episodes.parquet "failure"), classified by the scene from privileged state; "" = older runs
FAILURE_MODES = (
    "none",
    "no_contact",
    "no_grasp",
    "dropped",
    "misplaced",
    "timeout_holding",
    "unknown",
    "error",
    "unavailable",  # the initial state could not hold the level (status "unavailable"): no policy failure
)


@dataclass(frozen=True)
class EnvSpec:
    """A scene family's observation/action contract: its camera names and state/action sizes (docs/contracts.md).

    The tabletop families (built-in, LIBERO) share ``TABLETOP``; a family with another robot declares its own
    (RoboCasa365's PandaOmron: three cameras, 16-d state, 12-d action) and names the layout in ``layout``.
    """

    name: str
    cameras: tuple[str, ...] = CAMERAS
    state_dim: int = STATE_DIM
    action_dim: int = ACTION_DIM
    layout: str = (
        "state: eef pos 3 + eef axis-angle 3 + gripper qpos 2; action: delta pos 3 + delta rot 3 + gripper 1"
    )
    # The layout as named (segment, size) pairs in order, where policy families order them differently (RoboCasa365:
    # lerobot's wrapper is base-first, RoboCasa's convert_action arm-first); a family's convention reorders by name.
    state_parts: tuple[tuple[str, int], ...] = ()
    action_parts: tuple[tuple[str, int], ...] = ()

    def __post_init__(self) -> None:
        if self.state_dim < 1 or self.action_dim < 1 or not self.cameras:
            raise ConfigError(f"env spec {self.name}: needs cameras and positive state/action sizes")
        for what, parts, dim in (
            ("state", self.state_parts, self.state_dim),
            ("action", self.action_parts, self.action_dim),
        ):
            if parts and sum(n for _, n in parts) != dim:
                raise ConfigError(
                    f"env spec {self.name}: {what}_parts add up to {sum(n for _, n in parts)}, not {dim}"
                )

    def check_policy(self, spec: PolicySpec, scene: str) -> None:
        """Refuse, in one line and before any episode, a policy whose cameras or action size this family lacks."""
        unknown = [c for c in spec.cameras if c not in self.cameras]
        if unknown:
            raise ConfigError(
                f"policy {spec.name} reads camera(s) {unknown}, which scene {scene} does not have; its cameras are "
                f"{list(self.cameras)} (map the policy's image keys to these)"
            )
        if spec.action_dim is not None and spec.action_dim != self.action_dim:
            raise ConfigError(
                f"policy {spec.name} returns {spec.action_dim}-d actions but scene {scene} takes {self.action_dim}-d "
                f"({self.layout.split('action: ')[-1]}); evaluate it on a scene with its action space"
            )


TABLETOP = EnvSpec("tabletop")


@dataclass(frozen=True)
class Observation:
    """What a learned policy may see: camera images, the robot state and the instruction.

    The tabletop families give raw-orientation images and the 8-d state; another family's ``EnvSpec`` fixes its
    own sizes (its env's observation space checks them).

    Privileged simulator state never appears here; oracles read it from the scene directly. ``objects``
    (the pick object's and the target's pose, ``OBJECT_NAMES``) is filled only for low-dimensional policies
    whose spec declares ``observes_objects``; image policies never get it. ``history`` (the cameras' images of
    the env steps just before this one, oldest first) is filled only for policies whose spec declares
    ``history_steps``: at most that many, none at an episode's first query.
    """

    images: dict[str, np.ndarray]
    state: np.ndarray
    instruction: str
    extras: dict[str, object] = field(default_factory=dict)
    objects: np.ndarray | None = None
    history: tuple[dict[str, np.ndarray], ...] = ()

    def __post_init__(self) -> None:
        if np.ndim(self.state) != 1:
            raise ValueError(
                f"state must be a 1-d array (e.g. ({STATE_DIM},)), got shape {np.shape(self.state)}"
            )
        if self.objects is not None and np.shape(self.objects) != (OBJECT_DIM,):
            raise ValueError(f"objects must have shape ({OBJECT_DIM},), got {np.shape(self.objects)}")
        _check_images(self.images, "image")
        if not isinstance(self.history, tuple):
            raise ValueError(f"history must be a tuple of image dicts, got {type(self.history).__name__}")
        for k, frame in enumerate(self.history):
            _check_images(frame, f"history[{k}] image")


def _check_images(images: dict[str, np.ndarray], what: str) -> None:
    """Refuse anything but uint8 HxWx3 camera images."""
    if not isinstance(images, Mapping):
        raise ValueError(f"{what}s must be a dict of camera name -> image, got {type(images).__name__}")
    for name, img in images.items():
        if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
            raise ValueError(f"{what} {name!r} must be uint8 HxWx3, got {img.dtype} {img.shape}")


def validate_chunk(chunk: np.ndarray, batch: int, who: str, action_dim: int = ACTION_DIM) -> np.ndarray:
    """Check a policy's (B, T, action_dim) action chunk (7 on the tabletop families); raise ``PolicyError`` naming
    the policy otherwise."""
    arr = np.asarray(chunk)
    if arr.ndim == 2 and batch == 1:
        arr = arr[None]
    if arr.ndim != 3 or arr.shape[0] != batch or arr.shape[2] != action_dim or arr.shape[1] < 1:
        raise PolicyError(
            f"policy {who} returned actions of shape {arr.shape}; expected ({batch}, T, {action_dim})"
        )
    if not np.all(np.isfinite(arr)):
        raise PolicyError(f"policy {who} returned non-finite actions (NaN or inf)")
    return arr.astype(np.float32, copy=False)


def act_padded(policy, observations: list, size: int, who: str, action_dim: int = ACTION_DIM) -> np.ndarray:
    """One batched ``act`` over ``observations`` padded to ``size`` rows (the first repeated), checked; the chunks
    of the real rows. Which observations share a batch depends on timing, and a batched forward can round
    differently with the batch size (BLAS blocking), so a fixed size keeps outcomes the same from run to run.

    A policy whose ``act`` takes ``pad_to`` pads after its per-row pre-processing (the padded rows then cost
    the forward only, not another decode/resize each) and returns the real rows alone."""
    if size > len(observations) and getattr(policy, "pads_batches", False):
        return validate_chunk(policy.act(list(observations), pad_to=size), len(observations), who, action_dim)
    rows = list(observations) + list(observations[:1]) * (size - len(observations))
    return validate_chunk(policy.act(rows), len(rows), who, action_dim)[: len(observations)]


@dataclass(frozen=True)
class PolicySpec:
    """What a policy needs and returns, declared by its adapter so the engine can serve it.

    Attributes:
        family: adapter family (``lerobot``, ``openpi``, ``openvla-oft``, ``groot``, ``univla``, ``rynnvla``, ``standin``).
        name: the full spec string the user passed.
        chunk_size: actions per returned chunk (T).
        replan_steps: actions the engine executes from each chunk before asking again.
        cameras: the scene's camera names the policy reads (empty for state-only policies: nothing is rendered);
            the scene family's ``EnvSpec`` lists them (tabletop: agentview/wrist; RoboCasa365: its three).
        image_size: (H, W) the engine should render at, or None for the scene default.
        batched: one ``act`` call may carry several environments' observations.
        privileged: reads simulator state (oracles only); the engine passes it in ``Observation.extras``.
        flip_180: the model was trained on 180°-rotated images (LIBERO); the adapter applies it.
        observes_objects: a low-dimensional policy that reads ``Observation.objects`` (robomimic's "object"
            observation); never an image policy.
        action_dim: the size of its actions, when the adapter knows it (checked against the scene's ``EnvSpec``
            before any episode); None: whatever the scene takes.
        history_steps: how many env steps before each query the policy also sees (``Observation.history``:
            its cameras' images of those steps, e.g. RynnVLA-002's previous frame); the engine renders them,
            one extra render per query and history step. 0: the current observation only.
        training: the (scene, task, axis, level) cells its training data covered, when its files say
            (``indgen train``'s ``train_info.json``); ``evaluate`` records them and ``report`` marks those levels.
        reads_observations: False for a policy whose actions ignore every observation (``standin:random``,
            ``standin:noop``, a replayed or open-loop script): it can neither generalize nor fail to, so
            ``evaluate`` records it in the manifest and every report opens with "Cannot answer" for it.
    """

    family: str
    name: str
    chunk_size: int = 1
    replan_steps: int = 1
    cameras: tuple[str, ...] = CAMERAS
    image_size: tuple[int, int] | None = None
    batched: bool = False
    privileged: bool = False
    flip_180: bool = False
    observes_objects: bool = False
    action_dim: int | None = None
    training: tuple[TrainedCell, ...] = ()
    history_steps: int = 0
    reads_observations: bool = True

    def __post_init__(self) -> None:
        self._check_types()
        if self.chunk_size < 1:
            raise ConfigError(f"policy {self.name}: chunk_size must be >= 1, got {self.chunk_size}")
        if not 1 <= self.replan_steps <= self.chunk_size:
            raise ConfigError(
                f"policy {self.name}: replan_steps must be in 1..chunk_size ({self.chunk_size}), got {self.replan_steps}"
            )
        bad = [c for c in self.cameras if not (isinstance(c, str) and c.replace("_", "").isalnum())]
        if bad:  # which cameras exist is the scene's (EnvSpec.check_policy, before any episode)
            raise ConfigError(f"policy {self.name}: camera names must be identifiers, got {bad}")
        if self.action_dim is not None and self.action_dim < 1:
            raise ConfigError(f"policy {self.name}: action_dim must be >= 1, got {self.action_dim}")
        if self.observes_objects and self.cameras:
            raise ConfigError(
                f"policy {self.name}: object poses are for low-dimensional policies only; drop its cameras "
                "or observes_objects"
            )
        if not isinstance(self.reads_observations, bool):
            raise ConfigError(
                f"policy {self.name}: reads_observations must be true or false, got {self.reads_observations!r}"
            )
        steps = self.history_steps
        if isinstance(steps, bool) or not isinstance(steps, int) or steps < 0:
            raise ConfigError(f"policy {self.name}: history_steps must be an integer >= 0, got {steps!r}")
        if self.history_steps and not self.cameras:
            raise ConfigError(
                f"policy {self.name}: history_steps={self.history_steps} keeps camera images, but it reads no "
                "camera; declare its cameras or history_steps=0"
            )

    def _check_types(self) -> None:
        """A policy of one's own declares its spec by hand: a wrong type is one line here, not a TypeError (or a
        camera per letter of a name) mid-run; ``image_size=64`` is (64, 64)."""
        for name in ("chunk_size", "replan_steps"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Integral):
                raise ConfigError(f"policy {self.name}: {name} must be an integer, got {value!r}")
            object.__setattr__(self, name, int(value))
        for name in ("batched", "privileged", "flip_180", "observes_objects"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(
                    f"policy {self.name}: {name} must be true or false, got {getattr(self, name)!r}"
                )
        if isinstance(self.cameras, str) or not isinstance(self.cameras, tuple | list):
            raise ConfigError(f"policy {self.name}: cameras must be a tuple of camera names, e.g. ('agentview',) "
                              f"or () for none, got {self.cameras!r}")  # fmt: skip
        object.__setattr__(self, "cameras", tuple(self.cameras))
        size = self.image_size
        if isinstance(size, numbers.Integral) and not isinstance(size, bool):
            size = (size, size)
        if size is not None:
            ok = isinstance(size, tuple | list) and len(size) == 2
            if not (
                ok
                and all(isinstance(x, numbers.Integral) and not isinstance(x, bool) and x >= 1 for x in size)
            ):
                raise ConfigError(
                    f"policy {self.name}: image_size must be (H, W) in pixels or None, got {size!r}"
                )
            object.__setattr__(self, "image_size", (int(size[0]), int(size[1])))


def declared_reads(values: Iterable[bool | None]) -> bool | None:
    """Several runs' manifest ``reads_observations`` as one (a merge's shards, a group of seeds): False when any
    declares a blind policy, True when all declare a seeing one, None (unknown: a run made before the field)
    otherwise."""
    values = list(values)
    if False in values:
        return False
    return True if values and all(v is True for v in values) else None


@dataclass(frozen=True)
class ScenePreview:
    """What a policy will ask of the scene, read from its files before it loads (``registry.preview_policy``), so
    workers build the first scenes during the load; the loaded policy's ``PolicySpec`` stays the authority (the
    engine discards the early scenes when the two disagree). Fields as in ``PolicySpec``."""

    cameras: tuple[str, ...]
    image_size: tuple[int, int] | None = None
    privileged: bool = False
    observes_objects: bool = False
    history_steps: int = 0


@runtime_checkable
class Policy(Protocol):
    """Observation batch in, (B, T, 7) float32 action chunk out.

    ``reset`` starts a new episode. Policies that keep per-episode state declare ``batched=False``
    and the engine gives each environment its own instance; batched policies must be stateless
    between ``act`` calls.
    """

    spec: PolicySpec

    def reset(self, instruction: str, seed: int | None = None) -> None: ...

    def act(self, observations: Sequence[Observation]) -> Action: ...

    def close(self) -> None: ...
