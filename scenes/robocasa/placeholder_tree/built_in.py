"""Placeholder builders of the kitchen's built-in fixtures: the sink, the microwave, the oven and the dishwasher
(racks and a door hinged at its bottom), the stove's burners and knobs, and the fridge."""

from __future__ import annotations

from .model import Joint, Model


def sink(m: Model) -> None:
    """A basin open at the top: RoboCasa's checks want the object's centre inside reg_basin (obj_inside_of with
    partial_check), which a solid box would hold only for objects under 6 cm tall; its floor is the region's bottom
    (RoboCasa drops objects placed in the sink there), its rim the sink's top (the counter's top)."""
    hx, hy, hz = m.hx, m.hy, m.hz
    m.hollow((hx, hy), (hx * 0.7, hy * 0.6), -hz * 0.4, hz)
    m.region("basin", (0, 0, hz * 0.2), (hx * 0.7, hy * 0.6, hz * 0.6))
    # the class finds ./body/body/body/joint[@name=handle_joint] and ./body/body/body/site[@name=water];
    # the spout stands above the basin's rear, inside the footprint (behind it is the wall)
    m.bodies.append(
        f'<body name="spout" pos="0 {hy * 0.6:.4g} {hz + 0.05:.4g}">'
        '<joint name="handle_joint" type="hinge" axis="1 0 0" range="0 0.8" limited="true" damping="2" '
        'armature="0.01"/><geom name="spout_g" type="box" size="0.02 0.02 0.02" group="0" density="200" '
        'contype="0" conaffinity="0"/>'
        f'<site name="water" pos="0 -0.12 -0.1" size="0.03 0.05" type="cylinder" rgba="0 0 1 0"/>'
        '<body name="spout2" pos="0 0 0.05"><joint name="spout_joint" type="hinge" axis="0 0 1" '
        'range="-1.57 1.57" limited="true" damping="2" armature="0.01"/>'
        '<geom name="spout2_g" type="box" size="0.01 0.01 0.01" group="0" density="200" contype="0" '
        'conaffinity="0"/><body name="handle_temp" pos="0 0 0.03"><joint name="handle_temp_joint" type="hinge" '
        'axis="0 1 0" range="-0.8 0.8" limited="true" damping="2" armature="0.01"/>'
        '<geom name="handle_temp_g" type="box" size="0.005 0.005 0.005" group="0" density="200" contype="0" '
        'conaffinity="0"/></body></body></body>'
    )


def microwave(m: Model) -> None:
    """The interior region, a door hinged at its left edge and the start and stop buttons."""
    hx, hy, hz, front, t = m.hx, m.hy, m.hz, m.front, m.thin
    m.region("int", (0, 0, 0), (hx * 0.8, hy * 0.8, hz * 0.8))
    m.part(
        "door",
        Joint("microjoint", axis=(0, 0, 1), rng=(-1.57, 0.0), pivot=(-hx * 0.9, 0, 0)),
        (0, front, 0),
        (hx * 0.9, t, hz * 0.8),
        geom_names=("door",),
    )
    m.box("start_button", (hx * 0.9, front, hz * 0.3), (0.01, t * 0.5, 0.01))
    m.box("stop_button", (hx * 0.9, front, -hz * 0.3), (0.01, t * 0.5, 0.01))


def racked_door(m: Model, knobs: tuple[str, ...], tray: bool = False, door: bool = True) -> None:
    """An oven-like box: two racks (a toaster oven's tray under them with ``tray``), a door hinged at its bottom
    edge (opening swings it down toward the front; ``door=False``: the caller hinges its own) and a knob per name in
    ``knobs`` on the front."""
    hx, hy, hz, front, t, small = m.hx, m.hy, m.hz, m.front, m.thin, m.small
    for i, z in enumerate((-0.3, 0.3)):  # racks and trays: inside the box, touched by no task here
        m.region(f"rack{i}", (0, 0, hz * z), (hx * 0.8, hy * 0.8, hz * 0.15))
        m.part(
            f"rack{i}",
            Joint(f"rack{i}_joint", kind="slide", axis=(0, -1, 0), rng=(0.0, 0.3)),
            (0, 0, hz * z),
            (hx * 0.5, 0.005, 0.005),
            collide=False,
        )
    if tray:
        m.region("tray0", (0, 0, -hz * 0.6), (hx * 0.8, hy * 0.8, hz * 0.1))
        m.part(
            "tray0",
            Joint("tray0_joint", kind="slide", axis=(0, -1, 0), rng=(0.0, 0.3)),
            (0, 0, -hz * 0.6),
            (hx * 0.5, 0.005, 0.005),
            collide=False,
        )
    if door:
        m.part(
            "door",
            Joint("door_joint", axis=(1, 0, 0), rng=(0.0, 1.57), pivot=(0, 0, -hz * 0.8)),
            (0, front, 0),
            (hx * 0.7, t, hz * 0.8),
        )
    for i, k in enumerate(knobs):
        m.part(
            f"knob_{k}",
            Joint(f"knob_{k}_joint", axis=(0, 1, 0), rng=(0.0, 3.14)),
            (hx * 0.85, front, hz * (0.6 - 0.3 * i)),
            small,
            collide=False,
        )


def oven(m: Model) -> None:
    racked_door(m, ("time", "temp"))


def dishwasher(m: Model) -> None:
    racked_door(m, ("doneness", "function", "temp", "time"))


def stove(m: Model) -> None:
    """A burner site and a place site per burner location on the top, a knob per burner on the front."""
    hx, hy, hz, front, small = m.hx, m.hy, m.hz, m.front, m.small
    for i, loc in enumerate(("front_left", "front_right", "rear_left", "rear_right", "center")):
        x = (-0.5 if "left" in loc else 0.5 if "right" in loc else 0.0) * hx
        y = (-0.5 if "front" in loc else 0.5 if "rear" in loc else 0.0) * hy
        m.site(f"burner_on_{loc}", (x, y, hz))
        m.site(f"burner_{loc}_place_site", (x, y, hz))
        m.part(
            f"knob_{loc}",
            Joint(f"knob_{loc}_joint", axis=(0, 1, 0), rng=(-6.3, 6.3)),
            (hx * (-0.8 + 0.4 * i), front, 0),
            small,
            collide=False,
        )


# the fridge (heights over its floor, m): a solid freezer under an open compartment whose crisper drawer (RoboCasa's
# reg_type "drawer", opened 0.8 of its travel by PickPlaceFridgeDrawerToShelf) slides out under a shelf set back
# from the front, so a hand over the opened drawer's object has the room above it
FREEZER_TOP, DRAWER_WALL, SHELF_Z, SHELF_BACK = 0.86, 0.1, 1.08, 0.13  # SHELF_BACK: behind the door slab
DRAWER_DEPTH, DRAWER_TRAVEL, WALL = 0.3, 0.25, 0.04


def fridge(m: Model) -> None:
    """RoboCasa's fridge fixture (``robocasa/models/fixtures/fridge.py``) reads its regions and joints by name:
    ``fridge``/``freezer`` in a region's name is its compartment, ``drawer`` in it a drawer (any other a shelf,
    which ``get_reset_regions`` keeps at 0.2 m tall or more with its floor 0.5-1.5 m up), and a joint named with
    ``drawer`` slides one out; ``update_state`` moves a drawer's region with its geom, so the region lies in the
    drawer's body (at the model's origin, as the XML ``pos`` RoboCasa reads is that body's)."""
    hx, hy, hz, s, t = m.hx, m.hy, m.hz, m.slab, m.thin
    z = lambda h: h - hz  # noqa: E731  (a height over the floor in the model's frame)
    y0, y1, ix = -hy + s, hy - WALL, hx - WALL  # the compartment: behind the door slab, to the back wall
    m.box("freezer", (0, s / 2, (z(0) + z(FREEZER_TOP)) / 2), (hx, hy - s / 2, FREEZER_TOP / 2))
    zc, hc = (z(FREEZER_TOP) + hz) / 2, (hz - z(FREEZER_TOP)) / 2
    m.box("wall_back", (0, (y1 + hy) / 2, zc), (hx, WALL / 2, hc))
    for side, tag in ((-1, "neg"), (1, "pos")):
        m.box(f"wall_x{tag}", (side * (ix + hx) / 2, (y0 + y1) / 2, zc), (WALL / 2, (y1 - y0) / 2, hc))
    m.box("ceiling", (0, (y0 + y1) / 2, hz - WALL / 2), (ix, (y1 - y0) / 2, WALL / 2))
    ys, sz = y0 + SHELF_BACK, z(SHELF_Z)
    m.box("shelf", (0, (ys + y1) / 2, sz - 0.01), (ix, (y1 - ys) / 2, 0.01))
    m.region("fridge_shelf0", (0, (ys + y1) / 2, sz + 0.25), (ix - 0.01, (y1 - ys) / 2 - 0.01, 0.25))
    m.region("freezer_shelf0", (0, s / 2, z(FREEZER_TOP / 2)), (hx * 0.8, hy * 0.7, 0.18))
    # the drawer: a tray (floor and four walls) 5 mm over the freezer's top, its front just behind the door slab
    dx, d0, fz = ix - 0.01, y0 + 0.005, z(FREEZER_TOP) + 0.005
    d1, top = d0 + DRAWER_DEPTH, fz + 0.02 + DRAWER_WALL
    tray: list[str] = []
    m.box("drawer_floor", (0, (d0 + d1) / 2, fz + 0.01), (dx, DRAWER_DEPTH / 2, 0.01), into=tray)
    for y, tag in ((d0 + 0.005, "front"), (d1 - 0.005, "back")):
        m.box(f"drawer_{tag}", (0, y, (fz + 0.02 + top) / 2), (dx, 0.005, DRAWER_WALL / 2), into=tray)
    for side, tag in ((-1, "neg"), (1, "pos")):
        m.box(f"drawer_x{tag}", (side * (dx - 0.005), (d0 + d1) / 2, (fz + 0.02 + top) / 2),
              (0.005, DRAWER_DEPTH / 2 - 0.01, DRAWER_WALL / 2), into=tray)  # fmt: skip
    m.region("fridge_drawer0", (0, (d0 + d1) / 2, (fz + 0.02 + top) / 2),
             (dx - 0.01, DRAWER_DEPTH / 2 - 0.01, DRAWER_WALL / 2), into=tray)  # fmt: skip
    m.bodies.append(
        '<body name="fridge_drawer0" pos="0 0 0"><joint name="fridge_drawer0_joint" type="slide" axis="0 -1 0" '
        f'range="0 {DRAWER_TRAVEL:g}" limited="true" damping="2" armature="0.01" frictionloss="1"/>'
        + "".join(tray)
        + "</body>"
    )
    door = (hz - z(FREEZER_TOP)) / 2 - 0.005
    m.part(
        "fridge_door",
        Joint("fridge_door_joint", axis=(0, 0, 1), rng=(-1.57, 0.0), pivot=(-hx * 0.9, 0, 0)),
        (0, m.front, hz - door - 0.005),
        (hx * 0.9, t, door),
    )
    m.part(
        "freezer_door",
        Joint("freezer_door_joint", axis=(0, 0, 1), rng=(-1.57, 0.0), pivot=(-hx * 0.9, 0, 0)),
        (0, m.front, z(FREEZER_TOP / 2)),
        (hx * 0.9, t, FREEZER_TOP / 2 - 0.01),
    )


# m, the stand mixer's bowl at nominal size: its floor's height over the mixer's bottom, its walls' thickness, its
# depth (the rim over its floor) and the height of reg_bowl over its floor
BOWL_FLOOR, BOWL_WALL, BOWL_DEPTH, BOWL_REGION = 0.03, 0.01, 0.08, 0.2
