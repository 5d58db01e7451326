"""dancedata report / dancedata.viz.report: a self-contained page whose numbers equal
``dancedata info --json``, rendered by a real browser (headless Chromium, Debian package
installed by `make browser`, which `make test` runs)."""

from __future__ import annotations

import base64
import io
import json
import os
import re
import shutil
import subprocess
import sys
import time
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
import zarr

from tests.helpers import importorskip_unless_ci, run_cli
from tests.viz_helpers import write_keyframes_table

importorskip_unless_ci("matplotlib")

from dancedata.viz.report import build_report, gallery_sequences  # noqa: E402
from dancedata.viz.report_stats import array_stats, expected_range  # noqa: E402

# slow: builds report pages over featurized stores; headless Chromium screenshots
pytestmark = pytest.mark.slow

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"]


@pytest.fixture(scope="module")
def store(small_featurized_store):
    return small_featurized_store


@pytest.fixture(scope="module")
def page(store, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("report-page") / "report.html"
    proc = run_cli("report", str(store), str(out), "--gallery", "2")
    assert "wrote" in proc.stdout
    return out


def _info(store, *args: str) -> dict:
    return json.loads(run_cli("info", str(store), "--json", *args).stdout)


class _InfoCells(HTMLParser):
    """Text of every element that carries data-info="key"."""

    def __init__(self) -> None:
        super().__init__()
        self.cells: dict[str, str] = {}
        self._open: list[str | None] = []

    def handle_starttag(self, tag, attrs):
        if tag in ("br", "meta", "img", "rect", "line"):
            return
        self._open.append(dict(attrs).get("data-info"))

    def handle_endtag(self, tag):
        if self._open:
            self._open.pop()

    def handle_data(self, data):
        if self._open and self._open[-1]:
            key = self._open[-1]
            self.cells[key] = self.cells.get(key, "") + data


def _info_cells(html_text: str) -> dict[str, str]:
    parser = _InfoCells()
    parser.feed(html_text)
    return {k: v.strip() for k, v in parser.cells.items()}


def _lookup(info: dict, dotted: str):
    value = info
    parts = dotted.split(".")
    while parts:  # keys may hold dots themselves: take the longest key that exists
        for n in range(len(parts), 0, -1):
            key = ".".join(parts[:n])
            if isinstance(value, dict) and key in value:
                value, parts = value[key], parts[n:]
                break
        else:
            raise KeyError(dotted)
    return value


def _check_against_info(cells: dict[str, str], info: dict) -> None:
    required = {"version", "sequences", "frames", "hours", "music_tracks", "skipped"}
    required |= {f"genres.{g}" for g in info["genres"]}
    required |= {f"sources.{s}" for s in info["sources"]}
    required |= {
        f"splits_in_store.{scheme}.{split}"
        for scheme, splits in info.get("splits_in_store", {}).items()
        for split in splits
    }
    required |= {f"tables.{name}" for name in info["tables"]}
    if "measures" in info:
        required.add("measures")
    assert required <= set(cells), sorted(required - set(cells))
    for key, text in cells.items():
        assert text == str(_lookup(info, key)), key


def test_numbers_on_the_page_equal_info_json(store, page):
    cells = _info_cells(page.read_text())
    _check_against_info(cells, _info(store))
    assert cells["sequences"] == "2" and cells["measures"] == "8"


def test_older_version_page_equals_its_info(store):
    html_text = build_report(store, "v2", gallery=0)
    cells = _info_cells(html_text)
    _check_against_info(cells, _info(store, "--version", "v2"))
    assert "measures" not in cells and "the latest version is v3" in html_text


def test_page_is_self_contained(page):
    text = page.read_text()
    assert "<script" not in text.lower() and "<link" not in text.lower()
    assert not re.search(r"""(src|href)\s*=\s*["'](?!data:|#)""", text)
    assert not re.search(r"url\(", text)
    images = re.findall(r'src="data:image/png;base64,([^"]+)"', text)
    assert len(images) == 2  # the gallery
    from PIL import Image

    for data in images:
        img = Image.open(io.BytesIO(base64.b64decode(data)))
        assert img.format == "PNG" and img.width >= 400
    for section in ("lineage", "counts", "durations", "skipped", "features", "gallery"):
        assert f'id="{section}"' in text
    # lineage: every version's command and full fingerprint
    for v in ("v1", "v2", "v3"):
        manifest = json.loads((page_store(page) / "versions" / v / "manifest.json").read_text())
        assert manifest["fingerprint"] in text and manifest["command"] in text


def page_store(page: Path) -> Path:
    match = re.search(r"from <code>([^<]+)</code> version", page.read_text())
    assert match
    return Path(match.group(1))


def test_nan_arrays_are_listed_with_exact_counts(store, page):
    text = page.read_text()
    group = zarr.open_group(str(store / "versions" / "v3" / "data.zarr"), mode="r")
    kp = np.asarray(group["motion/keypoints3d"][...])
    nan = int(np.isnan(kp).sum())
    assert nan > 0  # the synthetic twin has AIST++-like NaN frames
    assert f'<code>motion/keypoints3d</code>: <span class="bad">{nan} NaN</span>' in text
    assert "<code>motion/rotmat</code>:" not in text  # clean arrays are not flagged


def test_array_stats_against_brute_force():
    rng = np.random.default_rng(0)
    values = rng.uniform(-1.2, 1.2, size=(1000, 4, 3)).astype(np.float32)
    values[5, 0, 0] = np.nan
    values[700, 1, 2] = np.inf
    values[999, 3, 1] = -np.inf
    arr = zarr.create_array(store={}, shape=values.shape, chunks=(64, 4, 3), dtype="float32")
    arr[...] = values
    stats = array_stats(arr, "motion/rotmat", max_hist_rows=100, bins=10)
    finite = values[np.isfinite(values)].astype(np.float64)
    low, high, _ = expected_range("motion/rotmat")
    assert stats.values == values.size and stats.nan == 1 and stats.inf == 2
    assert stats.out_of_range == int(((finite < low) | (finite > high)).sum()) > 0
    assert stats.minimum == finite.min() and stats.maximum == finite.max()
    assert stats.mean == pytest.approx(finite.mean(), rel=1e-9)
    sample = values[::10].reshape(-1).astype(np.float64)  # ceil(1000 / 100) = every 10th row
    sample = sample[np.isfinite(sample)]
    counts, _ = np.histogram(sample, bins=10, range=(sample.min(), sample.max()))
    np.testing.assert_array_equal(stats.hist_counts, counts)
    assert stats.hist_rows == 100 and stats.flagged
    assert expected_range("motion/trans") is None
    assert expected_range("audio/stems/drums/onset_peaks")[:2] == (0, 1)


def test_skipped_inputs_are_listed_with_reasons(tmp_path):
    import pickle

    raw, store = tmp_path / "raw", tmp_path / "store"
    run_cli("synth", "aist", str(raw), "--sequences", "3", "--seed", "2", "-q")
    bad = sorted((raw / "motions").iterdir())[0]
    bad.write_bytes(pickle.dumps({"smpl_poses": np.zeros((10, 70), np.float32)}))
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q", "--on-error", "skip")
    html_text = build_report(store, gallery=1)
    cells = _info_cells(html_text)
    _check_against_info(cells, _info(store))
    assert cells["skipped"] == "1"
    assert str(bad) in html_text and "shape (10, 70)" in html_text


def test_keyframes_and_measure_lengths(store, tmp_path):
    copy = tmp_path / "store"
    shutil.copytree(store, copy)
    plain = build_report(copy, gallery=0)
    assert 'id="keyframes"' not in plain  # no table, no section
    rows = write_keyframes_table(copy / "versions" / "v3")
    html_text = build_report(copy, gallery=0)
    section = html_text[html_text.index('id="keyframes"') :].split("</section>")[0]
    n_measures = len({(r["seq_id"], r["measure"]) for r in rows})
    even = [r for r in rows if r["strategy"] == "even"]
    assert (
        f'<td>even</td><td class="num">3</td><td class="num">{len(even)}</td>'
        f'<td class="num">{n_measures}</td><td class="num">1</td>'
    ) in section
    assert f"edge {2 * n_measures}, peak {3 * n_measures}" in section
    assert "measures (time_stop − time_start)" in html_text


def test_a_missing_genre_is_named_as_info_json_names_it():
    """Video stores have no genre: info --json writes the None key as "null"."""
    from dancedata.viz.report_html import bar_chart

    chart = bar_chart({None: 2, "gBR": 1}, "genre", info_prefix="genres")
    info = json.loads(json.dumps({"genres": {None: 2, "gBR": 1}}))
    cells = _info_cells(chart)
    assert cells == {"genres.null": "2", "genres.gBR": "1"} and "(none)" in chart
    assert all(str(_lookup(info, k)) == v for k, v in cells.items())


def test_gallery_spans_genres():
    rows = [{"seq_id": f"{g}{i}", "genre": g} for g in ("gPO", "gBR", "gJS") for i in range(3)]
    assert gallery_sequences(rows, 4) == ["gBR0", "gJS0", "gPO0", "gBR1"]
    assert gallery_sequences(rows[:1], 3) == ["gPO0"]


def test_without_the_viz_extra_the_commands_name_it(store, tmp_path):
    """A matplotlib that cannot be imported (a shadowing package raising ImportError) gives
    one line naming the extra, exit 1, and no output file."""
    fake = tmp_path / "shadow" / "matplotlib"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("raise ImportError('matplotlib removed for this test')\n")
    env = {**os.environ, "PYTHONPATH": str(fake.parent)}
    for args in (
        ("report", str(store), str(tmp_path / "r.html")),
        ("plot", str(store), "gBR_sBM_cAll_d01_mBR1_ch01", str(tmp_path / "p.png")),
    ):
        proc = subprocess.run(
            [sys.executable, "-m", "dancedata.cli", *args],
            capture_output=True,
            text=True,
            env=env,
            timeout=300,
        )
        assert proc.returncode == 1, proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and "pip install 'dancedata[viz]'" in lines[0], proc.stderr
    assert not list(tmp_path.glob("*.html")) and not list(tmp_path.glob("*.png"))


# -- a real browser --------------------------------------------------------------------------


def chromium() -> str:
    """Path of the Chromium binary; skip without it (fail under CI=true: `make test` installs
    it through `make browser`)."""
    found = shutil.which("chromium") or (
        "/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None
    )
    if found:
        return found
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail("CI=true but chromium is not installed; run `make browser`")
    pytest.skip("chromium not installed (make browser)")


def _run_chromium(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [chromium(), *CHROMIUM_ARGS, *args], capture_output=True, text=True, timeout=120
    )


# Appended to a copy of the page only, to read the browser's own clock at the load event:
# performance.now() is milliseconds since navigation start.
LOAD_PROBE = (
    "<script>addEventListener('load',()=>{document.body.setAttribute("
    "'data-load-ms',String(performance.now()))});</script>"
)


def test_report_renders_in_headless_chromium(store, page, tmp_path, record_property):
    from PIL import Image

    shot = tmp_path / "report.png"
    started = time.perf_counter()
    proc = _run_chromium(f"--screenshot={shot}", "--window-size=1280,2000", page.as_uri())
    screenshot_s = time.perf_counter() - started
    assert shot.is_file(), proc.stderr[-2000:]
    img = np.asarray(Image.open(shot).convert("RGB"))
    assert img.shape[:2] == (2000, 1280)
    colours = np.unique(img.reshape(-1, 3), axis=0)
    assert img.std() > 20 and len(colours) > 50  # not blank: text, charts, header
    # the header band is the page's dark blue, not the browser's default white
    assert np.abs(img[20, 640].astype(int) - (0x1D, 0x35, 0x57)).max() < 8

    dom = _run_chromium("--dump-dom", page.as_uri()).stdout
    assert "<h2>Version lineage</h2>" in dom
    cells = _info_cells(dom)  # the DOM the browser built, not the file
    _check_against_info(cells, _info(store))
    text = re.sub(r"<[^>]+>", " ", dom)
    for word in ("Feature value distributions", "Skipped inputs", "gBR", "aistpp"):
        assert word in text

    probe = tmp_path / "probe.html"
    probe.write_text(page.read_text().replace("</body>", LOAD_PROBE + "</body>"))
    loads = []
    for _ in range(2):
        dumped = _run_chromium("--dump-dom", probe.as_uri()).stdout
        match = re.search(r'data-load-ms="([0-9.]+)"', dumped)
        assert match, "the load event never fired"
        loads.append(float(match.group(1)))
    load_ms = min(loads)
    record_property("report_load_ms", load_ms)
    record_property("report_bytes", page.stat().st_size)
    print(
        f"\nreport page: {page.stat().st_size / 1e3:.0f} kB, load event at {load_ms:.0f} ms "
        f"(best of 2), screenshot command {screenshot_s:.1f} s"
    )
    assert load_ms < 5000


PHONE_PROBE = (
    '<!DOCTYPE html><html><body style="margin:0"><iframe id="f" src="{page}" width="375" '
    'height="800" style="border:0"></iframe><script>'
    "document.getElementById('f').addEventListener('load',()=>{{"
    "const d=document.getElementById('f').contentDocument;"
    "const c=[...d.querySelector('.cards').children];"
    "const rows=new Set(c.map(e=>Math.round(e.getBoundingClientRect().top)));"
    "document.body.setAttribute('data-card-rows',String(rows.size));"
    "document.body.setAttribute('data-cards',String(c.length));"
    "document.body.setAttribute('data-page-width',String(d.documentElement.scrollWidth))}});"
    "</script></body></html>"
)


def test_report_at_phone_width_tiles_two_per_row(page, tmp_path):
    """In a 375 px viewport (a phone; an iframe, as headless Chromium's window is at least
    500 px wide) the count tiles sit two per row (they stacked one per row) and the page does
    not scroll sideways."""
    probe = tmp_path / "phone.html"
    probe.write_text(PHONE_PROBE.format(page=page.as_uri()))
    dom = _run_chromium("--allow-file-access-from-files", "--dump-dom", probe.as_uri()).stdout
    found = {k: int(v) for k, v in re.findall(r'data-(card-rows|cards|page-width)="(\d+)"', dom)}
    assert found.get("cards", 0) >= 6, (found, dom[-500:])
    assert found["card-rows"] == -(-found["cards"] // 2), found
    assert found["page-width"] <= 375, found


def test_header_says_sequence_in_the_singular(tmp_path):
    from dancedata.viz.report import build_report

    raw, store = tmp_path / "raw", tmp_path / "s"
    run_cli("synth", "aist", str(raw), "--sequences", "1", "--seed", "0", "-q")
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    text = build_report(store, gallery=0)
    assert "· 1 sequence</p>" in text and "1 sequences" not in text
