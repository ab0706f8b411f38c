"""Why an episode failed, read from privileged simulator state the policy never sees.

The scene env feeds a ``FailureTrace`` one sample per control step (does a finger touch the pick object,
how high is its bottom, does the action command the gripper closed); ``classify`` turns the trace into one
mode. The names follow the manipulation-failure taxonomies (AHA/FailGen: no grasp, slip, placement error)
as far as the simulator state can tell them apart:

| mode | meaning |
|---|---|
| ``none`` | the episode succeeded |
| ``no_contact`` | the gripper never touched the pick object |
| ``no_grasp`` | the gripper touched the object but never lifted it ``LIFT_M`` above where it started |
| ``dropped`` | the object was lifted, then left the fingers while the gripper was still commanded closed (slip) |
| ``misplaced`` | the object was lifted and released (gripper commanded open) somewhere the task does not count |
| ``timeout_holding`` | the step limit came while the fingers still touched the object after lifting it |
| ``unknown`` | the scene cannot tell (no contact signals for this task, e.g. RoboCasa's fixture tasks) |
| ``error`` | the episode crashed (policy, server or simulator); set by the engine, not by the trace |

The same trace gives the ordinal **progress** score (``progress``; ``indgen_vla.core.reporting.partial_credit.STAGES``): the highest
stage whose predicate held at some control step, with the same predicates at every level of every axis:

| score | stage | predicate (privileged state, per control step) |
|---|---|---|
| 0 | ``no_contact`` | none of the below |
| 1 | ``contact`` | a finger touches the pick object |
| 2 | ``grasp`` | a finger touches it while the gripper is commanded closed, ``GRASP_STEPS`` steps in a row |
| 3 | ``lift`` | a finger touches it while its bottom is ``LIFT_M`` above its start (the failure modes' lift) |
| 4 | ``transport`` | lifted as in 3 (touching, up) while its centre is over the goal region (``over_goal``) |
| 5 | ``success`` | the scene's success predicate |

So progress 0 is ``no_contact``, 1-2 is ``no_grasp`` and 3-4 is ``dropped``/``misplaced``/``timeout_holding``.
The goal region is the family's (``SceneEnv._over_goal``); a family without one has no stage 4, and a family
or task without contact signals (an external family whose worker sends no facts: RoboCasa's fixture tasks) has no
progress at all (None, stored as missing) and fails as ``unknown``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from indgen_vla.core.protocol.interface import FAILURE_MODES

__all__ = ["FAILURE_MODES", "GRASP_STEPS", "LIFT_M", "FailureTrace"]
LIFT_M = 0.02  # the object's bottom must rise this far above its start for a grasp to count as a lift
GRASP_STEPS = 3  # consecutive closed-gripper contact steps for a grasp (a touch while closing is not one)


@dataclass
class FailureTrace:
    """Running summary of one episode's contacts and lifts (a few booleans, O(1) per step)."""

    start_bottom: float
    touched: bool = False
    lifted: bool = False
    holding: bool = False  # touching now
    released_closed: bool | None = None  # gripper command at the last release after a lift; None = none yet
    closed_contact: int = 0  # consecutive steps touching with the gripper commanded closed
    grasped: bool = False
    transported: bool = False

    def update(
        self, touching: bool, bottom: float, gripper_closed: bool, over_goal: Callable[[], bool | None] | None = None
    ) -> None:  # fmt: skip
        """Add one control step: finger contact, the object's bottom z, the commanded gripper state, and (read
        only while the object is lifted, not yet transported) whether it is over the goal region."""
        up = bottom >= self.start_bottom + LIFT_M
        if self.holding and not touching and self.lifted:
            self.released_closed = gripper_closed
        self.touched |= touching
        self.lifted |= touching and up
        self.holding = touching
        self.closed_contact = self.closed_contact + 1 if touching and gripper_closed else 0
        self.grasped |= self.closed_contact >= GRASP_STEPS
        if touching and up and not self.transported and over_goal is not None:
            self.transported = bool(over_goal())

    def progress(self, success: bool) -> int:
        """The ordinal progress score 0..5 (module table): the highest stage reached."""
        if success:
            return 5
        if self.transported:
            return 4
        if self.lifted:
            return 3
        if self.grasped:
            return 2
        return 1 if self.touched else 0

    def classify(self, success: bool) -> str:
        """The episode's failure mode (``none`` on success); see the module table."""
        if success:
            return "none"
        if not self.touched:
            return "no_contact"
        if not self.lifted:
            return "no_grasp"
        if self.holding:
            return "timeout_holding"
        if self.released_closed:
            return "dropped"
        return "misplaced"
