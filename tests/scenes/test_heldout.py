"""The held-out rule (scenes.heldout): its error, computed by exact binomial enumeration, stays below 5 % however
many attempts a level gets, where keeping the best of several 59/59 attempts does not; README.md quotes these
numbers; attempts draw blocks nothing used; the shipped certificates carry their ledgers."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from scipy.stats import binom

from indgen_vla.core.resources import certification_dir
from scenes.certificates import episodes_needed, load_certification
from scenes.heldout import (
    ALPHA,
    EXHAUSTIVE,
    IN_SAMPLE,
    attempt_alpha,
    attempt_confidence,
    basis,
    burn_block,
    burnt_blocks,
    false_certification,
    fixed_states_basis,
    naive_false_certification,
    next_block,
    spent_attempts,
)

README = Path(__file__).resolve().parents[2] / "scenes" / "certification" / "README.md"


def test_the_spending_sums_below_alpha_and_attempt_one_is_still_59():
    assert sum(attempt_alpha(j) for j in range(1, 31)) < ALPHA
    assert [episodes_needed(0.95, attempt_confidence(j)) for j in (1, 2, 3, 4)] == [59, 141, 154, 168]
    for j in (0, 31):
        with pytest.raises(ValueError, match="attempt"):
            attempt_alpha(j)


def test_false_certification_by_exact_enumeration():
    """At p = 0.95 (the worst rate a level below the threshold can have) an attempt of n all-success episodes
    certifies with probability p**n; the rule's total stays < 5 % for any number of attempts, the old one's grows."""
    assert false_certification(0.95, 1) == pytest.approx(0.95**59, abs=1e-12)
    assert false_certification(0.95, 2) == pytest.approx(1 - (1 - 0.95**59) * (1 - 0.95**141), abs=1e-12)
    assert all(false_certification(0.95, k) < ALPHA for k in (1, 2, 3, 10, 30))
    assert naive_false_certification(0.95, 2) == pytest.approx(0.0946, abs=1e-4)  # the 9.5 %
    assert naive_false_certification(0.95, 3) == pytest.approx(0.1385, abs=1e-4)  # and 13.9 %
    # lower rates: smaller; with a failure tolerated (n_max 100: 99/100 certifies at attempt 1) still < 5 %
    assert false_certification(0.90, 3) < false_certification(0.95, 3)
    assert false_certification(0.95, 1, n_max=100) == pytest.approx(binom.sf(98, 100, 0.95), abs=1e-12)
    assert false_certification(0.95, 1, n_max=100) < ALPHA


def test_the_readme_quotes_what_the_enumeration_computes():
    """Every row of README.md's error table is recomputed here (a doc that drifts from the code fails)."""
    rows = re.findall(r"^\| (\d+) \| ([\d.]+) % \| ([\d.]+) % \|", README.read_text(), re.M)
    assert len(rows) >= 4, "README.md lost its error table"
    for k, rule, old in rows:
        assert float(rule) == round(100 * false_certification(0.95, int(k)), 2), k
        assert float(old) == round(100 * naive_false_certification(0.95, int(k)), 2), k


def test_blocks_are_never_reused_and_burnt_ones_skipped():
    row = {"block": 1, "attempts": [{"block": 1, "held_out": True, "alpha": 0.0485}]}
    assert next_block(None) == 1 and next_block(row) == 2  # block 0 is burnt everywhere
    cert: dict = {}
    burn_block(cert, 3, 2, "replayed episode 4 to debug a slip")
    burn_block(cert, 3, 2, "again")  # once
    assert burnt_blocks(cert, 3) == [{"block": 2, "why": "replayed episode 4 to debug a slip"}]
    assert next_block(row, burnt_blocks(cert, 3)) == 3 and next_block(row, burnt_blocks(cert, 0)) == 2
    assert spent_attempts(row) == 1 and spent_attempts({"attempts": [{"held_out": False, "alpha": 0}]}) == 0
    assert basis({"status": "certified"}) == IN_SAMPLE  # no record of how: unknown history, in-sample


def test_a_fixed_state_family_is_exhaustive_never_held_out():
    """LIBERO: every block repeats its 50 states, so no attempt is held-out or spends error; a certified row that
    played all 50 (unavailable ones included) is exhaustive, one that did not is in-sample."""
    row = {"n": 59, "successes": 59, "status": "certified", "unavailable": 4, "certified_on": "held-out",
           "attempts": [{"attempt": 1, "block": 1, "held_out": True, "alpha": 0.0485}]}  # fmt: skip
    out = fixed_states_basis(row, 50)
    assert (
        out["certified_on"] == EXHAUSTIVE and spent_attempts(out) == 0 and not out["attempts"][0]["held_out"]
    )
    assert fixed_states_basis({**row, "n": 40, "unavailable": 0}, 50)["certified_on"] == IN_SAMPLE
    assert "certified_on" not in fixed_states_basis({**row, "status": "failed"}, 50)


def test_every_shipped_certificate_records_its_ledger():
    """Oracle (class, version), seed block, attempts with outcomes and the asset tree, on every shipped row; no
    level is in-sample: the one certified after a failure on its own seeds (LIBERO cream_cheese pick_y -2) is, like
    every LIBERO level, certified on all 50 fixed initial states, and its block-1 re-run reproduced it."""
    in_sample, libero = [], set()
    paths = sorted(certification_dir().glob("*/*/*/certify.json"))
    assert len(paths) > 100
    for path in paths:
        cert = load_certification(path)
        assert cert["oracle"]["name"] and cert["oracle"]["version"] >= 1 and cert["assets"], path
        for row in cert["levels"]:
            assert "block" in row and row["attempts"], (path, row["level"])
            last = row["attempts"][-1]
            assert (last["n"], last["successes"], last["status"]) == (
                row["n"],
                row["successes"],
                row["status"],
            )
            assert "code_hash" in last["oracle"] and "version" in last["oracle"]
            if row["status"] == "certified":
                assert row["certified_on"] in ("held-out", EXHAUSTIVE, IN_SAMPLE)
                if row["certified_on"] == IN_SAMPLE:
                    in_sample.append((*path.parent.relative_to(certification_dir()).parts, row["level"]))
                if cert["scene"].startswith("libero"):
                    libero.add(row["certified_on"])
    assert in_sample == [] and libero == {EXHAUSTIVE}
    row = load_certification(certification_dir() / "libero_object/cream_cheese/pick_y")["levels"][1]
    assert [(a["block"], a["n"], a["successes"]) for a in row["attempts"]] == [
        (0, 6, 5),
        (0, 59, 59),
        (1, 59, 59),
    ]
