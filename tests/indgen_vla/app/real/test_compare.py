"""``indgen compare`` of two real runs planned alike (real.md step 5): paired (exact McNemar) once both hold every
planned episode; while one is still being recorded, Boschloo, with a reason that says so rather than "different
plans"."""

from __future__ import annotations

import json

from indgen_vla.app.cli import main
from tests.indgen_vla.app.real.pty_session import ROOT

OUTCOMES = [
    "success",
    "success",
    "failure:misplaced",
    "success",
    "success",
] * 2  # 10 episodes: levels 0:1 x 5


def _run(tmp_path, name: str, recorded: int):
    run = tmp_path / name
    assert main(["real", "plan", "--setup", "stack", "--levels", "0:1", "--episodes", "5", "--adaptive", "off",
                 "--policy", name, "--out", str(run)]) == 0  # fmt: skip
    for outcome in OUTCOMES[:recorded]:
        assert main(["real", "record", str(run), "--outcome", outcome, "--no-report"]) == 0
    return run


def test_a_run_still_recording_is_compared_unpaired_and_the_reason_says_so(tmp_path, capsys):
    a, b = _run(tmp_path, "pol_a", 10), _run(tmp_path, "pol_b", 7)
    assert main(["compare", str(a), str(b), "--out", str(tmp_path / "ab")]) == 0
    res = json.loads((tmp_path / "ab" / "compare.json").read_text())
    assert res["test"] == "boschloo" and res["paired"] is False
    assert res["unpaired_reason"] == (
        "the runs do not hold the same episodes on stack (10 vs 7: other tasks, levels or --episodes, or a run "
        "not finished)"
    )
    for outcome in OUTCOMES[7:]:  # the operator finishes run B: now every planned episode is in both
        assert main(["real", "record", str(b), "--outcome", outcome, "--no-report"]) == 0
    assert main(["compare", str(a), str(b), "--out", str(tmp_path / "ab2")]) == 0
    res = json.loads((tmp_path / "ab2" / "compare.json").read_text())
    assert res["test"] == "mcnemar_exact" and res["paired"] is True
    capsys.readouterr()


def test_runs_of_two_set_ups_with_other_heights_are_not_paired_and_the_reason_names_the_set_up(
    tmp_path, capsys
):
    """A copied preset with 0.5 in risers: level 1 is another height, so no episode pairs with the preset's."""
    a = _run(tmp_path, "pol_a", 10)
    yaml = tmp_path / "my_stack.yaml"
    yaml.write_text((ROOT / "configs" / "real" / "stack.yaml").read_text().replace("step: 0.25", "step: 0.5"))
    b = tmp_path / "pol_b"
    assert main(["real", "plan", "--setup", str(yaml), "--levels", "0:1", "--episodes", "5", "--adaptive", "off",
                 "--policy", "pol_b", "--out", str(b)]) == 0  # fmt: skip
    for outcome in OUTCOMES:
        assert main(["real", "record", str(b), "--outcome", outcome, "--no-report"]) == 0
    assert main(["compare", str(a), str(b), "--out", str(tmp_path / "ab")]) == 0
    res = json.loads((tmp_path / "ab" / "compare.json").read_text())
    assert res["paired"] is False and res["unpaired_reason"] == (
        "level parameters differ on stack (different --step, or a real set-up's YAML)"
    )
    capsys.readouterr()
