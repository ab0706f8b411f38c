"""The privileged oracle of RoboCasa365 (``standin:oracle`` on ``--scene robocasa``): PandaOmron's arm and base.

It reads the ``PrivilegedState`` the worker's facts become (``scenes.robocasa.privileged_state``) and emits RoboCasa's
12-d action (``convert_action`` order: eef pos 3 + eef rot 3 + gripper 1 + base motion 4 + control mode 1). The arm's
OSC_POSE takes deltas in the mobile base's frame (robosuite's ``default_pandaomron.json``: ``input_ref_frame:
base``, 0.05 m and 0.5 rad per unit), so world errors are rotated by the base's yaw; base motion stays 0 and the
control mode -1 (arm), but for the fixture tasks' base phase first (``oracle_base``: base mode, the base driven). Five scripts: counter to cabinet (``oracle_cabinet``: lift to the cabinet floor, slide in, set down, release,
back out past ``gripper_obj_far``'s 0.25 m), cabinet to counter (in over the object at the cabinet's mouth, grasp,
pull out, lower onto the counter), a carry onto the worker's ``place_pos`` (sink to counter: onto the container;
counter to drawer: into the open drawer's uncovered part; counter to sink: onto the basin's floor; counter to
blender: over the jar's rim onto its floor; fridge drawer to shelf, the base first driven nearer where the shelf
lies beyond ``CARRY_REACH``; the mug under the coffee machine's pour site; where the worker sets ``carry_drives``
(or ``reach_drives`` and the object lies beyond ``PICK_REACH``: counter to sink) the base drives to the object,
then holding it to the place point: the cheese onto the bread (CheesyBread, over
what stands between them, ``oracle_carry`` keeping the hand off the bread), and, run but not listed, counter to
stand mixer over the bowl's rim), a press:
the stand mixer's head (pushed down near its free end, the hand tipped further while the reach falls short) or a
button (the blender's power button, the kettle's lid button: pressed, then left straight up), the electric kettle's
standing lid, swept shut from behind and pressed down (``oracle_fixtures.close_lid``), its power lever pressed down
at its free end (``oracle_lever.press_lever``), and the stand mixer's head lifted open from under its front edge,
or the toaster oven's open door lifted shut from under its free edge (``oracle_lift.lift_hinge``). ``tasks``
lists the tasks certify may certify; it refuses the others. Fingers close across the object's narrower side. Deterministic given the episode; one instance per environment.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from indgen_vla.core.errors import PolicyError
from indgen_vla.core.protocol.interface import ROT_SCALE, Observation
from scenes.oracles import R_DOWN, _axis_angle, oracle_spec
from scenes.privileged import PrivilegedState, privileged_of
from scenes.robocasa.oracle_base import base_goal, drive_phase, rz, to_base
from scenes.robocasa.oracle_cabinet import OPEN, pick_place, unload
from scenes.robocasa.oracle_carry import clear_twist, side_turn
from scenes.robocasa.oracle_fixtures import CLOSED, MAX_PRESS_TILT, close_lid
from scenes.robocasa.oracle_lever import press_lever
from scenes.robocasa.oracle_lift import lift_hinge

ACTION_DIM = 12  # RoboCasa365's PandaOmron action (scenes.robocasa.PANDA_OMRON)
GRIPPER, MODE = 6, 11
# radians the hand tips forward to press a button low on an appliance's front (the blender's): PRESS_TILT swings
# the fingers into the appliance's face above it
BUTTON_TILT = 0.25
CLEARANCE = 0.06  # m the carried object's bottom clears the higher of its two surfaces by (the carry script)
# m ahead of the base a carry's place point may lie: farther (the fridge's shelf from a base moved back along
# base_y), the base drives nearer first, where the worker reports its room (facts.base_room)
CARRY_REACH = 0.6
HAND_ROOM = 0.4  # m over a surface a vertical hand holding an object needs (the carry tips it under less)
PRESS_TILT = 0.5  # radians the hand tips forward to press: a tipped hand reaches farther over a far appliance
# radians the carry tips the hand under something low: TILT swings the object's far edge 4.9 cm forward, into the
# coffee machine's face 5.1 cm from the mug's centre
UNDER_TILT = 0.35
# m between the place point and what hangs over it under which a carry that drives twice (carry_drives) grasps
# tipped, as into a cabinet: the bread under a wall cabinet (CheesyBread, 0.23 m; UNDER_TILT left the wrist on the
# cabinet's bottom; at 0.277 m, over 0.25, the hand pointing down stalled 16 cm short of a bread 0.60 m out); the
# coffee machine's button is as low (0.235-0.313 m over the counter, CoffeeSetupMug pick_x levels 0 and 4), but
# that carry does not drive and keeps UNDER_TILT
CRAMPED = 0.3
# radians the hand tips there: at TILT the wrist met the wall cabinet's door 0.16 m in front of the bread (its
# grip site stalled 2.8 cm short of the bread's centre, the cheese let go on its near edge fell off)
CRAMPED_TILT = 1.0
# m ahead of the base the tipped hand grasps from (nearer, the base backs off first: at 0.26 m the hand stalled
# 23 cm over the cheese, at 0.40 m 3 cm over its centre, holding it by its top edge, and lost it in 2 of 18
# certification episodes; at 0.50 m it closes 2.3 cm over it) and puts down at most (the drive forward, as far as
# the room allows)
CRAMPED_REACH = (0.5, 0.45)
# m from the base (its centre, in the floor plane) beyond which a carry's pick object is out of the arm's reach where
# the worker sets reach_drives (PickPlaceCounterToSink): the carry then drives twice, as a carry_drives one does
# (horizon level 0 episode 0, pretrain: 0.75 m out, 0.64 m to the side, the hand stalled 4.8 cm over its grasp
# height and the fingers closed on the object's top edge)
PICK_REACH = 0.65
HELD_DRIVE = 0.5  # of full scale: the base's speed while the carry holds the object (over the deadband, 0.25)


class RoboCasaOracle:
    """Scripted PandaOmron arm from privileged poses: cabinet pick-and-place, or the stand mixer's head."""

    spec = oracle_spec(ACTION_DIM)
    version = 6  # bumped by hand with every change of behaviour (scenes.tabletop.oracle.OraclePolicy.version)
    # the tasks it scripts (scenes.oracles.oracle_scripts): certify refuses the others, whose levels stay uncertified
    # (the carry into the stand mixer's bowl, which drives twice as CheesyBread's does, fails its first levels:
    # docs/results/robocasa_oracle.md)
    tasks = (
        "PickPlaceCounterToCabinet",
        "PickPlaceCabinetToCounter",
        "PickPlaceSinkToCounter",
        "PickPlaceCounterToDrawer",
        "PickPlaceCounterToSink",
        "PickPlaceCounterToBlender",
        "PickPlaceFridgeDrawerToShelf",
        "CoffeeSetupMug",
        "CloseStandMixerHead",
        "OpenStandMixerHead",
        "TurnOnBlender",
        "OpenElectricKettleLid",
        "CloseElectricKettleLid",
        "CloseToasterOvenDoor",
        "TurnOnElectricKettle",
        "CheesyBread",
    )

    def __init__(self, gain: float = 10.0):
        self.gain = gain
        self.reset("")

    def reset(self, instruction: str, seed: int | None = None) -> None:
        self.phase, self._count, self._trail = "approach", 0, []
        self._offset = 0.0  # grip site above the object's bottom, measured at the grasp
        self._hold: np.ndarray | None = None
        self._clear: np.ndarray | None = None
        self._carry_z: float | None = None  # the carry script's height for the object's bottom
        self._grasp_tilt: float | None = None
        self._hold_release: np.ndarray | None = None
        self._rise: float | None = None  # how far the counter-to-cabinet script rises once it let go
        # the press's hand tilt (PRESS_TILT, a button's BUTTON_TILT): raised while the approach stalls short
        self._tilt: float | None = None
        self._twist: float | None = None  # fixed at the first action from the object's pose (_grasp_twist)
        self._base_goal: np.ndarray | None = None  # world xy the base phase drives to (oracle_base)
        self._base_trail: list = []
        self._drove = False  # the carry's base phase was planned (run or not needed)
        self._rim = False  # the carry's hand starts under a container's rim: it rises over it first
        self._drives: bool | None = None  # the carry drives twice (to the object, then to the place point)
        self._turn = 0.0  # the cramped grasp's sideways tip (oracle_carry.side_turn), back to 0 once lifted
        self.seed = seed

    def close(self) -> None:
        pass

    def act(self, observations: Sequence[Observation]) -> np.ndarray:
        if len(observations) != 1:
            raise PolicyError(f"standin:oracle is not batched; got {len(observations)} observations")
        s = privileged_of(observations[0], "standin:oracle")
        if s.robot_base is None:
            raise PolicyError("standin:oracle (RoboCasa): the privileged state has no mobile base pose")
        return self.action(s)[None, None, :].astype(np.float32)

    # ---- motion ------------------------------------------------------------------------------
    def _hand(self, s: PrivilegedState, tilt: float, twist: float = 0.0, turn: float = 0.0) -> np.ndarray:
        """The grip site's world orientation: pointing down, tipped by ``tilt`` toward the base's +x turned by
        ``turn`` about the vertical, turned about its own approach axis by ``twist``."""
        c, sn = np.cos(-tilt), np.sin(-tilt)
        pitch = np.array([[c, 0.0, sn], [0.0, 1.0, 0.0], [-sn, 0.0, c]])
        return rz(float(s.robot_base[2]) + turn) @ pitch @ R_DOWN @ rz(twist)

    def _grasp_twist(self, s: PrivilegedState) -> float:
        """The twist that closes the fingers (the grip site's x axis: robosuite's panda_gripper.xml fingers slide
        along it) across the object's narrower horizontal side, or across either side of a square one (the
        smaller turn: a 6 cm square turned 45 deg is 8.5 cm across the hand's axis, past the Panda's 8 cm opening,
        and the fingers landed on its top); 0 where the scene gives no extents."""
        ext = s.pick.half_extents
        if ext is None:
            return 0.0
        w, x, y, z = (float(q) for q in s.pick.quat_wxyz)
        axis_x = np.array([1 - 2 * (y * y + z * z), 2 * (x * y + w * z)])  # the object's x axis, world xy
        axis_x = axis_x / max(np.linalg.norm(axis_x), 1e-9)
        axis_y = np.array([-axis_x[1], axis_x[0]])
        grid = np.linspace(-np.pi / 2, np.pi / 2, 181)
        if (
            abs(float(ext[0]) - float(ext[1])) < 0.005
        ):  # square: either side, rounded so the smaller turn wins
            across = lambda g: round(max(abs(self._hand(s, 0.0, g)[:2, 0] @ a) for a in (axis_x, axis_y)), 3)  # noqa: E731
        else:
            narrow = axis_x if ext[0] < ext[1] else axis_y
            across = lambda g: abs(self._hand(s, 0.0, g)[:2, 0] @ narrow)  # noqa: E731
        return float(max(grid, key=lambda g: (across(g), -abs(g))))

    def _goto(
        self, s: PrivilegedState, target, grip: float, speed: float = 1.0, tilt: float = 0.0, hand=None
    ) -> np.ndarray:
        """One action toward the world point ``target``, gripper pointing down (tipped forward, toward the base's
        +x, by ``tilt`` radians; turned by the episode's grasp twist about its approach axis), in the base's
        frame; ``hand``, a world orientation, replaces that one (the lift's and the lever's scripts)."""
        base = rz(float(s.robot_base[2]))
        a = np.zeros(ACTION_DIM)
        err = base.T @ (np.asarray(target, dtype=np.float64) - s.eef_pos)
        a[:3] = np.clip(self.gain * err, -speed, speed)
        hand = self._hand(s, tilt, self._twist or 0.0) if hand is None else hand
        rot = _axis_angle(hand @ s.eef_mat.T)  # world frame
        a[3:6] = np.clip(base.T @ rot / ROT_SCALE, -1.0, 1.0)
        a[GRIPPER], a[MODE] = grip, -1.0
        return a

    def _next(self, phase: str) -> None:
        self.phase, self._count, self._trail = phase, 0, self._trail[-1:]

    def _near(self, s: PrivilegedState, target, tol: float = 0.012) -> bool:
        """At ``target``, or stalled short of it (moved < 2 mm in 10 steps: a reach limit or a contact)."""
        if np.linalg.norm(np.asarray(target) - s.eef_pos) < tol:
            return True
        return self._count > 12 and bool(np.linalg.norm(s.eef_pos - self._trail[-10]) < 0.002)

    def _descend(self, s: PrivilegedState, p, tilt: float, hand=None, limit: int = 50) -> np.ndarray:
        """Straight down to the pick object's grasp height, fingers open (both pick-and-place scripts)."""
        target = np.array([p.pos[0], p.pos[1], max(p.bottom + 0.02, p.pos[2])])
        if self._near(s, target, 0.012) or self._count > limit:
            self._next("grasp")
        return self._goto(s, target, OPEN, speed=0.5, tilt=tilt, hand=hand)

    def _grasp(self, s: PrivilegedState, p, tilt: float, hand=None) -> tuple[np.ndarray, bool]:
        """Close the fingers where the hand stopped; True once closed (the hand's height over the object's
        bottom is kept in ``_offset`` for the carry)."""
        if self._hold is None:
            self._hold = s.eef_pos.copy()
        closed = self._count > 15
        if closed:
            self._offset = float(s.eef_pos[2] - p.bottom)
        return self._goto(s, self._hold, CLOSED, tilt=tilt, hand=hand), closed

    def action(self, s: PrivilegedState) -> np.ndarray:
        """One action from the privileged state ``s`` (advances the phase machine)."""
        self._count += 1
        self._trail = [*self._trail[-9:], s.eef_pos.copy()]
        press = s.target.floor_z is None  # a fixture part to push: no receptacle floor to put anything on
        if self._twist is None:
            self._twist = 0.0 if press else self._grasp_twist(s)
        if press and s.goal is not None:  # a hinged part (its hinge the goal): a standing lid, a head to lift
            return lift_hinge(self, s) if s.facts.lift else close_lid(self, s)
        if press and s.facts.lever:  # the kettle's power lever, low beside it
            return press_lever(self, s)
        if press:
            return self._press(s)
        if s.facts.fixture_centre is not None:
            return unload(self, s)
        if s.facts.receptacle_inner is None:  # no cabinet interior: a put-down onto place_pos
            return self._carry(s)
        return pick_place(self, s)

    # ---- press: the stand mixer's head down, the blender's button ------------------------------
    def _press(self, s: PrivilegedState) -> np.ndarray:
        """Above the head's free end (``target``: most lever from the hinge), then straight down at full OSC
        force until RoboCasa reports it closed (frictionloss of the hinge needs it), then up; a button (the
        blender's power button, ``target`` its top) is left straight up at the first touch."""
        press = np.array([*s.target.place_xy, s.target.grasp_z])
        above = press + np.array([0.0, 0.0, 0.10])
        if self._tilt is None:
            self._tilt = BUTTON_TILT if s.facts.button else PRESS_TILT
            if s.facts.base_room is not None:  # the mixer's head: sideways until the press point is ahead
                self._base_goal = base_goal(s, press, 0.0, np.inf)
                self._next("drive" if self._base_goal is not None else "approach")
        if (a := drive_phase(self, s, CLOSED)) is not None:
            return a
        if self.phase == "approach":
            if np.linalg.norm(above - s.eef_pos) < 0.02 or self._count > 150:
                self._next("press")
            elif self._near(s, above, 0.02) and self._count > 20:  # stalled short: the reach limit
                if self._tilt >= MAX_PRESS_TILT:
                    self._next("press")
                else:  # a hand tipped further reaches farther (its wrist stays nearer the shoulder)
                    self._tilt, self._count = min(MAX_PRESS_TILT, self._tilt + 0.2), 1
            return self._goto(s, above, CLOSED, tilt=self._tilt)
        if self.phase == "press":  # down onto the head until RoboCasa says it is closed, or onto a button
            if s.pick.touching_gripper:  # a button: RoboCasa counts the press when the contact ends
                self._hold_release = s.eef_pos.copy()
                self._next("lift_off")
            elif s.bddl_success or self._count > 200:
                self._next("retreat")
            if s.facts.button:  # gently: at full force the fingers swing into the face above the button
                return self._goto(s, press - np.array([0.0, 0.0, 0.03]), CLOSED, speed=0.4, tilt=self._tilt)
            return self._goto(s, press - np.array([0.0, 0.0, 0.15]), CLOSED, speed=1.0, tilt=self._tilt)
        if self.phase == "lift_off":  # straight up, the hand kept tipped: a second touch would count again
            return self._goto(
                s, self._hold_release + np.array([0.0, 0.0, 0.15]), CLOSED, speed=0.5, tilt=self._tilt
            )
        return self._goto(s, s.pick.pos + np.array([0.0, 0.0, 0.25]), CLOSED, speed=0.5)

    # ---- release, rise, back out (every pick-and-place script) ----------------------------------
    def _let_go(
        self, s: PrivilegedState, tilt: float, rise: float, tol: float, limit: int, back_up: float = 0.0,
        along: bool = False,
    ) -> np.ndarray:  # fmt: skip
        """Open where the hand stopped, rise ``rise`` straight up (fingers off the object first: backing out low
        drags it along), or ``along`` the tipped hand's own axis (under a wall cabinet, where straight up the
        wrist meets its bottom), then back 0.4 m away from the base's heading (past ``gripper_obj_far``'s 0.25 m),
        ``back_up`` higher."""
        yaw = float(s.robot_base[2])
        fwd = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        if self.phase == "release":
            if self._hold_release is None or self._count == 1:
                self._hold_release = s.eef_pos.copy()
            if self._count > 12:
                self._next("rise")
            return self._goto(s, self._hold_release, OPEN, tilt=tilt)
        way = np.array([0.0, 0.0, 1.0])
        if along:  # back up the hand's own axis (it points down, tipped toward the base's heading)
            way = way * np.cos(tilt) - fwd * np.sin(tilt)
        up = self._hold_release + way * rise
        if self.phase == "rise":
            if self._near(s, up, tol) or self._count > limit:
                self._next("retreat")
            return self._goto(s, up, OPEN, speed=0.3, tilt=tilt)
        return self._goto(s, up - fwd * 0.4 + np.array([0.0, 0.0, back_up]), OPEN, speed=0.5, tilt=tilt)

    # ---- onto a surface, into a drawer, a sink or a jar (sink to counter, coffee, drawer, sink, blender) --
    def _carry(self, s: PrivilegedState) -> np.ndarray:
        """Hand pointing down: over the object, down, grasp, up until its bottom clears both surfaces by
        ``CLEARANCE``, over the place point (``target``), down until it rests there (a stall), then ``_let_go``
        high enough to clear a drawer's walls."""
        p, t = s.pick, s.target
        # something low over the place point (the coffee machine's button): once grasped, the hand tips toward it
        # (gradually, while lifting), so the wrist stays back from under it (as into a cabinet); cramped under a
        # wall cabinet, it grasps tipped already, fingers across the base's heading (untwisted: R_DOWN slides them
        # along the base's y), so the object stays level and rests flat where it is put down
        room = np.inf if s.goal is None else s.goal.top - t.place_bottom
        if self._drives is None:  # where the worker says so, or (reach_drives) the object is beyond reach
            far = s.facts.reach_drives and np.linalg.norm(to_base(s, p.pos)) > PICK_REACH
            self._drives = bool(s.facts.carry_drives or far)
        drives = self._drives
        cramped, low = drives and room < CRAMPED, room < HAND_ROOM
        tilt = CRAMPED_TILT if cramped else UNDER_TILT if low else 0.0
        grip_tilt = tilt if cramped else 0.0
        if self._carry_z is None:  # fixed first: the object's bottom (in clear_z) rises once held
            self._carry_z = t.clear_z + CLEARANCE
            self._twist = 0.0 if cramped else self._twist
            self._turn = side_turn(s) if cramped else 0.0
            if drives and not cramped:
                self._twist = clear_twist(self, s)
        carry_z = self._carry_z + self._offset
        if self.phase == "lift" and not cramped:
            tilt = min(tilt, 0.03 * self._count)
        # the place point beyond CARRY_REACH: the base drives nearer first (oracle_base); a carry that drives twice
        # first puts the pick object straight ahead (the arm clear of what stands beside it: the mixer's raised head)
        if self.phase == "approach" and not self._drove and s.facts.base_room is not None:
            self._drove = True
            first = p.pos if drives else [*t.place_xy, 0.0]
            near = CRAMPED_REACH[0] if cramped and drives else 0.0
            # reach_drives: the base drives only to a far object (drawn 2.5 cm nearer the sink, horizon level 1
            # episode 1's grasp of an object within reach missed)
            far = drives or not s.facts.reach_drives
            self._base_goal = base_goal(s, first, near, CARRY_REACH) if far else None
            if self._base_goal is not None:
                self._next("drive")
        if (a := drive_phase(self, s, OPEN)) is not None:
            return a
        # holding the object: at HELD_DRIVE of full speed (at full speed a cheese grasped near its top slipped out)
        if (a := drive_phase(self, s, CLOSED, "drive_place", "transport", HELD_DRIVE)) is not None:
            return a
        turned = self._hand(s, grip_tilt, self._twist or 0.0, self._turn)
        # a container's rim over both surfaces (the blender's jar) that the hand starts under: straight up over it
        # first, then over the object at that height (straight at the object beside the jar, the hand stalled on
        # the jar's side 16 cm short of it and 28 cm over it)
        rim = t.clear_z + CLEARANCE
        if self._clear is None:  # the first action: where the hand starts
            self._clear = s.eef_pos.copy()
            self._rim = not drives and t.clear_z > max(t.place_bottom, p.bottom) + 0.05 and s.eef_pos[2] < rim
            if self._rim and self.phase == "approach":
                self._next("over")
        if self.phase == "over":
            if self._near(s, [*self._clear[:2], rim], 0.02) or self._count > 40:
                self._next("approach")
            return self._goto(s, [*self._clear[:2], rim], OPEN, tilt=grip_tilt, hand=turned)
        if self.phase == "approach":
            target = np.array([p.pos[0], p.pos[1], max(p.top + 0.06, rim) if self._rim else p.top + 0.06])
            if self._near(s, target, 0.015) or self._count > 120:
                self._next("descend")
            return self._goto(s, target, OPEN, tilt=grip_tilt, hand=turned)
        if self.phase == "descend":
            # from over a rim the hand has 45 cm to go down, not 6 (at 0.7 cm a step, 50 left it 12 cm over)
            return self._descend(s, p, grip_tilt, hand=turned, limit=120 if self._rim else 50)
        if self.phase == "grasp":
            a, closed = self._grasp(s, p, grip_tilt, hand=turned)
            if closed:
                self._next("lift")
            return a
        if self.phase == "turn":  # lifted, a sideways tip turns back to the heading (the object stays level)
            self._turn -= np.sign(self._turn) * min(abs(self._turn), 0.05)
            if self._turn == 0.0 and self._count > 5:
                self._next("lift")
            hand = self._hand(s, tilt, 0.0, self._turn)
            return self._goto(s, [*self._hold[:2], carry_z], CLOSED, hand=hand)
        if self.phase == "lift":
            target = np.array([self._hold[0], self._hold[1], carry_z])
            if self._turn and self._near(s, target, 0.02) and self._count > 10:
                self._next("turn")
                return self._goto(s, target, CLOSED, hand=turned)
            if (self._near(s, target, 0.02) and (not low or self._count > 25)) or self._count > 80:
                self._next("transport")
                # held at the carry height: the base drives until the place point is straight ahead (the bread)
                if drives:
                    far = CRAMPED_REACH[1] if cramped else CARRY_REACH
                    self._base_goal, self._base_trail = base_goal(s, [*t.place_xy, 0.0], 0.0, far), []
                    if self._base_goal is not None:
                        self._next("drive_place")
            return self._goto(s, target, CLOSED, hand=self._hand(s, tilt, self._twist or 0.0, self._turn))
        # a carry that drives twice sets the object's centre, not the grip site, on the place point: tipped, the
        # hand holds the cheese 2.5 cm past its centre (set down that far short, it fell off the bread's near edge)
        held = drives and p.touching_gripper
        aim = t.place_xy + (s.eef_pos[:2] - p.pos[:2] if held else 0.0)
        if self.phase == "transport":
            target = np.array([*aim, carry_z])
            if (
                np.linalg.norm(target - s.eef_pos) < 0.012
                or (self._near(s, target) and self._count > 60)
                or self._count > 150
            ):
                self._next("lower")
            return self._goto(s, target, CLOSED, speed=0.6, tilt=tilt)
        if self.phase == "lower":  # the stall (the object resting on the surface) ends it
            target = np.array([*aim, t.place_bottom + 0.005 + self._offset])
            if (self._near(s, target, 0.01) and self._count > 10) or self._count > 100:
                self._next("release")
            return self._goto(s, target, CLOSED, speed=0.3, tilt=tilt)
        return self._let_go(s, tilt, rise=0.2, tol=0.015, limit=60, back_up=0.05, along=room < CRAMPED)
