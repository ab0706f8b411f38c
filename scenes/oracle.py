"""The privileged scripted oracle that certifies every level (Assumption 2): approach, grasp, lift, transport, release.

It reads ``observations[0].extras["privileged"]`` (the env's ``privileged_state()``, passed by the engine)
and emits 7-d OSC_POSE delta actions. It has no randomness, so it is deterministic given the episode.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from indgen_vla.errors import PolicyError
from indgen_vla.interface import ACTION_DIM, ROT_SCALE, Observation, PolicySpec

# Gripper pointing straight down, fingers closing along world y (the Panda's home orientation, untilted).
R_DOWN = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def _axis_angle(r: np.ndarray) -> np.ndarray:
    """Axis-angle vector of a rotation matrix."""
    cos = np.clip((np.trace(r) - 1) / 2, -1.0, 1.0)
    angle = np.arccos(cos)
    if angle < 1e-6:
        return np.zeros(3)
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    n = np.linalg.norm(v)
    if n < 1e-9:  # angle ~ pi: take the axis from the symmetric part
        w, vecs = np.linalg.eigh((r + r.T) / 2)
        return vecs[:, np.argmax(w)] * angle
    return v / n * angle


class OraclePolicy:
    """Scripted pick-and-place from privileged object poses; one instance per environment (not batched)."""

    spec = PolicySpec(family="standin", name="standin:oracle", privileged=True, cameras=(), batched=False)

    def __init__(self, gain: float = 12.0, max_retries: int = 2):
        self.gain = gain
        self.max_retries = max_retries
        self.reset("")

    def reset(self, instruction: str, seed: int | None = None) -> None:
        self._phase, self._count, self._retries, self._trace = "approach", 0, 0, []
        self._offset = 0.0
        self._start_bottom = -np.inf  # the pick's bottom when grasped: what it rested on must be cleared too
        self._hold: np.ndarray | None = None
        self.seed = seed

    def close(self) -> None:
        pass

    @property
    def phase(self) -> str:
        return self._phase

    def act(self, observations: Sequence[Observation]) -> np.ndarray:
        if len(observations) != 1:
            raise PolicyError(f"standin:oracle is not batched; got {len(observations)} observations")
        priv = observations[0].extras.get("privileged")
        if not isinstance(priv, dict):
            raise PolicyError(
                "standin:oracle needs the env's privileged state in Observation.extras['privileged']"
            )
        return self.action(priv)[None, None, :].astype(np.float32)

    # ---- the state machine ---------------------------------------------------------------------
    def _goto(self, s: dict, target: np.ndarray, grip: float, speed: float = 1.0) -> np.ndarray:
        err = target - s["eef_pos"]
        a = np.zeros(ACTION_DIM)
        a[:3] = np.clip(self.gain * err, -speed, speed)
        a[3:6] = np.clip(_axis_angle(R_DOWN @ s["eef_mat"].T) / ROT_SCALE, -1.0, 1.0)
        a[6] = grip
        return a

    def _next(self, phase: str) -> None:
        self._phase, self._count, self._trace = phase, 0, []

    def action(self, s: dict) -> np.ndarray:
        """One action from the privileged state ``s`` (advances the phase machine)."""
        self._count += 1
        eef, pick = s["eef_pos"], s["pick_pos"]
        travel_z = max(s["pick_top"], s["clear_z"]) + 0.07
        loaded_z = max(s["clear_z"], self._start_bottom) + 0.045 + self._offset
        phase = self._phase
        if phase in ("lift", "transport", "lower") and not s["pick_touching_gripper"] and self._count > 3:
            if self._retries < self.max_retries:  # dropped it: start over from the top
                self._retries += 1
                self._next("reopen")
                phase = "reopen"
        if phase == "reopen":
            target = np.array([eef[0], eef[1], travel_z])
            if abs(eef[2] - travel_z) < 0.02 or self._count > 40:
                self._next("approach")
            return self._goto(s, target, -1.0)
        if phase == "approach":
            target = np.array([pick[0], pick[1], travel_z])
            err = target - eef
            if np.linalg.norm(err[:2]) < 0.008 and abs(err[2]) < 0.02 or self._count > 120:
                self._next("descend")
            return self._goto(s, target, -1.0)
        if phase == "descend":
            target = np.array([pick[0], pick[1], s["grasp_z"]])
            err = target - eef
            self._trace.append(float(eef[2]))
            stalled = len(self._trace) > 6 and abs(self._trace[-6] - eef[2]) < 0.001 and abs(err[2]) < 0.02
            if (abs(err[2]) < 0.006 and np.linalg.norm(err[:2]) < 0.008) or stalled or self._count > 80:
                self._next("grasp")
            return self._goto(s, target, -1.0, speed=1.0)
        if phase == "grasp":
            if self._hold is None or self._count == 1:
                self._hold = np.array([pick[0], pick[1], s["grasp_z"]])
            if self._count >= 8:
                self._offset = float(eef[2] - s["pick_bottom"])
                self._start_bottom = float(s["pick_bottom"])
                self._next("lift")
            return self._goto(s, self._hold, 1.0)
        if phase == "lift":
            target = np.array([self._hold[0], self._hold[1], loaded_z])
            if abs(eef[2] - loaded_z) < 0.015 or self._count > 80:
                self._next("transport")
            return self._goto(s, target, 1.0)
        if phase == "transport":
            px, py = s["place_xy"]
            target = np.array([px, py, loaded_z])
            if np.linalg.norm((target - eef)[:2]) < 0.008 or self._count > 150:
                self._next("lower")
            return self._goto(s, target, 1.0)
        if phase == "lower":
            px, py = s["place_xy"]
            z = s["place_bottom"] + self._offset
            target = np.array([px, py, z])
            if abs(eef[2] - z) < 0.005 or s["pick_bottom"] <= s["place_bottom"] + 0.002 or self._count > 80:
                self._next("release")
            return self._goto(s, target, 1.0, speed=0.7)
        if phase == "release":
            if self._count == 1:
                self._hold = eef.copy()
            if self._count >= 10:
                self._next("retreat")
            return self._goto(s, self._hold, -1.0)
        # retreat and stay clear
        target = np.array([self._hold[0], self._hold[1], max(self._hold[2] + 0.08, travel_z - 0.02)])
        return self._goto(s, target, -1.0, speed=0.5)
