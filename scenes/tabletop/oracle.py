"""The tabletop family's privileged scripted oracle, which certifies every level (Assumption 2): approach, grasp, lift, transport, release.

It reads the env's ``PrivilegedState`` that the engine attaches to its observation (``scenes.privileged``) and
emits 7-d OSC_POSE delta actions. It has no randomness, so it is deterministic given the episode. Each phase
is a ``Phase`` member whose method emits one action and decides when the next phase starts.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence

import numpy as np

from indgen_vla.core.errors import PolicyError
from indgen_vla.core.protocol.interface import ACTION_DIM, ROT_SCALE, Observation
from scenes.oracles import R_DOWN, _axis_angle, oracle_spec
from scenes.privileged import PrivilegedState, privileged_of


class Phase(enum.Enum):
    """The oracle's phases in order; ``act`` emits one action of the member's phase and may start the next."""

    REOPEN = "reopen"  # dropped the object: open and rise to the travel height, then approach again
    APPROACH = "approach"
    DESCEND = "descend"
    GRASP = "grasp"
    LIFT = "lift"
    TRANSPORT = "transport"
    LOWER = "lower"
    RELEASE = "release"
    RETREAT = "retreat"  # and stay clear

    @property
    def carrying(self) -> bool:
        """Does this phase hold the object (so losing finger contact means it was dropped)?"""
        return self in (Phase.LIFT, Phase.TRANSPORT, Phase.LOWER)

    def act(self, o: OraclePolicy, s: PrivilegedState) -> np.ndarray:
        return getattr(self, f"_{self.value}")(o, s)

    def _reopen(self, o: OraclePolicy, s: PrivilegedState) -> np.ndarray:
        eef, travel_z = s.eef_pos, o.travel_z(s)
        target = np.array([eef[0], eef[1], travel_z])
        if abs(eef[2] - travel_z) < 0.02 or o._count > 40:
            o._next(Phase.APPROACH)
        return o._goto(s, target, -1.0)

    def _approach(self, o: OraclePolicy, s: PrivilegedState) -> np.ndarray:
        pick = o.grasp_xy(s)
        target = np.array([pick[0], pick[1], o.travel_z(s)])
        err = target - s.eef_pos
        if np.linalg.norm(err[:2]) < 0.008 and abs(err[2]) < 0.02 or o._count > 120:
            o._next(Phase.DESCEND)
        elif o.advance_on_stall and o._count > 40 and o._stalled() and np.linalg.norm(err[:2]) < 0.04:
            o._next(Phase.DESCEND)  # at the arm's reach: waiting for the last centimetres spends the episode
        return o._goto(s, target, -1.0)

    def _descend(self, o: OraclePolicy, s: PrivilegedState) -> np.ndarray:
        eef, pick = s.eef_pos, o.grasp_xy(s)
        target = np.array([pick[0], pick[1], s.target.grasp_z])
        err = target - eef
        o._trace.append(float(eef[2]))
        stalled = len(o._trace) > 6 and abs(o._trace[-6] - eef[2]) < 0.001 and abs(err[2]) < 0.02
        if (abs(err[2]) < 0.006 and np.linalg.norm(err[:2]) < 0.008) or stalled or o._count > 80:
            o._next(Phase.GRASP)
        return o._goto(s, target, -1.0, speed=1.0)

    def _grasp(self, o: OraclePolicy, s: PrivilegedState) -> np.ndarray:
        if o._hold is None or o._count == 1:
            o._hold = np.array([*o.grasp_xy(s), s.target.grasp_z])
        if o._count >= 8:
            o._carry_dxy = o.grasp_xy(s) - s.pick.pos[:2]  # held off centre: put the centre down at the place
            o._offset = float(s.eef_pos[2] - s.pick.bottom)
            o._start_bottom = float(s.pick.bottom)
            o._next(Phase.LIFT)
        return o._goto(s, o._hold, 1.0)

    def _lift(self, o: OraclePolicy, s: PrivilegedState) -> np.ndarray:
        loaded_z = o.loaded_z(s)
        target = np.array([o._hold[0], o._hold[1], loaded_z])
        stuck = o.advance_on_stall and o._count > 30 and o._stalled()  # never before a normal lift ends
        if abs(s.eef_pos[2] - loaded_z) < 0.015 or o._count > 80 or stuck:
            o._next(Phase.TRANSPORT)
        return o._goto(s, target, 1.0)

    def _transport(self, o: OraclePolicy, s: PrivilegedState) -> np.ndarray:
        px, py = s.target.place_xy + o._carry_dxy
        target = np.array([px, py, o.loaded_z(s)])
        if np.linalg.norm((target - s.eef_pos)[:2]) < 0.008 or o._count > 150:
            o._next(Phase.LOWER)
        return o._goto(s, target, 1.0)

    def _lower(self, o: OraclePolicy, s: PrivilegedState) -> np.ndarray:
        px, py = s.target.place_xy + o._carry_dxy
        place_bottom = s.target.place_bottom
        z = place_bottom + o._offset
        target = np.array([px, py, z])
        if abs(s.eef_pos[2] - z) < 0.005 or s.pick.bottom <= place_bottom + 0.002 or o._count > 80:
            o._next(Phase.RELEASE)
        return o._goto(s, target, 1.0, speed=0.7)

    def _release(self, o: OraclePolicy, s: PrivilegedState) -> np.ndarray:
        if o._count == 1:
            o._hold = s.eef_pos.copy()
        if o._count >= 10:
            o._next(Phase.RETREAT)
        return o._goto(s, o._hold, -1.0)

    def _retreat(self, o: OraclePolicy, s: PrivilegedState) -> np.ndarray:
        hold = o._hold
        target = np.array([hold[0], hold[1], max(hold[2] + 0.08, o.travel_z(s) - 0.02)])
        return o._goto(s, target, -1.0, speed=0.5)


class OraclePolicy:
    """Scripted pick-and-place from privileged object poses; one instance per environment (not batched)."""

    spec = oracle_spec(ACTION_DIM)
    # bumped by hand with every change of behaviour (also of this tabletop script, for each subclass), recorded in
    # each certificate row: a failed level made by another version is re-tried (scenes/certification/README.md)
    version = 1

    advance_on_stall = (
        False  # end approach/lift once the arm stops moving (LIBERO's far levels, at its reach)
    )

    def __init__(self, gain: float = 12.0, max_retries: int = 2):
        self.gain = gain
        self.max_retries = max_retries
        self.reset("")

    def reset(self, instruction: str, seed: int | None = None) -> None:
        self._phase, self._count, self._retries, self._trace = Phase.APPROACH, 0, 0, []
        self._offset = 0.0  # grip site above the object's bottom, measured at the grasp
        self._start_bottom = -np.inf  # the pick's bottom when grasped: what it rested on must be cleared too
        self._hold: np.ndarray | None = None
        self._moves: list[np.ndarray] = []  # recent grip-site positions (``_stalled``)
        self._carry_dxy = np.zeros(
            2
        )  # grip point minus object centre of an off-centre grasp (Targets.grasp_xy)
        self.seed = seed

    def close(self) -> None:
        pass

    @property
    def phase(self) -> str:
        return self._phase.value

    def act(self, observations: Sequence[Observation]) -> np.ndarray:
        if len(observations) != 1:
            raise PolicyError(f"standin:oracle is not batched; got {len(observations)} observations")
        return self.action(privileged_of(observations[0], "standin:oracle"))[None, None, :].astype(np.float32)

    # ---- the state machine ---------------------------------------------------------------------
    @staticmethod
    def grasp_xy(s: PrivilegedState) -> np.ndarray:
        """Where to grasp: the object's centre, unless the scene names a clear point (``Targets.grasp_xy``)."""
        return s.pick.pos[:2] if s.target.grasp_xy is None else s.target.grasp_xy

    def travel_z(self, s: PrivilegedState) -> float:
        """Height to travel at empty-handed: above the object and everything to clear."""
        return max(s.pick.top, s.target.clear_z) + 0.07

    def loaded_z(self, s: PrivilegedState) -> float:
        """Grip-site height to carry the object at: its bottom clears the obstacles and where it rested."""
        return max(s.target.clear_z, self._start_bottom) + 0.045 + self._offset

    def _goto(self, s: PrivilegedState, target: np.ndarray, grip: float, speed: float = 1.0) -> np.ndarray:
        err = target - s.eef_pos
        a = np.zeros(ACTION_DIM)
        a[:3] = np.clip(self.gain * err, -speed, speed)
        a[3:6] = np.clip(_axis_angle(R_DOWN @ s.eef_mat.T) / ROT_SCALE, -1.0, 1.0)
        a[6] = grip
        return a

    def _next(self, phase: Phase) -> None:
        self._phase, self._count, self._trace, self._moves = phase, 0, [], []

    def _stalled(self, window: int = 10, tol: float = 0.0015) -> bool:
        """The grip site moved less than ``tol`` over the phase's last ``window`` steps."""
        if len(self._moves) < window:
            return False
        pts = np.array(self._moves[-window:])
        return bool(np.all(pts.max(axis=0) - pts.min(axis=0) < tol))

    def action(self, s: PrivilegedState) -> np.ndarray:
        """One action from the privileged state ``s`` (advances the phase machine)."""
        self._count += 1
        if self.advance_on_stall:
            self._moves.append(np.array(s.eef_pos))
        if self._phase.carrying and not s.pick.touching_gripper and self._count > 3:
            if self._retries < self.max_retries:  # dropped it: start over from the top
                self._retries += 1
                self._next(Phase.REOPEN)
        return self._phase.act(self, s)
