"""Frozen scene specs: everything a builder needs to make one level of one task, and nothing else.

A spec is pure data. Successors (``scenes.axes``) edit exactly one field of it; builders
(``scenes.sim`` and the per-scene modules) turn it into MJCF and a seeded placement. Lengths are in
metres in the robosuite world frame: the table top is centred at (0, 0, 0.8), +x points away from the
robot, +y to the robot's left.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from indgen_vla.core.errors import ConfigError

INCH = 0.0254  # metres per inch (the stack axis is specified in inches, as in the paper's real robot)

# Pick objects of the pick-and-place scenes: key -> (display name, grasp height as a fraction of height).
PICK_OBJECTS: dict[str, tuple[str, float]] = {
    "milk": ("milk carton", 0.6),
    "bread": ("bread", 0.55),
    "can": ("soda can", 0.65),
    "lemon": ("lemon", 0.55),
    "bottle": ("bottle", 0.70),
    "cube": ("red cube", 0.55),
    "cylinder": ("green cylinder", 0.60),
}

BLOCK_COLOURS: dict[str, tuple[float, float, float, float]] = {
    "red": (0.85, 0.15, 0.12, 1.0),
    "green": (0.15, 0.65, 0.2, 1.0),
    "blue": (0.12, 0.3, 0.85, 1.0),
    "yellow": (0.92, 0.8, 0.1, 1.0),
    "orange": (0.95, 0.5, 0.1, 1.0),
}


def _finite(name: str, *values: float) -> None:
    for v in values:
        if not math.isfinite(v):
            raise ConfigError(f"scene spec field {name} must be finite, got {v}")


@dataclass(frozen=True)
class Item:
    """One physical object's identity and nominal pose on the table (before T0 jitter)."""

    kind: str
    x: float
    y: float
    scale: float = 1.0
    yaw: float = 0.0

    def __post_init__(self) -> None:
        _finite(f"{self.kind}.x/y/yaw", self.x, self.y, self.yaw)
        if not 0.3 <= self.scale <= 3.0:
            raise ConfigError(
                f"object {self.kind}: scale {self.scale:g} is outside the physical range 0.3..3"
            )


@dataclass(frozen=True)
class SceneSpec:
    """One task at one level. Each axis owns exactly one field (see ``scenes.axes``).

    Attributes:
        scene, task: registry names.
        pick: the object to move (``pick.x``/``pick.y``/``pick.scale`` are the pick_x/pick_y/scale axes).
        goal: the receptacle or target (``goal.y`` is the goal_y axis).
        jitter: half-width (m) of the uniform T0 jitter of pick and goal x/y; axes that translate those
            must step by more than twice this so level k leaves the support of the easier levels.
        robot_back: horizon axis, metres the robot base moves back from the table (world -x).
        fixture_x: fixture_x axis, metres the cabinet slides along its own x (its width; world +y).
        clutter: clutter axis, number of clutter objects in the receptacle/cabinet.
        distractors: distractor axis, number of visual-only distractors.
        stack_in: stack axis, height (inches) of the riser stack under the target block.
        dressing: other objects on the table, fixed for the scene.
    """

    scene: str
    task: str
    pick: Item
    goal: Item
    jitter: float = 0.01
    robot_back: float = 0.0
    fixture_x: float = 0.0
    clutter: int = 0
    distractors: int = 0
    stack_in: float = 0.0
    dressing: tuple[Item, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        _finite(
            "jitter/robot_back/fixture_x/stack_in",
            self.jitter,
            self.robot_back,
            self.fixture_x,
            self.stack_in,
        )
        if not 0 <= self.jitter <= 0.05:
            raise ConfigError(f"scene {self.scene}: jitter {self.jitter} must be in 0..0.05 m")
        if self.robot_back < -0.1:
            raise ConfigError(
                f"scene {self.scene}: robot_back {self.robot_back} would push the robot into the table"
            )
        for name in ("clutter", "distractors"):
            value = getattr(self, name)
            if not isinstance(value, int) or value < 0:
                raise ConfigError(f"scene {self.scene}: {name} must be a non-negative integer, got {value!r}")
        if self.stack_in < 0:
            raise ConfigError(f"scene {self.scene}: stack height {self.stack_in} in must be >= 0")

    @property
    def stack_m(self) -> float:
        return self.stack_in * INCH
