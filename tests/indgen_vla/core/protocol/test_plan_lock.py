"""plan.lock: hash, refusal of edited locks, deviations in the protocol and in the analysis."""

import json

import pytest

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.plan_lock import (
    UNPUBLISHED,
    analysis_deviations,
    make_lock,
    protocol_deviations,
    read_lock,
    run_status,
)

PLAN = {"policy": "standin:oracle", "scene": "pick_place", "tasks": ["milk"], "axes": ["pick_y"],
        "levels": {"pick_y": [0, 1]}, "episodes": 5, "seed": 0}  # fmt: skip
FP = {"scene": "pick_place", "family": "F", "simulator": {"mujoco": "3.8.1"}, "horizon": 280}


def _lock():
    return make_lock(PLAN, "abc", FP, {"gamma": 0.2, "ci": "wilson", "alpha": 0.05}, {"rollouts_planned": 10})


def test_a_lock_round_trips_and_an_edited_one_is_refused(tmp_path):
    p = tmp_path / "plan.lock"
    p.write_text(json.dumps(_lock()))
    assert read_lock(p)["hash"] == _lock()["hash"]
    edited = {**_lock(), "plan": {**PLAN, "episodes": 50}}
    p.write_text(json.dumps(edited))
    with pytest.raises(ConfigError, match="does not match its hash"):
        read_lock(p)
    with pytest.raises(ConfigError, match="no such file"):
        read_lock(tmp_path / "missing.lock")


def test_deviations_name_the_field():
    lock = _lock()
    assert protocol_deviations(lock, PLAN, "abc", FP) == []
    found = protocol_deviations(lock, {**PLAN, "episodes": 3}, "abd", {**FP, "simulator": {"mujoco": "3.9"}})
    assert found[0] == "episodes is 3, locked 5"
    assert any("planned episodes" in f for f in found) and any(
        "fingerprint.simulator.mujoco" in f for f in found
    )
    assert analysis_deviations(lock, gamma=0.3, ci="wilson") == ["gamma is 0.3, locked 0.2"]


def test_run_status_says_locked_and_where_published_or_lists_deviations():
    lock = _lock()
    manifest = {"plan": PLAN, "resolved": {"jobs_sha256": "abc"}, "fingerprint": FP,
                "preregistered": {"hash": lock["hash"], "lock": lock}}  # fmt: skip
    assert run_status(manifest, 10, gamma=0.2) == f"locked, hash {lock['hash'][:12]}, followed; {UNPUBLISHED}"
    assert UNPUBLISHED.startswith("not shown to precede the run")
    assert run_status(manifest, 10, "https://osf.io/x", gamma=0.2).endswith(
        "followed; published https://osf.io/x"
    )
    line = run_status(manifest, 7, gamma=0.25)
    assert "2 deviation(s)" in line and "stopped early: 7 of 10" in line and "gamma is 0.25" in line
    assert run_status({"plan": PLAN}, 10) is None
