"""The live page keeps up beside two CPU-bound processes (issue 24): on every tab the machine time the
page shows keeps pace with the machine, and a click on the PLC panel shows its effect within 1 s.

The test makes the load itself: two ``while 1: pass`` processes on the 2 CPUs (stopped by their
PIDs at the end), beside the served machine (1 ms cycle), its page server and Chromium. The clicks are
Playwright's normal clicks (visible, enabled, stable, receiving events), with its normal timeouts.
"""
from __future__ import annotations

import statistics
import subprocess
import sys
import time
from pathlib import Path

import pytest
from playwright.sync_api import expect

from tests.ui.conftest import open_page, serve_with_page_server
from tests.ui.test_page import tab

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "serve_z.toml"
TABS = ("Scope", "Object browser", "PLC panel", "Machine view")


@pytest.fixture(scope="module")
def load():
    """Two CPU-bound processes for the whole module."""
    hogs = [subprocess.Popen([sys.executable, "-c", "while 1: pass"]) for _ in range(2)]
    try:
        yield hogs
    finally:
        for h in hogs:
            h.kill()
            h.wait(10)


@pytest.fixture(scope="module")
def served(load):
    with serve_with_page_server(SCN) as pair:
        yield pair


@pytest.fixture(scope="module")
def page(served, browser):
    _, ui = served
    pg = open_page(browser, ui.url)
    yield pg
    pg.close()


def shown_lag(page, hub) -> float:
    """How far the machine time the page shows is behind the machine's (s)."""
    shown = float(page.locator(".machine-t").inner_text())
    return hub.snapshot["t"] - shown


@pytest.mark.parametrize("name", TABS)
def test_the_shown_machine_time_keeps_pace_on_every_tab(served, page, name):
    _, ui = served
    tab(page, name)
    page.wait_for_timeout(1000)
    lags = []
    for _ in range(6):                      # 7.5 s on the tab
        page.wait_for_timeout(1250)
        lags.append(shown_lag(page, ui.hub))
    print(f"{name}: shown time behind the machine {', '.join(f'{x:.2f}' for x in lags)} s")
    # the clock shows the machine time of the last frame: a few frames behind at most, and not more
    # and more (the lag fell 12.9 s -> 37.8 s behind in 40 s on the PLC panel before issue 24)
    assert max(lags[-3:]) < 1.5, (name, lags)
    assert lags[-1] - min(lags[:3]) < 0.75, (name, lags)


def test_a_click_on_the_plc_panel_shows_its_effect_within_a_second(served, page):
    sm, ui = served
    tab(page, "PLC panel")
    state = page.locator(".plc-status-Z .state")
    expect(state).to_have_text("INACTIVE")
    page.locator(".plc-pos-Z input").fill("40")
    page.locator(".plc-pos-Z input").press("Enter")
    clicks, shown = [], []
    for name, want in [("ON", "ACTIVE"), ("OFF", "INACTIVE")] * 3:
        page.wait_for_timeout(700)
        t0 = time.monotonic()
        page.locator(f".plc-Z-{name} button").click()
        t1 = time.monotonic()
        expect(state).to_have_text(want)
        t2 = time.monotonic()
        clicks.append(t1 - t0)
        shown.append(t2 - t1)
    print(f"clicks {', '.join(f'{x:.2f}' for x in clicks)} s; shown {', '.join(f'{x:.2f}' for x in shown)} s later")
    # the effect on the page within 1 s of the click (median), none later than 2 s; the click itself
    # (Playwright waits until the button is stable and receives events) in well under a second
    assert statistics.median(shown) <= 1.0 and max(shown) <= 2.0, (clicks, shown)
    assert statistics.median(clicks) <= 1.0 and max(clicks) <= 3.0, (clicks, shown)
    assert sm.machine.outputs["Z"].hli_state == 0


def test_switching_tabs_answers_at_once(served, page):
    for name in ("PLC panel", "Machine view", "Object browser", "PLC panel", "Scope"):
        t0 = time.monotonic()
        tab(page, name)
        expect(page.locator(".bk-tab.bk-active")).to_have_text(name)
        assert time.monotonic() - t0 < 2.0, name
