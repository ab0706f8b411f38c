"""The index ``indgen view`` serves: one row per run directory (and comparison) found under a folder, read from the
files a run writes (manifest.json, summary.json, episodes.parquet and its journal), never from a running process."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from indgen_vla.core.reporting.html_page import HTML_REPORT, Section, esc, render_page, table_html
from indgen_vla.core.runs.records import EPISODES, JOURNAL, MANIFEST, SUMMARY
from indgen_vla.core.stats.metrics import pooled_text

LIVE_S = 120.0  # a run whose episodes changed this recently counts as running
REFRESH_S = 10  # the index and a live run's page reload this often while a run is running
SKIP = {"videos", "plots", "preview", "report.d", ".git", "__pycache__", "node_modules"}
KINDS = ("run", "comparison", "overlay")  # a run dir; compare's --out; report RUN RUN...'s overlay
COLUMNS = ("run", "kind", "policy", "scene", "axes", "tasks", "k* per axis", "n", "status", "date")


@dataclass(frozen=True)
class IndexRow:
    """One run (or comparison) of the index; ``href`` opens its page, relative to the served folder."""

    run: str
    kind: str
    policy: str
    scene: str
    axes: str
    tasks: str
    kstar: str
    n: str
    status: str
    date: str
    href: str

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"index row kind must be one of {KINDS}, got {self.kind!r}")

    def cells(self) -> dict[str, str]:
        return dict(zip(COLUMNS, (self.run, self.kind, self.policy, self.scene, self.axes, self.tasks, self.kstar,
                                  self.n, self.status, self.date), strict=True), _href=self.href)  # fmt: skip


def _read_json(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def episode_count(run: Path) -> int:
    """Finished episodes on disk: the Parquet file's rows (its footer only) plus the journal's unflushed lines."""
    n = 0
    if (run / EPISODES).is_file():
        import pyarrow.parquet as pq

        try:
            n = pq.read_metadata(run / EPISODES).num_rows
        except (OSError, ValueError):
            n = 0
    if (run / JOURNAL).is_file():
        with open(run / JOURNAL, "rb") as f:
            n += sum(1 for line in f if line.strip())
    return n


def _mtime(*paths: Path) -> float:
    return max((p.stat().st_mtime for p in paths if p.exists()), default=0.0)


def _kstar_of(b: dict, verdict: dict, d: str) -> str:
    """A summary written before k* statuses existed: its point k* ("none": no break in range)."""
    if str(verdict.get(d, "")).startswith("not evaluated"):  # no level on that side was run
        return "not evaluated"
    k = b.get(d)
    return "none" if k is None else (k if isinstance(k, str) else f"L{k}")


def kstar_cell(summary: dict) -> str:
    """k* per axis and direction in the report's words and with its status (summary.json ``kstar_status``), e.g.
    "pick_y +: k* = +2, determined; −: k* ∈ [−1, −3]"; "" before the first report."""
    parts = []
    for axis, a in (summary.get("axes") or {}).items():
        status = a.get("kstar_status") or {}
        b, verdict = a.get("break_level") or {}, a.get("verdict") or {}
        sides = (("pos", "+"), ("neg", "−")) if a.get("signed") else (("pos", ""),)
        words = [
            f"{sign}: {status[d]['text']}" if d in status else f"{sign}: {_kstar_of(b, verdict, d)}"
            for d, sign in sides
        ]
        parts.append(f"{axis} {'; '.join(words)}" if a.get("signed") else f"{axis} {words[0][2:]}")
    return " | ".join(parts)


def run_status(run: Path, n: int, planned: int | None, now: float) -> str:
    """running (episodes written within ``LIVE_S``, none reported since), finished (every planned episode, or a
    report written after the last episode of an adaptive run), else stopped: resume it with the same command."""
    data = _mtime(run / EPISODES, run / JOURNAL)
    if data and now - data < LIVE_S and _mtime(run / HTML_REPORT) < data:  # a finished run reports last
        return "running"
    if planned and n >= planned:
        return "finished"
    if (
        planned is None and n and _mtime(run / HTML_REPORT) >= data
    ):  # adaptive: its rule decided where to stop
        return "finished"
    return "stopped (re-run its evaluate command to resume)" if n else "no episodes yet"


def run_row(run: Path, root: Path, now: float) -> IndexRow:
    """The index row of one run directory."""
    m, s = _read_json(run / MANIFEST), _read_json(run / SUMMARY)
    plan = m.get("plan") or {}
    planned = (m.get("resolved") or {}).get("episodes")
    adaptive = bool(plan.get("adaptive"))
    n = episode_count(run)
    status = run_status(run, n, None if adaptive else planned, now)
    rel = run.relative_to(root).as_posix() if run != root else "."
    live = status == "running" or not (run / HTML_REPORT).exists()
    href = f"/live/{rel}/".replace("/./", "/") if live else f"/{rel}/{HTML_REPORT}".replace("/./", "/")
    of = f" of {planned}" + (" max (adaptive)" if adaptive else "") if planned else ""
    regime = f" ({m['data_regime']})" if m.get("data_regime") else ""
    return IndexRow(run=rel, kind="run", policy=f"{m.get('policy', '')}{regime}", scene=str(m.get("scene", "")),
                    axes=", ".join(plan.get("axes") or []), tasks=", ".join(plan.get("tasks") or []),
                    kstar=kstar_cell(s), n=f"{n}{of}", status=status, date=_utc(m.get("created")),
                    href=href)  # fmt: skip


def _utc(created: object) -> str:
    """A manifest's ISO time as the index shows every date, e.g. "2026-11-28 04:51 UTC" ("" when unknown)."""
    import datetime as dt

    try:
        t = dt.datetime.fromisoformat(str(created))
    except ValueError:
        return str(created or "")
    return (t.astimezone(dt.UTC) if t.tzinfo else t).strftime("%Y-%m-%d %H:%M UTC")


def _clip(text: str, limit: int = 240) -> str:
    return text if len(text) <= limit else text[:limit].rsplit(" ", 1)[0] + " … (open it for the rest)"


def comparison_row(folder: Path, root: Path) -> IndexRow:
    """The index row of a comparison or overlay folder (compare.json or report.md without a manifest)."""
    c = _read_json(folder / "compare.json")
    rel = folder.relative_to(root).as_posix()
    date = time.strftime(
        "%Y-%m-%d %H:%M UTC", time.gmtime(_mtime(folder / HTML_REPORT, folder / "report.md"))
    )
    pair = " vs ".join(x for x in (c.get("label_a"), c.get("label_b")) if x)
    axes = c.get("axes") or {}  # the tasks each compared axis's rates pool (its verdict's claim)
    tasks = [  # a two-run comparison's text ("task milk"); a group comparison's list
        (a, x["tasks"] if isinstance(x["tasks"], str) else pooled_text(list(x["tasks"])))
        for a, x in axes.items()
        if isinstance(x, dict) and x.get("tasks")
    ]
    pooled = tasks[0][1] if len(tasks) == 1 else "; ".join(f"{a}: {t}" for a, t in tasks)
    return IndexRow(run=rel, kind="comparison" if c else "overlay", policy=pair, scene="", axes=", ".join(c.get("axes") or []),
                    tasks=pooled, kstar="", n="", status=_clip(str(c.get("verdict", ""))), date=date,
                    href=f"/{rel}/{HTML_REPORT}")  # fmt: skip


def find_rows(root: Path, now: float | None = None) -> list[IndexRow]:
    """Every run directory and comparison under ``root`` (its folders walked once), newest first."""
    root, now = Path(root), time.time() if now is None else now
    rows = []
    for here, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d not in SKIP and not d.startswith(".tmp"))
        folder = Path(here)
        if MANIFEST in files and (EPISODES in files or "plan" in _read_json(folder / MANIFEST)):
            rows.append(run_row(folder, root, now))
        elif HTML_REPORT in files and ("compare.json" in files or "report.md" in files):
            rows.append(comparison_row(folder, root))
    return sorted(rows, key=lambda r: r.date, reverse=True)


def index_page(root: Path, rows: Sequence[IndexRow]) -> str:
    """The index as one page: a sortable, filterable table whose first cell opens each run's report; it reloads
    every ``REFRESH_S`` seconds while a run is running."""
    live = any(r.status == "running" for r in rows)
    note = (f'<p class="note">{len(rows)} runs and comparisons under <code>{esc(root)}</code>; click a run to open '
            "its report.html (a running run, or one without a report yet, opens a live page built from its "
            f"episodes so far).{f' This page reloads every {REFRESH_S} s while a run is running.' if live else ''}"
            "</p>")  # fmt: skip
    table = table_html("runs", COLUMNS, [r.cells() for r in rows], links={"run": "_href"},
                       example="status=running scene=pick_place") if rows else (
        '<p class="note">No run directories here yet (a run directory holds manifest.json).</p>')  # fmt: skip
    return render_page("indgen runs", [Section("runs", "Runs", note + table)], str(root),
                       REFRESH_S if live else None)  # fmt: skip
