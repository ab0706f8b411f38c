"""``CertifyConfig``: the command's flags, the API's keywords and the flat record made from one definition, evaluate's
own fields where the idea is evaluate's, and one line per bad value."""

from __future__ import annotations

import argparse
import dataclasses

import pytest

import indgen_vla
from indgen_vla.app.certify.certify_config import (
    FIRST_BLOCK,
    THRESHOLD,
    CertifyConfig,
    CertifyPlan,
    CertifyRule,
    certify_config,
)
from indgen_vla.app.cli import build_parser
from indgen_vla.app.config_fields import flat_options, from_args, from_flat, to_flat
from indgen_vla.app.engine.config import OPTIONS
from indgen_vla.core.errors import ConfigError
from scenes.certificates import THRESHOLD as RULE_THRESHOLD
from scenes.heldout import FIRST_BLOCK as RULE_FIRST_BLOCK

# every flag 'indgen certify' had before its config, in its order (docs/cli.md, the CLI tests)
FLAGS = ["--scene", "--task", "--axis", "--levels", "--step", "--axes-preset", "--episodes", "--threshold", "--seed",
         "--audit", "--evaluation-states", "--run", "--held-out", "--max-steps", "--workers", "--split",
         "--obj-registries", "--out"]  # fmt: skip
SHARED = ("scene", "task", "axes", "levels", "step", "axes_preset", "max_steps", "split", "obj_registries")


def _certify_parser() -> argparse.ArgumentParser:
    sp = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return sp.choices["certify"]


def test_the_flags_are_the_fields_and_keep_their_spellings_and_defaults():
    p = _certify_parser()
    flags = [a.option_strings[0] for a in p._actions if a.option_strings and a.dest != "help"]
    assert flags == FLAGS
    cfg = from_args(
        CertifyConfig, p.parse_args(["--scene", "pick_place", "--axis", "pick_y"]), command="certify"
    )
    assert (cfg.rule.seed, cfg.rule.threshold, cfg.rule.episodes, cfg.run.workers) == (1, 0.95, None, 1)
    assert (cfg.rule.held_out, cfg.run.out, cfg.mode, cfg.plan.axis.name) == (
        False,
        None,
        "certify",
        "pick_y",
    )
    # the constants the light config keeps stay the rule's own
    assert (THRESHOLD, FIRST_BLOCK) == (RULE_THRESHOLD, RULE_FIRST_BLOCK)


def test_evaluates_ideas_are_evaluates_fields():
    """scene, task, axes (--axis), levels, step, axes_preset, max_steps and the family's options: one definition."""
    ours = flat_options(CertifyConfig)
    for name in SHARED:
        assert ours[name].flag == OPTIONS[name].flag, name
        theirs = dict(OPTIONS[name].field.metadata["argparse"])
        assert dict(ours[name].field.metadata["argparse"]) == theirs, name


def test_flags_and_keywords_make_the_same_config_and_it_round_trips():
    argv = ["--scene", "stack", "--task", "all", "--axis", "stack", "--levels", "0:1", "--episodes", "2",
            "--threshold", "0.9", "--seed", "3", "--held-out", "--workers", "2", "--out", "certs"]  # fmt: skip
    cli = from_args(CertifyConfig, _certify_parser().parse_args(argv), command="certify")
    api = certify_config(scene="stack", task="all", axis="stack", levels=[0, 1], episodes=2, threshold=0.9, seed=3,
                         held_out=True, workers=2, out="certs")  # fmt: skip
    assert api.plan.levels == "0,1" and cli.plan.levels == "0:1"
    assert dataclasses.replace(api, plan=dataclasses.replace(api.plan, levels="0:1")) == cli
    assert from_flat(CertifyConfig, to_flat(cli), command="certify") == cli
    assert certify_config(cli, episodes=5, held_out=None).rule == dataclasses.replace(cli.rule, episodes=5)
    assert CertifyConfig(plan=CertifyPlan(scene="stack", axes="stack")).plan.axes == ("stack",)


@pytest.mark.parametrize(
    "options, line",
    [
        ({"scene": "stack"}, r"indgen certify needs --scene and --axis \(or --audit N"),
        ({"scene": "stack", "axis": "stack", "episodes": 0}, "--episodes must be >= 1, got 0"),
        ({"scene": "stack", "axis": "stack", "workers": 0}, "--workers must be >= 1, got 0"),
        ({"scene": "stack", "axis": "stack", "threshold": 1.5}, r"--threshold must be in \(0, 1\), got 1.5"),
        ({"scene": "stack", "axis": "stack", "step": 0.0}, "--step must be positive"),
        ({"scene": "stack", "axis": "pick_y,scale"}, "certify takes one axis or composition, got 2"),
        ({"scene": "stack", "axis": "pick_y+"}, "write compositions as 'pick_y\\+distractor'"),
        ({"evaluation_states": True}, "--evaluation-states needs --run DIR"),
        ({"audit": 0}, "--audit must be >= 1 levels, got 0"),
        ({"audit": 2, "evaluation_states": True, "run": "r"}, "two modes; give one of them"),
        ({"scene": "stack", "axis": "stack", "retest": True}, "unknown option 'retest' for certify"),
    ],
)
def test_each_bad_value_is_one_line(options, line):
    with pytest.raises(ConfigError, match=line) as e:
        certify_config(**options)
    assert "\n" not in str(e.value)


def test_the_other_modes_need_no_axis_and_the_api_certifies_only():
    audit = certify_config(audit=3, scene="pick_place,stack")
    assert (audit.mode, audit.audit_scenes, audit.audit_episodes) == ("audit", ["pick_place", "stack"], 20)
    assert certify_config(evaluation_states=True, run="runs/x").check.run_dir == "runs/x"
    with pytest.raises(
        ConfigError, match="certify\\(\\) certifies levels; audit is the command's other mode"
    ):
        indgen_vla.certify(audit=3)
    with pytest.raises(ConfigError, match="CertifyRule"):
        CertifyConfig(rule={"episodes": 3})
    assert CertifyRule(episodes=3).threshold == 0.95 and indgen_vla.CertifyConfig is CertifyConfig
