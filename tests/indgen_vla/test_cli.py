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
