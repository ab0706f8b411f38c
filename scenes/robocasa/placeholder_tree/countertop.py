"""Placeholder builders of the counter-top appliances: the stand mixer (its head and open bowl), the electric
kettle (its lid and lid button), the coffee machine, the blender (an open jar), the toaster, the toaster oven, and
the racks and bowls that only hold an interior region."""

from __future__ import annotations

from .built_in import racked_door
from .model import SIZES, Joint, Model


def stand_mixer(m: Model) -> None:
    """The bowl under the head (``mixer_bowl``), the head, and the bowl's, speed knob's and head lock's joints."""
    hx, hy, hz, front, top, t, small = m.hx, m.hy, m.hz, m.front, m.top, m.thin, m.small
    mixer_bowl(m)
    # the head lies in the top slab, hinged at its rear edge: opening (qpos up to 0.8) lifts its front; the
    # joint's friction holds it open against gravity (RoboCasa's head is closed at qpos 0). As a tilt-head
    # mixer's head, it reaches over the front (since version 6): its front edge overhangs the free front slab,
    # so a finger can get under it and lift it (OpenStandMixerHead); before, it lay on the collider's top
    m.part(
        "head",
        Joint("head_joint", axis=(-1, 0, 0), rng=(0.0, 0.8), pivot=(0, hy, 0), friction=1.0),
        (0, 0, top),
        (hx * 0.6, hy, t),
    )
    m.part(
        "bowl_b",
        Joint("bowl_joint", axis=(0, 0, 1), rng=(-3.2, 3.2)),
        (0, front, -hz * 0.5),
        small,
        collide=False,
    )
    m.part(
        "knob_speed", Joint("knob_speed_joint", rng=(0.0, 1.57)), (hx * 0.6, front, 0), small, collide=False
    )
    m.part(
        "button_head_lock",
        Joint("button_head_lock_joint", kind="slide", axis=(0, 1, 0), rng=(-0.01, 0.0)),
        (-hx * 0.6, front, 0),
        small,
        collide=False,
    )


def electric_kettle(m: Model) -> None:
    """The lid hinged at its rear edge, the power lever (``kettle_switch``) and the lid's release button."""
    hx, hy, hz, top, t = m.hx, m.hy, m.hz, m.top, m.thin
    m.part(
        "lid",
        Joint("lid_joint", axis=(-1, 0, 0), rng=(0.0, 1.57), pivot=(0, hy * 0.7, 0), friction=0.5),
        (0, 0, top),
        (hx * 0.7, hy * 0.7, t),
    )
    kettle_switch(m)
    # the lid's release button (ElectricKettle.update_state opens the shut lid once it reads > 0.1 of its
    # range): since version 6 a collider on the top beside the lid (where a kettle's handle carries it), pushed
    # down 1 cm to its stop and sprung back up (its spring at rest 1 cm over the top stop), away from where
    # CloseElectricKettleLid's oracle sweeps and presses the lid; before, it collided with nothing. Its top
    # stands 4 mm over the lid's (a finger on both counts the press before it meets the lid) and its bottom,
    # pushed down, 4 mm over the collider
    xb, top_b, bottom_b = (hx + hx * 0.7) / 2, hz - 0.001, hz - m.slab + 0.014
    m.part(
        "button_lid",
        Joint(
            "button_lid_joint",
            kind="slide",
            axis=(0, 0, 1),
            rng=(-0.01, 0.0),
            friction=0.02,
            spring=(20.0, 0.01),
        ),
        (xb, 0, (top_b + bottom_b) / 2),
        ((hx * 0.3) / 2 - 0.002, 0.015, (top_b - bottom_b) / 2),
    )


def kettle_switch(m: Model) -> None:
    """The kettle's collider with a free slab on its +x side, and in it, low, the power lever (``switch_joint``):
    RoboCasa's kettles carry it at the foot of the handle, on their +x side under the lid button, a plate sticking
    out about 4 cm over the counter and pressed down at its free end (ElectricKettle003's ``Lever001_joint`` slides
    12 mm down; 011, 021 and 028 hinge it at its inner end about +y, 0.26-0.52 rad; robocasa/robocasa 0e206dd1), and
    ``ElectricKettle.update_state`` turns the kettle on once it reads >= 0.95. Here it is hinged at its inner end
    about +y (0..0.26 rad, its free end down), 4 cm up, the slab over it free up to the lid button (since version 8:
    before, a 3 cm plate on the kettle's front rocking about its own middle)."""
    hx, hy, hz, s = m.hx, m.hy, m.hz, m.slab
    m.box("body", (-s / 2, s / 2, -s / 2), (hx - s / 2, hy - s / 2, hz - s / 2))
    length = s - 0.006  # 3 mm off the collider's side and inside the footprint's edge
    m.part(
        "switch",
        Joint("switch_joint", axis=(0, 1, 0), rng=(0.0, 0.26), pivot=(-length / 2, 0, 0), friction=0.05),
        (hx - s / 2, 0, -hz + 0.04),
        (length / 2, 0.0125, 0.003),
    )


def coffee_machine(m: Model) -> None:
    """The pour site low in the front slab, the start button above it."""
    hz, front, t = m.hz, m.front, m.thin
    m.site("receptacle_place_site", (0, front, -hz * 0.8))
    m.box("start_button", (0, front, hz * 0.6), (0.01, t * 0.5, 0.01))


def blender(m: Model) -> None:
    """A motor base (up to 0.4 of the height) under an open jar, behind the front slab; the jar's interior is reg_int
    (objects go in; RoboCasa drops TurnOnBlender's fruit there), its rim the blender's top, where the lid (an
    auxiliary fixture) is placed at anchor_site: its origin half its height above the rim (the lid's nominal size
    matches the blender's footprint, so both scale alike); Blender.update_state counts a press on the geom
    <blender>_power_button_main, a button standing out of the base's front into the slab."""
    hx, hy, hz, front = m.hx, m.hy, m.hz, m.front
    depth, y0, base = hy - m.slab / 2, m.slab / 2, -hz * 0.4
    inner = (hx * 0.7, depth * 0.7)
    m.hollow((hx, depth), inner, base, hz, y0)
    m.region("int", (0, y0, hz * 0.2), (*inner, hz * 0.6))
    m.box("power_button_main", (0, front, (base - hz) / 2), (0.015, m.slab / 2, 0.012))
    m.site("anchor_site", (0, y0, hz + SIZES["blender_lid"][2] / 2), outer=True)


def toaster(m: Model) -> None:
    """Two slots' knobs and levers, the cancel button."""
    hx, hz, front, t, small = m.hx, m.hz, m.front, m.thin, m.small
    for i, pair in enumerate(("0_0", "0_1")):
        m.part(
            f"knob_{pair}",
            Joint(f"knob_{pair}_joint", axis=(0, 1, 0), rng=(0.0, 3.14)),
            (hx * (0.3 + 0.3 * i), front, 0),
            small,
            collide=False,
        )
        m.part(
            f"lever_{pair}",
            Joint(f"lever_{pair}_joint", kind="slide", axis=(0, 0, 1), rng=(-0.05, 0.0)),
            (-hx * (0.3 + 0.3 * i), front, 0),
            small,
            collide=False,
        )
    m.box("button_cancel", (0, front, -hz * 0.5), (0.01, t * 0.5, 0.01))


# the toaster oven's door (since version 7): its hinge's height over the oven's bottom (a fraction of the oven's
# height) and its half thickness (m, nominal size). A toaster oven's door starts above its feet and the base under
# its cavity, and a glass door in its frame is about 2 cm thick; RoboCasa opens it flat (CloseToasterOvenDoor), so
# its free edge stands ~6 cm over the counter (nominal) and a finger gets under it. Before, hinged 3 cm up and
# 4 cm thick, the open door lay 8 mm over the counter at its stop: nothing could get under it
DOOR_HINGE, DOOR_HALF = 0.25, 0.01


def toaster_oven(m: Model) -> None:
    """Racks and a tray and four knobs (``built_in.racked_door``), the door hinged at its bottom edge
    ``DOOR_HINGE`` of the height up, up to where the oven's door always ended (0.8 of the half height)."""
    racked_door(m, ("doneness", "function", "temp", "time"), tray=True, door=False)
    bottom, top = -m.hz + DOOR_HINGE * 2 * m.hz, m.hz * 0.8
    half = (top - bottom) / 2
    m.part(
        "door",
        Joint("door_joint", axis=(1, 0, 0), rng=(0.0, 1.57), pivot=(0, 0, -half)),
        (0, m.front, (top + bottom) / 2),
        (m.hx * 0.7, DOOR_HALF, half),
    )


def open_top(m: Model) -> None:
    """A rack or a bowl: only an interior region on its top."""
    m.region("int", (0, 0, m.hz), (m.hx * 0.8, m.hy * 0.8, 0.02))


# m, the stand mixer's bowl at nominal size: its floor's height over the mixer's bottom, its walls' thickness, its
# depth (the rim over its floor) and the height of reg_bowl over its floor
BOWL_FLOOR, BOWL_WALL, BOWL_DEPTH, BOWL_REGION = 0.03, 0.01, 0.08, 0.2


def mixer_bowl(m: Model) -> None:
    """The stand mixer under its head (the top slab): a foot, a column at the back and, in front of it, an open bowl
    (floor and four walls, ``BOWL_DEPTH`` deep) holding ``reg_bowl``, the one region ``StandMixer`` reads
    (``get_reset_region_names``); ``check_item_in_bowl`` wants every corner of the object in that region's lower
    half, so the region runs ``BOWL_REGION`` up from the bowl's floor (a solid mixer held it inside its collider)."""
    hx, hy, hz, s = m.hx, m.hy, m.hz, m.slab
    floor, w = -hz + BOWL_FLOOR, BOWL_WALL
    y0, y1 = -hy + w, hy * 0.25  # the bowl's inside, from its front wall to the column
    ix, iy, yc = hx - 2 * w, (y1 - y0) / 2 - w, (y0 + y1) / 2
    m.box("foot", (0, 0, (floor - hz) / 2), (hx, hy, BOWL_FLOOR / 2))
    m.box("column", (0, (y1 + hy) / 2, (floor + hz - s) / 2), (hx, (hy - y1) / 2, (hz - s - floor) / 2))
    m.walls((ix + w, iy + w), (ix, iy), floor, floor + BOWL_DEPTH, yc, name="bowl")
    m.region("bowl", (0, yc, floor + BOWL_REGION / 2), (ix, iy, BOWL_REGION / 2))
