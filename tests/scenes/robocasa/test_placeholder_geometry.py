"""The placeholder sink and blender are containers open at the top (``placeholder_tree.model.Model.hollow``): RoboCasa's
checks want an object inside their regions (``reg_basin``, ``reg_int``), which a solid box made unreachable; the
blender carries the ``anchor_site`` RoboCasa places its lid at and the ``power_button_main`` geom
``Blender.update_state`` counts a press on. Needs the RoboCasa venv (the tree is written from RoboCasa's registry)."""

from __future__ import annotations

import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from tests.scenes.robocasa.test_robocasa import _box, needs_venv

# RoboCasa's Fridge and StandMixer on the tree (what test_fridge_and_mixer_bowl checks): the fridge's drawer joint,
# its highest drawer region (PickPlaceFridgeDrawerToShelf's rack_index=-1), its shelf (standing on the floor, as a
# layout places it) and the mixer's bowl; the fixture is named 'fr': robosuite leaves a name that already starts
# with the prefix unprefixed, and Fridge strips the prefix to find "fridge" in its joints and regions
FRIDGE_AND_MIXER = (
    "from robocasa.models.fixtures.fridge import Fridge\n"
    "from robocasa.models.fixtures.stand_mixer import StandMixer\n"
    "f = Fridge(xml=root + '/fixtures/fridges/Refrigerator064', name='fr')\n"
    "f.set_pos([0.0, 0.0, f.height / 2])\n"
    "m = StandMixer(xml=root + '/fixtures/stand_mixers/StandMixer003', name='mixer')\n"
    "print([j[len('fr_'):] for j in f._drawer_joint_names],\n"
    "      sorted(f.get_reset_regions(None, compartment='fridge', reg_type='drawer', rack_index=-1)),\n"
    "      sorted(f.get_reset_regions(None, compartment='fridge', reg_type='shelf')), sorted(m.get_int_sites()))\n"
)


def _model(placeholders, folder: str) -> ET.Element:
    return ET.parse(next((placeholders / "fixtures" / folder).glob("*/model.xml"))).getroot()


def _object(root: ET.Element) -> ET.Element:
    return next(b for b in root.iter("body") if b.get("name") == "object")


def _colliders(body: ET.Element) -> list[tuple[np.ndarray, np.ndarray]]:
    """(centre, half size) of each colliding box of the fixture's own body."""
    return [_box(g) for g in body.findall("geom") if g.get("contype") != "0" and g.get("type") == "box"]


def _region(body: ET.Element, name: str) -> tuple[np.ndarray, np.ndarray]:
    return _box(next(g for g in body.findall("geom") if g.get("name") == f"reg_{name}"))


def _solid_at(colliders, point) -> bool:
    return any(np.all(np.abs(np.asarray(point) - c) <= h + 1e-9) for c, h in colliders)


def _check_open_container(body: ET.Element, region: str) -> None:
    """No collider reaches into the region; a floor lies right under it and a wall just outside each of its four
    sides (so an object dropped in stays in)."""
    boxes, (c, h) = _colliders(body), _region(body, region)
    for bc, bh in boxes:
        assert not np.all(np.abs(bc - c) < bh + h - 1e-9), f"a collider at {bc} reaches into reg_{region}"
    assert _solid_at(boxes, c - [0, 0, h[2] + 0.005]), "no floor under the region"
    for axis in (0, 1):
        for side in (-1, 1):
            p = c.copy()
            p[axis] += side * (h[axis] + 0.005)
            assert _solid_at(boxes, p), f"no wall on the region's {'xy'[axis]} {side:+d} side"


@needs_venv
def test_the_sink_is_a_basin_whose_region_is_free_space(placeholders):
    body = _object(_model(placeholders, "sinks"))
    _check_open_container(body, "basin")
    # the floor is the region's bottom (RoboCasa drops objects placed in the sink there) and the rim the sink's top
    (c, h), (_, main) = _region(body, "basin"), _region(body, "main")
    tops = [bc[2] + bh[2] for bc, bh in _colliders(body)]
    assert min(tops) == pytest.approx(c[2] - h[2]) and max(tops) == pytest.approx(main[2])


@needs_venv
def test_the_blender_has_a_hollow_jar_its_lid_anchor_and_its_power_button(placeholders):
    root = _model(placeholders, "blenders")
    body = _object(root)
    _check_open_container(body, "int")
    # RoboCasa's MJCFObject.anchor_offset reads ./body/site[@name=anchor_site] (the lid goes there): above the rim
    anchor = root.find("worldbody").find("./body/site[@name='anchor_site']")
    assert anchor is not None
    rim = max(bc[2] + bh[2] for bc, bh in _colliders(body))
    assert float(anchor.get("pos").split()[2]) > rim
    # Blender.update_state: a contact with <blender>_power_button_main; the button stands out of the front
    button = next(g for g in body.findall("geom") if g.get("name") == "power_button_main")
    assert button.get("contype") != "0"
    bc, bh = _box(button)
    others = [(c, h) for c, h in _colliders(body) if not np.allclose(c, bc)]
    assert not _solid_at(others, bc - [0, bh[1], 0])  # its front face is free: a finger can reach it


@needs_venv
def test_robocasa_reads_the_regions_the_lid_anchor_and_the_button(placeholders):
    """What RoboCasa's own classes read from the tree: the sink's basin, the blender's interior and lid anchor."""
    from scenes.robocasa.environment import find_python

    code = (
        "import robocasa, sys\n"
        "from robocasa.models.fixtures.sink import Sink\n"
        "from robocasa.models.fixtures.blender import Blender\n"
        f"root = {str(placeholders)!r}\n"
        "s = Sink(xml=root + '/fixtures/sinks/Sink001', name='sink')\n"
        "b = Blender(xml=root + '/fixtures/blenders/Blender001', name='blender')\n"
        "names = [g.get('name') for g in b.worldbody.iter('geom')]\n"
        "print(sorted(s.get_int_sites()), sorted(b.get_int_sites()), b.anchor_offset is not None,\n"
        "      'blender_power_button_main' in names)\n" + FRIDGE_AND_MIXER
    )
    r = subprocess.run([str(find_python()), "-c", code], capture_output=True, text=True,
                       env={"ROBOCASA_ASSETS_PATH": str(placeholders), "MUJOCO_GL": "egl", "PATH": "/usr/bin:/bin",
                            "HOME": str(Path.home())})  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip().splitlines()[-2] == "['basin'] ['int'] True True"
    # test_fridge_and_mixer_bowl's reads, in this one interpreter (RoboCasa's import is most of the test's time)
    assert (
        r.stdout.strip().splitlines()[-1]
        == "['fridge_drawer0_joint'] ['fridge_drawer0'] ['fridge_shelf0'] ['bowl']"
    )


def test_a_placeholder_tree_of_an_older_generator_is_refused_in_one_line(tmp_path, monkeypatch):
    """Its sink and blender were solid boxes: bumping ``placeholder_tree.VERSION`` makes it rewritten, never used."""
    from indgen_vla.core.errors import SceneError
    from scenes.robocasa.environment import PLACEHOLDER_MARKER, find_assets
    from scenes.robocasa.placeholder_tree import VERSION

    for d in ("fixtures/fixture_registry", "scenes/kitchen_layouts", "objects/lightwheel/apple/apple_ph"):
        (tmp_path / d).mkdir(parents=True)
    (tmp_path / "objects/lightwheel/apple/apple_ph/model.xml").write_text(
        "<mujoco/>"
    )  # a tree with an object
    monkeypatch.setenv("INDGEN_ROBOCASA_ASSETS", str(tmp_path))
    (tmp_path / PLACEHOLDER_MARKER).write_text(f"version {VERSION - 1}\nrobocasa 1.0.1\n")
    old = f"older generator \\(version {VERSION - 1}; current: version {VERSION}\\)"
    with pytest.raises(SceneError, match=old):
        find_assets()
    assert find_assets(required=False) is None
    (tmp_path / PLACEHOLDER_MARKER).write_text(f"version {VERSION}\nrobocasa 1.0.1\n")
    assert find_assets() == tmp_path.resolve()
