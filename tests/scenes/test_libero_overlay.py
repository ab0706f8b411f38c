"""The partial-asset overlay: missing referenced files are filled with placeholders MuJoCo can load, present ones
are linked, and a filled mesh that is not named as visual is reported as a possible collision mesh; references inside comments are not needed."""

import mujoco

from scenes.libero.assets import PLACEHOLDER_MARK, is_placeholder_tree
from scenes.libero.overlay import (
    collision_suspects,
    overlay_assets,
    placeholder_bytes,
    referenced_missing,
)

OBJ = "v 0 0 0\nv 0.02 0 0\nv 0 0.02 0\nv 0 0 0.02\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def _tree(root):
    (root / "thing" / "visual").mkdir(parents=True)
    (root / "thing" / "thing_col.obj").write_text(OBJ)
    (root / "thing" / "thing.xml").write_text(
        """<mujoco model="thing">
  <asset>
    <texture name="tex" type="2d" file="texture.png"/>
    <material name="mat" texture="tex"/>
    <mesh name="vis" file="visual/thing_vis.msh"/>
    <mesh name="col" file="thing_col.obj"/>
    <mesh name="frame" file="frame.stl"/>
    <!-- <mesh name="old" file="visual/old.stl"/> -->
  </asset>
  <worldbody>
    <body name="thing">
      <geom type="mesh" mesh="vis" material="mat" contype="0" conaffinity="0" group="1"/>
      <geom type="mesh" mesh="col"/>
      <geom type="mesh" mesh="frame"/>
    </body>
  </worldbody>
</mujoco>"""
    )
    return root


def test_overlay_fills_missing_files_that_mujoco_then_loads(tmp_path):
    src = _tree(tmp_path / "src")
    assert [p.name for p in referenced_missing(src)] == ["frame.stl", "texture.png", "thing_vis.msh"]
    filled = overlay_assets(src, tmp_path / "dst")
    assert sorted(filled) == ["thing/frame.stl", "thing/texture.png", "thing/visual/thing_vis.msh"]
    dst = tmp_path / "dst" / "thing"
    assert (dst / "thing_col.obj").is_symlink() and (dst / "thing.xml").is_symlink()
    assert not (src / "thing" / "frame.stl").exists()  # the source tree is never written
    model = mujoco.MjModel.from_xml_path(str(dst / "thing.xml"))  # the placeholders are valid mesh/PNG files
    assert model.nmesh == 3 and model.ntex == 1
    assert collision_suspects(filled) == ["thing/frame.stl"]  # not under visual/ nor *_vis.*
    assert overlay_assets(src, tmp_path / "dst") == filled  # re-running keeps what is there
    assert is_placeholder_tree(tmp_path / "dst") and not is_placeholder_tree(
        src
    )  # filled pictures: no measurement
    whole = tmp_path / "whole"
    overlay_assets(
        tmp_path / "dst", whole
    )  # nothing missing: a faithful copy is not marked by the overlay...
    assert (whole / PLACEHOLDER_MARK).is_symlink()  # ...but keeps the mark of a tree that had one


def test_overlay_cli(tmp_path, capsys):
    src = _tree(tmp_path / "src")
    from indgen_vla.app.cli import main

    assert main(["setup", "libero", "--overlay", str(src), "--dest", str(tmp_path / "dst")]) == 0
    out = capsys.readouterr().out
    assert "3 placeholder file(s)" in out and "1 may be collision meshes: thing/frame.stl" in out
    assert (
        main(["setup", "libero", "--overlay", str(tmp_path / "nope"), "--dest", str(tmp_path / "dst2")]) == 2
    )
    assert "is not a folder" in capsys.readouterr().err
    assert main(["setup", "libero", "--overlay", str(src)]) == 2
    assert "needs --dest DST" in capsys.readouterr().err


def test_placeholders_compile_in_mujoco(tmp_path):
    for suffix in (".msh", ".stl", ".obj", ".png"):
        (tmp_path / f"p{suffix}").write_bytes(placeholder_bytes(suffix))
    xml = f"""<mujoco><asset>
      <mesh name="a" file="{tmp_path}/p.msh"/><mesh name="b" file="{tmp_path}/p.stl"/>
      <mesh name="c" file="{tmp_path}/p.obj"/><texture name="t" type="2d" file="{tmp_path}/p.png"/>
      <material name="m" texture="t"/></asset><worldbody>
      <geom type="mesh" mesh="a"/><geom type="mesh" mesh="b"/><geom type="mesh" mesh="c" material="m"/>
      </worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    assert list(m.mesh_vertnum) == [4, 4, 4]


def test_overlay_links_present_files_and_fills_only_missing_ones(tmp_path):
    src = tmp_path / "src"
    (src / "obj").mkdir(parents=True)
    (src / "obj" / "col.obj").write_text("v 0 0 0\n")
    (src / "obj" / "o.xml").write_text(
        '<mujoco><mesh file="col.obj"/><mesh file="visual/vis.msh"/><texture file="/abs/elsewhere.png"/></mujoco>'
    )
    dst = tmp_path / "dst"
    assert overlay_assets(src, dst) == ["obj/visual/vis.msh"]
    assert (dst / "obj" / "col.obj").is_symlink() and (dst / "obj" / "col.obj").read_text() == "v 0 0 0\n"
    assert (dst / "obj" / "visual" / "vis.msh").read_bytes() == placeholder_bytes(".msh")
    assert not (src / "obj" / "visual").exists()  # the source tree is left alone
