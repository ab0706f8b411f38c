"""The real run's section of ``report.md``: progress and voids, which ``episodes.parquet`` does not hold.

``indgen report`` appends the run directory's ``report.d/*.md`` files to ``report.md`` (``indgen_vla.core.reporting.report``);
the recorder rewrites ``report.d/real.md`` (atomically) with every journal change, beside the Parquet view, so
a report written at any time (even while a session records) says how many episodes are still queued and which
voided episodes are still waiting for their re-run, and why each was voided.
"""

from __future__ import annotations

from indgen_vla.app.real.design import RealRun
from indgen_vla.app.real.store import JOURNAL, State
from indgen_vla.core.runs.records import SECTIONS, atomic_write_text

SECTION = "real.md"


def render_section(rr: RealRun, state: State) -> str:
    """Markdown: operator/robot/set-up, counted vs queued episodes, every void with its reason and its fate."""
    m = rr.manifest["real"]
    queue = rr.queue(state)
    pending = {key for key in queue if state.voids.get(key)}
    n_voids = sum(len(v) for v in state.voids.values())
    last = state.live[-1].time if state.live else "none yet"
    lines = ["## Real-robot run (`indgen real`)", "",
             f"Set-up `{m['setup_name']}` (axis {rr.axis.name}, unit {rr.axis.unit}), robot {m['robot'] or 'not named'}, "
             f"operator {m['operator'] or 'not named'}; verdicts from `{JOURNAL}` (last {last}).", "",
             f"- episodes counted: {len(state.counted)}; still queued: {len(queue)}"
             + (" (the run is complete)" if not queue else " (the run is not complete: the rates above are provisional)"),
             f"- voids (never counted; the episode is re-run): {n_voids}, {len(pending)} episode(s) still pending "
             "a re-run"]  # fmt: skip
    if n_voids:
        lines += [
            "",
            "| level | episode | void reason | operator | time | re-run |",
            "|---|---|---|---|---|---|",
        ]
        for (k, i), entries in sorted(state.voids.items()):
            fate = "pending" if (k, i) in pending else "counted" if (k, i) in state.counted else "not needed"
            for e in entries:
                reason = e.reason.replace("|", "/")
                lines.append(f"| {k} | {i} | {reason} | {e.operator or '—'} | {e.time or '—'} | {fate} |")
    return "\n".join(lines) + "\n"


def write_section(rr: RealRun, state: State) -> None:
    """Rewrite ``RUN/report.d/real.md`` (atomic: a report being written meanwhile reads the old or the new)."""
    d = rr.run.path / SECTIONS
    d.mkdir(exist_ok=True)
    atomic_write_text(d / SECTION, render_section(rr, state))
