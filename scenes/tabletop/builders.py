"""Scene builders: a frozen ``SceneSpec`` in, a simulator ``Layout`` (objects, poses, facts) out.

Each builder reads only the spec (and its scene family's distractor slots), so the layout of a level is a pure
function of its spec; the seeded T0 jitter is applied by the simulator at reset.
"""

from __future__ import annotations

import numpy as np

import scenes.tabletop.mjcf as O
from indgen_vla.core.errors import InfeasibleLevelError
from scenes.mujoco_geom import grasp_height
from scenes.privileged import GoalState, PickState, SceneFacts, Targets
from scenes.sim import TABLE_TOP, FreeObject, Layout
from scenes.spec import PICK_OBJECTS, SceneSpec

Slots = tuple[tuple[float, float], ...]  # a family's distractor spots (``Scene.distractor_slots``)

CLUTTER_SLOTS = [
    (-0.045, 0.10),
    (0.045, -0.10),
    (0.045, 0.10),
    (-0.045, -0.10),
]  # relative to the compartment
CAB_X, CAB_Y0 = 0.14, -0.19


def _grasp_frac(kind: str) -> float:
    return PICK_OBJECTS[kind][1] if kind in PICK_OBJECTS else 0.5


def _distractors(spec: SceneSpec, slots: Slots) -> list[tuple[object, tuple[float, float, float]]]:
    if spec.distractors > len(slots):
        raise InfeasibleLevelError(
            f"scene {spec.scene} has {len(slots)} distractor slots; level asks for {spec.distractors}"
        )
    out = []
    for i in range(spec.distractors):
        kind = O.DISTRACTOR_KINDS[i % len(O.DISTRACTOR_KINDS)]
        obj = O.make_object(kind, f"distractor{i}", visual=True)
        x, y = slots[i]
        out.append((obj, (x, y, TABLE_TOP - float(obj.bottom_offset[2]) + 0.001)))
    return out


def _pick(spec: SceneSpec, x0: float = 0.0, y0: float = 0.0, z: float = TABLE_TOP) -> FreeObject:
    """The pick object every layout has, at the spec's offset from (x0, y0), resting at height z."""
    return FreeObject(
        "pick", O.make_object(spec.pick.kind, "pick", spec.pick.scale), x0 + spec.pick.x, y0 + spec.pick.y, z,
        spec.pick.yaw, jitter="pick",
    )  # fmt: skip


def pick_place_layout(spec: SceneSpec, slots: Slots) -> Layout:
    """LIBERO-Object style: the pick object, a basket, two dressing objects, visual distractors."""
    frac = _grasp_frac(spec.pick.kind)
    free = [
        _pick(spec),
        FreeObject(
            "goal", O.basket("basket"), spec.goal.x, spec.goal.y, TABLE_TOP, spec.goal.yaw, jitter="goal"
        ),
    ]
    for i, item in enumerate(spec.dressing):
        free.append(
            FreeObject(
                f"dress{i}",
                O.make_object(item.kind, f"dress{i}", item.scale),
                item.x,
                item.y,
                TABLE_TOP,
                item.yaw,
            )
        )
    floor_off = -O.BASKET_WALL_H + 2 * O.BASKET_T

    def targets(pick: PickState, goal: GoalState) -> Targets:
        floor = float(goal.pos[2] + floor_off)
        return Targets(
            place_xy=np.array(goal.pos[:2]),
            place_bottom=floor + 0.012,
            clear_z=float(goal.top),
            grasp_z=grasp_height(pick.bottom, pick.top, frac),
            floor_z=floor,
        )

    return Layout(
        free=free,
        static=_distractors(spec, slots),
        pick="pick",
        goal="goal",
        robot_back=spec.robot_back,
        jitter=spec.jitter,
        facts=SceneFacts(receptacle_inner=O.BASKET_INNER),
        targets=targets,
    )


def stack_layout(spec: SceneSpec, slots: Slots) -> Layout:
    """Stack: a pick block and a target block raised by ``stack_in`` inches of riser plates."""
    n_plates = int(round(spec.stack_in / 0.25))
    if abs(n_plates * 0.25 - spec.stack_in) > 1e-6:
        raise ValueError(f"stack height {spec.stack_in} in is not a whole number of 0.25 in plates")
    colour = spec.goal.kind.removeprefix("block_")
    free = [
        _pick(spec),
        FreeObject(
            "goal",
            O.target_block(colour, "target"),
            spec.goal.x,
            spec.goal.y,
            TABLE_TOP + spec.stack_m,
            spec.goal.yaw,
            jitter="goal",
        ),
    ]
    if n_plates:
        free.append(
            FreeObject(
                "riser",
                O.riser_stack(n_plates, "riser"),
                spec.goal.x,
                spec.goal.y,
                TABLE_TOP,
                spec.goal.yaw,
                jitter="goal",
            )
        )

    def targets(pick: PickState, goal: GoalState) -> Targets:
        return Targets(
            place_xy=np.array(goal.pos[:2]),
            place_bottom=float(goal.top) + 0.004,
            clear_z=float(goal.top),
            grasp_z=grasp_height(pick.bottom, pick.top, 0.5),
        )

    return Layout(
        free=free,
        static=_distractors(spec, slots),
        pick="pick",
        goal="goal",
        robot_back=spec.robot_back,
        jitter=spec.jitter,
        targets=targets,
    )


def cabinet_layout(spec: SceneSpec, slots: Slots) -> Layout:
    """RoboCasa style: an object in a cabinet compartment (with clutter) to be put on the table."""
    if spec.clutter > len(CLUTTER_SLOTS):
        raise InfeasibleLevelError(
            f"the cabinet holds {len(CLUTTER_SLOTS)} clutter objects; asked for {spec.clutter}"
        )
    cab_y = CAB_Y0 + spec.fixture_x
    cab = O.cabinet("cabinet")
    half_h = (O.CAB_FLOOR + O.CAB_WALL) / 2
    floor = TABLE_TOP + O.CAB_FLOOR
    free = [_pick(spec, CAB_X, cab_y, floor)]
    for i in range(spec.clutter):
        dx, dy = CLUTTER_SLOTS[i]
        free.append(
            FreeObject(f"clutter{i}", O.clutter_object(i, f"clutter{i}"), CAB_X + dx, cab_y + dy, floor)
        )
    frac = _grasp_frac(spec.pick.kind)
    centre = np.array([CAB_X, cab_y])
    half = (O.CAB_INNER[0] + 2 * O.CAB_T, O.CAB_INNER[1] + 2 * O.CAB_T)
    wall_top = TABLE_TOP + O.CAB_FLOOR + O.CAB_WALL
    place = np.array([spec.goal.x, cab_y + spec.goal.y])

    def targets(pick: PickState, goal: None) -> Targets:
        return Targets(
            place_xy=place,
            place_bottom=TABLE_TOP + 0.004,
            clear_z=wall_top,
            grasp_z=grasp_height(pick.bottom, pick.top, frac),
        )

    static = [(cab, (CAB_X, cab_y, TABLE_TOP + half_h))] + _distractors(spec, slots)
    facts = SceneFacts(fixture_centre=centre, fixture_half=half)
    return Layout(
        free=free,
        static=static,
        pick="pick",
        goal=None,
        robot_back=spec.robot_back,
        jitter=spec.jitter,
        facts=facts,
        targets=targets,
    )
