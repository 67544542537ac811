"""The page's hostile-input campaign (bench/stress_serve.py page, issue 39) keeps going where a busy
machine slows it down: a live page that Chromium cannot draw within the allowance is recorded in the
segment, not a traceback that ends the campaign (the resumed campaign of 2026-11-28 stopped at 271
inputs that way), and a stopped campaign resumes with the next input."""
from __future__ import annotations

import json

from tests.scripts import load_script

stress_serve = load_script("bench/stress_serve.py", "distctrl_bench_stress_serve", beside=True)


class _NeverDrawn:
    """Chromium on a starved machine: the page does not draw within the allowance."""

    def __init__(self, url, n=1):
        from playwright.sync_api import TimeoutError as PlaywrightTimeout
        raise PlaywrightTimeout("Timeout 300000ms exceeded waiting for locator('.scope-plot')")


def test_page_campaign_goes_on_when_the_page_cannot_be_drawn(tmp_path, monkeypatch):
    monkeypatch.setattr(stress_serve, "Browser", _NeverDrawn)
    st = stress_serve.run_campaign("page", 12, None, tmp_path, log=print)
    fig = st["figures"]
    assert fig["inputs"] == 12 and fig["escapes"] == 0, fig["escape_kinds"]
    assert "not drawn" in st["segments"][-1]["page"]
    assert fig["pages_not_drawn"] == 1
    assert fig["serve_stops"][0]["returncode"] == 0 and not fig["serve_stops"][0]["traceback"]


def test_page_campaign_resumes_with_the_next_input(tmp_path):
    first = stress_serve.run_campaign("page", 30, 0.0, tmp_path, log=print, page_open=False)
    assert first["stopped_by"] == "budget" and first["next"] == 1
    saved = json.loads((tmp_path / "page.json").read_text())
    assert saved["next"] == 1 and saved["figures"]["complete"] is False
    done = stress_serve.run_campaign("page", 30, None, tmp_path, log=print, page_open=False)
    assert done["next"] == 30 and done["figures"]["complete"] and len(done["segments"]) == 2
    assert done["figures"]["escapes"] == 0, done["figures"]["escape_kinds"]
