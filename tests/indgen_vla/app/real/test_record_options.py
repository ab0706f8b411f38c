"""The script form's ``--episode LEVEL:INDEX`` and ``--video-pattern``, and the section ``report.md`` of a real run
gets from ``report.d/real.md``: episodes still queued and every void with its reason and whether it still waits."""

from __future__ import annotations

import pyarrow.parquet as pq

from indgen_vla.app.cli import main

PATTERN = "/data/{axis}_L{level}_e{episode}_a{attempt}_s{seed}.mp4"


def _record(run, capsys, *args: str) -> tuple[int, list[str], str]:
    rc = main(["real", "record", str(run), *args])
    out, err = capsys.readouterr()
    return rc, out.strip().splitlines(), err.strip()


def test_episode_and_video_pattern_in_the_script_form(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["real", "plan", "--setup", "stack", "--levels", "0:1", "--episodes", "2", "--order", "blocked",
                 "--adaptive", "off", "--policy", "pi05-droid", "--out", str(run)]) == 0  # fmt: skip
    capsys.readouterr()
    from indgen_vla.app.real.design import RealRun

    seeds = RealRun.open(run).seeds
    # an episode out of the queue's order (the set-up of level 1 is on the table now)
    rc, out, _ = _record(run, capsys, "--outcome", "success", "--episode", "1:1", "--video-pattern", PATTERN)
    assert (
        rc == 0
        and out[0]
        == f"saved: level 1 episode 1 success; video /data/stack_L1_e1_a0_s{seeds[1]}.mp4 (journal line 1)"
    )
    assert out[-1] == "next: level 0 episode 0"  # the queue's head is unchanged
    for bad, message in [
        (
            "1:1",
            "error: level 1 episode 1 is not waiting to be run (next: level 0 episode 0)",
        ),  # already counted
        ("2:0", "error: level 2 episode 0 is not waiting to be run (next: level 0 episode 0)"),  # not planned
        ("0:9", "error: level 0 episode 9 is not waiting to be run (next: level 0 episode 0)"),
        ("1-0", "error: --episode '1-0' must look like LEVEL:INDEX, e.g. 2:7"),
    ]:
        assert _record(run, capsys, "--outcome", "success", "--episode", bad) == (2, [], message)
    # a void, then its re-run: the attempt number moves the pattern's path; an explicit --video wins
    rc, out, _ = _record(
        run, capsys, "--outcome", "void:gripper cable", "--episode", "0:1", "--video-pattern", PATTERN
    )
    assert (
        out[0]
        == f"saved: level 0 episode 1 VOID (gripper cable): re-queued; video /data/stack_L0_e1_a0_s{seeds[1]}.mp4 "
        "(journal line 2)"
    )
    rc, out, _ = _record(
        run, capsys, "--outcome", "failure:dropped", "--episode", "0:1", "--video-pattern", PATTERN
    )
    assert (
        out[0]
        == f"saved: level 0 episode 1 failure (dropped); video /data/stack_L0_e1_a1_s{seeds[1]}.mp4 (journal line 3)"
    )
    rc, out, _ = _record(
        run, capsys, "--outcome", "success", "--video", "/mine.mp4", "--video-pattern", PATTERN
    )
    assert out[0] == "saved: level 0 episode 0 success; video /mine.mp4 (journal line 4)"
    rc, out, _ = _record(run, capsys, "--outcome", "void:riser slipped", "--episode", "1:0")
    rows = pq.read_table(run / "episodes.parquet").to_pylist()
    assert [(r["level"], r["episode"], r["video"]) for r in rows] == [
        (0, 0, "/mine.mp4"), (0, 1, f"/data/stack_L0_e1_a1_s{seeds[1]}.mp4"),
        (1, 1, f"/data/stack_L1_e1_a0_s{seeds[1]}.mp4")]  # fmt: skip
    assert _record(run, capsys, "--outcome", "success", "--video-pattern", "/v/{lvl}.mp4")[2] == (
        "error: --video-pattern '/v/{lvl}.mp4': unknown field {lvl} (did you mean {level}?); fields: run, axis, task, "
        "level, param, unit, episode, attempt, seed, instruction, placement, policy"
    )

    # report.md while 1:0's void is pending (the run is not complete), then after its re-run
    assert main(["report", str(run)]) == 0
    capsys.readouterr()
    report = (run / "report.md").read_text()
    section = report[report.index("## Real-robot run (`indgen real`)") :]
    assert (
        "- episodes counted: 3; still queued: 1 (the run is not complete: the rates above are provisional)"
        in section
    )
    assert "- voids (never counted; the episode is re-run): 2, 1 episode(s) still pending a re-run" in section
    assert "| 0 | 1 | gripper cable | — |" in section and section.split("gripper cable")[1].split("\n")[
        0
    ].endswith("| counted |")
    assert "| 1 | 0 | riser slipped | — |" in section and section.rstrip().endswith("| pending |")
    assert report.index("## Axis `stack`") < report.index("## Real-robot run")  # appended after the tables
    rc, out, _ = _record(run, capsys, "--outcome", "success", "--no-report")  # the re-run of 1:0: complete
    assert out[0] == "saved: level 1 episode 0 success (journal line 6)" and out[-1] == "run complete"
    section = (run / "report.d" / "real.md").read_text()  # what the next report.md appends
    assert "- episodes counted: 4; still queued: 0 (the run is complete)" in section
    assert "2, 0 episode(s) still pending" in section and "| pending |" not in section


def test_a_journal_recording_an_episode_twice_is_mended_with_undo(tmp_path, capsys):
    """Two writers, or a hand edit, can leave one episode recorded twice: no session opens such a journal, so its
    error names the way out, ``record RUN --undo LINE``, which cancels that line without replaying first."""
    import json

    from indgen_vla.app.real.store import JOURNAL

    run = tmp_path / "run"
    assert main(["real", "plan", "--setup", "stack", "--levels", "0:1", "--episodes", "2", "--order", "blocked",
                 "--adaptive", "off", "--policy", "pi05-droid", "--out", str(run)]) == 0  # fmt: skip
    capsys.readouterr()
    assert _record(run, capsys, "--outcome", "success")[0] == 0  # journal line 1: level 0 episode 0
    first = (run / JOURNAL).read_text().splitlines()[0]
    twin = json.loads(first) | {"seq": 2, "kind": "failure", "operator": "bob"}  # another writer's line
    (run / JOURNAL).write_text(first + "\n" + json.dumps(twin) + "\n")
    rc, out, err = _record(run, capsys, "--outcome", "success")
    assert rc == 2 and "records level 0 episode 0 twice (lines 1 and 2)" in err
    assert "'indgen real record RUN --undo LINE'" in err
    assert _record(run, capsys, "--undo", "2") == (
        0,
        ["undone: journal line 2, level 0 episode 0 failure; it keeps line 1's success"],
        "",
    )
    for line, why in (("2", "journal line 2 is undone already"), ("3", "journal line 3 is an undo"),
                      ("9", "the journal has no line 9 (lines 1-3)")):  # fmt: skip
        rc, out, err = _record(run, capsys, "--undo", line)
        assert rc == 2 and err.startswith(f"error: {run}: {why}; give the line of a verdict in force"), err
    assert _record(run, capsys, "--undo", "1", "--outcome", "success")[2] == (
        "error: --undo cancels a verdict and --outcome records one: give one of them"
    )
    rc, out, _ = _record(run, capsys, "--outcome", "failure")  # the session goes on: the next queued episode
    assert rc == 0 and out[0] == "saved: level 0 episode 1 failure (mode not given) (journal line 4)"
    assert _record(run, capsys, "--undo", "4")[1] == [
        "undone: journal line 4, level 0 episode 1 failure; it is queued again"
    ]
