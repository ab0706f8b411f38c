"""The pure helpers of scripts/bench_vs_lerobot.py: placeholder assets, profile categories, paired ratios."""

import importlib.util
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location(
    "bench_vs_lerobot", Path(__file__).resolve().parents[2] / "scripts" / "bench_vs_lerobot.py"
)
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)


def test_parse_sizes_accepts_lists_and_refuses_bad_input():
    assert bench.parse_sizes("128,256") == [128, 256]
    for bad in ("", "128,x", "0", "-5"):
        with pytest.raises(SystemExit, match="--sizes"):
            bench.parse_sizes(bad)


def test_placeholders_compile_in_mujoco(tmp_path):
    import mujoco

    for suffix in (".msh", ".stl", ".obj", ".png"):
        (tmp_path / f"p{suffix}").write_bytes(bench.placeholder_bytes(suffix))
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
    assert bench.overlay_assets(src, dst) == ["obj/visual/vis.msh"]
    assert (dst / "obj" / "col.obj").is_symlink() and (dst / "obj" / "col.obj").read_text() == "v 0 0 0\n"
    assert (dst / "obj" / "visual" / "vis.msh").read_bytes() == bench.placeholder_bytes(".msh")
    assert not (src / "obj" / "visual").exists()  # the source tree is left alone


def test_categorize_takes_the_first_matching_rule_over_the_whole_stack(tmp_path):
    raw = tmp_path / "p.txt"
    raw.write_text(
        "rollout (lerobot_eval.py:1);step (robosuite/environments/base.py:2);render (robosuite/utils/binding_utils.py:3) 6\n"
        "step (robosuite/environments/base.py:2);run_controller (robosuite/robots/single_arm.py:9) 3\n"
        "render_frame (lerobot_eval.py:4);render (lerobot/envs/libero.py:281);render (robosuite/utils/binding_utils.py:3) 1\n"
        "not a sample line\n"
    )
    shares = bench.categorize(raw)
    assert shares == {"render": 60.0, "physics (OSC control + mj_step)": 30.0,
                      "video (lerobot's extra frames + mp4)": 10.0}  # fmt: skip


def test_paired_ratio_is_the_geometric_mean_with_a_t_interval():
    r = bench.paired_ratio([2.0, 4.0], [1.0, 2.0])
    assert r["ratio"] == 2.0 and r["ci95"] == [2.0, 2.0] and r["n"] == 2 and r["paired"]
    r = bench.paired_ratio([3.0, 1.0], [1.0, 1.0])
    assert r["ratio"] == pytest.approx(3**0.5, abs=1e-3) and r["ci95"][0] < 1.0 < 3.0 < r["ci95"][1]
    assert bench.paired_ratio([1.5], [1.0])["ci95"] is None
