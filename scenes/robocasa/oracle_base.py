"""The RoboCasa oracle's base phase: PandaOmron's mobile base driven, with the base dims of RoboCasa's own action,
until a fixture part stands where the arm's scripts succeed; kept apart from ``oracle.py`` for its length.

The convention, read in upstream code (robosuite 1.5 as pinned, praxis-robosuite 1.5.2.post1; RoboCasa be22d659):
``robocasa/wrappers/gym_wrapper.py`` ``PandaOmronKeyConverter.unmap_action`` sends ``action.base_motion[0:3]`` to
``robot0_base`` and ``[3:4]`` to ``robot0_torso``, and ``action.control_mode`` > 0.5 as base mode (+1); the base's
``JOINT_VELOCITY`` controllers (``robosuite/controllers/parts/mobile_base/joint_vel.py``) take (forward, left, yaw)
velocities in the base's **current** frame and rotate them by the yaw turned since the reset into the frame of the
three base joints (``robosuite/models/assets/bases/omron_mobile_base.xml``: ``joint_mobile_forward`` along x,
``joint_mobile_side`` along y, ``joint_mobile_yaw`` about z, all fixed at the reset's heading). Those joints are
velocity actuators (kv 1000, ctrlrange +-1 m/s) against a frictionloss of 250 N, so a command under 0.25 of full
scale moves nothing (``DEADBAND``). The oracle never turns the base (yaw 0): both controllers robosuite ships
(``JOINT_VELOCITY`` and RoboCasa's ``JOINT_VELOCITY_LEGACY``) then read the same command the same way.
"""

from __future__ import annotations

import numpy as np

from scenes.privileged import PrivilegedState

BASE = slice(7, 9)  # forward, left: RoboCasa's action.base_motion[0:2] in the 12-d action
MODE = 11  # action.control_mode: +1 base mode (the arm holds its goal in the moving base's frame)
DEADBAND = 0.25  # of full scale: omron_mobile_base.xml's frictionloss 250 N over its actuators' kv 1000
GAIN = 5.0  # full scale per metre left to drive, on top of the deadband
TOL = 0.01  # m: there
MARGIN = 0.03  # m left between the base's front and the nearest fixture ahead (worker_facts.base_room)
MAX_STEPS = 60  # a drive's limit (3 s at 20 Hz; 0.5 m takes about 20 steps)


def rz(yaw: float) -> np.ndarray:
    """The rotation by ``yaw`` about z (the base's heading; shared by the oracle's arm scripts)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def to_base(s: PrivilegedState, point) -> np.ndarray:
    """World ``point``'s xy in the base's frame (forward, left)."""
    yaw = float(s.robot_base[2])
    c, sn = np.cos(yaw), np.sin(yaw)
    d = np.asarray(point, dtype=np.float64)[:2] - s.robot_base[:2]
    return np.array([c * d[0] + sn * d[1], -sn * d[0] + c * d[1]])


def base_goal(s: PrivilegedState, point, near: float, far: float) -> np.ndarray | None:
    """The world xy the base drives to so that ``point`` ends straight in front of it, between ``near`` and ``far``
    m ahead (the nearer bound of the two it lies outside), each way only as far as the room allows
    (``facts.base_room``: ahead, back, left, right, less ``MARGIN``; none known: no drive); None when under 2 cm."""
    rel = to_base(s, point)
    ahead, back, left, right = (max(0.0, r - MARGIN) for r in (s.facts.base_room or (0.0,) * 4))
    fwd = float(np.clip(rel[0] - far, 0.0, None) + np.clip(rel[0] - near, None, 0.0))
    move = np.array([np.clip(fwd, -back, ahead), np.clip(rel[1], -right, left)])
    if np.linalg.norm(move) < 0.02:
        return None
    yaw = float(s.robot_base[2])
    c, sn = np.cos(yaw), np.sin(yaw)
    return s.robot_base[:2] + np.array([c * move[0] - sn * move[1], sn * move[0] + c * move[1]])


def base_command(err) -> np.ndarray:
    """Full-scale base velocities (forward, left) for a base-frame error ``err`` (m): past the deadband, growing with
    the distance, 0 on an axis already within ``TOL``."""
    err = np.asarray(err, dtype=np.float64)
    cmd = np.sign(err) * np.minimum(1.0, DEADBAND + GAIN * np.abs(err))
    return np.where(np.abs(err) < TOL, 0.0, cmd)


def drive(o, s: PrivilegedState, goal, grip: float, cap: float = 1.0) -> np.ndarray | None:
    """One base-mode action toward the world xy ``goal`` (arm held, gripper ``grip``, no turn, at most ``cap`` of
    full scale); None once there, stalled (moved < 3 mm in 5 steps: a fixture in the way) or out of steps. ``o`` is
    the ``RoboCasaOracle``."""
    err = to_base(s, [*goal, 0.0])
    o._base_trail = [*o._base_trail[-5:], s.robot_base[:2].copy()]
    stalled = len(o._base_trail) > 5 and np.linalg.norm(o._base_trail[-1] - o._base_trail[0]) < 0.003
    if np.all(np.abs(err) < TOL) or stalled or o._count > MAX_STEPS:
        return None
    a = np.zeros(12)
    a[BASE], a[6], a[MODE] = np.clip(base_command(err), -cap, cap), grip, 1.0
    return a


def drive_phase(
    o, s: PrivilegedState, grip: float, phase: str = "drive", then: str = "approach", cap: float = 1.0
) -> np.ndarray | None:
    """In the phase ``phase``, ``drive``'s action toward ``o._base_goal`` (at most ``cap``); once it gives none, on
    to ``then``. None outside the phase or on arrival: the script's next phase acts this step."""
    if o.phase != phase:
        return None
    a = drive(o, s, o._base_goal, grip, cap)
    if a is None:
        o._next(then)
    return a
