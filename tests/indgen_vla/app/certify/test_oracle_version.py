"""The oracle's version in certificates: every certificate and row records the oracle that made it; a level any
version certified stays certified, a level another version failed is re-tried by ``certify`` and reported
"failed (oracle vN, current vM)" until then; certificates made before versions were recorded load as v1."""

from __future__ import annotations

import json

import pytest

from indgen_vla.app.certify.suite import write_summary
from indgen_vla.core.resources import certification_dir
from scenes.certificates import (
    cert_path,
    find_certification,
    infeasible_levels,
    level_verdict,
    load_certification,
    row_oracle_version,
)
from scenes.family import get_scene, registered_scenes
from scenes.oracles import oracle_identity
from scenes.planning import resolve_scene_plan
from scenes.tabletop.oracle import OraclePolicy
from tests.fixtures.certify import run_certify, run_prepare


def test_every_family_oracle_has_a_version():
    """Each registered scene's oracle names its class and an integer version; LIBERO's is at least the v2 of the
    sweep (docs/results/libero_object_real_assets.md)."""
    ids = {s.name: oracle_identity(s) for s in registered_scenes()}
    assert all(isinstance(i["version"], int) and i["version"] >= 1 for i in ids.values()), ids
    assert {k: ids["stack"][k] for k in ("name", "version")} == {"name": "scenes.tabletop.oracle:OraclePolicy",
                                                                 "version": OraclePolicy.version}  # fmt: skip
    # the source hash: LIBERO's oracle (a subclass, its own module) differs from the tabletop one
    assert all(len(i["code_hash"]) == 16 for i in ids.values())
    assert ids["libero_object"]["code_hash"] != ids["stack"]["code_hash"] == ids["pick_place"]["code_hash"]
    assert ids["libero_object"]["name"] == "scenes.libero.oracle:LiberoOracle"
    assert ids["libero_object"]["version"] >= 2


def _old_certificate(tmp_path):
    """A stack certificate as made before versions were recorded (``prepare``'s header, rows written here): level 0
    failed at its first episode, level 1 certified (59/59), no ``oracle`` field anywhere."""
    out = cert_path(get_scene("stack"), "orange_on_blue", "stack", root=tmp_path)
    old = run_prepare("stack", "stack", task="orange_on_blue", levels="0", max_steps=5).cert
    assert old.pop("oracle") == oracle_identity(get_scene("stack"))
    fail = {"level": 0, "param": 0.0, "n": 1, "successes": 0, "rate": 0.0, "lower_bound": 0.0, "status": "failed",
            "certified": False, "feasible": False, "stopped_early": True, "mean_steps": 5.0, "wall_s": 1.0}  # fmt: skip
    ok = {**fail, "level": 1, "param": 0.25, "n": 59, "successes": 59, "rate": 1.0, "lower_bound": 0.951,
          "status": "certified", "certified": True, "feasible": True, "stopped_early": False}  # fmt: skip
    out.parent.mkdir(parents=True)
    out.write_text(json.dumps({**old, "levels": [fail, ok]}))
    return out


def test_a_failure_by_an_older_oracle_is_retried_and_a_certificate_by_any_stays(tmp_path, monkeypatch):
    out = _old_certificate(tmp_path)
    old = load_certification(out)
    assert [row_oracle_version(r, old) for r in old["levels"]] == [1, 1]  # no field: v1
    logs = []
    same = run_prepare(
        "stack", "stack", task="orange_on_blue", levels="0:1", max_steps=5, path=out, log=logs.append
    )
    assert same.jobs == [] and not any("again" in m for m in logs)  # same version: nothing to re-run

    monkeypatch.setattr(OraclePolicy, "version", 2)  # the oracle changed since
    cert = load_certification(out)
    assert level_verdict(cert["levels"][0], cert, 2) == "failed (oracle v1, current v2)"
    assert level_verdict(cert["levels"][1], cert, 2) == "certified"
    assert infeasible_levels(cert) == [0]  # refused by evaluate until re-tried
    summary = write_summary(tmp_path).read_text()
    assert "| 0: 0/1!v1 1: 59/59~ | 1 | 0, 2, 3, 4 | v1 |" in summary  # ~: no ledger, history unknown

    monkeypatch.setenv("INDGEN_CERT_DIR", str(tmp_path))
    plan = resolve_scene_plan(get_scene("stack"), "orange_on_blue", ("stack",), "0:1")
    assert [c.evidence for c in plan.cells] == ["0/1 (failed (oracle v1, current v2))", "59/59 (certified)"]

    logs.clear()
    again = run_certify(
        "stack", "stack", task="orange_on_blue", levels="0:1", max_steps=5, path=out, log=logs.append
    )
    assert any("levels [0] failed under an older oracle; trying them again with oracle v2" in m for m in logs)
    rows = {r["level"]: r for r in again["levels"]}
    assert rows[0]["oracle_version"] == 2 and rows[0]["status"] == "failed"  # 5 steps still cannot stack
    # the re-try is held-out attempt 2 (the row without a ledger counts as a spent attempt 1 on block 0), on block 1
    assert any(
        "level 0: held-out attempt 2 on seed block 1 (confidence 0.99925: 141/141 certifies)" in m
        for m in logs
    )
    first, retry = rows[0]["attempts"]
    assert (first["block"], first["alpha"], first["history"][:7]) == (0, 0.0485, "unknown")
    assert (retry["attempt"], retry["block"], retry["n_max"], retry["oracle"]["version"]) == (2, 1, 141, 2)
    assert rows[1]["oracle_version"] == 1 and rows[1]["status"] == "certified"  # feasibility stays
    assert again["oracle"]["version"] == 2
    assert (
        "| 0: 0/1! 1: 59/59~ | 1 | 0, 2, 3, 4 | OraclePolicy v1, v2 |" in write_summary(tmp_path).read_text()
    )
    assert find_certification(get_scene("stack"), "orange_on_blue", "stack")["levels"] == again["levels"]


def test_a_partial_level_of_another_oracle_version_is_not_reused(tmp_path, monkeypatch):
    """Episodes a killed run of another oracle version left are not mixed into this version's level."""
    out = tmp_path / "certify.json"
    key = run_prepare("stack", "stack", task="orange_on_blue", levels="0", path=out).jobs[0].key
    monkeypatch.setattr(OraclePolicy, "version", 2)
    assert run_prepare("stack", "stack", task="orange_on_blue", levels="0", path=out).jobs[0].key != key


@pytest.mark.parametrize("path", ["libero_object/alphabet_soup/goal_y", "stack/orange_on_blue/stack"])
def test_shipped_certificates_without_a_version_still_load(path):
    """Certificates shipped before versions were recorded load, count as v1, and keep their verdicts."""
    cert = load_certification(certification_dir() / path)
    rows = cert["levels"]
    assert rows and all(row_oracle_version(r, cert) >= 1 for r in rows)
    assert all(level_verdict(r, cert, 99) == "certified" for r in rows)  # certified by any version stays
