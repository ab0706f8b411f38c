"""``indgen certify --audit N`` on a built-in scene: shipped certified levels drawn at random re-run on held-out
seed blocks (>= 1000, never one an attempt drew), exactly as certify runs them, each judged by the exact one-sided
binomial test of "rate >= 0.95"."""

from __future__ import annotations

import json

import pytest

from indgen_vla.app.certify.audit import AUDIT_FIRST_BLOCK, audit, holds, shipped_levels
from indgen_vla.app.certify.certify_config import certify_config
from indgen_vla.app.cli import main
from indgen_vla.core.resources import certification_dir
from scenes.family import get_scene


def test_the_holding_rule_is_the_exact_binomial_test():
    """17/20 holds, 16/20 does not (P(X <= 16 | 20, 0.95) = 0.016 < 0.05 <= P(X <= 17) = 0.075)."""
    assert holds(17, 20)[0] and not holds(16, 20)[0]
    assert holds(16, 20)[1] == pytest.approx(0.0159, abs=1e-4) and holds(2, 2) == (True, 1.0)
    assert not holds(0, 2)[0] and holds(1, 2)[0]  # 1/2: p = 0.0975


def test_audit_reruns_shipped_pick_place_levels_on_fresh_blocks(tmp_path, capsys):
    levels = shipped_levels(certification_dir(), ["pick_place"])
    assert len(levels) > 200 and all(s == "pick_place" for s, *_ in levels)
    assert main(["certify", "--audit", "1", "--scene", "pick_place", "--episodes", "2", "--seed", "3",
                 "--out", str(tmp_path)]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert "audit: 1 of 1 levels hold (2 held-out episodes each" in out
    result = json.loads((tmp_path / "audit.json").read_text())
    (row,) = result["levels"]
    assert row["scene"] == "pick_place" and row["block"] >= AUDIT_FIRST_BLOCK and row["basis"] == "held-out"
    assert (row["n"], row["successes"], row["holds"]) == (2, 2, True)  # the oracle solves pick_place levels
    # the draw is the seed's: the same level again
    config = certify_config(audit=1, episodes=1, seed=3)
    again = audit(config, [get_scene("pick_place")], log=None)["levels"][0]
    assert (again["task"], again["axis"], again["level"]) == (row["task"], row["axis"], row["level"])


def test_audit_refuses_a_scene_with_no_shipped_level(capsys):
    assert (
        main(["certify", "--audit", "1", "--scene", "robocasa"]) == 2
    )  # certified per machine: none shipped
    assert "no shipped certified level" in capsys.readouterr().err
    assert main(["certify", "--audit", "1", "--scene", "no_such_scene"]) == 2
    assert "unknown scene 'no_such_scene'" in capsys.readouterr().err
    assert main(["certify", "--axis", "pick_y"]) == 2  # neither --scene nor --audit: one line
    assert "needs --scene and --axis (or --audit N" in capsys.readouterr().err
    assert main(["certify", "--evaluation-states"]) == 2
    assert "--evaluation-states needs --run DIR" in capsys.readouterr().err
