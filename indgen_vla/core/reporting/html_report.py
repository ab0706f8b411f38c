"""A run's ``report.html`` beside its ``report.md``: verdicts first, then plots, the level preview sheet, example
videos by outcome, failure modes, every episode in a sortable table, and report.md itself (``indgen_vla.core.reporting.html_page``)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from indgen_vla.core.reporting.caveats import report_caveats
from indgen_vla.core.reporting.failures import MODES
from indgen_vla.core.reporting.figures import AXES_PLOT
from indgen_vla.core.reporting.html_page import (
    HTML_REPORT,
    Section,
    esc,
    image_html,
    markdown_html,
    table_html,
    video_html,
    write_page,
)
from indgen_vla.core.reporting.levels import verdict_line
from indgen_vla.core.stats.metrics import UNDETERMINED, ci_name, pooled_text

PREVIEW_DIR = "preview"  # a run's level preview sheets (``indgen preview --out RUN/preview/AXIS.png``)
EPISODE_COLUMNS = ("task", "axis", "level", "param", "episode", "seed", "success", "steps", "status", "failure",
                   "progress", "wall_s", "shared_from", "video", "error")  # fmt: skip
VIDEOS_PER_OUTCOME = 3  # example videos shown per level and outcome (the episodes table links every one)


def _kstar(k: Any) -> str:
    if k == UNDETERMINED:
        return UNDETERMINED
    return "none (no level below γ)" if k is None else f"L{k}"


def kstar_text(a: Mapping[str, Any]) -> str:
    """k* per direction of one axis summary, e.g. "+: L2; −: none (no level below γ)"."""
    b = a["break_level"]
    if not a["signed"]:
        return _kstar(b["pos"])
    return f"+: {_kstar(b['pos'])}; −: {_kstar(b.get('neg'))}"


def _level_rows(a: Mapping[str, Any], unit: str = "") -> str:
    """One axis's levels: the parameter (in ``unit``), success with its 95 % CI and n (or why there is no rate),
    errors, the level's verdict."""
    param_head = f"param ({esc(unit)})" if unit else "param"
    head = (f"<tr><th>level</th><th>{param_head}</th><th>success</th><th>95% CI</th><th>n</th><th>errors</th>"
            "<th>verdict</th>")  # fmt: skip
    rows = []
    for r in a["levels"]:
        param = "—" if r.get("param") is None else f"{r['param']:.4g}"
        if r.get("not_run"):
            rate, ci = "not run (past the observed break)", ""
        elif r.get("insufficient", r["n"] == 0):
            of = f" of {r['planned']}" if r.get("planned") else ""
            rate, ci = f"insufficient data (n = {r['n']}{of})", ""
        else:
            only = f" ({pooled_text(r['pooled_only'])} only)" if r.get("pooled_only") else ""
            rate = f"{100 * r['rate']:.0f}%{only}"
            ci = f"[{100 * r['ci_low']:.0f}, {100 * r['ci_high']:.0f}]"
        cells = (r["level"], param, rate, ci, r["n"], r.get("errors", 0), r.get("decision") or "")
        rows.append("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in cells) + "</tr>")
    return f'<table class="levels">{head}</tr>{"".join(rows)}</table>'


def verdict_section(summaries: Sequence[tuple[str, Mapping[str, Any]]], order: Sequence[str] = (),
                    units: Mapping[str, str] | None = None) -> Section:  # fmt: skip
    """The page's first section: what the study cannot answer, then per run and axis k* per direction, the verdict
    sentence, the tasks pooled and each level's rate with its CI and n (the claims report.md makes); ``units``: each
    axis's parameter unit (the manifest's)."""
    body = [f'<div class="caveat">{markdown_html(c)}</div>' for c in report_caveats(list(summaries))]
    axes = list(order) or sorted({a for _, s in summaries for a in s["axes"]})
    for axis in axes:
        for label, s in summaries:
            a = s["axes"].get(axis)
            if a is None:
                continue
            who = f" — {esc(label)}" if len(summaries) > 1 else ""
            verdict = verdict_line(a["verdict"], a["signed"]) if "verdict" in a else "—"
            # is k* decided? report.md's "k* status" row and the index's k* cell say so; so does the page
            st = a.get("kstar_status") or {}
            status = "; ".join(
                f"{'+' if d == 'pos' else '−'}: {st[d]['text']}" for d in ("pos", "neg") if d in st
            )
            body.append(
                f'<div class="verdict"><h3>Axis <code>{esc(axis)}</code>{who}</h3>'
                f"<p><b>k*</b> (first level with success &lt; γ = {esc(s['gamma'])}): {esc(kstar_text(a))}</p>"
                + (f"<p><b>k* status</b>: {esc(status)}</p>" if status else "")
                + f"<p><b>verdict</b>: {esc(verdict)}</p>"
                f'<p class="note">{esc(pooled_text(a.get("pooled_tasks") or []))}; success with {esc(ci_name(s["ci"]))} '
                "95 % CI; n = finished episodes (errors counted beside it); one run: nothing is paired here "
                "(indgen compare pairs runs).</p>"
                f"{_level_rows(a, (units or {}).get(axis) or '')}</div>"
            )
    return Section("verdicts", "Verdicts", "".join(body))


def plots_section(plots: Path, missing: str = "no plots yet") -> Section:
    """Every PNG under ``plots``, the all-axes overview first, inlined; an axis's SVG headline curve where its PNG is
    not drawn (a run's own report: ``indgen report RUN`` draws the rest)."""
    plots = Path(plots)
    pngs = list(plots.glob("*.png")) if plots.is_dir() else []
    drawn = {p.stem for p in pngs}
    svgs = [p for p in plots.glob("*.svg") if p.stem not in drawn] if plots.is_dir() else []
    files = sorted(pngs + svgs, key=lambda p: (p.name != AXES_PLOT, p.name))
    figs = "".join(image_html(p, p.stem) for p in files)
    if svgs:
        figs += (f'<p class="note">The success curve only; <code>indgen report {esc(plots.parent)}</code> draws every '
                 "plot (failure modes, stage shares, all axes, grids) as PNG.</p>")  # fmt: skip
    return Section("plots", "Plots", figs or f'<p class="note">{esc(missing)}</p>')


def preview_section(run_path: Path, manifest: Mapping[str, Any], axes: Sequence[str]) -> Section:
    """The level preview sheets of the run (what the policy sees at t = 0 per level), or the command that makes them
    (a real run: the operator's protocol instead; ``indgen preview`` renders simulated scenes only)."""
    sheets = sorted((run_path / PREVIEW_DIR).glob("*.png")) if (run_path / PREVIEW_DIR).is_dir() else []
    if sheets:
        return Section("preview", "Level preview", "".join(image_html(p, f"t = 0 at each level: {p.stem}")
                                                             for p in sheets))  # fmt: skip
    if manifest.get("real"):
        return Section("preview", "Level preview", '<p class="note">A real-robot run: each level\'s set-up is in '
                       '<a href="protocol.md">protocol.md</a> (the operator\'s sheet); there is no simulated '
                       "preview.</p>")  # fmt: skip
    levels = (manifest.get("plan") or {}).get("levels") or {}
    cmds = []
    for axis in axes:
        lv = levels.get(axis) or []
        span = f" --levels {min(lv)}:{max(lv)}" if lv else ""
        cmds.append(f"indgen preview --scene {manifest.get('scene', 'SCENE')} --axis {axis}{span} "
                    f"--out {run_path}/{PREVIEW_DIR}/{axis}.png")  # fmt: skip
    hint = "".join(f"<pre><code>{esc(c)}</code></pre>" for c in cmds)
    return Section("preview", "Level preview", "<p class=\"note\">No preview sheet in this run. Make one (seconds, no "
                   f"policy), then re-run <code>indgen report {esc(run_path)}</code>:</p>{hint}")  # fmt: skip


def videos_section(run_path: Path, rows: Sequence[Mapping[str, Any]], real: bool = False) -> Section:
    """Example videos per axis and level, successes beside failures (runs made with --video; a real run's verdicts
    recorded with a video)."""
    cells: dict[tuple, dict[bool, list]] = {}
    for r in rows:
        if r.get("video") and (run_path / str(r["video"])).is_file():
            cells.setdefault((r["axis"], int(r["level"])), {True: [], False: []})[bool(r["success"])].append(
                r
            )
    if not cells:
        how = ("indgen real record --video PATH or --video-pattern attaches one to each verdict" if real else
               "evaluate with --video records some per level")  # fmt: skip
        return Section("videos", "Example videos", f'<p class="note">No videos in this run ({how}).</p>')
    head = "<tr><th>axis</th><th>level</th><th>success</th><th>failure</th></tr>"
    out = []
    for (axis, level), by in sorted(cells.items()):
        tds = []
        for outcome in (True, False):
            vids = by[outcome][:VIDEOS_PER_OUTCOME]
            tds.append("".join(video_html(str(v["video"]), f"{v['task']} ep {v['episode']}"
                                          + ("" if outcome else f" ({v.get('failure') or 'failure'})"))
                               for v in vids) or '<span class="note">none</span>')  # fmt: skip
        out.append(f"<tr><td>{esc(axis)}</td><td>{level}</td><td>{tds[0]}</td><td>{tds[1]}</td></tr>")
    return Section("videos", "Example videos", f"<table>{head}{''.join(out)}</table>")


def failures_section(summaries: Sequence[tuple[str, Mapping[str, Any]]], order: Sequence[str],
                     real: bool = False) -> Section:  # fmt: skip
    """Per run and axis, episodes per failure mode at each level (``none`` = success; modes that occur only); who
    classified them: the scene, or a real run's operator."""
    out = []
    for axis in order:
        for label, s in summaries:
            a = s["axes"].get(axis)
            if a is None:
                continue
            used = [m for m in MODES if any(r.get("failures", {}).get(m) for r in a["levels"])]
            if not used:
                continue
            head = "<tr><th>level</th>" + "".join(f"<th>{esc(m)}</th>" for m in used) + "</tr>"
            body = "".join(
                f"<tr><td>{r['level']}</td>" + "".join(f"<td>{r.get('failures', {}).get(m, 0)}</td>" for m in used)
                + "</tr>" for r in a["levels"]
            )  # fmt: skip
            who = f" — {esc(label)}" if len(summaries) > 1 else ""
            out.append(f"<h3>Axis <code>{esc(axis)}</code>{who}</h3><table>{head}{body}</table>")
    text = "".join(out) or '<p class="note">No failure modes classified in this run.</p>'
    who = ("given by the operator with each verdict (<code>unclassified</code>: a failure without a mode)" if real
           else "classified by the scene from simulator state the policy never sees")  # fmt: skip
    return Section("failures", "Failure modes", f'{text}<p class="note">Modes are {who}; <code>none</code> = '
                   "success.</p>")  # fmt: skip


def episode_rows(episodes) -> list[dict[str, Any]]:
    """The episodes table's rows (``RunDir.episodes()`` as plain dicts; missing progress shown empty)."""
    columns = []
    for c in EPISODE_COLUMNS:
        values, missing = episodes[c].tolist(), episodes[c].isna().tolist()  # column-wise: 10,000s of rows
        columns.append([None if m else v for v, m in zip(values, missing, strict=True)])
    return [dict(zip(EPISODE_COLUMNS, row, strict=True)) for row in zip(*columns, strict=True)]


def episodes_section(rows: Sequence[Mapping[str, Any]]) -> Section:
    """Every episode of the run, one table row each, sortable and filterable; a video cell links its file."""
    shown = [{**r, "_href": r.get("video") or "", "video": "video" if r.get("video") else ""} for r in rows]
    table = table_html("episodes", EPISODE_COLUMNS, shown, links={"video": "_href"})
    return Section("episodes", f"Episodes ({len(rows)})", table)


def run_page_sections(run_path: Path, manifest: Mapping[str, Any], summary: Mapping[str, Any], episodes,
                      markdown: str, label: str, order: Sequence[str]) -> list[Section]:  # fmt: skip
    """Every section of one run's page, verdicts first."""
    rows = episode_rows(episodes)
    one = [(label, summary)]
    axes = manifest.get("axes") or {}
    units = {ax: str(spec.get("unit") or "") for ax, spec in axes.items() if isinstance(spec, Mapping)}
    return [
        verdict_section(one, order, units),
        plots_section(run_path / "plots"),
        preview_section(run_path, manifest, order),
        videos_section(run_path, rows, bool(manifest.get("real"))),
        failures_section(one, order, bool(manifest.get("real"))),
        episodes_section(rows),
        Section("report", "Full report (report.md)", markdown_html(markdown)),
    ]


def _subtitle(manifest: Mapping[str, Any]) -> str:
    plan = manifest.get("plan") or {}
    tasks = ", ".join(plan.get("tasks") or []) or "?"
    parts = [f"policy {manifest.get('policy', '?')}", f"scene {manifest.get('scene', '?')}", f"tasks {tasks}",
             f"created {manifest.get('created', '?')}"]  # fmt: skip
    if manifest.get("measurement"):
        parts.append(str(manifest["measurement"]))
    return " · ".join(parts)


def write_run_html(run_path: Path, manifest: Mapping[str, Any], summary: Mapping[str, Any], episodes,
                   markdown: str, label: str, order: Sequence[str]) -> Path:  # fmt: skip
    """``RUN/report.html``: the run's page (see the module docstring); returns its path."""
    sections = run_page_sections(Path(run_path), manifest, summary, episodes, markdown, label, order)
    return write_page(Path(run_path) / HTML_REPORT, f"Report: {label}", sections, _subtitle(manifest))


def write_overlay_html(out: Path, summaries: Sequence[tuple[str, Mapping[str, Any]]], markdown: str,
                       order: Sequence[str]) -> Path:  # fmt: skip
    """``indgen report RUN RUN...``'s overlay page: each run's verdicts side by side (not compared), the overlay
    plots, failure modes and the overlay report.md."""
    sections = [
        verdict_section(summaries, order),
        plots_section(Path(out) / "plots"),
        failures_section(summaries, order),
        Section("report", "Full report (report.md)", markdown_html(markdown)),
    ]
    return write_page(Path(out) / HTML_REPORT, "Inductive generalization: run comparison", sections,
                      "side by side, not compared: indgen compare tests the difference")  # fmt: skip
