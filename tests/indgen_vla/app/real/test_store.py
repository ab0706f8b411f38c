"""The journal on disk: a torn last line longer than the 64 KiB read-back step must cost only itself."""

from __future__ import annotations

import json

from indgen_vla.app.real.store import JOURNAL, Entry, append_entry, read_journal


def test_a_torn_line_longer_than_64_kib_keeps_the_lines_before_it(tmp_path):
    append_entry(tmp_path, Entry(seq=1, kind="success", axis="stack", level=0, episode=0))
    append_entry(tmp_path, Entry(seq=2, kind="failure", axis="stack", level=0, episode=1, failure="dropped"))
    with (tmp_path / JOURNAL).open("ab") as f:  # a writer killed mid-way through a 100 kB note
        f.write(b'{"seq": 3, "kind": "success", "note": "' + b"x" * 100_000)
    assert [e.seq for e in read_journal(tmp_path)] == [1, 2]  # the torn tail is not read
    append_entry(tmp_path, Entry(seq=3, kind="success", axis="stack", level=0, episode=2))
    lines = (tmp_path / JOURNAL).read_text().splitlines()
    assert [json.loads(x)["seq"] for x in lines] == [1, 2, 3]
    assert json.loads(lines[1])["failure"] == "dropped"


def test_a_torn_first_line_is_cut_to_nothing(tmp_path):
    (tmp_path / JOURNAL).write_bytes(b'{"seq": 1, "kind": "succ')
    append_entry(tmp_path, Entry(seq=1, kind="void", axis="stack", reason="e-stop"))
    assert [(e.seq, e.kind) for e in read_journal(tmp_path)] == [(1, "void")]
