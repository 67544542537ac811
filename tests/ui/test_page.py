"""The live page (issue 17) in a real browser: Debian's Chromium driven by Playwright, beside pyads.

One served machine (one Z axis with a probe, 1 ms cycle) with its page server, one browser, module
scope. Chromium must be there (``make chromium`` installs it; a missing browser fails, never skips).
"""
from __future__ import annotations

import gc
import time
from pathlib import Path
from urllib.parse import urlsplit

import pyads
import pytest
from playwright.sync_api import expect

from distctrl.sim.scenario import scenario_from_dict
from distctrl.ui import UiServer
from tests.ads import wait_for
from tests.ui.conftest import serve_with_page_server

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
# an address of our own: pyads keeps one TCP connection per IP for the whole process (tests/ads has
# 127.0.0.1, tests/test_serve.py 127.0.0.2, tests/cli 127.0.0.4)
HOST, NET_ID = "127.0.0.3", "127.0.0.3.1.1"
UNIT = "gpAx[1].lr_mc_control.distance_control"


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    sc = scenario_from_dict({
        "name": "served Z for the page", "program_text": "N10 #TIME 3600\nN20 M30\n",
        "axes": {"Z": {"params": str(SCN / "z_probe.lis"), "start": 40.0, "kv": 50.0}},
        "surface": {"base": 40.0},
        "sensor": {"axis": "Z", "kind": "encoder", "range_min": -20.0, "range_max": 20.0, "noise_std": 0.002,
                   "seed": 3}}, base_dir=SCN)
    gc.collect()
    gc.freeze()              # as tests/test_serve.py: pytest's heap must not stop the cycle for long
    try:
        with serve_with_page_server(sc, machine={"host": HOST, "net_id": NET_ID},
                                    page={"host": HOST, "allowed": ["127.0.0.0/8"],
                                          "export_dir": tmp_path_factory.mktemp("exports")}) as pair:
            yield pair
    finally:
        gc.unfreeze()


@pytest.fixture(scope="module")
def page(served, browser):
    _, ui = served
    pg = browser.new_page(viewport={"width": 1300, "height": 900})
    pg.problems, pg.requests = [], []
    pg.on("console", lambda m: pg.problems.append(m.text) if m.type == "error" else None)
    pg.on("pageerror", lambda e: pg.problems.append(str(e)))
    pg.on("request", lambda r: pg.requests.append(r.url))
    pg.goto(ui.url)
    pg.locator(".scope-plot").first.wait_for(timeout=15000)
    yield pg
    pg.close()


@pytest.fixture(scope="module")
def plc(served):
    conn = pyads.Connection(NET_ID, 851, HOST)
    conn.open()
    yield conn
    conn.close()


def tab(page, name: str) -> None:
    header = page.locator(".bk-tab", has_text=name).first
    if "bk-active" not in (header.get_attribute("class") or ""):
        header.click()


def bring_to(served, transition: str, state: int) -> None:
    """A PLC command through the hub (as the panel does) and wait for the state."""
    sm, ui = served
    assert wait_for(lambda: ui.hub.plc_command("Z", transition, 40.0)[0], 3.0)
    assert wait_for(lambda: sm.machine.outputs["Z"].hli_state == state, 5.0)


def test_page_loads_without_console_error_or_outside_request(served, page):
    _, ui = served
    page.wait_for_timeout(1000)
    assert page.problems == []
    origin = urlsplit(ui.url).netloc
    assert page.requests and all(urlsplit(u).netloc == origin for u in page.requests), page.requests
    text = page.locator(".dc-status .bk-clearfix").inner_text()
    assert "served Z for the page" in text and "INACTIVE" in text


def test_scope_shows_a_moving_signal(served, page):
    tab(page, "Scope")
    plot = page.locator(".scope-plot").first
    t0 = float(page.locator(".machine-t").inner_text())
    first = plot.screenshot()
    page.wait_for_timeout(600)
    second = plot.screenshot()
    page.wait_for_timeout(400)
    assert float(page.locator(".machine-t").inner_text()) > t0 + 0.3      # the page's clock runs
    assert first != second                                                # the traces moved
    _, ui = served
    assert ui.hub.rows > 1000                                             # every cycle recorded


def test_on_from_the_plc_panel_goes_active_in_the_page_and_over_ads(served, page, plc):
    bring_to(served, "OFF", 0)
    tab(page, "PLC panel")
    state = page.locator(".plc-status-Z .state")
    expect(state).to_have_text("INACTIVE", timeout=5000)
    assert plc.read_by_name(f"{UNIT}.state_r.actual_state", pyads.PLCTYPE_UDINT) == 0
    page.locator(".plc-pos-Z input").fill("40")
    page.locator(".plc-pos-Z input").press("Enter")
    page.locator(".plc-Z-ON button").click()
    expect(state).to_have_text("ACTIVE", timeout=5000)
    t_page = time.monotonic()
    assert wait_for(lambda: plc.read_by_name(f"{UNIT}.state_r.actual_state", pyads.PLCTYPE_UDINT) == 1, 1.0)
    assert time.monotonic() - t_page < 0.5           # the same state, seen at once in both
    assert plc.read_by_name(f"{UNIT}.state_r.command_source", pyads.PLCTYPE_UDINT) == 1     # PLC
    expect(page.locator(".plc-message .bk-clearfix")).to_contain_text("ON 40.0000 mm written")
    expect(page.locator(".plc-status-Z .bk-clearfix")).to_contain_text("command_semaphore_rw FALSE")


def test_object_write_shows_pending_then_adopted(served, page):
    sm, _ = served
    bring_to(served, "ON", 1)
    tab(page, "Object browser")
    page.locator(".obj-name select").select_option("DIST_CTRL::kp")
    page.locator(".obj-value input").fill("0.5")
    page.locator(".obj-value input").press("Enter")
    page.locator(".obj-write button").click()
    expect(page.locator(".obj-message .bk-clearfix")).to_contain_text("pending until")
    expect(page.locator(".obj-state")).to_have_text("pending 0.5", timeout=3000)
    assert sm.machine.controllers["Z"].state.pending.get("kp") == 0.5
    bring_to(served, "FREEZE", 2)                      # FREEZE -> ACTIVE adopts it (§9.4 remark)
    bring_to(served, "ON", 1)
    expect(page.locator(".obj-state")).to_have_text("adopted", timeout=3000)
    expect(page.locator(".obj-status .bk-clearfix")).to_contain_text("raw 0.5 -")


def test_the_object_table_shows_what_the_machine_has_now(served, page):
    """The table's shown cells follow the machine, not only its data: with the axis filter (a CDSView)
    Bokeh's DataTable drew the patched source's old values (DIST_CTRL::state IDLE while ACTIVE)."""
    bring_to(served, "OFF", 0)
    tab(page, "Object browser")
    state_row = page.locator(".obj-table .slick-row", has_text="DIST_CTRL::state")
    expect(state_row).to_contain_text("IDLE", timeout=3000)
    bring_to(served, "ON", 1)
    expect(state_row).to_contain_text("ACTIVE", timeout=3000)
    bring_to(served, "OFF", 0)
    expect(state_row).to_contain_text("IDLE", timeout=3000)


def test_object_write_out_of_range_is_refused_in_the_page(served, page):
    tab(page, "Object browser")
    page.locator(".obj-name select").select_option("DIST_CTRL::kp")
    page.locator(".obj-value input").fill("7")
    page.locator(".obj-value input").press("Enter")
    page.locator(".obj-write button").click()
    expect(page.locator(".obj-message .bk-clearfix")).to_contain_text("DIST_CTRL::kp = 7.0")


def test_sensor_jump_raises_the_documented_error_in_the_page(served, page):
    sm, _ = served
    bring_to(served, "ON", 1)
    tab(page, "PLC panel")
    page.locator(".plc-fault-jump button").click()
    # docs/errors.md: 70329, sensor change |Δs|/T above max_act_value_change (10 m/s here; 30 mm in 1 ms)
    expect(page.locator(".plc-events .bk-clearfix")).to_contain_text("error 70329", timeout=5000)
    expect(page.locator(".last-event")).to_have_text("70329", timeout=3000)
    assert any(ev.id == 70329 for _, ev in sm.machine.events)
    page.locator(".plc-fault-clear button").click()
    expect(page.locator(".plc-message .bk-clearfix")).to_contain_text("sensor faults cleared")


def test_two_pages_see_the_same_machine(served, browser, page):
    _, ui = served
    other = browser.new_page(viewport={"width": 1000, "height": 700})
    try:
        other.goto(ui.url)
        other.locator(".scope-plot").first.wait_for(timeout=15000)
        tab(page, "PLC panel")
        page.locator(".plc-override input").count()        # the slider exists
        assert ui.hub.set_override(0.5)[0]
        expect(other.locator(".override")).to_have_text("50", timeout=3000)
        expect(page.locator(".override")).to_have_text("50", timeout=3000)
        assert ui.hub.set_override(1.0)[0]
        expect(other.locator(".override")).to_have_text("100", timeout=3000)
        assert ui.sessions >= 2
    finally:
        other.close()


def test_export_writes_a_trace_csv_that_distctrl_plot_reads(served, page, tmp_path):
    from distctrl.trace import Trace
    from distctrl.trace.plot_file import plot_trace_file

    _, ui = served
    tab(page, "Scope")
    page.locator(".scope-export button").click()
    expect(page.locator(".scope-info .bk-clearfix")).to_contain_text("exported", timeout=10000)
    name = page.locator(".scope-info a").first.inner_text()
    path = ui.hub.exports[name]
    trace = Trace.from_csv(path)
    assert trace.columns[:2] == ["t", "line"] and "Z.dc.state" in trace.columns
    assert trace.unit("true.distance") == "mm"
    assert len(trace) > 1000 and abs(trace.t[1] - trace.t[0] - 0.001) < 1e-9   # every cycle
    assert 70329 in [e["id"] for e in trace.meta["errors"]]
    out = tmp_path / "scope.png"
    plot_trace_file(path, out, signals=["true.distance", "Z.dc.state"])
    assert out.stat().st_size > 1000


def test_a_client_outside_the_allowed_networks_is_refused(served):
    import socket

    sm, ui = served
    assert ui.is_allowed("127.0.0.1") and not ui.is_allowed("192.168.10.5")
    with socket.create_connection((HOST, ui.port), timeout=2) as s:     # loopback is allowed
        s.sendall(b"GET / HTTP/1.0\r\n\r\n")
        assert s.recv(12).startswith(b"HTTP/1.")
    # a page server that allows only another network closes a loopback client at once, unanswered
    other = UiServer(sm, host=HOST, port=0, allowed=["192.168.10.0/24"])
    other.start()
    try:
        with socket.create_connection((HOST, other.port), timeout=2) as s:
            try:
                s.sendall(b"GET / HTTP/1.0\r\n\r\n")
                answer = s.recv(12)
            except ConnectionResetError:               # closed while the request was on its way
                answer = b""
            assert answer == b""
        assert other.refused == 1
    finally:
        other.stop()
    assert other.hub._after_cycle not in sm.observers


def test_a_stalled_connection_is_said_in_the_status_line(served, page):
    """R2 of the 2026-11-27 audit: offline for a few seconds, the status line froze without a word."""
    tab(page, "Scope")
    lag = page.locator(".dc-lag")
    expect(lag).to_have_text("")
    cdp = page.context.new_cdp_session(page)
    cdp.send("Network.enable")
    cdp.send("Network.emulateNetworkConditions", {"offline": True, "latency": 0, "downloadThroughput": -1,
                                                  "uploadThroughput": -1})
    try:
        expect(lag).to_contain_text("connection stalled: no update for", timeout=8000)
    finally:
        cdp.send("Network.emulateNetworkConditions", {"offline": False, "latency": 0, "downloadThroughput": -1,
                                                      "uploadThroughput": -1})
        cdp.detach()
    expect(lag).to_have_text("", timeout=8000)
    t0 = float(page.locator(".machine-t").inner_text())
    page.wait_for_timeout(500)
    assert float(page.locator(".machine-t").inner_text()) > t0           # live again


def test_closing_a_page_logs_nothing(served, browser, caplog):
    """R8: closing pages logged "Failed sending message as connection was closed" on the console."""
    import logging

    _, ui = served
    caplog.set_level(logging.INFO)
    for _ in range(2):
        other = browser.new_page(viewport={"width": 1000, "height": 700})
        other.goto(ui.url)
        other.locator(".scope-plot").first.wait_for(timeout=15000)
        other.wait_for_timeout(500)
        other.close()
        time.sleep(1.0)
    assert [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING] == []


def test_a_page_behind_says_so_in_the_status_line(served, page, monkeypatch):
    """Messages that arrive later than the fastest one did (here: stamped 3 s early by the server) make
    the status line say by how much the page is behind; on time again, it says nothing."""
    from distctrl.ui.live import Live

    tab(page, "Scope")
    lag = page.locator(".dc-lag")
    expect(lag).to_have_text("")
    monkeypatch.setattr(Live, "clock", staticmethod(lambda: time.time() - 3.0))
    expect(lag).to_contain_text("page behind by 3.", timeout=5000)
    monkeypatch.undo()
    expect(lag).to_have_text("", timeout=5000)
