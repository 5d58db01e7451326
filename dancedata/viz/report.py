"""The store's dataset card: one self-contained HTML page (``dancedata report``).

    from dancedata.viz.report import build_report
    html = build_report("data/stores/aist-demo")          # latest version
    open("card.html", "w").write(html)

What it shows, for one version: the version lineage (command, parent, time, fingerprint,
stage fingerprints, config), counts per split, genre, tempo, dancer and source, durations,
the inputs skipped with their reasons, every array's value distribution with NaN, Inf and
out-of-range counts (:mod:`dancedata.viz.report_stats`), and a small gallery of sequence
figures (:mod:`dancedata.viz.plot`).

The headline numbers come from :func:`dancedata.store.summary.summarize`, the function behind
``dancedata info --json``, and are written verbatim; each such element carries
``data-info="<key>"`` (dotted for nested keys, e.g. ``genres.gBR``) naming the field it shows.
Images are inline (gallery PNGs as base64, charts as SVG), CSS is inline, and there is no
script and no external reference, so the page opens offline and can be mailed as one file.
"""

from __future__ import annotations

import base64
import io
import json
import os
import time
from pathlib import Path
from typing import Any

from dancedata._version import __version__
from dancedata.errors import DancedataError, InputError
from dancedata.store.backend import StoreBackend
from dancedata.store.reader import _VersionReader
from dancedata.store.summary import lineage, summarize
from dancedata.viz import report_html as h
from dancedata.viz.plot_data import read_keyframes
from dancedata.viz.report_counts import (
    count_by,
    duration_histogram,
    duration_summary,
    sequence_durations,
)
from dancedata.viz.report_stats import ArrayStats, array_stats


def _overview(info: dict[str, Any]) -> str:
    cards = [h.card("version", info["version"], "version")]
    for label, key in (
        ("sequences", "sequences"),
        ("motion frames", "frames"),
        ("hours of motion", "hours"),
        ("music tracks", "music_tracks"),
        ("measures", "measures"),
        ("inputs skipped", "skipped"),
    ):
        if key in info:
            cards.append(h.card(label, info[key], key))
    cards.append(h.card("committed versions", len(info["versions"])))
    latest = info["latest"]
    note = (
        ""
        if latest == info["version"]
        else f'<p class="bad">This page shows {h.esc(info["version"])}; the latest version is '
        f"{h.esc(latest)}.</p>"
    )
    missing = {k: n for k, n in (info.get("annotations_missing") or {}).items() if n}
    if missing:
        note += (
            "<p>Sequences lacking an annotation kind: "
            + ", ".join(
                f'{h.esc(k)} <span data-info="annotations_missing.{h.esc(k)}">{n}</span>'
                for k, n in missing.items()
            )
            + "</p>"
        )
    tables = info.get("tables") or {}
    if tables:
        note += (
            "<p>Tables (rows): "
            + ", ".join(
                f'<code>{h.esc(name)}</code> <span data-info="tables.{h.esc(name)}">{rows}</span>'
                for name, rows in tables.items()
            )
            + f"; {len(info.get('arrays') or {})} arrays (see feature distributions).</p>"
        )
    if info.get("audio_truncated_sequences"):
        note += (
            '<p class="muted">Music longer than the motion (cut off) in '
            f'<span data-info="audio_truncated_sequences">{info["audio_truncated_sequences"]}'
            "</span> sequences.</p>"
        )
    return h.section("overview", "Overview", f'<div class="cards">{"".join(cards)}</div>{note}')


def _lineage(chain: list[dict[str, Any]]) -> str:
    rows = []
    details = []
    for m in chain:
        stages = m.get("stages") or {}
        rows.append(
            [
                h.esc(m.get("version")),
                f"<code>dancedata {h.esc(m.get('command'))}</code>",
                h.esc(m.get("parent") or "—"),
                h.esc(m.get("created_at")),
                f'<span class="mono">{h.esc(m.get("fingerprint", ""))}</span>',
                "<br>".join(
                    f'{h.esc(k)} <span class="mono">{h.esc(str(v)[:12])}</span>'
                    for k, v in stages.items()
                ),
                str(len(m.get("skipped") or [])),
            ]
        )
        config = json.dumps(m.get("config", {}), indent=1, sort_keys=True, default=str)
        libraries = ", ".join(f"{k} {v}" for k, v in (m.get("libraries") or {}).items())
        details.append(
            f"<details><summary>{h.esc(m.get('version'))}: config of "
            f"<code>{h.esc(m.get('command'))}</code> ({h.esc(len(m.get('inputs') or []))} "
            f'inputs; {h.esc(libraries)})</summary><pre class="mono">{h.esc(config)}</pre>'
            "</details>"
        )
    body = (
        "<p>Newest first. Each version was written by one command from its parent; the "
        "fingerprint hashes its inputs and settings, so rerunning a command with the same ones "
        "writes nothing.</p>"
        + h.table(
            ["version", "command", "parent", "created", "fingerprint", "stages", "skipped"],
            rows,
            numeric={6},
            raw=True,
        )
        + "".join(details)
    )
    return h.section("lineage", "Version lineage", body)


def _counts(info: dict[str, Any], sequences: list[dict[str, Any]]) -> str:
    charts = []
    for scheme, splits in (info.get("splits_in_store") or {}).items():
        charts.append(
            h.bar_chart(splits, f"split scheme {scheme}", info_prefix=f"splits_in_store.{scheme}")
        )
    if "genres" in info:
        charts.append(h.bar_chart(info["genres"], "genre", info_prefix="genres"))
    charts.append(h.bar_chart(count_by(sequences, "bpm"), "tempo (BPM)"))
    charts.append(h.bar_chart(count_by(sequences, "dancer"), "dancer"))
    if "sources" in info:
        charts.append(h.bar_chart(info["sources"], "source", info_prefix="sources"))
    body = f'<p>Sequences per value.</p><div class="grid">{"".join(charts)}</div>'
    files = info.get("split_files")
    if files:
        rows = []
        for scheme, splits in (files.get("schemes") or {}).items():
            for split, c in splits.items():
                rows.append(
                    [
                        f"{scheme}/{split}",
                        c.get("listed"),
                        c.get("ignored"),
                        c.get("usable"),
                        c.get("in_store"),
                        c.get("missing_from_store"),
                    ]
                )
        body += (
            "<h3>Split files</h3><p>From the dataset's split lists (ignore list: "
            f"{h.esc(files.get('ignore_list', 0))} names, "
            f"{h.esc(files.get('ignore_list_in_store', 0))} of them in the store).</p>"
            + h.table(
                ["split", "listed", "ignored", "usable", "in store", "listed, not in store"],
                rows,
                numeric={1, 2, 3, 4, 5},
            )
        )
    return h.section("counts", "Counts", body)


def _durations(
    sequences: list[dict[str, Any]], music: list[dict[str, Any]], measures: list[dict[str, Any]]
) -> str:
    parts = []
    for label, seconds in (
        ("sequences (n_frames / fps)", sequence_durations(sequences)),
        ("music tracks (duration_s)", [float(m["duration_s"]) for m in music]),
        ("measures (time_stop − time_start)", [m["time_stop"] - m["time_start"] for m in measures]),
    ):
        s = duration_summary(seconds)
        if not s["n"]:
            continue
        counts, edges = duration_histogram(seconds)
        parts.append(
            f"<div><h3>{h.esc(label)}</h3>"
            + h.table(
                ["n", "total (s)", "min (s)", "median (s)", "mean (s)", "max (s)"],
                [
                    [
                        s["n"],
                        *(
                            h.number(s[k])
                            for k in ("total_s", "min_s", "median_s", "mean_s", "max_s")
                        ),
                    ]
                ],
                numeric={0, 1, 2, 3, 4, 5},
            )
            + h.histogram_svg(
                counts,
                edges,
                width=300,
                height=60,
                colour=h.BAR_COLOUR,
                label=f"durations of {label}",
            )
            + "</div>"
        )
    return h.section("durations", "Durations", f'<div class="grid">{"".join(parts)}</div>')


def _keyframes(rows: list[dict[str, Any]]) -> str:
    """Per (strategy, N): keyframe rows, measures covered, runs, and keyframes per source."""
    groups: dict[tuple[str, int], dict[str, Any]] = {}
    for r in rows:
        g = groups.setdefault(
            (str(r["strategy"]), int(r["n_keyframes"])),
            {"rows": 0, "measures": set(), "runs": set(), "sources": {}},
        )
        g["rows"] += 1
        g["measures"].add((r["seq_id"], r["measure"]))
        g["runs"].add(r.get("run_id"))
        source = str(r.get("source"))
        g["sources"][source] = g["sources"].get(source, 0) + 1
    table_rows = [
        [
            strategy,
            n,
            g["rows"],
            len(g["measures"]),
            len(g["runs"]),
            ", ".join(f"{k} {v}" for k, v in sorted(g["sources"].items())),
        ]
        for (strategy, n), g in sorted(groups.items())
    ]
    body = "<p>The version's <code>keyframes</code> table (one row per keyframe).</p>" + h.table(
        ["strategy", "N", "keyframes", "measures", "runs", "by source"],
        table_rows,
        numeric={1, 2, 3, 4},
    )
    return h.section("keyframes", "Keyframes", body)


def _skipped(chain: list[dict[str, Any]]) -> str:
    rows = [
        [m.get("version"), m.get("command"), item.get("path", ""), item.get("error", "")]
        for m in chain
        for item in (m.get("skipped") or [])
    ]
    if not rows:
        body = '<p class="ok">No input was skipped in any version of this lineage.</p>'
    else:
        body = f"<p>{len(rows)} inputs skipped (<code>--on-error skip</code>).</p>" + h.table(
            ["version", "command", "input", "reason"], rows
        )
    return h.section("skipped", "Skipped inputs", body)


def _range_text(s: ArrayStats) -> str:
    if s.expected is None:
        return '<span class="muted">—</span>'
    low, high, why = s.expected
    return f'<span title="{h.esc(why)}">[{h.number(low)}, {h.number(high)}]</span>'


def _features(stats: list[ArrayStats]) -> str:
    flagged = [s for s in stats if s.flagged]
    if flagged:
        items = "".join(
            f"<li><code>{h.esc(s.name)}</code>: "
            + ", ".join(
                f'<span class="bad">{n} {what}</span>'
                for n, what in ((s.nan, "NaN"), (s.inf, "Inf"), (s.out_of_range, "out of range"))
                if n
            )
            + f" of {s.values} values</li>"
            for s in flagged
        )
        head = f"<h3>Arrays with NaN, Inf or out-of-range values</h3><ul>{items}</ul>"
    else:
        head = '<p class="ok">No array holds NaN, Inf or out-of-range values.</p>'
    rows = []
    for s in stats:

        def cell(n: int) -> str:
            return f'<span class="bad">{n}</span>' if n else "0"

        rows.append(
            [
                f"<code>{h.esc(s.name)}</code>",
                h.esc(" × ".join(map(str, s.shape))),
                h.esc(s.dtype),
                h.number(s.minimum),
                h.number(s.mean),
                h.number(s.maximum),
                cell(s.nan),
                cell(s.inf),
                cell(s.out_of_range),
                _range_text(s),
                h.histogram_svg(s.hist_counts, s.hist_edges, label=f"values of {s.name}")
                if s.hist_counts is not None
                else '<span class="muted">no finite values</span>',
            ]
        )
    note = (
        "<p>Counts are exact over every value. Histograms show the finite values of at most "
        "20 000 rows taken at an even stride. Expected ranges are what each array's recipe "
        "guarantees (hover for the reason); AIST++ keypoints hold NaN where triangulation or "
        "detection failed.</p>"
    )
    table = h.table(
        [
            "array",
            "shape",
            "dtype",
            "min",
            "mean",
            "max",
            "NaN",
            "Inf",
            "out of range",
            "expected",
            "histogram",
        ],
        rows,
        numeric={3, 4, 5, 6, 7, 8},
        raw=True,
    )
    return h.section("features", "Feature value distributions", head + note + table)


def gallery_sequences(sequences: list[dict[str, Any]], n: int) -> list[str]:
    """Up to ``n`` sequence ids: the first of each genre in genre order, then the next of each
    genre, and so on (so a small gallery spans the genres)."""
    by_genre: dict[str, list[str]] = {}
    for s in sequences:
        by_genre.setdefault(str(s.get("genre") or ""), []).append(s["seq_id"])
    chosen: list[str] = []
    rank = 0
    while len(chosen) < n and any(rank < len(v) for v in by_genre.values()):
        for genre in sorted(by_genre):
            if rank < len(by_genre[genre]) and len(chosen) < n:
                chosen.append(by_genre[genre][rank])
        rank += 1
    return chosen


def figure_png_base64(fig: Any, dpi: float) -> str:
    """A matplotlib figure as base64 PNG text."""
    from dancedata.viz.plot import literal_text, make_literal

    buffer = io.BytesIO()
    make_literal(fig)
    with literal_text():  # names from the store are drawn as written, never as mathtext
        fig.savefig(buffer, format="png", dpi=dpi)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def _gallery(reader: _VersionReader, seq_ids: list[str], dpi: float) -> str:
    from dancedata.read.loader import DanceStore
    from dancedata.viz.plot import sequence_figure

    ds = DanceStore(reader)  # the version the card describes, already open
    figures = []
    for seq_id in seq_ids:
        try:
            fig = sequence_figure(ds, seq_id, width=10.0, dpi=dpi)
        except DancedataError as exc:
            figures.append(f'<p class="bad">{h.esc(seq_id)}: {h.esc(exc)}</p>')
            continue
        data = figure_png_base64(fig, dpi)
        figures.append(
            f'<figure><img alt="plot of {h.esc(seq_id)}" src="data:image/png;base64,{data}">'
            f"<figcaption><code>dancedata plot STORE {h.esc(seq_id)} OUT.png</code></figcaption>"
            "</figure>"
        )
    if not figures:
        return ""
    return h.section("gallery", "Gallery", f'<div class="gallery">{"".join(figures)}</div>')


def build_report(
    store: str | Path | StoreBackend,
    version: str | None = None,
    *,
    gallery: int = 3,
    gallery_dpi: float = 60.0,
    max_hist_rows: int = 20000,
    croissant: str | None = None,
) -> str:
    """The dataset card of ``version`` (default latest) of ``store`` as one HTML string;
    ``croissant``: the relative address of its Croissant record, linked from the page."""
    started = time.perf_counter()
    from dancedata.store.backend_open import make_backend

    reader = _VersionReader(make_backend(store), version)  # opened once for the whole card
    info = summarize(reader)
    chain = lineage(reader.layout, reader.version)
    sequences = reader.table("sequences").to_pylist() if reader.has_table("sequences") else []
    music = reader.table("music").to_pylist() if reader.has_table("music") else []
    measures = reader.table("measures").to_pylist() if reader.has_table("measures") else []
    keyframes = read_keyframes(reader)
    stats = [
        array_stats(reader.array(name), name, max_hist_rows=max_hist_rows)
        for name in reader.array_names()
    ]
    sections = [
        _overview(info),
        _counts(info, sequences),
        _durations(sequences, music, measures),
        _lineage(chain),
        _skipped(chain),
        *([_keyframes(keyframes)] if keyframes else []),
        _features(stats),
    ]
    if gallery > 0 and sequences:
        sections.append(_gallery(reader, gallery_sequences(sequences, gallery), gallery_dpi))
    elapsed = time.perf_counter() - started
    sections.append(
        f'<p class="muted">Written by dancedata {h.esc(__version__)} in {elapsed:.1f} s '
        f"from <code>{h.esc(info['store'])}</code> version {h.esc(info['version'])}. "
        "Numbers marked above are those of <code>dancedata info --json</code>.</p>"
    )
    if croissant:
        sections.append(
            f'<p class="muted">Machine-readable record: {h.link(croissant, "Croissant JSON-LD")}'
            " (<code>dancedata card</code>).</p>"
        )
    return h.page(
        f"Dataset card: {Path(str(info['store'])).name or info['store']}",
        f"{info['store']} · version {info['version']} (latest {info['latest']}) · "
        f"{info.get('sequences', 0)} sequence{'' if info.get('sequences', 0) == 1 else 's'}",
        sections,
    )


def check_report_path(out: str | Path) -> Path:
    """``out`` as a Path when its folder exists, else an InputError (checked before building)."""
    out = Path(out)
    if not out.parent.is_dir():
        raise InputError("output folder does not exist", out.parent)
    return out


def write_report(html_text: str, out: str | Path) -> Path:
    """Write the page to ``out`` through a temporary file and a rename (never half-written)."""
    out = check_report_path(out)
    tmp = out.with_name(f".{out.name}.tmp{os.getpid()}")
    try:
        tmp.write_text(html_text, encoding="utf-8")
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    return out
