"""EvalConfig's sections: each validates its own fields, the flat names runs record stay as they were, and the
evaluate flags, the API's keywords and the YAML keys all come from the fields' metadata."""

from __future__ import annotations

import argparse
import dataclasses

import pytest

from indgen_vla.app.engine.config import (
    ADAPTIVE_MODES,
    OPTIONS,
    RECORD_ORDER,
    AdaptiveConfig,
    EvalConfig,
    PlanConfig,
    PolicyConfig,
    RunConfig,
    config_from_values,
    load_config_preset,
)
from indgen_vla.core.errors import ConfigError

BASE = dict(policy="standin:oracle", scene="pick_place", axes=("pick_y",), out="x")


def test_each_section_checks_its_own_fields_in_one_line():
    with pytest.raises(ConfigError, match="^--episodes must be >= 1, got 0$"):
        PlanConfig(scene="pick_place", axes=("pick_y",), episodes=0)
    with pytest.raises(ConfigError, match="^--gamma must be in"):
        PlanConfig(scene="pick_place", axes=("pick_y",), gamma=0)
    with pytest.raises(ConfigError, match="needs --device cuda"):
        PolicyConfig(spec="lerobot:x", compile="reduce-overhead")
    assert PolicyConfig(spec="lerobot:x", device="cuda:1", compile="reduce-overhead").options() == {
        "compile": "reduce-overhead"
    }
    with pytest.raises(ConfigError, match="--workers auto follows a Ray cluster's CPUs"):
        RunConfig(out="x", workers="auto")
    with pytest.raises(ConfigError, match="--pipeline is for --backend local"):
        RunConfig(out="x", pipeline=True, backend="ray")
    with pytest.raises(ConfigError, match="--adaptive must be one of kstar, curve, until-failure"):
        AdaptiveConfig(mode="fast")
    with pytest.raises(ConfigError, match="EvalConfig plan must be a PlanConfig, got dict"):
        EvalConfig(plan={"scene": "pick_place"}, policy=PolicyConfig(spec="p"), run=RunConfig(out="x"))


def test_the_adaptive_rule_is_checked_against_the_plan():
    """The rule's cap is the plan's --episodes, so the whole rule is EvalConfig's check."""
    with pytest.raises(ConfigError, match="round"):
        EvalConfig.from_flat(**BASE, adaptive="kstar", round_size=0)
    cfg = EvalConfig.from_flat(**BASE, adaptive="kstar", episodes=20, gamma=0.3)
    recorded = cfg.plan_dict(["t"], {"pick_y": [0]}, None)["adaptive"]
    assert cfg.sequential_rule().max_episodes == 20 and recorded["gamma"] == pytest.approx(0.3)


def test_adaptive_modes_are_the_rules():
    from indgen_vla.core.stats.sprt import MODES

    assert tuple(ADAPTIVE_MODES) == tuple(MODES)


def test_flat_names_are_those_runs_have_always_recorded():
    """The manifest's ``config`` is ``cfg.flat()``: the keys (and their order) of the flat config it replaced."""
    cfg = EvalConfig.from_flat(**BASE, episodes=3, adaptive_delta=0.05)
    flat = cfg.flat()
    assert tuple(flat) == RECORD_ORDER and set(OPTIONS) == set(RECORD_ORDER)
    assert (
        flat["policy"] == "standin:oracle" and flat["adaptive_delta"] == 0.05 and flat["axes"] == ("pick_y",)
    )
    assert EvalConfig.from_flat(**flat) == cfg
    moved = cfg.override(policy="standin:random", out="y")
    assert (moved.policy.spec, moved.run.out, moved.plan) == ("standin:random", "y", cfg.plan)
    with pytest.raises(ConfigError, match="unknown option"):
        EvalConfig.from_flat(**BASE, episode=3)


def test_sections_given_whole_match_the_flat_keywords():
    flat = config_from_values(
        {**BASE, "axis": "pick_y", "levels": [0, 1], "episodes": 2, "workers": 1}, strict=True
    )
    nested = config_from_values(
        {
            "policy": "standin:oracle",
            "plan": PlanConfig(scene="pick_place", axes=("pick_y",), levels="0,1", episodes=2),
            "run": RunConfig(out="x", workers=1),
        },
        strict=True,
    )
    assert nested == flat
    # a section as a mapping, a policy section, and a flat keyword over a section
    again = config_from_values(
        {"policy": PolicyConfig(spec="standin:oracle"), "plan": {"scene": "pick_place", "axis": "pick_y",
         "levels": "0,1", "episodes": 5}, "run": {"out": "x", "workers": 1}, "episodes": 2},
        strict=True,
    )  # fmt: skip
    assert again == flat
    adaptive = config_from_values(
        {**BASE, "adaptive": AdaptiveConfig(mode="curve", round_size=2)}, strict=True
    )
    assert (adaptive.adaptive.mode, adaptive.adaptive.round_size) == ("curve", 2)
    # an EvalConfig as the preset (the API's config=): its sections and flat keywords override it
    base = EvalConfig.from_flat(**BASE, episodes=9, workers=3)
    plan = PlanConfig(scene="pick_place", axes=("pick_y",), episodes=3)
    cfg = config_from_values({"plan": plan, "policy": "standin:random"}, base, strict=True)
    assert (cfg.plan, cfg.policy.spec, cfg.run) == (plan, "standin:random", base.run)
    with pytest.raises(
        ConfigError, match=r"unknown option\(s\) in plan: episode \(did you mean episodes\?\)"
    ):
        config_from_values({**BASE, "plan": {"scene": "pick_place", "episode": 2}}, strict=True)
    with pytest.raises(ConfigError, match="run must be a RunConfig or a mapping of its fields, got str"):
        config_from_values({**BASE, "run": "fast"}, strict=True)


def test_yaml_presets_take_flat_keys_or_sections(tmp_path):
    flat = tmp_path / "flat.yaml"
    flat.write_text("scene: pick_place\naxis: [pick_y]\nepisodes: 7\nadaptive: kstar\nround-size: 3\n")
    nested = tmp_path / "nested.yaml"
    nested.write_text(
        "plan:\n  scene: pick_place\n  axes: [pick_y]\n  episodes: 7\n"
        "adaptive:\n  mode: kstar\n  round_size: 3\npolicy:\n  device: cpu\n"
    )
    assert load_config_preset(str(flat)) == {
        "scene": "pick_place", "axes": ["pick_y"], "episodes": 7, "adaptive": "kstar", "round_size": 3,
    }  # fmt: skip
    both = load_config_preset(str(nested))
    assert both.pop("device") == "cpu" and both == load_config_preset(str(flat))
    a, b = (config_from_values({"policy": "p", "out": "x"}, str(p)) for p in (flat, nested))
    assert a == b and a.adaptive.round_size == 3
    bad = tmp_path / "bad.yaml"
    bad.write_text("adaptive:\n  mod: kstar\n")
    with pytest.raises(
        ConfigError, match=r"bad.yaml: unknown option\(s\) in adaptive: mod \(did you mean mode\?\)"
    ):
        load_config_preset(str(bad))
    bad.write_text("episode: 3\n")
    with pytest.raises(ConfigError, match=r"unknown option\(s\) episode \(did you mean episodes\?\)"):
        load_config_preset(str(bad))


@pytest.mark.parametrize(
    ("yaml_text", "says"),
    [("episodes: five\n", "--episodes must be a whole number, got 'five' (str); e.g. --episodes 50"),
     ("episodes: 7.5\n", "--episodes must be a whole number, got 7.5 (float)"),
     ("gamma: high\n", "--gamma must be a number, got 'high' (str); e.g. --gamma 0.2"),
     ("plan:\n  seed: true\n", "--seed must be a whole number, got True (bool)")],
)  # fmt: skip
def test_a_preset_value_of_the_wrong_type_is_one_line(tmp_path, yaml_text, says):
    """A preset's ``episodes: five`` reached a comparison as a TypeError traceback (exit 1); the API's
    ``episodes="5"`` too. Both are now one line naming the option, as argparse's type check does for a flag."""
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml_text)
    with pytest.raises(ConfigError) as e:
        load_config_preset(str(bad))
    assert str(e.value).startswith(f"--config {bad}: {says}") and "\n" not in str(e.value)
    with pytest.raises(
        ConfigError, match="^--episodes must be a whole number, got '5' \\(str\\); e.g. --episodes 50$"
    ):
        config_from_values({**BASE, "episodes": "5"}, strict=True)
    assert config_from_values({**BASE, "gamma": 1, "step": 0.02}).plan.gamma == 1  # an int is a number


def test_the_evaluate_parser_is_made_from_the_fields():
    """Every option with a help line is a flag of evaluate (and of budget and series, which copy it); its type and
    choices are the field's; options without one (warmup_steps, max_retries) are the API's and YAML's only."""
    from indgen_vla.app.cli import build_parser

    sub = build_parser()._subparsers._group_actions[0].choices
    actions = {a.dest: a for a in sub["evaluate"]._actions}
    for name, o in OPTIONS.items():
        if o.flag is None:
            assert name not in actions and o.field.name in ("warmup_steps", "max_retries")
            continue
        a = actions[o.flag]
        meta = o.field.metadata
        assert a.help.startswith(meta["help"].split("{")[0]) and a.choices == meta["argparse"].get("choices")
    assert actions["axis"].option_strings == ["--axis"] and actions["adaptive_delta"].type is float
    assert isinstance(actions["share_t0"], argparse.BooleanOptionalAction) and actions["video"].const is True
    ns = sub["evaluate"].parse_args(["--policy", "p", "--scene", "pick_place", "--axis", "pick_y", "--out", "x",
                                     "--episodes", "3", "--no-share-t0", "--workers", "2"])  # fmt: skip
    cfg = config_from_values(vars(ns))
    assert (cfg.plan.episodes, cfg.plan.share_t0, cfg.run.workers) == (3, False, 2)


def test_every_field_is_an_option_with_a_flat_name():
    for cls in (PlanConfig, PolicyConfig, RunConfig, AdaptiveConfig):
        for f in dataclasses.fields(cls):
            assert set(f.metadata) == {"help", "name", "flag", "argparse"}, f.name


def test_levels_take_one_level_a_sequence_or_text_and_refuse_the_rest():
    """The Python API's and YAML's ``levels``: ``levels=2`` (it was a TypeError deep in the plan), a list, a range,
    a NumPy array, or the flag's text; anything else is one line naming --levels. certify and demos take the same."""
    import numpy as np

    from indgen_vla.app.certify.certify_config import CertifyPlan
    from indgen_vla.app.engine.config import PlanConfig
    from indgen_vla.app.regimes.demos import LevelRequest

    plan = dict(scene="pick_place", axes=("pick_y",))
    for given, text in [(2, "2"), (-1, "-1"), ([0, 1], "0,1"), (range(-1, 2), "-1,0,1"), (np.arange(2), "0,1"),
                        ("-3:3", "-3:3"), (None, None)]:  # fmt: skip
        assert PlanConfig(**plan, levels=given).levels == text
    assert (
        CertifyPlan(levels=np.int64(1)).levels == "1" and LevelRequest(axes="pick_y", levels=2).levels == "2"
    )
    for bad in (1.5, [], [0, "1"], True):
        with pytest.raises(
            ConfigError, match=r"^--levels must be a range like '-3:3', a list of levels or one"
        ):
            PlanConfig(**plan, levels=bad)
