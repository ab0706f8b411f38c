"""Set-up YAMLs (the paper's presets, one-line errors), the run directory ``indgen real plan`` writes, the episode
order, and the pairing ``indgen compare`` sees between two real runs of the same set-up."""

from __future__ import annotations

import json

import pytest

from indgen_vla.app.cli import main
from indgen_vla.app.real.design import RealRun
from indgen_vla.app.real.setup import load_setup, setup_from_dict
from indgen_vla.app.real.store import State
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.seeding import episode_seed


def test_presets_are_the_papers_tasks():
    stack = load_setup("stack")  # §5.3: "increasing z-height (incremented by 0.25 inches)", τ0..τ4
    a = stack.axis(None)
    assert stack.instruction == "Place the orange block on the blue block" and a.unit == "in"
    assert [lv.param for lv in a.levels] == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert a.level(2).setup.startswith("raise the blue block's support to 0.50 in")
    scale = load_setup("scale")  # "Pick up the cup and put it in the black bowl", a larger bowl per level
    assert scale.instruction == "Pick up the cup and put it in the black bowl"
    assert scale.axis("scale").max_level == 4 and scale.axis("scale").change == "cheap"


GOOD = {"name": "t", "task": "t", "instruction": "do it",
        "axes": {"h": {"unit": "cm", "step": 1.0, "max_level": 2, "setup": "raise to {param:g} cm"}}}  # fmt: skip


@pytest.mark.parametrize(
    "patch, message",
    [
        ({"axes": {"h": {"unit": "cm", "levels": [{"param": 1, "setup": "a"}, {"param": 1, "setup": "b"}]}}},
         "level 1's param 1 must exceed level 0's 1"),
        ({"instrction": "x"}, "unknown key(s) instrction (did you mean instruction?)"),
        ({"axes": {"h": {"unit": "cm", "step": 1.0, "max_level": 2, "setup": "{height}"}}}, "setup template"),
        ({"axes": {"h": {"unit": "cm", "step": 1.0, "max_level": 2, "setup": "x", "change": "fast"}}},
         "change must be 'cheap' or 'slow'"),
        ({"axes": {"h": {"unit": "cm", "step": 1, "levels": []}}}, "either 'levels'"),
    ],
)  # fmt: skip
def test_bad_setups_fail_in_one_line(patch, message):
    with pytest.raises(ConfigError, match=None) as e:
        setup_from_dict({**GOOD, **patch}, source="x.yaml")
    assert message in str(e.value) and "\n" not in str(e.value)


def test_plan_cli_errors_are_one_line(tmp_path, capsys):
    base = ["real", "plan", "--policy", "p", "--out", str(tmp_path / "r")]
    assert main([*base, "--setup", "stak"]) == 2
    assert (
        capsys.readouterr().err.strip()
        == "error: --setup stak: no such file; give a YAML path or a preset (scale, stack)"
    )
    assert main([*base, "--setup", "stack", "--levels", "0:7"]) == 2
    assert "axis stack of this set-up has levels 0..4" in capsys.readouterr().err
    assert main([*base, "--setup", "stack", "--axis", "stakc"]) == 2
    assert "did you mean 'stack'" in capsys.readouterr().err
    assert main(["real", "record", str(tmp_path / "nope"), "--outcome", "success"]) == 2
    assert "is not a run directory" in capsys.readouterr().err


def _plan(run, *extra):
    args = [
        "real",
        "plan",
        "--setup",
        "stack",
        "--levels",
        "0:2",
        "--episodes",
        "4",
        "--policy",
        "pi05-droid",
    ]
    assert main([*args, "--operator", "bob", "--robot", "fr3-lab2", "--out", str(run), *extra]) == 0


def test_manifest_is_a_normal_run_dir(tmp_path, capsys):
    run = tmp_path / "run"
    _plan(run)
    m = json.loads((run / "manifest.json").read_text())
    assert m["scene"] == "real:stack" and m["policy"] == "pi05-droid"
    assert m["plan"]["tasks"] == ["orange_on_blue"] and m["plan"]["levels"] == {"stack": [0, 1, 2]}
    assert m["real"]["operator"] == "bob" and m["real"]["robot"] == "fr3-lab2"
    assert m["real"]["setup_yaml"] == load_setup("stack").text and m["axes"]["stack"]["signed"] is False
    assert "| 2 | 0.5 in | raise the blue block's support to 0.50 in" in (run / "protocol.md").read_text()
    _plan(run, "--operator", "carol")  # same plan again: accepted (a new operator does not change the plan)
    assert (
        main(
            [
                "real",
                "plan",
                "--setup",
                "stack",
                "--levels",
                "0:3",
                "--policy",
                "pi05-droid",
                "--out",
                str(run),
            ]
        )
        == 2
    )
    assert "holds a run with a different plan" in capsys.readouterr().err
    rr = RealRun.open(run)  # episode i gets the engine's seed: runs with one --seed pair episode by episode
    assert rr.seeds[3] == episode_seed(0, "real:stack", "orange_on_blue", 3)


def test_order_interleaved_cycles_and_blocked_blocks(tmp_path):
    """Every level's episodes (--adaptive off: the stack preset's own rule, until-failure, runs one level at a time)."""
    _plan(tmp_path / "i", "--adaptive", "off")
    _plan(tmp_path / "b", "--order", "blocked", "--adaptive", "off")
    empty = State({}, {}, [], None)
    q = RealRun.open(tmp_path / "i").queue(empty)
    assert len(q) == 12 and all(sorted(k for k, i in q[3 * c : 3 * c + 3]) == [0, 1, 2] and
                                {i for _, i in q[3 * c : 3 * c + 3]} == {c} for c in range(4))  # fmt: skip
    assert q != sorted(q, key=lambda x: (x[1], x[0]))  # shuffled within cycles (seeded, so stable)
    assert RealRun.open(tmp_path / "b").queue(empty) == [(k, i) for k in range(3) for i in range(4)]


def test_compare_pairs_two_real_runs_of_the_same_setup(tmp_path):
    from indgen_vla.core.comparison.two_runs import pair_episodes
    from indgen_vla.core.runs.records import RunDir

    outcomes = {"a": ["success"] * 4, "b": ["success", "failure:misplaced"] * 2, "c": ["success"] * 4}
    for name, outs in outcomes.items():
        args = [
            "real",
            "plan",
            "--setup",
            "stack",
            "--levels",
            "0:1",
            "--episodes",
            "2",
            "--order",
            "blocked",
        ]
        seed = "1" if name == "c" else "0"
        assert main([*args, "--policy", name, "--seed", seed, "--out", str(tmp_path / name)]) == 0
        for o in outs:
            assert main(["real", "record", str(tmp_path / name), "--outcome", o, "--no-report"]) == 0
    ea, eb, ec = (RunDir.open(tmp_path / n).episodes() for n in "abc")
    pairs, why = pair_episodes(ea, eb, "stack")  # compare's rule: same set-up, episodes, seeds and params
    assert pairs == {0: [(True, True), (True, False)], 1: [(True, True), (True, False)]}, why
    assert pair_episodes(ea, ec, "stack") == (None, "episode seeds differ on stack (different --seed)")


@pytest.mark.parametrize(
    ("extra", "first"),
    [
        (("--episodes", "3"), "3 a level is below the 5-episode data floor"),
        (
            ("--episodes", "10"),
            "even 0/10 leaves the Wilson 95 % CI above γ = 0.2",
        ),  # Wilson 0/15 > 0.2 > 0/16
        # fixed design, 3 levels: 5 pairs and Holm over 2 levels -> best p = 2 · 2 · 0.5**5 = 0.125
        (("--episodes", "5", "--adaptive", "off"), "even 0/5 leaves the Wilson 95 % CI"),
        (("--episodes", "16", "--adaptive", "off"), None),
    ],
)
def test_protocol_and_status_open_with_what_the_plan_cannot_show(tmp_path, capsys, extra, first):
    run = tmp_path / "run"
    assert main(["real", "plan", "--setup", "stack", "--levels", "0:2", "--policy", "p", "--out", str(run),
                 *extra]) == 0  # fmt: skip
    lines = (run / "protocol.md").read_text().splitlines()
    caveats = RealRun.open(run).caveats()
    assert (first is None) == (caveats == []) and (first is None or first in lines[2])
    if "off" in extra and first:  # every level is tested against T0: the power line follows
        assert "Holm p = 0.125 ≥ α = 0.05" in lines[4] and "needs ≥ 7 pairs a level" in lines[4]
    capsys.readouterr()
    assert main(["real", "status", str(run)]) == 0
    assert capsys.readouterr().out.splitlines()[: len(caveats)] == [c.replace("**", "") for c in caveats]


def test_a_plan_without_level_0_says_it_has_no_baseline(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["real", "plan", "--setup", "stack", "--levels", "1:3", "--episodes", "20", "--adaptive", "off",
                 "--policy", "p", "--out", str(run)]) == 0  # fmt: skip
    line = ("**No level 0** (set-up stack, `stack`, task orange_on_blue): without the training set-up nothing shows "
            "the policy solves it and no level is tested against T0; plan --levels 0:3.")  # fmt: skip
    assert (run / "protocol.md").read_text().splitlines()[2] == line
    capsys.readouterr()
    assert main(["real", "status", str(run)]) == 0
    assert capsys.readouterr().out.splitlines()[0] == line.replace("**", "")
