"""The headline figure without matplotlib: one axis's success against level as a small SVG, written in about a
millisecond so that the report at a run's end stays off its critical path (``indgen report`` draws the PNG set)."""

from __future__ import annotations

import textwrap
from collections.abc import Mapping
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape

from indgen_vla.core.reporting.figures import NO_RATE, curve_note
from indgen_vla.core.runs.records import atomic_write_text
from indgen_vla.core.stats.metrics import ci_name, usable_rows

W, H = 560, 360  # px; the plot area's margins below
LEFT, RIGHT, TOP, BOTTOM = 52, 16, 40, 58
COLOUR = "#1f77b4"  # matplotlib's C0, as the PNG draws a single run
CAPTION_CHARS = 95  # a caption line's characters at font-size 10 (about 5.6 px each) within the 560 px width


def axis_svg(label: str, a: Mapping[str, Any], axis: str, gamma: float, ci: str = "") -> str:
    """Success vs level of one axis of one run: points joined, the 95 % CI band, the γ line, k* ringed, n per level
    and the tasks pooled in the caption; levels without enough data are not drawn (as ``figures.plot_axis``)."""
    rows = usable_rows(a["levels"])
    levels = sorted({int(r["level"]) for r in rows or a["levels"]}) or [0]  # none usable: the levels run
    if a.get("signed"):
        m = max(abs(k) for k in levels)
        lo, hi = -m - 0.5, m + 0.5
    else:
        lo, hi = min(levels) - 0.5, max(levels) + 0.5
    note = curve_note([a])
    caption = textwrap.wrap(f"{label} ({note})" if note else label, CAPTION_CHARS) + textwrap.wrap(
        f"shaded: {ci_name(ci) + ' ' if ci else ''}95 % CI; dashed: γ = {gamma}; ringed: k* (first level "
        "below γ)", CAPTION_CHARS)  # fmt: skip
    height = H + 13 * (len(caption) - 1)  # one line more per caption line: a long label wraps, never clips
    pw, ph = W - LEFT - RIGHT, H - TOP - BOTTOM

    def x(k: float) -> float:
        return round(LEFT + (k - lo) / (hi - lo) * pw, 1)

    def y(v: float) -> float:
        return round(TOP + (1.03 - v) / 1.06 * ph, 1)

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{height}" viewBox="0 0 {W} {height}" '
           'font-family="DejaVu Sans, Arial, sans-serif" font-size="11">',
           f'<rect width="{W}" height="{height}" fill="white"/>',
           f'<text x="{W / 2}" y="20" text-anchor="middle" font-size="13">{escape(axis)}</text>']  # fmt: skip
    for v in (0, 0.2, 0.4, 0.6, 0.8, 1.0):  # grid and y ticks
        out.append(f'<line x1="{LEFT}" x2="{W - RIGHT}" y1="{y(v)}" y2="{y(v)}" stroke="#ddd"/>'
                   f'<text x="{LEFT - 6}" y="{y(v) + 4}" text-anchor="end">{v:.1f}</text>')  # fmt: skip
    for k in levels:
        out.append(f'<line x1="{x(k)}" x2="{x(k)}" y1="{TOP}" y2="{TOP + ph}" stroke="#eee"/>'
                   f'<text x="{x(k)}" y="{TOP + ph + 16}" text-anchor="middle">{k}</text>')  # fmt: skip
    if a.get("signed") and lo < 0 < hi:
        out.append(f'<line x1="{x(0)}" x2="{x(0)}" y1="{TOP}" y2="{TOP + ph}" stroke="#999"/>')
    out.append(f'<rect x="{LEFT}" y="{TOP}" width="{pw}" height="{ph}" fill="none" stroke="#333"/>')
    if not rows:
        out += [f'<text x="{LEFT + pw / 2}" y="{TOP + ph / 2 + 14 * i}" text-anchor="middle" fill="dimgrey">'
                f"{escape(line)}</text>" for i, line in enumerate(NO_RATE.split("\n"))]  # fmt: skip
    if rows:
        band = [(x(r["level"]), y(r["ci_high"])) for r in rows] + [
            (x(r["level"]), y(r["ci_low"])) for r in reversed(rows)
        ]
        out.append(f'<polygon points="{_pts(band)}" fill="{COLOUR}" fill-opacity="0.18"/>')
        out.append(f'<polyline points="{_pts((x(r["level"]), y(r["rate"])) for r in rows)}" fill="none" '
                   f'stroke="{COLOUR}" stroke-width="1.5"/>')  # fmt: skip
        out += [f'<circle cx="{x(r["level"])}" cy="{y(r["rate"])}" r="3" fill="{COLOUR}"/>' for r in rows]
    out.append(f'<line x1="{LEFT}" x2="{W - RIGHT}" y1="{y(gamma)}" y2="{y(gamma)}" stroke="grey" '
               'stroke-dasharray="5,3"/>')  # fmt: skip
    rate = {r["level"]: r["rate"] for r in rows}
    for k in (a.get("break_level") or {}).values():  # "undetermined" or None: nothing to mark
        if isinstance(k, int) and k in rate:
            out.append(f'<circle cx="{x(k)}" cy="{y(rate[k])}" r="7" fill="none" stroke="{COLOUR}" '
                       'stroke-width="1.5"/>')  # fmt: skip
    out.append(f'<text x="{LEFT + pw / 2}" y="{TOP + ph + 32}" text-anchor="middle">level k along '
               f"{escape(axis)}</text>")  # fmt: skip
    out.append(f'<text transform="translate(14 {TOP + ph / 2}) rotate(-90)" text-anchor="middle">success rate'
               "</text>")  # fmt: skip
    out += [f'<text x="{W / 2}" y="{TOP + ph + 50 + 13 * i}" text-anchor="middle" font-size="10">{escape(line)}'
            "</text>" for i, line in enumerate(caption)]  # fmt: skip
    out.append("</svg>")
    return "\n".join(out) + "\n"


def _pts(points) -> str:
    return " ".join(f"{px},{py}" for px, py in points)


def write_axis_svg(
    label: str, a: Mapping[str, Any], axis: str, gamma: float, path: Path, ci: str = ""
) -> Path:
    """``axis_svg`` written atomically to ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, axis_svg(label, a, axis, gamma, ci))
    return path
