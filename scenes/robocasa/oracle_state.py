"""The RoboCasa worker's privileged facts (``backend.RoboCasaLevel.privileged``) as a ``PrivilegedState``: what
``standin:oracle`` (``scenes/robocasa/oracle.py``) reads. Importing this is cheap (NumPy inside the functions)."""

from __future__ import annotations

from scenes.privileged import GoalState, PickState, PrivilegedState, SceneFacts, Targets

PRESS_LEVER = 0.16  # m from the mixer head's hinge the press lands at most (tree 5's head: 0.153 m)


def press_point(raw: dict, part):
    """Where a fixture oracle pushes: on the stand mixer's head, 70 % of the hinge-to-centre lever beyond the
    head's centre (toward its free end: pushing at the hinge closes nothing), but at most ``PRESS_LEVER`` from the
    hinge (the long head of placeholder tree 6 lifts its free end 0.2 m over the hinge, where the press stalled in
    3 of 7 episodes); else the part itself."""
    import numpy as np

    part = np.asarray(part, dtype=np.float64)
    hinge = raw.get("mixer_hinge_pos")
    if hinge is None or np.linalg.norm(part - hinge) < 0.01:
        return part.copy()
    lever = 1.7 * (part - np.asarray(hinge, dtype=np.float64))
    return hinge + lever * min(1.0, PRESS_LEVER / float(np.linalg.norm(lever)))


def hinge_goal(raw: dict):
    """A hinged lid's hinge as the goal: its world anchor, turned (about z) to the way the fixture faces, its top
    the lid's half thickness (``worker_facts.hinge_facts``)."""
    import numpy as np

    front = np.asarray(raw["hinge_front"], dtype=np.float64)
    half = np.arctan2(front[1], front[0]) / 2
    quat = np.array([np.cos(half), 0.0, 0.0, np.sin(half)])
    return GoalState(np.asarray(raw["hinge_pos"], dtype=np.float64), quat, float(raw["hinge_thick"]))


def hinge_target(raw: dict):
    """A hinged lid's target: the lid's free edge (``place_xy``, ``grasp_z``) and how open RoboCasa reads it
    (``clear_z``, 0 closed .. 1 open); no floor (a push, not a put-down)."""
    import numpy as np

    edge = np.asarray(raw["hinge_edge"], dtype=np.float64)
    return Targets(edge[:2].copy(), float(edge[2]), float(raw["hinge_state"]), float(edge[2]))


def unload_target(raw: dict, pick, centre):
    """Cabinet to counter: put the object down on the counter 12 cm (plus its half width) in front of the cabinet's
    face, straight back from where it stands; the cabinet is the fixture it must leave (``SceneFacts``)."""
    import numpy as np

    yaw = float(raw["base_yaw"])
    fwd = np.array([np.cos(yaw), np.sin(yaw)])  # the base faces the cabinet
    half = tuple(float(h) for h in raw["goal_half"])
    front = float(np.dot(centre[:2], fwd)) - half[1]
    xy = pick.pos[:2] + fwd * (front - 0.12 - pick.half_width - float(np.dot(pick.pos[:2], fwd)))
    top = float(raw["counter_top"])
    target = Targets(xy, top, float(pick.top), float(pick.pos[2]), floor_z=top)
    return target, SceneFacts(receptacle_inner=half, fixture_centre=np.asarray(centre[:2]), fixture_half=half)


def _room(raw: dict, ceiling: str) -> dict:
    """The base phase's facts (``oracle_base``): the base's room each way and what hangs over the part."""
    room = raw.get("base_room")
    return {"base_room": None if room is None else tuple(float(r) for r in room), "ceiling": raw.get(ceiling)}


def privileged_state(raw: dict):
    """The worker's privileged facts (``backend.RoboCasaLevel.privileged``) as a ``PrivilegedState``.

    ``pick`` is the object to move, or on a fixture task the part to push (the stand mixer's head, the blender's
    power button: ``touching_gripper`` is the gripper's contact with the button); ``goal`` and ``target`` are the
    cabinet interior the object goes into (its centre, floor and ceiling); a put-down task's ``place_pos`` is
    ``target`` (``clear_z``: the highest of it, the object's bottom and ``place_clear``, a container's rim;
    ``goal.top``: the underside of what hangs over it, if anything), else ``target`` is where to push that part
    (``press_point``).
    """
    import numpy as np

    f64 = lambda v: np.asarray(v, dtype=np.float64)  # noqa: E731
    # TurnOnBlender's fruit waits in the jar: the power button is what its oracle pushes
    if "obj_pos" in raw and "button_pos" not in raw:
        pos = f64(raw["obj_pos"])
        ext = raw.get("obj_half_extents")
        pick = PickState(pos, f64(raw["obj_quat"]), f64(raw["obj_linvel"]), raw["obj_bottom"], raw["obj_top"],
                         raw["obj_half_width"], raw["obj_touching"], None if ext is None else f64(ext))  # fmt: skip
    else:
        # the blender's button, the stand mixer's head, the kettle's lid, else the moved fixture
        part = raw.get("button_pos", raw.get("mixer_head_pos", raw.get("fixture_pos")))
        part = raw.get("hinge_edge", raw["eef_pos"] if part is None else part)
        pos, touched = f64(part), bool(raw.get("button_touched", False))
        quat = f64(raw.get("button_quat", [1.0, 0, 0, 0]))  # the kettle's lever: its heading
        pick = PickState(pos, quat, np.zeros(3), float(pos[2]), float(pos[2]), 0.0, touched)
    goal, facts = None, SceneFacts()
    if "goal_centre" in raw:
        c = f64(raw["goal_centre"])
        goal = GoalState(c, f64([1.0, 0, 0, 0]), float(raw["goal_top"]))
        target = Targets(c[:2].copy(), float(raw["goal_floor"]), float(raw["goal_floor"]), float(pick.pos[2]),
                         floor_z=float(raw["goal_floor"]))  # fmt: skip
        room = raw.get("base_room")  # counter to cabinet: the base may drive nearer
        facts = SceneFacts(receptacle_inner=tuple(raw["goal_half"]),
                           base_room=None if room is None else tuple(float(r) for r in room))  # fmt: skip
        if raw.get("counter_top") is not None:  # cabinet to counter: out of the cabinet, onto the counter
            target, facts = unload_target(raw, pick, c)
    elif "place_pos" in raw:  # put down on a surface or into an open drawer (worker_facts.place_facts)
        place, ceiling = f64(raw["place_pos"]), raw.get("place_ceiling")  # ceiling: what hangs over it
        clear = max(float(place[2]), pick.bottom, float(raw.get("place_clear", place[2])))  # a jar's rim
        target = Targets(
            place[:2].copy(), float(place[2]), clear, float(pick.pos[2]), floor_z=float(place[2])
        )
        goal = None if ceiling is None else GoalState(place, f64([1.0, 0, 0, 0]), float(ceiling))
        if raw.get("base_room") is not None:  # the carry may drive the base (the fridge's shelf, the bread)
            facts = SceneFacts(base_room=tuple(float(r) for r in raw["base_room"]),
                               carry_drives=bool(raw.get("carry_drives", False)),
                               reach_drives=bool(raw.get("reach_drives", False)))  # fmt: skip
    elif "hinge_pos" in raw:  # a part to swing shut (or open): goal is its hinge, turned the way it faces
        goal, target = hinge_goal(raw), hinge_target(raw)
        facts = SceneFacts(**_room(raw, "hinge_ceiling"), lift=raw.get("hinge_lift"))
    else:
        press = press_point(raw, pick.pos)
        target = Targets(press[:2].copy(), float(press[2]), float(press[2]), float(press[2]))
        facts = SceneFacts(button="button_pos" in raw, lever="button_quat" in raw, **_room(raw, "ceiling"))
    return PrivilegedState(
        eef_pos=f64(raw["eef_pos"]), eef_mat=f64(raw["eef_mat"]), gripper_qpos=f64(raw["gripper_qpos"]),
        pick=pick, goal=goal, target=target, facts=facts, bddl_success=bool(raw["success"]),
        robot_base=f64([*raw["base_pos"][:2], raw["base_yaw"]]),
    )  # fmt: skip
