"""Self-contained HTML pages (inline CSS and JS, images as data URIs): what every report.html is built from.

A page is a title and a list of ``Section``s; nothing in it points outside the page's own folder, so it opens from
``file://`` and offline. Other writers (a checkpoint series, a gate) build their pages with ``Section``,
``markdown_html``, ``image_html``, ``table_html`` and ``write_page``.
"""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from indgen_vla.core.runs.records import atomic_write_text

HTML_REPORT = "report.html"
IMAGE_TYPES = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".svg": "image/svg+xml"}

CSS = """
:root{--fg:#1d2330;--muted:#5b6475;--line:#dde1e8;--bg:#fff;--soft:#f5f7fa;--ok:#2e7d32;--bad:#c62828;--acc:#1f5fbf}
*{box-sizing:border-box}
body{margin:0;font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:var(--fg);background:var(--bg)}
header{padding:14px 24px;border-bottom:1px solid var(--line);background:var(--soft)}
header h1{margin:0;font-size:20px}
header p{margin:4px 0 0;color:var(--muted)}
nav{padding:6px 24px;border-bottom:1px solid var(--line);position:sticky;top:0;background:var(--bg);z-index:2;
white-space:nowrap;overflow-x:auto}
nav a{margin-right:14px;color:var(--acc);text-decoration:none;font-size:13px}
main{padding:8px 24px 40px;max-width:1400px}
section{margin:18px 0 26px;scroll-margin-top:44px}
section>h2{font-size:17px;border-bottom:2px solid var(--line);padding-bottom:4px}
h3{font-size:15px;margin:16px 0 6px}h4{font-size:14px;margin:14px 0 6px}
header,main{overflow-wrap:break-word}
table{border-collapse:collapse;margin:8px 0;font-size:13px}
main table:not(.sortable){display:block;max-width:100%;overflow-x:auto}
table.levels td{white-space:nowrap}
th,td{border:1px solid var(--line);padding:3px 8px;text-align:left;vertical-align:top}
th{background:var(--soft)}
code{background:var(--soft);padding:0 3px;border-radius:3px}
pre{max-width:100%;overflow-x:auto}
.verdict{border-left:4px solid var(--acc);background:var(--soft);padding:8px 12px;margin:10px 0}
.verdict p{margin:4px 0}
.note{color:var(--muted)}
.caveat{border-left:4px solid var(--bad);padding:6px 12px;margin:8px 0;background:#fff5f5}
.ok{color:var(--ok);font-weight:600}.bad{color:var(--bad);font-weight:600}
figure{display:inline-block;margin:6px 12px 12px 0;vertical-align:top}
figure img{max-width:100%;border:1px solid var(--line)}
figcaption{color:var(--muted);font-size:12px}
video{width:256px;border:1px solid var(--line);background:#000}
.tablebar{margin:8px 0}
.tablebar input{width:480px;max-width:100%;padding:4px 6px;font:inherit}
table.sortable th{cursor:pointer;user-select:none;white-space:nowrap}
table.sortable th[aria-sort=ascending]::after{content:" \\25B2"}
table.sortable th[aria-sort=descending]::after{content:" \\25BC"}
.scroll{max-height:640px;overflow:auto;display:inline-block;max-width:100%}
.scroll table{margin:0}.scroll th{position:sticky;top:0}
#runs td:nth-child(2),#runs td:nth-child(8),#runs td:nth-child(10){white-space:nowrap}
"""

# sortable, filterable tables: click a header to sort (numbers as numbers); the box keeps rows whose text holds
# every word, and a word "column=value" keeps rows whose cell in that column equals value
JS = """
(function(){
function key(td){var v=td.textContent.trim(),f=parseFloat(v);return (v!==''&&isFinite(v))?[0,f]:[1,v.toLowerCase()];}
function cmp(a,b){if(a[0]!==b[0])return a[0]-b[0];return a[1]<b[1]?-1:a[1]>b[1]?1:0;}
document.querySelectorAll('table.sortable').forEach(function(t){
 var heads=t.tHead.rows[0].cells,body=t.tBodies[0];
 Array.prototype.forEach.call(heads,function(th,i){th.addEventListener('click',function(){
  var asc=th.getAttribute('aria-sort')!=='ascending';
  Array.prototype.forEach.call(heads,function(h){h.removeAttribute('aria-sort');});
  th.setAttribute('aria-sort',asc?'ascending':'descending');
  var rows=Array.prototype.slice.call(body.rows);
  rows.sort(function(a,b){var c=cmp(key(a.cells[i]),key(b.cells[i]));return asc?c:-c;});
  rows.forEach(function(r){body.appendChild(r);});});});
 var box=document.getElementById(t.id+'-filter'),count=document.getElementById(t.id+'-count');
 if(!box)return;
 var names=Array.prototype.map.call(heads,function(h){return h.textContent.trim().toLowerCase();});
 box.addEventListener('input',function(){
  var words=box.value.toLowerCase().split(/\\s+/).filter(Boolean),shown=0;
  Array.prototype.forEach.call(body.rows,function(r){
   var text=r.textContent.toLowerCase(),ok=words.every(function(w){var eq=w.indexOf('=');
    if(eq>0){var c=names.indexOf(w.slice(0,eq));
     if(c>=0)return r.cells[c].textContent.trim().toLowerCase()===w.slice(eq+1);}
    return text.indexOf(w)>=0;});
   r.style.display=ok?'':'none';if(ok)shown++;});
  count.textContent=shown+' of '+body.rows.length+' rows';});});
})();
"""


@dataclass(frozen=True)
class Section:
    """One titled part of a page; ``body`` is HTML that this module or its caller escaped."""

    id: str
    title: str
    body: str

    def __post_init__(self) -> None:
        if not self.id or not all(c.isalnum() or c in "-_" for c in self.id):
            raise ValueError(f"section id must be letters, digits, - or _, got {self.id!r}")


def esc(value: object) -> str:
    """Text as HTML (quotes too, so it is safe inside attributes)."""
    return html.escape("" if value is None else str(value), quote=True)


def markdown_html(text: str) -> str:
    """Markdown (headings, tables, lists, emphasis, code) as HTML; raw HTML in the text is shown, not run."""
    from markdown_it import MarkdownIt

    out = MarkdownIt("commonmark", {"html": False}).enable("table").render(text)
    return re.sub(
        r"<(/?)h([12])>", lambda m: f"<{m.group(1)}h{int(m.group(2)) + 2}>", out
    )  # under the page's h2


def image_html(path: Path, caption: str = "") -> str:
    """An image file inlined as a data URI in a captioned figure ("" when the file is not there)."""
    path = Path(path)
    kind = IMAGE_TYPES.get(path.suffix.lower())
    if kind is None or not path.is_file():
        return ""
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    cap = f"<figcaption>{esc(caption)}</figcaption>" if caption else ""
    return f'<figure><img alt="{esc(caption or path.stem)}" src="data:{kind};base64,{data}">{cap}</figure>'


def video_html(relative: str, caption: str) -> str:
    """An episode video by its path relative to the page (videos can be large: linked, not inlined)."""
    return (
        f'<figure><video controls preload="metadata" src="{esc(relative)}"></video>'
        f'<figcaption><a href="{esc(relative)}">{esc(caption)}</a></figcaption></figure>'
    )


def _cell(v: object) -> str:
    """A table cell's text: floats to 6 significant digits, numbers and booleans as is, text escaped."""
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v) if isinstance(v, int) else esc(v)  # bool is an int


def table_html(
    table_id: str,
    columns: Sequence[str],
    rows: Sequence[Mapping[str, object]],
    *,
    links: Mapping[str, str] | None = None,
    filterable: bool = True,
    example: str = "level=2 success=false",
) -> str:
    """A sortable (and with ``filterable`` filterable) table; ``links`` maps a column to the row key holding its
    href (a relative path). Cells that read as numbers sort as numbers. ``example``: a filter on this table's own
    columns, shown in the empty box."""
    links = links or {}
    head = "".join(f"<th>{esc(c)}</th>" for c in columns)
    body = []
    for row in rows:
        cells = []
        for c in columns:
            text = _cell(row.get(c))
            if c in links and row.get(links[c]):
                text = f'<a href="{esc(row[links[c]])}">{text}</a>'
            cells.append(f"<td>{text}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    bar = ""
    if filterable:
        bar = (
            f'<div class="tablebar"><input id="{table_id}-filter" type="search" placeholder="filter: words, or '
            f'column=value (e.g. {esc(example)})"> <span id="{table_id}-count" class="note">{len(rows)} '
            "rows</span></div>"
        )
    return (
        f'{bar}<div class="scroll"><table id="{table_id}" class="sortable"><thead><tr>{head}</tr></thead>'
        f"<tbody>{''.join(body)}</tbody></table></div>"
    )


def render_page(
    title: str, sections: Sequence[Section], subtitle: str = "", refresh_s: int | None = None
) -> str:
    """The whole page: header, a link per section, the sections in order, the table script."""
    refresh = f'<meta http-equiv="refresh" content="{int(refresh_s)}">' if refresh_s else ""
    nav = "".join(f'<a href="#{s.id}">{esc(s.title)}</a>' for s in sections)
    body = "".join(f'<section id="{s.id}"><h2>{esc(s.title)}</h2>{s.body}</section>' for s in sections)
    sub = f"<p>{esc(subtitle)}</p>" if subtitle else ""
    return (
        f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">{refresh}'
        f'<meta name="viewport" content="width=device-width, initial-scale=1"><title>{esc(title)}</title>'
        '<link rel="icon" href="data:,">'  # no favicon request: a served page makes none that fails
        f"<style>{CSS}</style></head><body><header><h1>{esc(title)}</h1>{sub}</header><nav>{nav}</nav>"
        f"<main>{body}</main><script>{JS}</script></body></html>\n"
    )


def write_page(path: Path, title: str, sections: Sequence[Section], subtitle: str = "") -> Path:
    """Write ``render_page`` atomically to ``path`` (e.g. a series' ``report.html``); returns ``path``."""
    atomic_write_text(Path(path), render_page(title, sections, subtitle))
    return Path(path)


def markdown_page(out_dir: Path, title: str, markdown: str, verdicts: Sequence[str] = (), plots: Path | None = None,
                  extra: Sequence[Section] = (), caveats: Sequence[str] = ()) -> Path:  # fmt: skip
    """``out_dir/report.html`` from a Markdown report: its caveats (what it cannot answer) and verdict lines first,
    the plots under ``plots`` (every PNG, inlined), ``extra`` sections, then the Markdown itself. The hook for series
    and gate pages."""
    sections = []
    if verdicts or caveats:
        body = "".join(f'<div class="caveat">{markdown_html(c)}</div>' for c in caveats)
        body += "".join(f'<div class="verdict">{markdown_html(v)}</div>' for v in verdicts)
        sections.append(Section("verdicts", "Verdicts", body))
    if plots is not None and Path(plots).is_dir():
        figs = "".join(image_html(p, p.stem) for p in sorted(Path(plots).glob("*.png")))
        if figs:
            sections.append(Section("plots", "Plots", figs))
    sections += list(extra)
    sections.append(Section("report", "Full report", markdown_html(markdown)))
    return write_page(Path(out_dir) / HTML_REPORT, title, sections)
