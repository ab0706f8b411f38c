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
| ``error`` | the episode crashed (policy, server or simulator); set by the engine, not by the trace |
"""

from __future__ import annotations

from dataclasses import dataclass

from indgen_vla.interface import FAILURE_MODES

__all__ = ["FAILURE_MODES", "LIFT_M", "FailureTrace"]
LIFT_M = 0.02  # the object's bottom must rise this far above its start for a grasp to count as a lift


@dataclass
class FailureTrace:
    """Running summary of one episode's contacts and lifts (a few booleans, O(1) per step)."""

    start_bottom: float
    touched: bool = False
    lifted: bool = False
    holding: bool = False  # touching now
    released_closed: bool | None = None  # gripper command at the last release after a lift; None = none yet

    def update(self, touching: bool, bottom: float, gripper_closed: bool) -> None:
        """Add one control step: finger contact, the object's bottom z, and the commanded gripper state."""
        up = bottom >= self.start_bottom + LIFT_M
        if self.holding and not touching and self.lifted:
            self.released_closed = gripper_closed
        self.touched |= touching
        self.lifted |= touching and up
        self.holding = touching

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
