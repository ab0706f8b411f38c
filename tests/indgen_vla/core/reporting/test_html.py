"""report.html beside every report.md / compare.md, and ``indgen view``'s index, read back with html.parser."""

import dataclasses
import json
import threading
import urllib.error
import urllib.parse
import urllib.request
from html.parser import HTMLParser

import numpy as np
import pytest

from indgen_vla.app.cli import main
from indgen_vla.app.cli.view import ViewConfig, make_server
from indgen_vla.core.reporting.html_index import LIVE_S, find_rows
from indgen_vla.core.reporting.html_page import Section, markdown_page
from indgen_vla.core.runs.records import EpisodeRecord, RunDir
from indgen_vla.core.runs.video import write_mp4
from tests.indgen_vla.core.reporting.test_report import make_run
from tests.indgen_vla.core.runs.test_records import rec


class Page(HTMLParser):
    """What a test reads of a page: section ids in order, rows per table, every URL, scripts and styles."""

    def __init__(self, text: str):
        super().__init__()
        self.sections, self.rows, self.urls, self.meta, self.videos = [], {}, [], [], []
        self._table, self._in_body, self.script_src = None, False, []
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "section":
            self.sections.append(a["id"])
        if tag == "table":
            self._table = a.get("id")
        if tag == "tbody":
            self._in_body = True
        if tag == "tr" and self._in_body and self._table:
            self.rows[self._table] = self.rows.get(self._table, 0) + 1
        for key in ("href", "src", "action", "poster"):
            if a.get(key) is not None:
                self.urls.append(a[key])
        if tag == "script" and a.get("src"):
            self.script_src.append(a["src"])
        if tag == "link":
            self.urls.append(a.get("href", ""))
        if tag == "meta":
            self.meta.append(a)
        if tag == "video":
            self.videos.append(a["src"])

    def handle_endtag(self, tag):
        if tag == "tbody":
            self._in_body = False
        if tag == "table":
            self._table = None


def external(urls):
    """URLs that would leave the page's folder: a scheme other than data:, or a protocol-relative //host."""
    return [u for u in urls if u.startswith("//") or ("://" in u or u.split(":", 1)[0] in ("http", "https"))
            or (":" in u.split("/")[0] and not u.startswith("data:"))]  # fmt: skip


def test_a_run_report_writes_a_self_contained_report_html(tmp_path):
    run = make_run(tmp_path / "run", {-1: (4, 6), 0: (6, 6), 1: (3, 6), 2: (0, 6)}, errors=1)
    write_mp4([np.full((16, 16, 3), 40 * i, np.uint8) for i in range(4)], run.path / "videos" / "a.mp4")
    run.append([dataclasses.replace(rec(2, 50, success=False), video="videos/a.mp4", failure="no_grasp"),
                dataclasses.replace(rec(0, 51), video="videos/a.mp4", failure="none")])  # fmt: skip
    assert main(["report", str(run.path)]) == 0
    text = (run.path / "report.html").read_text()
    page = Page(text)
    assert page.sections == ["verdicts", "plots", "preview", "videos", "failures", "episodes", "report"]
    assert page.rows["episodes"] == len(run.episodes()) == 27  # one row per episode, error rows included
    assert not external(page.urls) and not page.script_src and 'rel="stylesheet"' not in text
    assert all(u.startswith(("data:image/png;base64,", "#", "videos/")) or u == "data:," for u in page.urls)
    assert page.videos == [
        "videos/a.mp4",
        "videos/a.mp4",
    ]  # one success and one failure example at their levels
    verdicts = text[text.index('id="verdicts"') : text.index('id="plots"')]
    assert (
        "k*" in verdicts
        and "+: L2" in verdicts
        and "task t" in verdicts
        and "[" in verdicts
        and "n</th>" in verdicts
    )
    summary = json.loads((run.path / "summary.json").read_text())
    assert summary["axes"]["pick_y"]["verdict"]["pos"] in verdicts.replace("&#x27;", "'")
    status = summary["axes"]["pick_y"][
        "kstar_status"
    ]  # whether k* is decided: report.md's row, said here too
    assert f"<b>k* status</b>: +: {status['pos']['text']}; −: {status['neg']['text']}" in verdicts
    assert "no_grasp" in text[text.index('id="failures"') :]
    preview = text[text.index('id="preview"') : text.index('id="videos"')]
    assert (
        "indgen preview --scene" in preview and "<img" not in preview
    )  # no sheet yet: the command that makes it
    (run.path / "preview").mkdir()
    (run.path / "preview" / "pick_y.png").write_bytes((run.path / "plots" / "pick_y.png").read_bytes())
    assert main(["report", str(run.path)]) == 0
    text = (run.path / "report.html").read_text()
    assert "<img" in text[text.index('id="preview"') : text.index('id="videos"')]


def test_overlay_and_compare_pages_carry_their_verdicts(tmp_path):
    a = make_run(tmp_path / "a", {0: (6, 6), 1: (5, 6)}, regime="h-only")
    b = make_run(tmp_path / "b", {0: (6, 6), 1: (0, 6)}, regime="h+mg")
    assert main(["report", str(a.path), str(b.path), "--out", str(tmp_path / "overlay")]) == 0
    overlay = Page((tmp_path / "overlay" / "report.html").read_text())
    assert overlay.sections[0] == "verdicts" and "report" in overlay.sections and not external(overlay.urls)
    assert main(["compare", str(a.path), str(b.path), "--out", str(tmp_path / "cmp")]) == 0
    text = (tmp_path / "cmp" / "report.html").read_text()
    result = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    assert Page(text).sections == ["verdicts", "plots", "report"]
    assert result["verdict"].split(":")[0] in text and "paired episode by episode" in text
    verdicts = text[text.index('id="verdicts"') : text.index('id="plots"')]
    # the verdict's "B − A" names its runs before the full report does
    assert f"A = <code>{result['label_a']}</code>, B = <code>{result['label_b']}</code>" in verdicts
    assert (
        verdicts.count('class="caveat"') == len(result["caveats"]) >= 1
    )  # too few pairs: said first, in red


def test_the_hook_a_series_or_gate_page_calls(tmp_path):
    path = markdown_page(tmp_path, "Series", "# s\n\n| step | k* |\n|---|---|\n| 10 | L2 |\n",
                         ["**k\\*** rises"], None, [Section("extra", "Extra", "<p>x</p>")])  # fmt: skip
    page = Page(path.read_text())
    assert page.sections == ["verdicts", "extra", "report"] and "<td>L2</td>" in path.read_text()
    with pytest.raises(ValueError, match="section id"):
        Section("a b", "t", "")


def _get(url):
    with urllib.request.urlopen(url, timeout=20) as r:
        return r.read().decode()


def test_view_serves_the_index_reports_and_live_runs_on_loopback_only(tmp_path, capsys):
    done = make_run(tmp_path / "runs" / "done", {0: (5, 5)}, scene="pick_place", created="2026-01-01")
    assert main(["report", str(done.path)]) == 0
    live = RunDir.create_or_resume(tmp_path / "runs" / "deep" / "live",
                                   {"plan": {"axes": ["pick_y"], "tasks": ["t"]}, "policy": "standin:noop",
                                    "resolved": {"episodes": 10}, "axes": {"pick_y": {"signed": True}}})  # fmt: skip
    write_mp4([np.full((16, 16, 3), 40 * i, np.uint8) for i in range(4)], live.path / "videos" / "a.mp4")
    live.append([dataclasses.replace(rec(0, i), video="videos/a.mp4" if i == 0 else None) for i in range(3)])
    rows = {r.run: r for r in find_rows(tmp_path / "runs")}
    assert set(rows) == {"done", "deep/live"} and rows["deep/live"].status == "running"
    assert rows["deep/live"].n == "3 of 10"
    # the report's words and status for k*, never a bare dash (level 0 alone: neither side evaluated)
    assert rows["done"].kstar == (
        "pick_y +: not evaluated (no level on this side of 0 was run); −: not evaluated (no level on this side of 0 "
        "was run)"
    )
    assert rows["done"].date == "2026-01-01 00:00 UTC" and rows["done"].kind == "run"
    later = {r.run: r for r in find_rows(tmp_path / "runs", now=__import__("time").time() + LIVE_S + 1)}
    assert later["deep/live"].status.startswith("stopped") and later["done"].status == "finished"

    server = make_server(ViewConfig(tmp_path / "runs", port=0))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        base = f"http://127.0.0.1:{server.server_address[1]}"
        index = Page(_get(base + "/"))
        assert index.rows["runs"] == 2 and not external(index.urls)
        assert {"http-equiv": "refresh", "content": "10"} in index.meta  # a run is running: the index reloads
        assert "/done/report.html" in index.urls and "/live/deep/live/" in index.urls
        assert Page(_get(base + "/done/report.html")).sections[0] == "verdicts"
        live_page = Page(_get(base + "/live/deep/live"))  # redirected to /live/deep/live/
        assert (
            live_page.rows["episodes"] == 3 and {"http-equiv": "refresh", "content": "10"} in live_page.meta
        )
        # the live page's videos load: its relative links resolve inside the run (before: /live/videos/a.mp4, 404)
        assert live_page.videos == ["videos/a.mp4"]
        url = urllib.parse.urljoin(base + "/live/deep/live/", live_page.videos[0])
        with urllib.request.urlopen(url, timeout=20) as r:
            assert r.read() == (live.path / "videos" / "a.mp4").read_bytes()
        for bad in ("/live/../../etc", "/live/nothing", "/../../etc/passwd"):
            with pytest.raises(urllib.error.HTTPError) as e:
                _get(base + bad)
            assert e.value.code == 404
    finally:
        server.shutdown()
        server.server_close()
    assert main(["view", str(tmp_path / "runs"), "--host", "0.0.0.0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "127.0.0.1 only" in err
    assert main(["view", str(tmp_path / "nowhere")]) == 2 and "not a directory" in capsys.readouterr().err


def test_a_page_escapes_what_runs_write(tmp_path):
    run = RunDir.create_or_resume(tmp_path / "r", {"plan": {}, "policy": "standin:<b>x</b>",
                                                   "axes": {"pick_y": {"signed": True}}})  # fmt: skip
    row = EpisodeRecord(run_id="r", policy="p", data_regime="", scene="s", task="<script>alert(1)</script>",
                        axis="pick_y", level=0, param=0.0, episode=0, seed=1, success=True, steps=1)  # fmt: skip
    run.append([dataclasses.replace(row, episode=i) for i in range(5)])
    assert main(["report", str(run.path)]) == 0
    text = (run.path / "report.html").read_text()
    assert "<script>alert" not in text and "&lt;script&gt;alert(1)&lt;/script&gt;" in text
    assert "<b>x</b>" not in text


def test_the_index_says_kstar_in_the_reports_words(tmp_path):
    """A determined k*, an interval and no break: the index cell holds summary.json's kstar_status texts, as the
    report's k* row prints them, not "+L2 −none"."""
    from indgen_vla.core.reporting.html_index import kstar_cell
    from indgen_vla.core.reporting.summary import summarize

    run = make_run(tmp_path / "r", {-2: (0, 20), -1: (5, 20), 0: (20, 20), 1: (19, 20), 2: (0, 20)})
    s = summarize(run.episodes(), run.manifest, 0.2)
    a = s["axes"]["pick_y"]
    cell = kstar_cell(s)
    assert cell == f"pick_y +: {a['kstar_status']['pos']['text']}; −: {a['kstar_status']['neg']['text']}"
    assert "+: k* = +2, determined" in cell and "−: k* ∈ [-2, -1]" in cell


def test_the_index_row_of_a_comparison_names_its_tasks_and_filters_by_its_own_columns(tmp_path):
    """A comparison's row says which tasks its verdict pools (compare.json), as a run's row does; the filter box's
    example uses the index's columns, not the episodes table's level/success."""
    a = make_run(tmp_path / "runs" / "a", {0: (6, 6), 1: (5, 6)})
    b = make_run(tmp_path / "runs" / "b", {0: (6, 6), 1: (0, 6)}, regime="h+mg")
    assert main(["compare", str(a.path), str(b.path), "--out", str(tmp_path / "runs" / "cmp")]) == 0
    args = ["compare", "--a", str(a.path), "--b", str(b.path), "--out", str(tmp_path / "runs" / "groups")]
    assert main(args) == 0  # a group comparison's compare.json lists its tasks: the same words
    rows = {r.run: r for r in find_rows(tmp_path / "runs")}
    assert rows["cmp"].kind == "comparison" and rows["cmp"].tasks == "task t" == rows["groups"].tasks
    from indgen_vla.core.reporting.html_index import index_page

    text = index_page(tmp_path / "runs", list(rows.values()))
    assert "e.g. status=running scene=pick_place" in text and "level=2" not in text


def test_a_real_run_page_points_at_its_protocol_not_at_simulator_commands(tmp_path):
    """A real-robot run (manifest "real"): no `indgen preview --scene real:...` hint (that command refuses real
    scenes), the videos hint names `indgen real record --video`, and its failure modes are the operator's."""
    run = make_run(tmp_path / "real", {0: (4, 5), 1: (0, 5)}, scene="real:stack", real={"setup_name": "stack"},
                   axes={"pick_y": {"signed": True, "unit": "in"}})  # fmt: skip
    assert main(["report", str(run.path)]) == 0
    text = (run.path / "report.html").read_text()
    assert (
        "<th>param (in)</th>" in text[: text.index('id="plots"')]
    )  # the level table's parameter has its unit
    preview = text[text.index('id="preview"') : text.index('id="videos"')]
    assert "indgen preview" not in preview and '<a href="protocol.md">protocol.md</a>' in preview
    assert "indgen real record --video" in text[text.index('id="videos"') : text.index('id="failures"')]
    failures = text[text.index('id="failures"') : text.index('id="episodes"')]
    assert "given by the operator" in failures and "simulator state" not in failures
    sim = make_run(tmp_path / "sim", {0: (4, 5), 1: (0, 5)}, scene="pick_place")
    assert main(["report", str(sim.path)]) == 0
    text = (sim.path / "report.html").read_text()
    assert "indgen preview --scene pick_place" in text and "evaluate with --video" in text
