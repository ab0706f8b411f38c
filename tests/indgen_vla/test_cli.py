import subprocess
import sys

import pytest

from indgen_vla.cli import HANDLERS, build_parser, main


def test_import_is_light():
    code = (
        "import sys, indgen_vla, indgen_vla.cli, indgen_vla.metrics, indgen_vla.records, indgen_vla.report; "
        "print(sorted(m for m in ('torch', 'robosuite', 'lerobot', 'mujoco') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_help_lists_every_design_subcommand(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    for cmd in ("evaluate", "certify", "report", "compare", "serve", "scenes", "axes", "policies",
                "blockenv", "demos", "mimicgen"):  # fmt: skip
        assert cmd in out
    assert set(HANDLERS) <= set(build_parser()._subparsers._group_actions[0].choices)


def test_typo_suggests(capsys):
    with pytest.raises(SystemExit) as e:
        main(["evalute"])
    assert e.value.code == 2
    assert "did you mean 'evaluate'?" in capsys.readouterr().err


def test_console_script_runs():
    exe = subprocess.run(
        [sys.executable, "-m", "indgen_vla.cli", "--version"], capture_output=True, text=True
    )
    assert exe.returncode == 0 and "indgen-vla" in exe.stdout


def test_negative_level_ranges_parse():
    ns = build_parser().parse_args(["evaluate", "--levels", "-3:3", "--axis", "pick_y"])
    assert ns.levels == "-3:3"
    assert build_parser().parse_args(["evaluate", "--levels", "-2,0,2"]).levels == "-2,0,2"
    assert build_parser().parse_args(["evaluate", "--levels", "-1"]).levels == "-1"


def test_passthrough_and_unknown_flags(capsys):
    with pytest.raises(SystemExit) as e:
        main(["report", "x", "--bogus"])
    assert e.value.code == 2 and "unrecognized arguments: --bogus" in capsys.readouterr().err


def test_paper_presets_run_the_suite_they_are_named_after():
    """A preset named after a LIBERO suite runs that suite; every other one starts with the built-in scene it
    runs (the stand-ins for suites the toolkit does not bundle end in ``_style``)."""
    import scenes
    from indgen_vla.engine.config import PRESET_DIR, load_preset

    presets = {p.stem: load_preset(str(p)) for p in sorted(PRESET_DIR.glob("*.yaml"))}
    assert {"libero_object", "pick_place_libero_object_style"} <= set(presets)
    suites = [s for s in scenes.scene_names() if s.startswith("libero_")]
    for name, d in presets.items():
        scene = d["scene"]
        suite = next((s for s in suites if name.startswith(s)), None)
        assert scene == (suite or scene) and name.startswith(scene), name
        if suite is None and any(w in name for w in ("libero", "robocasa", "real_robot")):
            assert name.endswith("_style") or "distractor" in name, name
        for axis in d["axes"]:
            assert set(axis.split("+")) <= set(scenes.axes_for(scene)), (name, axis)
    assert presets["libero_object"]["task"] == "all" and presets["libero_object"]["axes"] == [
        "pick_y",
        "goal_y",
        "scale",
    ]


def test_reference_subcommand_documents_every_option(capsys):
    with pytest.raises(SystemExit):
        main(["reference", "--help"])
    out = capsys.readouterr().out
    for opt in ("RUN_DIR", "--axis", "--task", "--out"):
        assert opt in out
    assert "held-out" in out.replace("\n", " ") or "held out" in out
