"""A miniature LIBERO asset tree: LIBERO's file names and layout with plain boxes, for LIBERO-Object and -Spatial.

Used by the tests (and for smoke-testing a machine without the Hub download): every LIBERO-Object and
LIBERO-Spatial task builds, steps, renders and loads its fixed initial states on it. Objects are 4 cm cubes
(any of LIBERO's quarter-turn placements leaves them upright) with a small box mesh as the visual; the basket keeps
LIBERO's wall layout; Spatial's fixtures are in ``miniature_spatial``.
"""

from __future__ import annotations

from pathlib import Path

import scenes.libero.miniature_common as common
from scenes.libero.assets import HOPE_OBJECTS, mark_placeholder
from scenes.libero.miniature_spatial import write_spatial_assets

HOPE_COLOURS = {  # LIBERO-Object's grocery items (assets.HOPE_OBJECTS) -> an RGB for their miniature
    "alphabet_soup": (0.85, 0.2, 0.15),
    "bbq_sauce": (0.45, 0.2, 0.1),
    "butter": (0.95, 0.85, 0.3),
    "chocolate_pudding": (0.4, 0.25, 0.15),
    "cream_cheese": (0.85, 0.9, 0.95),
    "ketchup": (0.8, 0.1, 0.1),
    "milk": (0.95, 0.95, 0.95),
    "orange_juice": (1.0, 0.6, 0.1),
    "salad_dressing": (0.5, 0.7, 0.3),
    "tomato_sauce": (0.75, 0.15, 0.2),
}
assert tuple(HOPE_COLOURS) == HOPE_OBJECTS  # one colour per LIBERO object, in LIBERO's order
CUBE_HALF = 0.02
TEXTURES = (
    "light-gray-floor-tile.png",
    "light-gray-plaster.png",
    "tile_grigia_caldera_porcelain_floor.png",
    "smooth_light_gray_plaster.png",
    "martin_novak_wood_table.png",
)

ARENA = common.arena_xml(f'<body name="floor" pos="0 0 0">\n      {common.FLOOR}\n    </body>')

# The basket's floor and four walls as (pos, half-size), LIBERO's layout.
_BASKET_WALLS = (
    ("0 0 0.0045", "0.0765 0.0724 0.0045"),
    ("-0.0727 0 0.0766", "0.0067 0.0724 0.0640"),
    ("0.0756 0 0.0766", "0.0067 0.0724 0.0640"),
    ("0 -0.0686 0.0766", "0.0765 0.0067 0.0640"),
    ("0 0.0691 0.0766", "0.0765 0.0067 0.0640"),
)
BASKET = common.object_xml(
    "basket",
    common.texture_asset("texture.png", "basket", "basket"),
    '<site type="box" pos="0 0 0.07185" quat="1 0 0 0" size="0.06108 0.06108 0.06949" group="0" rgba="0.8 0 0 0"\n'
    '          name="contain_region"/>'
    + "".join(
        f'\n        <geom {common.GEOM} type="box" pos="{p}" size="{s}" group="0" material="basket"/>'
        for p, s in _BASKET_WALLS
    ),
)


def write_miniature_assets(root: str | Path) -> Path:
    """Write the miniature tree under ``root`` (idempotent) and return it; use it as $INDGEN_LIBERO_ASSETS."""
    root = Path(root)
    for sub in ("scenes", "textures", "stable_hope_objects", "turbosquid_objects", "articulated_objects"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    (root / "scenes" / "libero_floor_base_style.xml").write_text(ARENA)
    for i, name in enumerate(TEXTURES):
        (root / "textures" / name).write_bytes(common.png((0.55 + 0.08 * i, 0.55 + 0.05 * i, 0.55)))
    for name, rgb in HOPE_COLOURS.items():
        common.write_hope_object(root / "stable_hope_objects" / name, CUBE_HALF, rgb)
    common.write_box_object(root / "stable_scanned_objects" / "basket", BASKET, (0.6, 0.45, 0.25))
    write_spatial_assets(root)
    mark_placeholder(
        root, "A miniature LIBERO asset tree (scenes.libero.miniature): boxes for objects, flat textures."
    )
    return root
