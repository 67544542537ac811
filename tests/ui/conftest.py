"""What the live page's browser tests share: Debian's Chromium driven by Playwright, one browser for
the whole session. Chromium must be there (``make chromium`` installs it): a missing browser fails,
never skips."""
from __future__ import annotations

import contextlib
from pathlib import Path

import pytest
from playwright.sync_api import sync_playwright

from distctrl.ads.devices import serve_over_ads
from distctrl.sim.scenario import load_scenario
from distctrl.ui import UiServer

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--headless", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]


@pytest.fixture(scope="session")
def browser():
    assert Path(CHROMIUM).is_file(), "Debian's chromium is needed (make chromium; apt-get install chromium)"
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        yield b
        b.close()


def open_page(browser, url: str):
    """A new page on ``url``, once the scope is drawn."""
    page = browser.new_page(viewport={"width": 1300, "height": 900})
    page.goto(url)
    page.locator(".scope-plot").first.wait_for(timeout=15000)
    return page


@contextlib.contextmanager
def serve_with_page_server(scenario, *, machine: dict | None = None, page: dict | None = None):
    """``scenario`` (a path or a loaded scenario) served without discovery, on a free port or as
    ``machine`` (serve_over_ads's options) says, with its page server (``page``: UiServer's options
    beside a free port): ``(served, ui)``."""
    sc = load_scenario(scenario) if isinstance(scenario, (str, Path)) else scenario
    served = serve_over_ads(sc, **(machine if machine is not None else {"port": 0}), discovery_port=None)
    ui = UiServer(served, **{"port": 0, **(page or {})})
    ui.start()
    served.start()
    try:
        yield served, ui
    finally:
        ui.stop()
        served.stop()
