"""``indgen view`` and report.html in a real headless Chromium (the OS package): the served index and a run's report
load without console errors or uncaught exceptions, their screenshots are not blank, and the episodes table sorts
and filters. Set INDGEN_SCREENSHOTS=DIR to keep the screenshots."""

import os
import threading
from pathlib import Path

import pytest

from indgen_vla.app.cli import main
from indgen_vla.app.cli.view import ViewConfig, make_server
from indgen_vla.core.runs.records import RunDir
from tests.fixtures.chromium import Chromium, chromium_binary, ink
from tests.indgen_vla.core.reporting.test_report import make_run
from tests.indgen_vla.core.runs.test_records import rec

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(chromium_binary() is None, reason="needs chromium (apt-get install -y chromium)"),
]


@pytest.fixture
def browser():
    b = Chromium(chromium_binary())
    yield b
    b.close()


def _shot(browser, session, name):
    png = browser.screenshot(session)
    if os.environ.get("INDGEN_SCREENSHOTS"):
        Path(os.environ["INDGEN_SCREENSHOTS"], name).write_bytes(png)
    return png


def test_index_and_report_load_cleanly_in_chromium(tmp_path, browser):
    a = make_run(tmp_path / "runs" / "a", {-1: (5, 6), 0: (6, 6), 1: (2, 6), 2: (0, 6)}, scene="pick_place")
    b = make_run(tmp_path / "runs" / "b", {-1: (6, 6), 0: (6, 6), 1: (6, 6), 2: (5, 6)}, regime="h+mg")
    assert main(["report", str(a.path)]) == 0 and main(["report", str(b.path)]) == 0
    assert main(["compare", str(a.path), str(b.path), "--out", str(tmp_path / "runs" / "a_vs_b")]) == 0
    live = RunDir.create_or_resume(tmp_path / "runs" / "live", {"plan": {"axes": ["pick_y"]}, "policy": "p",
                                                                 "axes": {"pick_y": {"signed": True}}})  # fmt: skip
    live.append([rec(0, i) for i in range(2)])
    for f in live.path.iterdir():  # stopped an hour ago: no page reloads mid-test (test_html checks reloads)
        os.utime(f, (f.stat().st_mtime - 3600,) * 2)
    server = make_server(ViewConfig(tmp_path / "runs", port=0))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        base = f"http://127.0.0.1:{server.server_address[1]}"
        index = browser.open(base + "/")
        assert browser.errors(index) == []
        assert browser.evaluate(index, "document.querySelectorAll('#runs tbody tr').length") == 4
        assert browser.evaluate(index, "document.querySelector('meta[http-equiv=refresh]')") is None
        share, colours = ink(_shot(browser, index, "index.png"))
        assert share > 0.02 and colours > 8, (share, colours)
        href = browser.evaluate(
            index, "[...document.querySelectorAll('#runs a')].find(x => x.textContent === 'a').href"
        )
        report = browser.open(href)
        assert browser.errors(report) == []
        assert browser.evaluate(report, "document.querySelector('section').id") == "verdicts"
        plots = len(list((a.path / "plots").glob("*.png")))  # every plot inlined and decoded
        assert browser.evaluate(report, "document.images.length") == plots >= 1
        assert browser.evaluate(report, "[...document.images].every(i => i.complete && i.naturalWidth > 0)")
        share, colours = ink(_shot(browser, report, "report.png"))
        assert share > 0.05 and colours > 50, (share, colours)
        # the episodes table: the level header sorts descending on its second click, the box filters by column
        level = "[...document.querySelectorAll('#episodes th')].find(h => h.textContent === 'level')"
        browser.evaluate(report, f"{level}.click(); {level}.click()")
        first = browser.evaluate(report, "document.querySelector('#episodes tbody tr').cells[2].textContent")
        assert first == "2"
        browser.evaluate(report, "const f = document.getElementById('episodes-filter'); f.value = 'level=1 "
                         "success=true'; f.dispatchEvent(new Event('input'))")  # fmt: skip
        shown = "[...document.querySelectorAll('#episodes tbody tr')].filter(r => r.style.display !== 'none').length"
        assert browser.evaluate(report, shown) == 2  # 2 of level 1's 6 episodes succeeded
        for path in ("/a_vs_b/report.html", "/live/live"):
            page = browser.open(base + path)
            assert (
                browser.errors(page) == []
                and ink(_shot(browser, page, path.strip("/").replace("/", "_") + ".png"))[0] > 0.02
            )
    finally:
        server.shutdown()
        server.server_close()


def test_pages_fit_a_phone_wide_screen(tmp_path, browser):
    """At 400 px the page never scrolls sideways: a long policy label wraps in the title, and the level, compare and
    report.md tables scroll inside their own box; the nav bar's links land each heading below the bar."""
    label = "lerobot:checkpoints/a_policy_name_far_too_long_for_one_phone_wide_line"
    a = make_run(tmp_path / "a", {-1: (5, 6), 0: (6, 6), 1: (2, 6)}, policy=label)
    b = make_run(tmp_path / "b", {-1: (6, 6), 0: (6, 6), 1: (6, 6)}, regime="h+mg")
    assert main(["report", str(a.path)]) == 0
    assert main(["compare", str(a.path), str(b.path), "--out", str(tmp_path / "cmp")]) == 0
    for page in (a.path / "report.html", tmp_path / "cmp" / "report.html"):
        s = browser.open(page.as_uri())
        browser.call(
            "Emulation.setDeviceMetricsOverride", s, width=400, height=900, deviceScaleFactor=1, mobile=False
        )
        width = browser.evaluate(
            s, "[document.documentElement.scrollWidth, document.documentElement.clientWidth]"
        )
        assert width == [400, 400], (page, width)
        _shot(browser, s, f"narrow_{page.parent.name}.png")
        # a nav link scrolls its section's heading into view below the sticky nav bar, not under it
        covered = browser.evaluate(s, """(async () => { const out = [];
          for (const a of document.querySelectorAll('nav a')) { a.click(); await new Promise(f => setTimeout(f, 50));
            const h = document.querySelector(a.getAttribute('href') + ' > h2').getBoundingClientRect().top;
            if (h < document.querySelector('nav').getBoundingClientRect().bottom) out.push(a.getAttribute('href')); }
          return out; })()""")  # fmt: skip
        assert covered == [], (page, covered)
