"""HTML building blocks of the report page: escaping, tables, inline SVG charts, the CSS.

Charts are hand-written inline SVG (bars and histograms), so the page needs no script, no
network and no image files; every string from a store is escaped."""

from __future__ import annotations

import html
import json
import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

CSS = """
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,"DejaVu Sans",sans-serif;
 margin:0;color:#1d2733;background:#f4f6f9}
header{background:#1d3557;color:#fff;padding:18px 32px}
header h1{margin:0 0 4px;font-size:24px} header p{margin:0;opacity:.85}
main{padding:8px 32px 40px;max-width:1280px}
section{background:#fff;border-radius:8px;padding:12px 20px 16px;margin:16px 0;
 box-shadow:0 1px 3px rgba(0,0,0,.08)}
h2{font-size:18px;margin:4px 0 10px;color:#1d3557} h3{font-size:15px;margin:12px 0 6px}
table{border-collapse:collapse;font-size:13px;margin:4px 0}
th,td{padding:3px 10px;border-bottom:1px solid #e3e7ee;text-align:left;vertical-align:top}
th{background:#eef2f7;font-weight:600;white-space:nowrap}
td.num{text-align:right;font-variant-numeric:tabular-nums}
code,.mono{font-family:"DejaVu Sans Mono",Menlo,Consolas,monospace;font-size:12px}
.cards{display:grid;grid-template-columns:repeat(auto-fill,minmax(120px,1fr));gap:12px}
.card{background:#eef2f7;border-radius:8px;padding:8px 16px;min-width:0;overflow-wrap:anywhere}
.card .v{font-size:22px;font-weight:700;color:#1d3557} .card .k{font-size:12px;color:#56657a}
.grid{display:flex;flex-wrap:wrap;gap:24px} .grid>div{min-width:220px}
.bad{color:#b00020;font-weight:600} .ok{color:#2a7a2a} .muted{color:#6b7785}
.gallery{display:grid;grid-template-columns:repeat(auto-fill,minmax(min(560px,100%),1fr));gap:12px}
figure{margin:8px 0} figure img{max-width:100%;border:1px solid #e3e7ee}
figcaption{font-size:12px;color:#56657a}
details summary{cursor:pointer;color:#1d3557}
section{overflow-x:auto}
@media (max-width:600px){
 header{padding:12px 14px} header h1{font-size:20px} main{padding:4px 8px 24px}
 section{padding:8px 10px 12px;margin:10px 0}
 .cards{grid-template-columns:repeat(2,minmax(0,1fr));gap:8px}
 .card{padding:6px 10px} .card .v{font-size:18px} .grid>div{min-width:0}
}
"""

BAR_COLOUR = "#457b9d"
HIST_COLOUR = "#e76f51"


def esc(value: Any) -> str:
    """Text for HTML, escaped."""
    return html.escape(str(value), quote=True)


def number(value: Any) -> str:
    """A number as text: ints as is, floats in ``%g`` with 4 significant digits, NaN as —."""
    if isinstance(value, bool) or value is None:
        return esc(value)
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        if math.isnan(value):
            return "—"
        return f"{float(value):.4g}"
    return esc(value)


def table(
    header: Sequence[str],
    rows: Iterable[Sequence[Any]],
    numeric: set[int] | None = None,
    raw: bool = False,
) -> str:
    """An HTML table; cells are escaped unless ``raw`` (already HTML); columns in ``numeric``
    are right-aligned."""
    numeric = numeric or set()
    head = "".join(f"<th>{esc(h)}</th>" for h in header)
    body = []
    for row in rows:
        cells = []
        for i, cell in enumerate(row):
            text = str(cell) if raw else esc(cell)
            cls = ' class="num"' if i in numeric else ""
            cells.append(f"<td{cls}>{text}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def bar_chart(
    counts: dict[Any, int],
    title: str,
    width: int = 320,
    bar_h: int = 16,
    info_prefix: str | None = None,
) -> str:
    """Horizontal bars, one per key, with its count written at the bar's end. With
    ``info_prefix``, each count's text carries ``data-info="<prefix>.<key>"``: the
    ``info --json`` field it shows."""
    if not counts:
        return f'<p class="muted">{esc(title)}: none</p>'
    label_w = min(150, 14 + 8 * max(len(_shown(k)) for k in counts))
    top = max(counts.values()) or 1
    span = width - label_w - 40
    height = bar_h * len(counts) + 4
    parts = [f'<svg width="{width}" height="{height}" role="img" aria-label="{esc(title)}">']
    for i, (key, n) in enumerate(counts.items()):
        y = 2 + i * bar_h
        w = max(1.0, span * n / top)
        parts.append(
            f'<text x="{label_w - 6}" y="{y + bar_h - 4}" text-anchor="end" font-size="11">'
            f"{esc(_shown(key))}</text>"
            f'<rect x="{label_w}" y="{y + 2}" width="{w:.1f}" height="{bar_h - 4}" '
            f'fill="{BAR_COLOUR}"/>'
            f'<text x="{label_w + w + 4:.1f}" y="{y + bar_h - 4}" font-size="11"'
            f"{_info_attr(info_prefix, key)}>{n}</text>"
        )
    parts.append("</svg>")
    return f"<div><h3>{esc(title)}</h3>{''.join(parts)}</div>"


def _shown(key: Any) -> str:
    """A count's label: the key, or "(none)" for a missing value."""
    return "(none)" if key is None else str(key)


def json_key(key: Any) -> str:
    """``key`` as ``json.dumps`` writes it as an object key (None → "null"), so data-info
    names the field exactly as ``info --json`` prints it."""
    return next(iter(json.loads(json.dumps({key: 0}))))


def _info_attr(prefix: str | None, key: Any) -> str:
    return f' data-info="{esc(prefix)}.{esc(json_key(key))}"' if prefix else ""


def histogram_svg(
    counts: np.ndarray,
    edges: np.ndarray,
    width: int = 180,
    height: int = 42,
    colour: str = HIST_COLOUR,
    label: str = "",
) -> str:
    """A small histogram: bars of ``counts`` over ``edges``, min and max written below."""
    if counts is None or len(counts) == 0:
        return '<span class="muted">no finite values</span>'
    top = float(max(counts.max(), 1))
    plot_h = height - 12
    bar_w = width / len(counts)
    rects = []
    for i, n in enumerate(counts):
        if n <= 0:
            continue
        h = max(1.0, plot_h * float(n) / top)
        rects.append(
            f'<rect x="{i * bar_w:.2f}" y="{plot_h - h:.2f}" width="{max(bar_w - 0.5, 0.5):.2f}"'
            f' height="{h:.2f}" fill="{colour}"/>'
        )
    lo, hi = number(float(edges[0])), number(float(edges[-1]))
    return (
        f'<svg width="{width}" height="{height}" role="img" aria-label="{esc(label)}">'
        f"{''.join(rects)}"
        f'<line x1="0" y1="{plot_h}" x2="{width}" y2="{plot_h}" stroke="#999" stroke-width="0.5"/>'
        f'<text x="0" y="{height - 1}" font-size="9" fill="#555">{lo}</text>'
        f'<text x="{width}" y="{height - 1}" font-size="9" fill="#555" text-anchor="end">{hi}'
        "</text></svg>"
    )


def card(key: str, value: Any, info_key: str | None = None) -> str:
    """A big number with its label; ``info_key`` names the ``info --json`` field it shows."""
    attr = f' data-info="{esc(info_key)}"' if info_key else ""
    shown = esc(value) if info_key else number(value)  # info values verbatim, as --json has them
    return (
        f'<div class="card"><div class="v"{attr}>{shown}</div><div class="k">{esc(key)}</div></div>'
    )


def page(title: str, subtitle: str, sections: list[str]) -> str:
    """The whole document: inline CSS, no scripts, no external references."""
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{esc(title)}</title>"
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<style>{CSS}</style></head><body>"
        f"<header><h1>{esc(title)}</h1><p>{esc(subtitle)}</p></header>"
        f"<main>{''.join(sections)}</main></body></html>\n"
    )


def link(href: str, text: str) -> str:
    """A link to a file next to the page (relative ``href``)."""
    return f'<a href="{esc(href)}">{esc(text)}</a>'


def section(anchor: str, title: str, body: str) -> str:
    return f'<section id="{esc(anchor)}"><h2>{esc(title)}</h2>{body}</section>'
