"""What RoboCasa's worker reports besides observations: the environment's versions and RoboCasa release (for the
manifest), the per-step failure facts (for ``scenes/failure.py`` over the pipe), the canonical-kitchen check and the
facts only the oracle reads (``oracle_facts``).

Runs in RoboCasa's venv, loaded by ``backend.py`` by path; imports only the standard library and numpy at module
level (RoboCasa inside the functions), so our own venv's tests import it as ``scenes.robocasa.worker_facts``.
"""

from __future__ import annotations

import numpy as np

# What each distribution that ships the ``robocasa`` package is (the manifest records which one a run used: the
# releases differ in more than the version number, e.g. v1.0.1 made the task horizons 1.5x longer than v1.0.0)
RELEASES = {
    "rlinf-robocasa365": "upstream RoboCasa v1.0.1 (be22d659) plus a ROBOCASA_ASSETS_PATH override",
    "praxis-robocasa": "upstream RoboCasa v1.0.0 (before v1.0.1's 1.5x longer horizons), no assets override",
    "robocasa": "RoboCasa from its own repository (a source install: the version alone names the release)",
}


def distribution_of(package: str, dists: dict | None = None, version=None) -> str:
    """'<distribution> <version>' of what installed ``package`` ('?' when no distribution claims it)."""
    from importlib import metadata

    dists = metadata.packages_distributions() if dists is None else dists
    version = version or metadata.version
    return ", ".join(f"{d} {version(d)}" for d in sorted(set(dists.get(package, ())))) or "?"


def robocasa_release(dist: str) -> str:
    """Which RoboCasa release ``dist`` (``distribution_of("robocasa")``) is, in words."""
    names = [d.split(" ")[0] for d in dist.split(", ") if d != "?"]
    if len(names) != 1:
        return f"ambiguous: {dist} ship robocasa" if names else "unknown (no distribution claims robocasa)"
    return RELEASES.get(names[0].lower(), f"{names[0]}: not a release indgen knows; see its own notes")


def versions() -> dict:
    import mujoco
    import robocasa
    import robosuite

    dist = distribution_of("robocasa")
    return {
        "robocasa": getattr(robocasa, "__version__", "?"),
        "robocasa_dist": dist,
        "robocasa_release": robocasa_release(dist),
        "robosuite": robosuite.__version__,
        "robosuite_dist": distribution_of("robosuite"),
        "mujoco": mujoco.__version__,
        "numpy": np.__version__,
    }


GRIPPER_INDEX = 6  # the gripper's entry of the 12-d action (convert_action: action[6:7] is "gripper_close")
# a task's pick object where its config is not named "obj" (kitchen_pick_place.py's CheesyBread: "cheese")
PICK_OBJECT = {"CheesyBread": "cheese"}


def pick_name(env) -> str:
    """The name of the pick object's config in ``env``'s task (its class name is the task's)."""
    return PICK_OBJECT.get(type(env).__name__, "obj")


def failure_facts(env, action=None) -> dict:
    """What the failure trace and the progress score read each step (``scenes/failure.py``), from MuJoCo's state.

    ``touching``: a geom of the gripper in contact with the pick object (robosuite's ``check_contact`` over
    MuJoCo's contact list); ``bottom``: the object's lowest z; ``placed``: RoboCasa's own success predicate with
    ``OU.gripper_obj_far`` taken as true (the object is where the task wants it, whether or not the gripper has
    let go); ``gripper_closed``: the last action commanded the gripper closed (> 0, robosuite's convention).
    Empty when the task has no pick object (``pick_name``: fixture tasks): its failures are then ``unknown`` and
    its progress missing, never a guessed class.
    """
    name = pick_name(env)
    if name not in getattr(env, "objects", {}):
        return {}
    import robocasa.utils.object_utils as OU

    obj, robot = env.objects[name], env.robots[0]
    far = OU.gripper_obj_far
    OU.gripper_obj_far = lambda *a, **k: (
        True
    )  # the task modules call it through the module (OU.gripper_obj_far)
    try:
        placed = bool(env._check_success())
    finally:
        OU.gripper_obj_far = far
    out = {
        "touching": bool(env.check_contact(robot.gripper["right"], obj)),
        "bottom": float(env.sim.data.body_xpos[env.obj_body_id[name]][2] + obj.bottom_offset[2]),
        "placed": placed,
    }
    if action is not None:
        out["gripper_closed"] = bool(np.asarray(action, dtype=np.float64)[GRIPPER_INDEX] > 0)
    return out


def check_kitchen(config: dict) -> None:
    """One line when the task's class excludes the pinned kitchen (RoboCasa's ``EXCLUDE_LAYOUTS`` /
    ``EXCLUDE_STYLES``, e.g. PickPlaceFridgeDrawerToShelf has no layout 18), before RoboCasa fails on an empty
    kitchen list."""
    if not config.get("layout_ids"):
        return
    import robocasa  # noqa: F401  (registers the kitchen tasks)
    from robosuite.environments.base import REGISTERED_ENVS

    cls = REGISTERED_ENVS[config["task"]]
    for ids, excluded, what in ((config["layout_ids"], cls.EXCLUDE_LAYOUTS, "layout"),
                                (config.get("style_ids") or (), cls.EXCLUDE_STYLES, "style")):  # fmt: skip
        bad = sorted(set(ids) & set(excluded))
        if bad:
            raise ValueError(
                f"RoboCasa's {config['task']} excludes {what} {bad[0]} ({cls.__name__}.EXCLUDE_{what.upper()}S): "
                "drop that kitchen from the run"
            )


def oracle_facts(env, task: str) -> dict:
    """The facts only ``scenes.robocasa.oracle`` reads (kept apart from ``privileged``'s shared ones)."""
    return {
        **fixture_part_facts(env, task), **unload_facts(env, task), **object_extent_facts(env), **place_facts(env, task),
        **button_facts(env, task), **hinged_facts(env, task),
        # the counter-to-cabinet script drives nearer a cabinet beyond its reach (oracle.CABINET_REACH)
        **({"base_room": base_room(env)} if task == "PickPlaceCounterToCabinet" else {}),
    }  # fmt: skip


def fixture_part_facts(env, task: str = "") -> dict:
    """Where the fixture oracles push (``scenes.robocasa.oracle``): the stand mixer head's hinge anchor (world), so
    the press lands on the head's free end (most lever; pushing on the hinge closes nothing); for
    CloseStandMixerHead also the base's room (its base phase)."""
    data, model = env.sim.data, env.sim.model
    out: dict = {}
    mixer = getattr(env, "stand_mixer", None)
    jn = getattr(mixer, "_joint_names", {}).get("head") if mixer is not None else None
    if jn and jn in model.joint_names:
        out["mixer_hinge_pos"] = np.array(data.xanchor[model.joint_name2id(jn)], dtype=np.float64)
        if task == "CloseStandMixerHead":
            out["base_room"] = base_room(env)
    return out


def button_facts(env, task: str) -> dict:
    """TurnOnBlender's power button (``Blender.update_state``: a press is the gripper's contact with
    ``<blender>_power_button_main``, counted at its release): ``button_pos``, a point of its top face
    ``BUTTON_EDGE`` in from its front edge (a finger pressing its middle touches the blender's face first), and
    ``button_touched``, that contact now; OpenElectricKettleLid's lid button: ``kettle_button_facts``; empty for
    the other tasks or a blender without that geom."""
    if task == "OpenElectricKettleLid":
        return kettle_button_facts(env)
    if task == "TurnOnElectricKettle":
        return kettle_switch_facts(env)
    blender = getattr(env, "blender", None)
    name = f"{getattr(blender, 'name', '')}_power_button_main"
    model, data = env.sim.model, env.sim.data
    if task != "TurnOnBlender" or blender is None or name not in model.geom_names:
        return {}
    g = model.geom_name2id(name)
    mat, size = np.asarray(data.geom_xmat[g]).reshape(3, 3), model.geom_size[g]
    out = -mat[:, 1]  # the button stands out along the blender's -y (RoboCasa's fixtures face their -y)
    top = np.array(data.geom_xpos[g], dtype=np.float64) + mat[:, 2] * size[2]
    return {
        "button_pos": top + out * max(0.0, float(size[1]) - BUTTON_EDGE),
        "button_touched": bool(env.check_contact(env.robots[0].gripper["right"], name)),
    }


def kettle_button_facts(env) -> dict:
    """OpenElectricKettleLid's lid button (``ElectricKettle._joint_names["lid_button"]``, its body
    ``<prefix>button_lid``): ``button_pos``, the middle of its top; ``button_touched``, that RoboCasa counts the
    press (``update_state`` opens the shut lid once the button reads > 0.1) or the lid has begun to open; and the
    base's room (the press's base phase)."""
    kettle = getattr(env, "electric_kettle", None)
    if kettle is None:
        return {}
    centre, half = _part_box(env, f"{kettle.naming_prefix}button_lid")
    state = kettle.get_state(env)
    pressed = float(state.get("lid_button") or 0.0) > 0.1 or float(state.get("lid") or 0.0) > 0.01
    return {"button_pos": centre + np.array([0.0, 0.0, half[2]]), "button_touched": pressed,
            "base_room": base_room(env)}  # fmt: skip


LEVER_IN = 0.01  # m in from the kettle's lever's free end its press lands (a finger's half thickness)


def kettle_switch_facts(env) -> dict:
    """TurnOnElectricKettle's power lever (``ElectricKettle._joint_names["switch"]``, pressed down at its free end;
    ``update_state`` turns the kettle on once it reads >= 0.95): ``button_pos``, its top ``LEVER_IN`` in from the
    free end (the hinge mirrored through the lever's middle); ``button_quat``, the lever's heading (about z, from
    its hinge to its free end); ``button_touched``, that RoboCasa reads it turned on; and the base's room."""
    kettle = getattr(env, "electric_kettle", None)
    jn = getattr(kettle, "_joint_names", {}).get("switch") if kettle is not None else None
    model, data = env.sim.model, env.sim.data
    if not jn or jn not in model.joint_names:
        return {}
    j = model.joint_name2id(jn)
    centre, half = _part_box(env, model.body_id2name(int(model.jnt_bodyid[j])))
    across = centre - np.asarray(data.xanchor[j], dtype=np.float64)
    across[2] = 0.0
    half_length = float(np.linalg.norm(across))
    out = across / max(half_length, 1e-9)
    yaw = float(np.arctan2(out[1], out[0]))
    top = centre + out * max(0.0, half_length - LEVER_IN) + np.array([0.0, 0.0, half[2]])
    return {"button_pos": top, "button_quat": np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]),
            "button_touched": bool(kettle.get_state(env)["turned_on"]), "base_room": base_room(env)}  # fmt: skip


def _front(env, fixture) -> np.ndarray:
    """The horizontal world unit vector ``fixture`` faces (RoboCasa's fixtures face their -y)."""
    mat = np.asarray(env.sim.data.get_body_xmat(f"{fixture.naming_prefix}main")).reshape(3, 3)
    return -mat[:, 1] / max(float(np.linalg.norm(mat[:2, 1])), 1e-9)


def _part_box(env, body: str, along=None):
    """The world AABB (centre, half sizes) of the collision geoms of ``body`` (MuJoCo's ``geom_aabb``, each geom's
    local box turned into the world); with ``along`` (a world unit vector), their half extent along it instead of
    the half sizes."""
    model, data = env.sim.model, env.sim.data
    b = model.body_name2id(body)
    lo, hi, ext = np.full(3, np.inf), np.full(3, -np.inf), 0.0
    for g in np.flatnonzero((model.geom_bodyid == b) & (model.geom_contype != 0)):
        mat = np.asarray(data.geom_xmat[g]).reshape(3, 3)
        c = data.geom_xpos[g] + mat @ model.geom_aabb[g][:3]
        h = np.abs(mat) @ model.geom_aabb[g][3:]
        lo, hi = np.minimum(lo, c - h), np.maximum(hi, c + h)
        if along is not None:
            ext = max(ext, float(np.abs(mat.T @ along) @ model.geom_aabb[g][3:]))
    return (lo + hi) / 2, ext if along is not None else (hi - lo) / 2


def hinged_facts(env, task: str) -> dict:
    """The hinged part a fixture task swings (``hinge_facts``): CloseElectricKettleLid's lid
    (``ElectricKettle._joint_names["lid"]``), shut by the oracle, OpenStandMixerHead's head
    (``StandMixer._joint_names["head"]``), lifted open from under its free edge (``hinge_lift`` "opens"), and
    CloseToasterOvenDoor's door (``ToasterOven._joint_names["door"]``), lifted shut the same way ("shuts"); empty for other
    tasks."""
    if task == "CloseElectricKettleLid" and getattr(env, "electric_kettle", None) is not None:
        kettle = env.electric_kettle
        return hinge_facts(env, kettle, "lid", float(kettle.get_state(env)["lid"]))
    if task == "CloseToasterOvenDoor" and getattr(env, "toaster_oven", None) is not None:
        oven = env.toaster_oven  # its door opens down toward the front: lifting its free edge shuts it
        oven.update_state(env)  # get_state reads the values update_state synced from the joint
        return {**hinge_facts(env, oven, "door", float(oven.get_state()["door"])), "hinge_lift": "shuts"}
    if task == "OpenStandMixerHead" and getattr(env, "stand_mixer", None) is not None:
        mixer = env.stand_mixer
        mixer.update_state(env)  # get_state reads the values update_state synced from the joint
        return {**hinge_facts(env, mixer, "head", float(mixer.get_state(env)["head"])), "hinge_lift": "opens"}
    return {}


def hinge_facts(env, fixture, part: str, state: float) -> dict:
    """``fixture``'s hinged ``part`` (its joint ``_joint_names[part]``, its body ``<prefix><part>``): the hinge
    (``hinge_pos``, world anchor), the free edge's middle (``hinge_edge``: the hinge mirrored through the part's
    centre), its half thickness, how open RoboCasa reads it (``hinge_state``, 0..1), the way the fixture faces
    (``hinge_front``), what hangs over it and the base's room."""
    model, data = env.sim.model, env.sim.data
    front = _front(env, fixture)
    j = model.joint_name2id(fixture._joint_names[part])
    hinge = np.array(data.xanchor[j], dtype=np.float64)
    body = f"{fixture.naming_prefix}{part}"
    centre, _ = _part_box(env, body)
    axis = np.asarray(data.xaxis[j], dtype=np.float64)
    across = centre - hinge - axis * float(np.dot(centre - hinge, axis))  # hinge to centre, off the axis
    normal = np.cross(axis, across / max(float(np.linalg.norm(across)), 1e-9))
    edge = hinge + 2 * across
    return {
        "hinge_pos": hinge, "hinge_edge": edge, "hinge_front": front,
        "hinge_thick": _part_box(env, body, normal)[1], "hinge_state": state,
        "hinge_ceiling": _ceiling(env, hinge[:2], max(float(hinge[2]), float(edge[2])), reach=0.1),
        "base_room": base_room(env),
    }  # fmt: skip


def base_room(env) -> list[float]:
    """How far the mobile base can drive straight ahead, back, left and right before its collision boxes touch a
    fixture's (``room_ahead`` over ``_boxes``): what the oracle's base phase (``oracle_base.base_goal``) may use."""
    data, model = env.sim.data, env.sim.model
    body = model.body_name2id("mobilebase0_base")
    fwd = np.asarray(data.xmat[body]).reshape(3, 3)[:2, 0]
    own = list(_collision_boxes(env, lambda name: name.startswith("mobilebase0")))
    others, origin = list(_boxes(env)), np.asarray(data.xpos[body][:2])
    left = np.array([-fwd[1], fwd[0]])
    return [room_ahead(origin, d, own, others) for d in (fwd, -fwd, left, -left)]


def room_ahead(origin, forward, own, others) -> float:
    """The distance along the unit vector ``forward`` (xy) that the boxes ``own`` (centre, world AABB half sizes)
    can move before one meets a box of ``others`` that overlaps their height and their span across ``forward``
    (inf when none does); read in the frame of ``forward`` at ``origin``. A box under their bottom (the floor) or
    over their top (a wall cabinet) is passed."""
    fwd = np.asarray(forward, dtype=np.float64)[:2]
    fwd = fwd / np.linalg.norm(fwd)
    frame = np.stack([fwd, np.array([-fwd[1], fwd[0]])])

    def span(pos, half):
        c, h = frame @ (np.asarray(pos[:2]) - origin), np.abs(frame) @ np.asarray(half[:2])
        return c - h, c + h, float(pos[2] - half[2]), float(pos[2] + half[2])

    mine = [span(p, h) for p, h in own]
    lo_side, hi_side = min(m[0][1] for m in mine), max(m[1][1] for m in mine)
    front, bottom, top = max(m[1][0] for m in mine), min(m[2] for m in mine), max(m[3] for m in mine)
    room = np.inf
    for pos, half in others:
        lo, hi, b, t = span(pos, half)
        if t > bottom + 0.01 and b < top and hi[1] > lo_side and lo[1] < hi_side and hi[0] > front:
            room = min(room, max(0.0, float(lo[0]) - front))
    return float(room)


def object_extent_facts(env) -> dict:
    """The pick object's half sizes along its own axes (its ``reg_bbox``, ``MJCFObject.size``): the oracle closes
    the fingers across the narrower side."""
    obj = getattr(env, "objects", {}).get(pick_name(env))
    return {} if obj is None else {"obj_half_extents": np.asarray(obj.size, dtype=np.float64) / 2}


def unload_facts(env, task: str) -> dict:
    """Where an object taken out of a fixture goes down (cabinet to counter): the counter's top (its body centre
    plus half its size, ``robocasa/models/fixtures/counter.py``); empty for the other tasks."""
    counter = getattr(env, "counter", None)
    if task != "PickPlaceCabinetToCounter" or counter is None:
        return {}
    return {"counter_top": float(counter.pos[2] + counter.size[2] / 2)}


BUTTON_EDGE = 0.012  # m in from a button's front edge the blender's press lands (a finger's half thickness)
COFFEE_SHIFT = 0.03  # m the mug goes down in front of the pour site (under the 0.04 m of RoboCasa's xy check)


def place_facts(env, task: str) -> dict:
    """Where a put-down task wants the pick object (``scenes.robocasa.oracle``'s carry script): ``place_pos``, the
    world point its bottom goes to, and, where something hangs over it, ``place_ceiling`` (that thing's underside).
    On the sink-to-counter container's top; under the coffee machine's pour site (``receptacle_place_site``), moved
    ``COFFEE_SHIFT`` toward the machine's front; into an open drawer's uncovered part (``drawer_facts``); onto the
    sink basin's floor at its middle (with the base's room and ``reach_drives``: the carry drives to an object out
    of the arm's reach); onto the blender jar's floor, carried over its rim (``place_clear``, the
    height the carried object's bottom must clear); into the stand mixer's bowl over its rim and CheesyBread's
    cheese onto the bread's top, each with the base's room and ``carry_drives`` (the carry drives the base to the
    object, then with it to the place point); empty for the other tasks."""
    data, model = env.sim.data, env.sim.model
    if task == "PickPlaceSinkToCounter" and "container" in env.objects:
        pos = np.array(data.body_xpos[env.obj_body_id["container"]], dtype=np.float64)
        return {"place_pos": pos + np.array([0.0, 0.0, env.objects["container"].top_offset[2]])}
    if task == "CoffeeSetupMug":
        site = model.site_name2id(f"{env.coffee_machine.naming_prefix}receptacle_place_site")
        front = -np.array(data.site_xmat[site]).reshape(3, 3)[:2, 1]  # the machine's front: its -y
        xy = np.array(data.site_xpos[site][:2]) + COFFEE_SHIFT * front / np.linalg.norm(front)
        z = env.counter.pos[2] + env.counter.size[2] / 2
        return {"place_pos": np.array([*xy, z]), "place_ceiling": _ceiling(env, xy, z)}
    if task == "PickPlaceCounterToDrawer":
        return drawer_facts(env)
    if task == "PickPlaceCounterToSink":  # the basin's floor, under its centre (RoboCasa checks the object's)
        return {"place_pos": _floor_centre(env.sink), "base_room": base_room(env), "reach_drives": True}
    if task == "PickPlaceCounterToBlender":  # into the jar: over its rim (the blender's top), onto its floor
        top = max(float(p[2]) for p in env.blender.get_ext_sites(all_points=True, relative=False))
        return {"place_pos": _floor_centre(env.blender), "place_clear": top}
    if task == "PickPlaceFridgeDrawerToShelf":
        return shelf_facts(env)
    if task == "PickPlaceCounterToStandMixer":  # into the bowl: over its rim, onto its floor
        return {"place_pos": _floor_centre(env.stand_mixer), "place_clear": _rim(env, env.stand_mixer),
                "base_room": base_room(env), "carry_drives": True}  # fmt: skip
    if task == "CheesyBread":  # the cheese onto the bread's top, its centre (_check_success: their contact)
        bread = np.array(data.body_xpos[env.obj_body_id["bread"]], dtype=np.float64)
        top = bread + np.array([0.0, 0.0, env.objects["bread"].top_offset[2]])
        cheese = data.body_xpos[env.obj_body_id["cheese"]][:2]
        skip = ("robot0", "mobilebase0", "gripper0", "cheese")  # the bread and its board stay: they stand too
        boxes = _collision_boxes(env, lambda name: not name.startswith(skip))
        over = standing_top(boxes, cheese, top[:2], float(top[2]), env.objects["cheese"].horizontal_radius)
        return {"place_pos": top, "place_ceiling": _ceiling(env, top[:2], float(top[2])),
                "place_clear": max(float(top[2]), over), "base_room": base_room(env), "carry_drives": True}  # fmt: skip
    return {}


def _rim(env, fixture) -> float:
    """The top of the highest collision geom of ``fixture``'s own body (not a moving part's: the mixer's raised
    head) over its first interior region's footprint: the rim of the mixer's bowl."""
    model, data = env.sim.model, env.sim.data
    p0, px, py, _ = _int_sites(fixture)
    lo, hi = np.minimum.reduce([p0, px, py]), np.maximum.reduce([p0, px, py])
    top = float(p0[2])
    for g in np.flatnonzero((model.geom_bodyid == model.body_name2id(f"{fixture.naming_prefix}main"))
                            & (model.geom_contype != 0)):  # fmt: skip
        mat = np.asarray(data.geom_xmat[g]).reshape(3, 3)
        c, h = data.geom_xpos[g] + mat @ model.geom_aabb[g][:3], np.abs(mat) @ model.geom_aabb[g][3:]
        if np.all(c[:2] - h[:2] < hi[:2]) and np.all(c[:2] + h[:2] > lo[:2]):
            top = max(top, float(c[2] + h[2]))
    return top


SHELF_IN = 0.04  # m between a fridge shelf's front edge and the put-down object's front face


def shelf_facts(env) -> dict:
    """PickPlaceFridgeDrawerToShelf: the lowest fridge shelf among those its ``_check_success`` reads
    (``Fridge.check_rack_contact`` over ``get_reset_regions(compartment="fridge", reg_type=("shelf"))``), at the
    middle of its width, the object's front face ``SHELF_IN`` behind the shelf's front edge (its back holds the
    task's distractor, sampled at ``pos=(0.0, 0.5)``); ``base_room``: how far the base may drive nearer
    (base_y moves it back)."""
    fridge, obj = env.fridge, env.objects["obj"]
    names = fridge.get_reset_regions(env, compartment="fridge", reg_type=("shelf"))
    sites = fridge.get_int_sites(relative=False)
    p0, px, py, _ = min((np.asarray(v, dtype=np.float64) for v in (sites[n] for n in names)),
                        key=lambda v: float(v[0][2]))  # fmt: skip
    inward = (py - p0) / max(float(np.linalg.norm(py - p0)), 1e-9)
    xy = ((p0 + px) / 2 + inward * (SHELF_IN + float(np.max(obj.size[:2])) / 2))[:2]
    return {"place_pos": np.array([*xy, p0[2]]), "base_room": base_room(env)}


def _int_sites(fixture) -> tuple[np.ndarray, ...]:
    """The corner sites (p0, px, py, pz; world) of ``fixture``'s first interior region."""
    return tuple(
        np.asarray(v, dtype=np.float64) for v in next(iter(fixture.get_int_sites(relative=False).values()))
    )


def _floor_centre(fixture) -> np.ndarray:
    """The middle of the floor of ``fixture``'s first interior region (world): where an object put in it rests."""
    p0, px, py, _ = _int_sites(fixture)
    return np.array([*((px[:2] + py[:2]) / 2), p0[2]])


def drawer_facts(env) -> dict:
    """The open drawer's floor point at the middle of its uncovered part (RoboCasa opens it in ``_setup_scene``):
    from the interior's front back to where the opening ends or a counter top above it begins (an island's top
    overhangs its cabinets by ~15 cm), whichever is nearer; ``drawer_gap``: that width."""
    data, drawer = env.sim.data, env.drawer
    p0, px, py, pz = _int_sites(drawer)
    joints = [j for j in env.sim.model.joint_names if j.startswith(drawer.naming_prefix) and "slide" in j]
    opened = abs(float(data.get_joint_qpos(joints[0]))) if joints else 0.0
    corners = [p0[:2], px[:2], py[:2], (px + py - p0)[:2]]
    centre = sum(corners) / 4
    # into the drawer from its front: the fixture's +y (RoboCasa's fixtures face their -y; it slides out along it)
    fwd = np.asarray(data.get_body_xmat(f"{drawer.naming_prefix}main")).reshape(3, 3)[:2, 1]
    fwd = fwd / np.linalg.norm(fwd)
    near = min(float(np.dot(c, fwd)) for c in corners)
    end = min(
        near + opened,
        max(float(np.dot(c, fwd)) for c in corners),
        _covered_from(env, pz[2], centre, fwd, near),
    )
    xy = centre + fwd * ((near + end) / 2 - float(np.dot(centre, fwd)))
    return {"place_pos": np.array([*xy, p0[2]]), "drawer_open": opened, "drawer_gap": max(0.0, end - near)}


def _collision_boxes(env, keep):
    """Each collision box whose geom name ``keep`` accepts: (centre, world AABB half sizes)."""
    data, model = env.sim.data, env.sim.model
    for g in np.flatnonzero((model.geom_type == 6) & (model.geom_contype != 0)):  # mjGEOM_BOX
        if keep(model.geom_id2name(g) or ""):
            yield data.geom_xpos[g], np.abs(np.asarray(data.geom_xmat[g]).reshape(3, 3)) @ model.geom_size[g]


def _boxes(env, skip=()):
    """Each collision box of the scene not of the robot, an object or a name in ``skip``: (centre, world AABB
    half sizes)."""
    skip = ("robot0", "mobilebase0", "gripper0", *env.objects, *skip)
    return _collision_boxes(env, lambda name: not name.startswith(skip))


def _ceiling(env, xy, z: float, reach: float = 0.05) -> float | None:
    """The underside of the lowest collision box hanging over ``xy`` (within ``reach``: the hand's half width) above
    height ``z`` + 2 cm: the coffee machine's spout or button over its pour site; None when nothing is."""
    under = [pos[2] - half[2] for pos, half in _boxes(env)
             if np.all(np.abs(pos[:2] - xy) <= half[:2] + reach) and pos[2] - half[2] > z + 0.02]  # fmt: skip
    return float(min(under)) if under else None


def standing_top(boxes, a, b, below: float, reach: float) -> float:
    """The top of the highest of ``boxes`` (centre, world AABB half sizes) standing on the counter (its bottom under
    ``below``) over the xy rectangle between ``a`` and ``b``, grown by ``reach`` and 3 cm: what the carry that
    drives twice takes the object over (CheesyBread's coffee machine between the cheese and the bread); -inf when
    nothing is."""
    lo, hi = np.minimum(a, b) - reach - 0.03, np.maximum(a, b) + reach + 0.03
    tops = [pos[2] + half[2] for pos, half in boxes
            if pos[2] - half[2] < below and np.all(pos[:2] + half[:2] > lo) and np.all(pos[:2] - half[:2] < hi)]  # fmt: skip
    return float(max(tops, default=-np.inf))


def _covered_from(env, z: float, centre, fwd, near: float) -> float:
    """Where, along ``fwd`` and past ``near``, the first collision box (not the robot's, the drawer's or an
    object's) within 15 cm above height ``z`` begins over the line through ``centre`` (inf when none): the counter
    top a drawer slides out from under."""
    side = np.array([-fwd[1], fwd[0]])
    start = np.inf
    for pos, half in _boxes(env, (env.drawer.naming_prefix,)):
        if not (z - 0.01 < pos[2] - half[2] < z + 0.15):
            continue
        if abs(float(np.dot(pos[:2] - centre, side))) > float(np.abs(side) @ half[:2]):
            continue  # not over the line through the drawer's centre
        along, reach = float(np.dot(pos[:2], fwd)), float(np.abs(fwd) @ half[:2])
        if along + reach > near:  # over the drawer's span, not behind the robot
            start = min(start, max(near, along - reach))
    return start
