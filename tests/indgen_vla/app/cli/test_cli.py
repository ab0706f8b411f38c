import subprocess
import sys
from pathlib import Path

import pytest

from indgen_vla.app.cli import HANDLERS, PARSERS, build_parser, main


def test_import_is_light():
    code = (
        "import sys, indgen_vla, indgen_vla.app.cli, indgen_vla.core.stats.metrics, indgen_vla.core.runs.records, indgen_vla.core.reporting.report; "
        "print(sorted(m for m in ('torch', 'robosuite', 'lerobot', 'mujoco') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_help_imports_no_numpy_and_no_scene():
    """``indgen --help`` builds every parser without numpy, scipy or a scene (``# lazy: start-up`` imports)."""
    code = (
        "import sys; from indgen_vla.app.cli import build_parser; build_parser(); "
        "print(sorted(m for m in ('numpy', 'scipy', 'pandas', 'scenes', 'torch', 'robosuite') if m in sys.modules))"
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
        [sys.executable, "-m", "indgen_vla.app.cli", "--version"], capture_output=True, text=True
    )
    assert exe.returncode == 0 and "indgen-vla" in exe.stdout


def test_negative_level_ranges_parse():
    ns = build_parser().parse_args(["evaluate", "--levels", "-3:3", "--axis", "pick_y"])
    assert ns.levels == "-3:3"
    assert build_parser().parse_args(["evaluate", "--levels", "-2,0,2"]).levels == "-2,0,2"
    assert build_parser().parse_args(["evaluate", "--levels", "-1"]).levels == "-1"


def test_levels_written_as_the_axes_table_prints_them_get_the_colon_form(tmp_path, capsys):
    """``indgen axes`` prints ranges as -3..3; typed into --levels that was argparse's bare "expected one
    argument" (a value starting with -digit read as a flag). It is now one line naming the colon form, exit 2,
    before anything is written; a malformed negative range reaches the level parser's own line too."""
    out = tmp_path / "run"
    for text, want in (("-3..3", "write a range with a colon, --levels -3:3"),
                       ("0..2", "write a range with a colon, --levels 0:2"),
                       ("-3:3x", "is not a range like -3:3")):  # fmt: skip
        argv = [
            "evaluate",
            "--policy",
            "standin:oracle",
            "--scene",
            "pick_place",
            "--axis",
            "pick_y",
            "--levels",
        ]
        assert main([*argv, text, "--episodes", "2", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert want in err and err.count("\n") == 1 and "expected one argument" not in err
    assert not out.exists()


def test_passthrough_and_unknown_flags(capsys):
    with pytest.raises(SystemExit) as e:
        main(["report", "x", "--bogus"])
    assert e.value.code == 2 and "unrecognized arguments: --bogus" in capsys.readouterr().err


def test_paper_presets_run_the_suite_they_are_named_after():
    """A preset named after a LIBERO suite runs that suite; every other one starts with the scene it runs (the
    stand-ins on a built-in scene for a benchmark the preset names end in ``_style``; robocasa_* run RoboCasa)."""
    import scenes
    from indgen_vla.app.engine.config import PRESET_DIR, load_config_preset
    from scenes.axes import resolve_alias

    presets = {p.stem: load_config_preset(str(p)) for p in sorted(PRESET_DIR.glob("*.yaml"))}
    assert {"libero_object", "pick_place_libero_object_style"} <= set(presets)
    suites = [s for s in scenes.scene_names() if s.startswith("libero_")]
    for name, d in presets.items():
        scene = d["scene"]
        suite = next((s for s in suites if name.startswith(s)), None)
        assert scene == (suite or scene) and name.startswith(scene), name
        if suite is None and any(
            w in name and not scene.startswith(w) for w in ("libero", "robocasa", "real_robot")
        ):
            assert name.endswith("_style") or "distractor" in name, name
        for axis in d["axes"]:
            assert set(map(resolve_alias, axis.split("+"))) <= set(list(scenes.get_scene(scene).axes)), (
                name,
                axis,
            )
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


def test_demos_help_says_levels_is_required_with_axis(capsys):
    """demos refuses --axis without --levels, so its help must not promise evaluate's default (the axis range)."""
    with pytest.raises(SystemExit):
        main(["demos", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "(required with --axis)" in out and "default: the axis range" not in out


@pytest.mark.parametrize(
    "argv, says",
    [
        (["real", "plan", "--setup", "stack", "--out", "r"], "required: --policy"),
        (["real", "plann"], "did you mean 'plan'?"),
        (["blockenv", "sample"], "required: --level"),
        (["mimicgen", "--n", "1"], "required: --source, --out"),
        (["train", "--out", "x"], "required: datasets"),
    ],
)
def test_passthrough_subcommands_refuse_bad_arguments_in_one_line(argv, says, capsys):
    """Their own parsers are indgen's: one error line (no usage block), exit 2, a "did you mean" on a typo."""
    with pytest.raises(SystemExit) as e:
        main(argv)
    err = capsys.readouterr().err
    assert e.value.code == 2 and says in err and err.count("\n") == 1 and "usage:" not in err


def test_report_help_names_where_the_overlay_goes(capsys):
    with pytest.raises(SystemExit):
        main(["report", "--help"])
    assert "(default: FIRST_RUN/overlay)" in " ".join(capsys.readouterr().out.split())


class _Captured(Exception):
    """Carries the parser a passthrough handler built, instead of letting it parse."""

    def __init__(self, parser):
        self.parser = parser


def _parsers_without_help(parser, where: str) -> list[str]:
    import argparse

    out = []
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sub in a.choices.items():
                out += _parsers_without_help(sub, f"{where} {name}")
        elif not isinstance(a, argparse._HelpAction) and not a.help:
            out.append(f"{where} {'/'.join(a.option_strings) or a.dest}")
    return out


@pytest.mark.parametrize("command", ["demos", "mimicgen", "train", "blockenv"])
def test_every_passthrough_option_has_a_help_line(command, monkeypatch):
    """The subcommands that parse their own arguments document every option too."""
    import argparse

    def capture(self, args=None, namespace=None):
        raise _Captured(self)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", capture)
    with pytest.raises(_Captured) as e:
        main([command])
    assert _parsers_without_help(e.value.parser, f"indgen {command}") == []


def test_every_option_has_a_help_line():
    assert _parsers_without_help(build_parser(), "indgen") == []


def test_presets_resolve_by_name_from_the_top_level_configs():
    """In a checkout the presets are the top-level configs/ (a wheel carries them as indgen_vla/configs/,
    tests/indgen_vla/core/test_resources.py): a bare preset name works from any working directory."""
    import indgen_vla
    from indgen_vla.app.engine.config import PRESET_DIR, load_config_preset
    from indgen_vla.core.resources import config_dir
    from scenes.axes import load_preset, preset_names

    configs = Path(indgen_vla.__file__).parents[1] / "configs"
    assert PRESET_DIR == config_dir("paper") == configs / "paper"
    assert load_config_preset("libero_object")["scene"] == "libero_object"
    assert {"paper", "quick"} <= set(preset_names()) and config_dir("axes") == configs / "axes"
    assert load_preset("quick")["pick_y"] == {"max_level": 1}
    with pytest.raises(ValueError, match="unknown config kind"):
        config_dir("nope")


def test_task_and_axis_errors_come_from_the_scene_registry(tmp_path):
    """evaluate and certify share one rule for tasks and axes: the same one-line errors."""
    from indgen_vla.app.engine.config import EvalConfig
    from indgen_vla.core.errors import UnknownNameError
    from tests.fixtures.resolved import build_plan

    def cfg(**kw):
        base = dict(policy="standin:oracle", scene="stack", axes=("stack",), out=str(tmp_path), levels="0:1")
        return EvalConfig.from_flat(**{**base, **kw})

    plan = build_plan(cfg(task="all"))
    assert len(plan.tasks) > 1 and plan.levels == {"stack": (0, 1)}
    assert build_plan(cfg()).tasks == plan.tasks[:1]
    with pytest.raises(UnknownNameError, match=r"unknown task of scene stack 'nope'.*all"):
        build_plan(cfg(task="nope"))
    with pytest.raises(UnknownNameError, match=r"unknown axis of scene cabinet_pick 'pick_y'"):
        build_plan(cfg(scene="cabinet_pick", axes=("pick_y",)))


def test_device_precision_and_compile_are_checked_and_recorded():
    from indgen_vla.app.engine.config import EvalConfig
    from indgen_vla.core.errors import ConfigError

    base = dict(policy="standin:random", scene="pick_place", axes=("pick_y",), out="x")
    cfg = EvalConfig.from_flat(**base, device="cuda:1", precision="bf16")
    assert (cfg.policy.device, cfg.policy.precision) == ("cuda:1", "bf16")  # manifest "config" is cfg.flat()
    with pytest.raises(ConfigError, match="--device"):
        EvalConfig.from_flat(**base, device="gpu")
    with pytest.raises(ConfigError, match="--precision"):
        EvalConfig.from_flat(**base, precision="fp16")
    cfg = EvalConfig.from_flat(**base, device="cuda", precision="bf16", compile="reduce-overhead")
    assert cfg.flat()["compile"] == "reduce-overhead"  # recorded in the manifest like precision
    assert cfg.policy_options() == {"precision": "bf16", "compile": "reduce-overhead"}
    assert EvalConfig.from_flat(**base).policy_options() == {}  # families without these options still load
    with pytest.raises(
        ConfigError, match="--compile reduce-overhead captures CUDA graphs and needs --device cuda"
    ):
        EvalConfig.from_flat(**base, compile="reduce-overhead")  # CPU: refused, never rewritten
    with pytest.raises(ConfigError, match="--compile must be one of"):
        EvalConfig.from_flat(**base, compile="fast")


def test_workers_get_one_egl_device_each_round_robin(monkeypatch):
    from indgen_vla.app.engine.local import egl_devices

    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "0,3")
    assert egl_devices() == 2
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "-1")
    assert egl_devices() == 0


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["evaluate"], "finished episodes are saved; re-run the same command to resume"),
        (["certify"], "levels finished so far are saved"),
        (["blockenv", "reproduce", "--resume"], "jobs are saved; re-run the same command to resume"),
        (["blockenv", "train"], "'indgen blockenv train' keeps no partial output; re-run it to start over"),
        (["blockenv", "ablate"], "each finished ablation is saved in the results JSON"),
        (["demos"], "finished episodes are saved; re-run the same command to resume"),
        (["train"], "last saved training state is kept; re-run the same command to resume"),
        (["mimicgen"], "every finished attempt is saved; re-run the same command to resume"),
    ],
)
def test_ctrl_c_promises_a_resume_only_where_there_is_one(argv, says, monkeypatch, capsys):
    """Ctrl-C exits 130 with one line; `blockenv train` keeps nothing, so its line must not say "finished episodes
    are saved; re-run to resume" (a re-run starts from scratch)."""
    import indgen_vla.app.cli as cli

    def interrupt(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_resolve", lambda command: interrupt)
    extra = {"evaluate": ["--policy", "standin:oracle", "--scene", "pick_place", "--axis", "pick_y", "--out", "x"],
             "certify": ["--scene", "pick_place", "--axis", "pick_y"]}.get(argv[0], [])  # fmt: skip
    assert main(argv + extra) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("interrupted:") and says in err[0]


def test_every_command_is_one_cli_module_holding_its_parser_and_handler():
    """Each subcommand's handler is ``main`` of a module under ``indgen_vla.app.cli`` that ``PARSERS`` builds
    ``--help`` from, and each such module has ``add_parser`` and ``main``."""
    import importlib

    for command, target in HANDLERS.items():
        module, _, func = target.partition(":")
        assert module.startswith("indgen_vla.app.cli.") and func == "main", command
        assert module in PARSERS, command
    for module in PARSERS:
        m = importlib.import_module(module)
        assert callable(m.add_parser) and callable(m.main), module


# scripts our code starts in a scene family's own interpreter with one path argument (RoboCasa's venv): no user runs them
FOREIGN_ENTRY_POINTS = {"scenes/external_worker.py", "scenes/robocasa/placeholder_tree/__main__.py"}


def test_no_library_package_parses_arguments():
    """argparse lives in the application layer: the core, scenes/ and policy_wrappers/ hold no subcommand and read
    no argv (the asset tools are ``indgen setup`` options)."""
    import ast

    root = Path(__file__).resolve().parents[4]
    found = []
    for top in ("indgen_vla/core", "scenes", "policy_wrappers"):
        for path in sorted((root / top).rglob("*.py")):
            names = {a.name for node in ast.walk(ast.parse(path.read_text())) if isinstance(node, ast.Import)
                     for a in node.names}  # fmt: skip
            rel = str(path.relative_to(root))
            if "argparse" in names or ("sys.argv" in path.read_text() and rel not in FOREIGN_ENTRY_POINTS):
                found.append(rel)
    assert found == []


@pytest.mark.parametrize(
    ("module", "command"),
    [
        ("scenes.robocasa.placeholders", "indgen setup robocasa --placeholders DIR"),
        ("scenes.libero.overlay", "indgen setup libero --overlay SRC --dest DST"),
    ],
)
def test_a_moved_command_module_fails_naming_its_new_command(tmp_path, module, command):
    """Modules that were commands before the asset tools became ``indgen setup`` options exit non-zero with one line
    naming the command (they exited 0 having written nothing), and write nothing."""
    r = subprocess.run([sys.executable, "-m", module, str(tmp_path / "dst")], capture_output=True, text=True,
                       cwd=Path(__file__).resolve().parents[4], timeout=120)  # fmt: skip
    assert r.returncode != 0 and r.stderr.strip().splitlines()[-1].endswith(f"run '{command}'"), r.stderr
    assert not (tmp_path / "dst").exists()
