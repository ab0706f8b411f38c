"""Held-out attempts in ``certify`` (scenes.heldout): a level certified in-sample is kept until ``held_out`` re-runs
it on a block it never used, as its next attempt; the ledger grows, never loses an attempt; evaluate's plan says
per level how it was certified."""

from __future__ import annotations

import dataclasses
import json

from indgen_vla.app.certify.partial import EpisodeLog
from indgen_vla.core.reporting.certification_view import plan_basis_lines
from scenes.certificates import cert_path, load_certification
from scenes.family import get_scene
from scenes.heldout import EXHAUSTIVE, HELD_OUT, IN_SAMPLE
from scenes.planning import resolve_scene_plan
from scenes.tabletop.oracle import OraclePolicy
from tests.fixtures.certify import run_certify, run_prepare


def _in_sample(tmp_path):
    """A stack certificate whose level 0 was certified in-sample (block 0, after a failure there) and level 1 on
    held-out states (block 1)."""
    out = cert_path(get_scene("stack"), "orange_on_blue", "stack", root=tmp_path)
    head = run_prepare("stack", "stack", task="orange_on_blue", levels="0", max_steps=5).cert
    ok = {"level": 0, "param": 0.0, "n": 59, "successes": 59, "rate": 1.0, "lower_bound": 0.9505, "status": "certified",
          "certified": True, "feasible": True, "stopped_early": False, "mean_steps": 5.0, "wall_s": 1.0, "block": 0,
          "oracle_version": 1, "certified_on": IN_SAMPLE,
          "attempts": [{"attempt": None, "block": 0, "held_out": False, "alpha": 0.0, "n": 1, "successes": 0,
                        "status": "failed"},
                       {"attempt": None, "block": 0, "held_out": False, "alpha": 0.0, "n": 59, "successes": 59,
                        "status": "certified"}]}  # fmt: skip
    held = {**ok, "level": 1, "param": 0.25, "block": 1, "certified_on": HELD_OUT,
            "attempts": [{"attempt": 1, "block": 1, "held_out": True, "alpha": 0.0485, "n": 59, "successes": 59,
                          "status": "certified"}]}  # fmt: skip
    out.parent.mkdir(parents=True)
    out.write_text(
        json.dumps({**head, "levels": [ok, held], "burnt": {"0": [{"block": 1, "why": "a sweep"}]}})
    )
    return out


def test_retest_reruns_an_in_sample_level_on_a_fresh_block(tmp_path, monkeypatch):
    out = _in_sample(tmp_path)
    assert (
        run_prepare("stack", "stack", task="orange_on_blue", levels="0:1", max_steps=5, path=out).jobs == []
    )
    again = run_prepare(
        "stack", "stack", task="orange_on_blue", levels="0:1", max_steps=5, path=out, held_out=True
    )
    (job,) = again.jobs  # level 1 was held-out: kept
    earlier, attempt = again.attempts[0]
    # in-sample attempts spent nothing: this is attempt 1 (59/59); blocks 0 (used) and 1 (burnt by a sweep) skipped
    assert (job.level, job.block, attempt["attempt"], attempt["block"], attempt["n_max"]) == (0, 2, 1, 2, 59)
    assert len(earlier) == 2

    monkeypatch.setenv("INDGEN_CERT_DIR", str(tmp_path))
    plan = resolve_scene_plan(get_scene("stack"), "orange_on_blue", ("stack",), "0:1")
    assert [c.basis for c in plan.cells] == [IN_SAMPLE, HELD_OUT]
    (line,) = plan_basis_lines(
        "stack", ["stack"], [dataclasses.asdict(c) for c in plan.cells]
    )  # evaluate prints it
    assert line.startswith("**Certificates** (stack, `stack`): certified on held-out states at orange_on_blue: +1; "
                           "**certified in-sample (tuned)** at orange_on_blue: 0 (in-sample:")  # fmt: skip

    logs = []
    cert = run_certify("stack", "stack", task="orange_on_blue", levels="0:1", max_steps=5, path=out, held_out=True,
                   log=logs.append)  # fmt: skip
    row = {r["level"]: r for r in cert["levels"]}[0]
    # 5 steps cannot stack: the held-out attempt fails and replaces the in-sample certificate, history kept
    assert row["status"] == "failed" and row["block"] == 2 and "certified_on" not in row
    assert [a["block"] for a in row["attempts"]] == [0, 0, 2] and row["attempts"][-1]["held_out"]
    assert load_certification(out)["levels"][0] == row
    plan = resolve_scene_plan(get_scene("stack"), "orange_on_blue", ("stack",), "0:1")
    assert [(c.certificate, c.basis) for c in plan.cells] == [("failed", ""), ("certified", HELD_OUT)]


def test_a_killed_attempt_resumes_on_its_block_and_another_oracle_never_reuses_it(tmp_path, monkeypatch):
    """The same attempt resumes its block; a killed attempt of another oracle version had looked at its block's
    first episodes, so the next attempt burns it and draws the next block."""
    out = tmp_path / "certify.json"
    (job,) = run_prepare("stack", "stack", task="orange_on_blue", levels="0", path=out).jobs
    EpisodeLog(job.partial, job.key).add(True, 50)  # one episode of block 1, then killed
    (same,) = run_prepare("stack", "stack", task="orange_on_blue", levels="0", path=out).jobs
    assert (same.block, same.key) == (1, job.key)  # resumes there
    monkeypatch.setattr(OraclePolicy, "version", OraclePolicy.version + 1)
    p = run_prepare("stack", "stack", task="orange_on_blue", levels="0", path=out)
    assert p.jobs[0].block == 2 and [b["block"] for b in p.cert["burnt"]["0"]] == [1]


def test_a_fixed_state_family_reports_exhaustive_certificates(tmp_path, monkeypatch):
    """A family with a finite set of initial states (LIBERO's 50; here stack given 50): a certified row that
    played all of them is reported "exhaustive", with or without a ledger (a user's older LIBERO certificate)."""
    out = _in_sample(tmp_path)
    monkeypatch.setenv("INDGEN_CERT_DIR", str(tmp_path))
    monkeypatch.setattr(type(get_scene("stack")), "fixed_state_count", 50)
    cert = json.loads(out.read_text())
    for r in cert["levels"]:
        r.pop("attempts"), r.pop("certified_on")  # as made before ledgers
    out.write_text(json.dumps(cert))
    plan = resolve_scene_plan(get_scene("stack"), "orange_on_blue", ("stack",), "0:1")
    assert [c.basis for c in plan.cells] == [EXHAUSTIVE, EXHAUSTIVE]
    monkeypatch.setattr(type(get_scene("stack")), "fixed_state_count", 60)  # 59 episodes do not cover 60
    plan = resolve_scene_plan(get_scene("stack"), "orange_on_blue", ("stack",), "0:1")
    assert [c.basis for c in plan.cells] == [IN_SAMPLE, IN_SAMPLE]
