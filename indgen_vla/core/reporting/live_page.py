"""The live page of a running run for ``indgen view``: built from its episodes so far, reloading while it runs."""

from __future__ import annotations

import time
from pathlib import Path

from indgen_vla.core.reporting.figures import axis_order
from indgen_vla.core.reporting.html_index import REFRESH_S, run_status
from indgen_vla.core.reporting.html_page import Section, render_page
from indgen_vla.core.reporting.html_report import run_page_sections
from indgen_vla.core.reporting.report import render_markdown, run_label
from indgen_vla.core.reporting.summary import summarize
from indgen_vla.core.runs.records import RunDir


def live_page(run_path: Path) -> str:
    """A run's page built now from its episodes so far (no plots: those are drawn when the run's report is written);
    it reloads every ``REFRESH_S`` seconds while the run is running."""
    run = RunDir.open(run_path)
    episodes, label = run.episodes(), run_label(run)
    if not len(episodes):
        body = '<p class="note">No finished episode yet; this page reloads.</p>'
        return render_page(
            f"Live: {label}", [Section("verdicts", "Verdicts", body)], str(run_path), REFRESH_S
        )
    summary = summarize(episodes, run.manifest, float((run.manifest.get("config") or {}).get("gamma", 0.2)))
    order = axis_order([(label, summary)], [run.manifest])
    text = render_markdown([(label, summary)], f"Report: {label}", order)
    running = run_status(run.path, len(episodes), None, time.time()) == "running"
    sections = [
        s if s.id != "plots" else Section("plots", "Plots", '<p class="note">Plots are drawn when the run writes '
                                          "its report (at its end, or <code>indgen report RUN</code>).</p>")
        for s in run_page_sections(run.path, run.manifest, summary, episodes, text, label, order)
    ]  # fmt: skip
    when = f"as of now, reloads every {REFRESH_S} s" if running else "as of now (the run is not running)"
    return render_page(f"Live: {label}", sections, f"{run_path} · {when}", REFRESH_S if running else None)
