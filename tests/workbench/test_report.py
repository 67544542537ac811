"""The HTML run report (distctrl.workbench.report): content, embedded images, no network, and a real
render in headless Chromium."""
from __future__ import annotations

import base64
import html
import re
import shutil
import struct
import subprocess
from pathlib import Path

import pytest

from distctrl.sim.runner import run
from distctrl.sim.scenario import load_scenario, scenario_from_text
from distctrl.workbench.report import report_from_trace, write_report

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = ROOT / "examples" / "scenarios"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

#: a program that selects distance control without SET_POS: error 70335 on NC line 1
ERROR_SCENARIO = '''
name = "select without SET_POS <70335> & 'more'"
program_text = """
N10 Z[DIST_CTRL ON]
N20 G1 X10 F3000
N30 M30
"""
duration = 1.0
[axes.X]
[axes.Z]
params = "z_probe.lis"
start = 30.0
[surface]
base = 29.7
[sensor]
axis = "Z"
kind = "encoder"
'''

_DATA_URI = re.compile(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"')
_URL_ATTR = re.compile(r'\b(?:src|href)\s*=\s*["\']?\s*(https?:)?//', re.IGNORECASE)


@pytest.fixture(scope="module")
def ok_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report_ok")
    sc = load_scenario(SCENARIOS / "dist_1.toml")
    result = run(sc, trace=out / "dist_1.csv")
    page = write_report(result, sc, out / "html")
    return result, sc, page, page.read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def err_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report_err")
    sc = scenario_from_text(ERROR_SCENARIO, base_dir=SCENARIOS, source="error.toml")
    result = run(sc)
    page = write_report(result, sc, out)
    return result, sc, page, page.read_text(encoding="utf-8")


def _pngs(text: str) -> list[bytes]:
    return [base64.b64decode(m) for m in _DATA_URI.findall(text)]


def _png_size(png: bytes) -> tuple[int, int]:
    assert png[:8] == PNG_MAGIC and png[12:16] == b"IHDR"
    return struct.unpack(">II", png[16:24])


def test_report_is_one_page_with_the_sections(ok_report):
    result, sc, page, text = ok_report
    assert page.name == "index.html" and page.is_file()
    assert list(page.parent.iterdir()) == [page]          # self-contained: nothing beside it
    assert text.startswith("<!DOCTYPE html>")
    for ident in ("scenario", "parameters", "result", "metrics", "events", "plots", "timeline", "scope",
                  "zoom"):
        assert f'id="{ident}"' in text, ident
    assert "<title>Run report: dist_1: the documents&#x27; %DIST_1 example</title>" in text
    assert re.search(r"generated \d{4}-\d\d-\d\dT\d\d:\d\d:\d\d", text)       # the date
    assert "1 ms" in text                                                       # cycle time
    # the program in a <pre>, line by line
    pre = re.search(r'<pre class="program">(.*?)</pre>', text, re.S).group(1)
    assert "N10 Z[DIST_CTRL SET_POS=30]" in pre and "N999 M30" in pre
    # axes table, surface features, sensor
    assert '<table class="axes">' in text and "z_probe.lis" in text
    assert '<table class="features">' in text and "<td>sine</td>" in text and "<td>80</td>" in text
    assert "<td>encoder</td>" in text
    assert "No timed events." in text
    # result
    assert '<span class="badge ok">completed</span>' in text
    assert f"<td>{result.cycles}</td>" in text and f"{result.cycles * result.cycle_time:.4g} s" in text
    assert "<td>INACTIVE</td>" in text


def test_report_parameter_lists_in_kernel_format(ok_report):
    _, sc, _, text = ok_report
    changed = re.findall(r'<pre class="params-changed">(.*?)</pre>', text, re.S)
    assert len(changed) == 1                              # only Z differs from the defaults
    assert re.search(r"kenngr\.distc\.max_deviation\s+250000", changed[0])
    assert "kenngr.distc.kp" not in changed[0]            # a default: only in the full list
    full = re.findall(r'<details><summary>Full list of axis (\w)</summary>'
                      r'<pre class="params-full">(.*?)</pre>', text, re.S)
    assert [a for a, _ in full] == ["X", "Y", "Z"]
    assert all("kenngr.distc.kp" in body for _, body in full)
    assert text.count("All values are the defaults.") == 2


def test_report_metrics_with_units(ok_report):
    result, _, _, text = ok_report
    table = re.search(r'<table class="metrics">(.*?)</table>', text, re.S).group(1)
    rows = {m[0]: m[1:] for m in re.findall(
        r"<tr><td>(\w+)</td><td class=\"num\">([^<]*)</td><td>([^<]*)</td>", table)}
    m = result.metrics
    assert rows["distance_error_rms"] == (f"{m['distance_error_rms']:.6g}", "mm")
    assert rows["distance_error_max"] == (f"{m['distance_error_max']:.6g}", "mm")
    assert rows["settle_time"] == (f"{m['settle_time']:.6g}", "s")
    assert rows["tracking_cycles"] == (str(m["tracking_cycles"]), "cycles")
    assert set(rows) == set(m)
    assert "No errors or warnings." in text


def test_report_zoom_is_at_the_largest_distance_error(ok_report):
    import numpy as np

    from distctrl.trace.plot import distance_error

    result, _, _, text = ok_report
    err, axis = distance_error(result.trace)
    assert axis == "Z"
    # the error recomputed from the trace is the runner's metric
    assert np.nanmax(np.abs(err)) == pytest.approx(result.metrics["distance_error_max"], abs=1e-9)
    assert int(np.sum(np.isfinite(err))) == result.metrics["tracking_cycles"]
    assert "around the largest distance error" in text


def test_report_images_are_embedded_pngs(ok_report):
    _, _, _, text = ok_report
    pngs = _pngs(text)
    assert len(pngs) == text.count("<img ") == 3          # timeline, scope, zoom
    for png in pngs:
        assert png[:8] == PNG_MAGIC
        w, h = _png_size(png)
        assert w >= 800 and h >= 200


def test_report_loads_nothing_from_outside(ok_report, err_report):
    for _, _, _, text in (ok_report, err_report):
        assert not _URL_ATTR.search(text)
        assert "http://" not in text and "https://" not in text
        assert "<link" not in text and "@import" not in text and "url(" not in text
        for src in re.findall(r'\bsrc="([^"]*)"', text):
            assert src.startswith("data:image/png;base64,")
        for href in re.findall(r'\bhref="([^"]*)"', text):
            assert href.startswith("#")
        assert "<script src" not in text
        assert 'http-equiv="Content-Security-Policy"' in text


def test_report_of_a_run_with_an_error(err_report):
    result, _, _, text = err_report
    assert not result.completed and [e["id"] for e in result.errors] == [70335]
    e = result.errors[0]
    assert '<span class="badge bad">aborted</span>' in text
    table = re.search(r'<table class="events">(.*?)</table>', text, re.S).group(1)
    rows = re.findall(r'<tr class="sev-(\w+)">(.*?)</tr>', table)
    assert len(rows) == 1
    sev, cells = rows[0]
    tds = re.findall(r"<td[^>]*>(.*?)</td>", cells)
    assert sev == "error"
    assert tds == [f"{e['t']:.4f}", "70335", str(e["line"]), html.escape(e["message"]), "error"]
    assert "SET_POS missing" in tds[3]
    # the erroneous program line is highlighted
    assert f'<span class="hit" id="line-{e["line"]}">' in text
    assert "<td>ERROR</td>" in text                       # final state
    # no tracking: the zoom is replaced by a note, still two images (timeline + scope)
    assert "No zoom: distance control never tracked" in text
    assert len(_pngs(text)) == 2


def test_report_escapes_text(err_report):
    _, _, _, text = err_report
    assert "select without SET_POS &lt;70335&gt; &amp; &#x27;more&#x27;" in text
    assert "<70335>" not in text


def test_report_from_trace(ok_report, tmp_path):
    result, _, page, _ = ok_report
    csv = Path(result.trace_path)
    out = report_from_trace(csv, tmp_path / "small")
    text = out.read_text(encoding="utf-8")
    for ident in ("trace", "metrics", "events", "plots", "columns", "scope", "zoom"):
        assert f'id="{ident}"' in text, ident
    assert "dist_1: the documents&#x27; %DIST_1 example" in text     # from the sidecar meta
    assert f"<td>{result.trace.rows}</td>" in text
    assert "<td>Z.dc.offset</td><td>mm</td>" in text
    assert f"{result.metrics['distance_error_max']:.6g}" in text
    assert all(p[:8] == PNG_MAGIC for p in _pngs(text)) and len(_pngs(text)) == 3
    assert not _URL_ATTR.search(text)


def test_report_from_trace_lists_errors_from_the_meta(tmp_path):
    from distctrl.trace import Trace

    sc = scenario_from_text(ERROR_SCENARIO, base_dir=SCENARIOS)
    result = run(sc)
    tr = result.trace
    Trace(tr.columns, tr.data, tr.units, dict(tr.meta, errors=result.errors)).to_csv(tmp_path / "e.csv")
    text = report_from_trace(tmp_path / "e.csv", tmp_path / "rep").read_text(encoding="utf-8")
    assert '<tr class="sev-error">' in text and "<td class=\"num\">70335</td>" in text


# ------------------------------------------------------------------------------------------------------
# a real browser: the page renders and every image decodes
# ------------------------------------------------------------------------------------------------------
def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        path = shutil.which(name)
        if path:
            return path
    return None


_CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                   "--disable-background-networking", "--disable-component-update", "--disable-sync",
                   "--hide-scrollbars")


def _chromium_run(exe: str, profile: Path, *args: str) -> subprocess.CompletedProcess:
    profile.mkdir(parents=True, exist_ok=False)             # a new, empty profile per start
    return subprocess.run([exe, *_CHROMIUM_FLAGS, f"--user-data-dir={profile}", *args],
                          capture_output=True, text=True, timeout=180)


def test_report_renders_in_headless_chromium(ok_report, tmp_path):
    exe = _chromium()
    # never a silent skip: `make test` installs Debian's chromium (the Makefile's chromium target fails
    # loudly when it cannot)
    assert exe is not None, "chromium not found on PATH (Debian: apt-get install -y chromium, or make chromium)"
    _, _, page, text = ok_report
    url = page.resolve().as_uri()
    shot = tmp_path / "report.png"
    proc = _chromium_run(exe, tmp_path / "profile1", f"--screenshot={shot}", "--window-size=1200,3000", url)
    assert shot.is_file(), f"no screenshot (exit {proc.returncode}): {proc.stderr[-2000:]}"
    png = shot.read_bytes()
    assert _png_size(png) == (1200, 3000)
    from PIL import Image

    with Image.open(shot) as im:
        colours = im.convert("RGB").resize((120, 300)).getcolors(maxcolors=100000)
    assert colours is not None and len(colours) > 20       # text, tables and plots, not a blank page

    proc = _chromium_run(exe, tmp_path / "profile2", "--dump-dom", "--virtual-time-budget=5000", url)
    dom = proc.stdout
    assert "</html>" in dom, f"no DOM dumped (exit {proc.returncode}): {proc.stderr[-2000:]}"
    imgs = re.findall(r"<img\b[^>]*>", dom)
    assert len(imgs) == text.count("<img ") == 3
    for tag in imgs:           # the page's inline script marks each decoded image
        assert 'data-loaded="1"' in tag, tag[:200]
        width = int(re.search(r'data-natural-width="(\d+)"', tag).group(1))
        assert width > 0
    assert 'data-images-loaded="3/3"' in dom
