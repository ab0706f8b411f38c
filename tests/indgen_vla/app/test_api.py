"""The public Python API: docs/api.md's example runs as written and writes what ``indgen evaluate`` writes."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

import indgen_vla
from indgen_vla.core.errors import ConfigError, RunDirError

ROOT = Path(__file__).resolve().parents[3]


def _digest(run: Path) -> dict[str, str]:
    spec = importlib.util.spec_from_file_location("run_digest", ROOT / "scripts" / "run_digest.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.run_digest(run)


def _examples() -> list[str]:
    """The python blocks of docs/api.md."""
    return re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "api.md").read_text(), re.S)


def _example() -> str:
    """The first python block of docs/api.md."""
    return _examples()[0]


def test_import_is_cheap_and_names_load_lazily():
    """``import indgen_vla`` loads none of numpy, scipy or the scenes; the API's names load the API (its libraries
    at its module top, scenes and scipy included) and still no simulator or torch."""
    heavy = "print(sorted(m for m in ('torch', 'robosuite', 'lerobot', 'mujoco', 'numpy', 'scipy', 'scenes') if m in sys.modules))"
    bare = subprocess.run([sys.executable, "-c", f"import sys, indgen_vla; {heavy}"], capture_output=True, text=True,
                          check=True)  # fmt: skip
    assert bare.stdout.strip() == "[]"
    code = (
        "import sys, indgen_vla; indgen_vla.evaluate; indgen_vla.report; indgen_vla.compare; indgen_vla.certify; "
        f"indgen_vla.Run; indgen_vla.KStar; {heavy}"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "['numpy', 'scenes', 'scipy']"
    with pytest.raises(AttributeError, match="no attribute 'evaluat'"):
        indgen_vla.evaluat  # noqa: B018


def test_docs_example_runs_and_matches_the_cli(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    scope: dict = {}
    exec(compile(_example(), "docs/api.md", "exec"), scope)  # noqa: S102
    run = scope["run"]
    assert run.path == Path("runs/x") and run.report_md.is_file()
    assert len(run.episodes()) == 4 and set(run.episodes()["status"]) == {"ok"}
    k = run.kstar("pick_y")
    assert k.axis == "pick_y" and k.signed and k.task is None
    assert k.pos == run.summary["axes"]["pick_y"]["break_level"]["pos"]
    assert "pick_y" in str(k) and set(k.verdict) == {"pos", "neg"}
    assert run.kstar("pick_y", task="milk").task == "milk"

    from indgen_vla.app.cli import main

    args = [
        "--scene",
        "pick_place",
        "--axis",
        "pick_y",
        "--levels",
        "0:1",
        "--episodes",
        "2",
        "--workers",
        "1",
    ]
    assert main(["evaluate", "--policy", "standin:oracle", *args, "--out", str(tmp_path / "cli")]) == 0
    assert _digest(tmp_path / "cli") == _digest(run.path)

    # resuming through the API runs nothing new and returns the same run
    again = indgen_vla.evaluate(policy="standin:oracle", scene="pick_place", axis=["pick_y"], levels=[0, 1],
                                episodes=2, out=tmp_path / "cli", workers=1, quiet=True)  # fmt: skip
    assert again.path == tmp_path / "cli" and _digest(again.path) == _digest(run.path)
    # docs/api.md's sections example names the same run: it resumes it, running nothing
    before = len(run.episodes())
    exec(compile(_examples()[1], "docs/api.md", "exec"), scope)  # noqa: S102
    assert scope["run"].path == run.path and len(scope["run"].episodes()) == before
    assert [r.path for r in indgen_vla.report(again)] == [again.path]
    result = indgen_vla.compare(run, again, out=tmp_path / "cmp")
    assert set(result["axes"]) == {"pick_y"} and (tmp_path / "cmp" / "compare.md").is_file()


def test_certify_writes_and_resumes_a_certificate(tmp_path):
    cert = indgen_vla.certify(scene="pick_place", axis="pick_y", levels=[0], episodes=1, out=tmp_path)
    assert [(r["level"], r["n"]) for r in cert["levels"]] == [(0, 1)] and (
        tmp_path / "certify.json"
    ).is_file()
    again = indgen_vla.certify(scene="pick_place", axis="pick_y", levels=[0], episodes=1, out=tmp_path)
    assert again["levels"] == cert["levels"]  # reused, not rerun


def test_bad_keywords_and_results_are_one_clear_line(tmp_path):
    with pytest.raises(ConfigError, match=r"unknown option\(s\) episode \(did you mean episodes\?\)"):
        indgen_vla.evaluate(
            policy="standin:oracle", scene="pick_place", axis="pick_y", episode=2, out=tmp_path
        )
    with pytest.raises(ConfigError, match="--episodes must be >= 1"):
        indgen_vla.evaluate(
            policy="standin:oracle", scene="pick_place", axis="pick_y", episodes=0, out=tmp_path
        )
    with pytest.raises(RunDirError, match="not a run directory"):
        indgen_vla.Run(tmp_path)
    # a keyword of the wrong type (argparse never saw it) is the same one line, not a TypeError deep inside
    with pytest.raises(
        ConfigError, match=r"^--episodes must be a whole number, got 'two' \(str\); e.g. --episodes 50$"
    ):
        indgen_vla.evaluate(
            policy="standin:oracle", scene="pick_place", axis="pick_y", episodes="two", out=tmp_path
        )
    with pytest.raises(
        ConfigError, match=r"^--seed must be a whole number, got 1.5 \(float\); e.g. --seed 1$"
    ):
        indgen_vla.certify(scene="pick_place", axis="pick_y", levels="0", seed=1.5, out=tmp_path)
    with pytest.raises(
        ConfigError, match=r"^--steps must be a whole number, got '100' \(str\); e.g. --steps 3000$"
    ):
        from indgen_vla.app.regimes.train import TrainRecipe

        TrainRecipe(steps="100")


def test_a_policy_object_keeps_the_label_its_config_gives(tmp_path):
    """A training loop's ``evaluate(config=cfg, policy=obj)`` records ``cfg``'s ``object:...@stepN`` (compare's and
    series' tables tell the steps apart); without one the run records the object's class."""
    from policy_wrappers.standin import RandomPolicy

    class Mine(RandomPolicy):
        pass

    flat = dict(scene="pick_place", axes=("pick_y",), levels="0", episodes=1, max_steps=3, workers=1)
    cfg = indgen_vla.EvalConfig.from_flat(policy="object:Mine@step7", out=str(tmp_path / "a"), **flat)
    assert (
        indgen_vla.evaluate(config=cfg, policy=Mine(), quiet=True).manifest["policy"] == "object:Mine@step7"
    )
    plain = indgen_vla.EvalConfig.from_flat(policy="standin:random", out=str(tmp_path / "b"), **flat)
    assert indgen_vla.evaluate(config=plain, policy=Mine(), quiet=True).manifest["policy"] == "object:Mine"


def test_episodes_that_ended_with_errors_are_a_warning_not_silence(tmp_path):
    """The command exits 3 when episodes ended ``error``; ``evaluate`` returns the run and warns in one line with the
    first cause (a policy returning NaN), so a training loop's rates over fewer episodes do not pass unnoticed."""
    import numpy as np

    from indgen_vla import ACTION_DIM, EpisodeErrorsWarning, PolicySpec

    class NaNs:
        spec = PolicySpec(
            family="mine", name="mine:nan", chunk_size=1, replan_steps=1, cameras=(), batched=True
        )

        def reset(self, instruction, seed=None):
            pass

        def act(self, observations):
            return np.full((len(observations), 1, ACTION_DIM), np.nan, np.float32)

        def close(self):
            pass

    args = dict(scene="pick_place", axis="pick_y", levels="0", episodes=1, max_steps=3, workers=1, quiet=True)
    with pytest.warns(
        EpisodeErrorsWarning, match=r"1 of 1 episode\(s\) ended with errors .*non-finite actions"
    ):
        run = indgen_vla.evaluate(policy=NaNs(), out=tmp_path / "nan", **args)
    assert list(run.episodes()["status"]) == ["error"]
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", EpisodeErrorsWarning)  # a clean run warns nothing
        indgen_vla.evaluate(policy="standin:oracle", out=tmp_path / "ok", **args)


# flags of a command that its function names otherwise (dest -> the function's keyword)
RENAMED = {("compare", "label_a"): "labels", ("compare", "label_b"): "labels", ("import", "harness"): None}
# the commands' modes the functions do not offer (the command is the way): report's overlay of several runs into one
# folder and its publication lock; compare of two groups of seeds (--a/--b) or two axes (--axes), whose --margin only
# those modes read
CLI_ONLY = {("report", "out"), ("report", "lock_published"), ("compare", "a"), ("compare", "b"),
            ("compare", "axes"), ("compare", "margin")}  # fmt: skip


def _accepted(command: str) -> set[str]:
    """The keywords ``indgen_vla.<command>`` takes: its signature's, and the options of the config it builds."""
    import inspect

    from indgen_vla.app.certify.certify_config import CertifyConfig
    from indgen_vla.app.config_fields import flat_options
    from indgen_vla.app.engine.config import FLAG_FIELDS, FLAG_NAMES

    func = {"import": indgen_vla.import_lerobot_eval}.get(command) or getattr(indgen_vla, command)
    names = set(inspect.signature(func).parameters) - {"options"}
    if command in ("evaluate", "series"):
        names |= FLAG_FIELDS | set(
            FLAG_NAMES
        )  # evaluate's keywords; a series' protocol is an EvalConfig of them
    if command == "series":
        names |= set(flat_options(indgen_vla.SeriesConfig))
    if command == "certify":
        names |= {n for n, o in flat_options(CertifyConfig).items()} | {
            o.flag for o in flat_options(CertifyConfig).values() if o.flag
        }
    return names


@pytest.mark.parametrize("command", ["evaluate", "series", "certify", "report", "compare", "import"])
def test_every_flag_of_a_command_is_a_keyword_of_its_function(command):
    """api.md: the functions take the commands' flags with ``_`` for ``-``; a flag added to a command and not to its
    function (``--log`` was) fails here, unless it is one of the command's own modes listed in ``CLI_ONLY``."""
    import argparse

    from indgen_vla.app.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[command]
    dests = {a.dest for a in sub._actions if a.dest != "help"}
    accepted = _accepted(command)
    missing = sorted(
        d
        for d in dests
        if (command, d) not in CLI_ONLY
        and RENAMED.get((command, d), d) is not None
        and RENAMED.get((command, d), d) not in accepted
    )
    assert not missing, f"indgen {command} flags the Python function lacks: {missing}"
