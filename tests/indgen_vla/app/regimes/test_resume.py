"""The pieces ``train`` and ``mimicgen`` resume with: --out states, the one-line refusal of other arguments, the
atomically replaced state directory."""

from __future__ import annotations

import json

import pytest

from indgen_vla.app.regimes.resume import (
    check_same_run,
    last_state,
    out_state,
    save_state,
    start_run,
)
from indgen_vla.core.errors import ConfigError


def test_out_states(tmp_path):
    out = tmp_path / "out"
    assert out_state(out, "done.json", "train") == "fresh"
    out.mkdir()
    assert out_state(out, "done.json", "train") == "fresh"
    assert out_state(out, "done.json", "mimicgen", run_file="meta/run.json") == "fresh"  # empty: as if absent
    (out / "resume").mkdir()  # killed before its run.json: nothing to keep
    assert out_state(out, "done.json", "train") == "fresh" and not (out / "resume").exists()
    # the same with its state elsewhere (mimicgen's meta/indgen_mimicgen.json): refused, kept
    (out / "resume").mkdir()
    with pytest.raises(ConfigError, match="not an unfinished 'mimicgen' output"):
        out_state(out, "done.json", "mimicgen", run_file="meta/run.json")
    assert (out / "resume").is_dir()
    start_run(out, {"config": {"n": 3}})
    assert json.loads((out / "resume" / "run.json").read_text()) == {"config": {"n": 3}}
    assert out_state(out, "done.json", "train") == "unfinished"
    (out / "done.json").write_text("{}")
    assert out_state(out, "done.json", "train") == "finished"
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="already exists and is not empty .*choose a new directory"):
        out_state(other, "done.json", "train")
    with pytest.raises(ConfigError, match="is a file"):
        out_state(other / "notes.txt", "done.json", "train")


def test_a_different_argument_is_named_in_one_line(tmp_path):
    saved = {"config": {"steps": 100, "cameras": ["agentview"], "objects": False, "dim_model": 32},
             "inputs": {"/d": "2 episodes, 259 frames"}}  # fmt: skip
    flags = ("steps", "cameras", "objects")
    check_same_run(tmp_path, saved, json.loads(json.dumps(saved)), "train", flags, finished=False)
    now = {**saved, "config": {**saved["config"], "steps": 200}}
    with pytest.raises(ConfigError) as e:
        check_same_run(tmp_path, saved, now, "train", flags, finished=False)
    assert str(e.value) == (f"train: --out {tmp_path} holds an unfinished run made with --steps 100, not --steps "
                            "200; rerun with --steps 100 to resume it, or choose a new --out")  # fmt: skip
    cases = [({"objects": True}, "made with no --objects, not --objects"),
             ({"cameras": ("agentview", "wrist")}, "made with --cameras agentview, not --cameras agentview,wrist"),
             ({"dim_model": 64}, "made with dim_model=32, not dim_model=64")]  # fmt: skip
    for change, says in cases:
        with pytest.raises(ConfigError, match=says):
            check_same_run(tmp_path, saved, {**saved, "config": {**saved["config"], **change}}, "train", flags,
                           finished=True)  # fmt: skip
    grown = {**saved, "inputs": {"/d": "3 episodes, 390 frames"}}
    with pytest.raises(ConfigError, match=r"/d changed since .*\(2 episodes, 259 frames then, 3 episodes"):
        check_same_run(tmp_path, saved, grown, "train", flags, finished=False)


def test_a_state_replaced_atomically_survives_a_kill_mid_save(tmp_path):
    assert last_state(tmp_path) is None
    save_state(tmp_path, "step_04", lambda d: (d / "w").write_text("4"))
    save_state(tmp_path, "step_08", lambda d: (d / "w").write_text("8"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["last.json", "step_08"]
    # a kill mid-save: a half-written temp directory, never pointed at
    (tmp_path / ".step_12.abc").mkdir()
    (tmp_path / ".step_12.abc" / "w").write_text("1")
    assert (last_state(tmp_path) / "w").read_text() == "8"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["last.json", "step_08"]
