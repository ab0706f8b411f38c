"""``indgen real record`` driven in a pseudo-terminal as an operator would: type verdicts, void one, kill -9 the
session, resume, finish; the journal, episodes.parquet and the report must hold exactly what was confirmed."""

from __future__ import annotations

import json

import pyarrow.parquet as pq

from indgen_vla.app.cli import main
from tests.indgen_vla.app.real.pty_session import PtySession, indgen

PROMPT = "outcome [s f v u q ?]> "


def _plan(run, *extra: str) -> None:
    args = [
        "real",
        "plan",
        "--setup",
        "stack",
        "--levels",
        "0:1",
        "--episodes",
        "3",
        "--policy",
        "pi05-droid",
    ]
    assert main([*args, "--operator", "alice", "--out", str(run), *extra]) == 0


def test_operator_session_void_kill9_resume(tmp_path, capsys):
    run = tmp_path / "run"
    _plan(run, "--order", "blocked")
    s = PtySession(indgen("real", "record", str(run)), tmp_path)
    s.expect("episode 0 of level 0 (stack = 0 in)")
    s.expect("set-up : set up level 0: blue block directly on the table (no riser)")
    s.expect('prompt : "Place the orange block on the blue block"')
    s.expect(PROMPT)
    s.type("s")
    s.expect("saved: level 0 episode 0 success")
    s.expect(PROMPT)
    s.type("f")
    s.expect("mode> ")
    s.type("4")
    s.expect("saved: level 0 episode 1 failure (misplaced)")
    # Wilson 95 % for 1/2 by hand: centre (0.5 + 1.96²/4)/(1 + 1.96²/2) = 0.5, half-width
    # 1.96·sqrt(0.5·0.5/2 + 1.96²/16)/(1 + 1.96²/2) = 0.4055 -> [9.4 %, 90.6 %]
    s.expect("level 0 (0 in): 1/2 success = 50 % (n = 2, 95 % Wilson CI 9-91 %); task orange_on_blue")
    s.expect(PROMPT)
    s.type("v cable snagged on the gripper")
    s.expect("saved: level 0 episode 2 VOID (cable snagged on the gripper): re-queued")
    s.expect("episode 2 of level 0 (stack = 0 in), re-run after 1 void(s)")  # the voided episode comes back
    s.expect(PROMPT)
    s.type("s clean place video=/data/l0e2.mp4")
    s.expect("saved: level 0 episode 2 success; note clean place; video /data/l0e2.mp4")
    s.expect("episode 0 of level 1 (stack = 0.25 in)")
    s.expect("set-up : CHANGE level 0 -> 1: raise the blue block's support to 0.25 in (1 riser plate(s)")
    s.expect(PROMPT)
    s.kill9()  # the operator's laptop dies while the next episode is on screen

    lines = (run / "journal.jsonl").read_text().splitlines()
    assert [json.loads(x)["kind"] for x in lines] == ["success", "failure", "void", "success"]
    rows = pq.read_table(run / "episodes.parquet").to_pylist()
    assert [(r["level"], r["episode"], r["success"], r["failure"]) for r in rows] == [
        (0, 0, True, "none"), (0, 1, False, "misplaced"), (0, 2, True, "none")]  # fmt: skip
    assert rows[2]["video"] == "/data/l0e2.mp4" and rows[0]["scene"] == "real:stack"
    # a writer killed mid-line leaves a torn tail, and one killed before rebuilding leaves a stale Parquet view
    with (run / "journal.jsonl").open("ab") as f:
        f.write(b'{"seq": 5, "kind": "succ')
    (run / "episodes.parquet").unlink()

    s = PtySession(indgen("real", "record", str(run), "--no-report"), tmp_path)  # report: see test_dry_run
    s.expect("episode 0 of level 1 (stack = 0.25 in)   [3 counted, 3 queued]")
    s.expect(PROMPT)
    assert len(pq.read_table(run / "episodes.parquet")) == 3  # rebuilt from the journal on start
    capsys.readouterr()
    assert main(["real", "record", str(run), "--outcome", "success"]) == 2  # a second recorder is refused
    assert capsys.readouterr().err.strip().splitlines() == [
        f"error: {run} is being recorded by another 'indgen real record' session; finish that one first"]  # fmt: skip
    s.type("f 1 never reached the block")
    s.expect("saved: level 1 episode 0 failure (no_contact); note never reached the block")
    s.expect(PROMPT)
    s.type("f dropped")
    s.expect("saved: level 1 episode 1 failure (dropped)")
    s.expect(PROMPT)
    s.type("u")
    s.expect("undo level 1 episode 1 (failure)? [y/N]> ")
    s.type("y")
    s.expect("undone: level 1 episode 1 failure; it is queued again")
    s.expect("episode 1 of level 1")
    s.expect(PROMPT)
    s.type("s")
    s.expect(PROMPT)
    s.type("s")
    s.expect("level 1 (0.25 in): 2/3 success = 67 % (n = 3")
    s.expect("run complete: every episode the plan needs is recorded.")
    assert s.wait() == 0

    entries = [json.loads(x) for x in (run / "journal.jsonl").read_text().splitlines()]
    assert [e["kind"] for e in entries] == ["success", "failure", "void", "success", "failure", "failure", "undo",
                                            "success", "success"]  # fmt: skip
    assert entries[6]["undo"] == entries[5]["seq"] and all(e["operator"] == "alice" for e in entries)
    assert entries[4]["wall_s"] > 0  # time from showing the episode to the verdict
    rows = pq.read_table(run / "episodes.parquet").to_pylist()
    assert [(r["level"], r["episode"], r["success"]) for r in rows] == [
        (0, 0, True), (0, 1, False), (0, 2, True), (1, 0, False), (1, 1, True), (1, 2, True)]  # fmt: skip
    assert [r["failure"] for r in rows] == ["none", "misplaced", "none", "no_contact", "none", "none"]


def test_a_resumed_session_says_what_was_saved_and_spells_the_set_up_out(tmp_path):
    """Killed while an episode is on screen, the operator must learn whether the last verdict was saved and see
    the set-up in full, not 'no change'; the same after an undo that steps back from a level change."""
    run = tmp_path / "run"
    _plan(run, "--order", "blocked", "--adaptive", "off")
    s = PtySession(indgen("real", "record", str(run), "--no-report"), tmp_path)
    s.expect(PROMPT)
    s.type("s")
    s.expect("saved: level 0 episode 0 success (journal line 1)")
    s.expect("set-up : no change (level 0 as before: 0 in)")
    s.expect(PROMPT)
    s.kill9()

    s = PtySession(indgen("real", "record", str(run), "--no-report"), tmp_path)
    s.expect("resuming: the journal's last line is 1, level 0 episode 0 success, at 20")
    s.expect("episode 1 of level 0 (stack = 0 in)   [1 counted, 5 queued]")
    s.expect("set-up : check level 0 is set up (as at the last verdict): blue block directly on the table")
    s.expect(PROMPT)
    s.type("s")
    s.expect(PROMPT)
    s.type("f 2")
    s.expect("saved: level 0 episode 2 failure (no_grasp) (journal line 3)")
    s.expect("set-up : CHANGE level 0 -> 1: raise the blue block's support to 0.25 in")
    s.expect(PROMPT)
    s.type("u")  # the riser may already be in: the set-up of the re-queued level-0 episode is spelled out
    s.expect("[y/N]> ")
    s.type("y")
    s.expect("episode 2 of level 0 (stack = 0 in)")
    s.expect("set-up : check level 0 is set up (as at the last verdict): blue block directly on the table")
    s.expect(PROMPT)
    s.type("q")
    assert s.wait() == 0
    s = PtySession(indgen("real", "record", str(run), "--no-report"), tmp_path)
    s.expect("resuming: the journal's last line is 4, undo of line 3 (level 0 episode 2), at 20")
    s.expect(PROMPT)
    s.type("q")
    assert s.wait() == 0
    assert [json.loads(x)["seq"] for x in (run / "journal.jsonl").read_text().splitlines()] == [1, 2, 3, 4]


def test_a_mistaken_f_or_v_backs_out_without_a_journal_line(tmp_path):
    """'f' or 'v' pressed for a success: Enter alone at the follow-up prompt goes back and journals nothing."""
    run = tmp_path / "run"
    _plan(run, "--adaptive", "off")
    s = PtySession(indgen("real", "record", str(run), "--no-report"), tmp_path)
    s.expect(PROMPT)
    s.type("f")
    s.expect("(0 = not sure; Enter alone: back to the outcome, nothing recorded)")
    s.expect("mode> ")
    s.type("7")
    s.expect("not a failure mode: '7'")
    s.expect("mode> ")
    s.type("")
    s.expect("back: nothing recorded")
    s.expect(PROMPT)
    s.type("v")
    s.expect("void reason (why it does not count; Enter alone: back to the outcome, nothing recorded)> ")
    s.type("")
    s.expect("back: nothing recorded")
    s.expect(PROMPT)
    assert not (run / "journal.jsonl").exists()
    s.type("s")
    s.expect("saved: level 0 episode 0 success (journal line 1)")
    s.expect(PROMPT)
    s.type("q")
    assert s.wait() == 0
    assert [json.loads(x)["kind"] for x in (run / "journal.jsonl").read_text().splitlines()] == ["success"]
