"""The PLC panel's process functions switched while the program runs (issue 17 with issue 16's
``ProcessProgram.set_enabled``), in the browser."""
from __future__ import annotations

from pathlib import Path

import pytest
from playwright.sync_api import expect

from tests.ui.conftest import open_page, serve_with_page_server
from tests.ui.test_page import tab

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "process_corner.toml"


@pytest.fixture(scope="module")
def served():
    with serve_with_page_server(SCN) as pair:
        yield pair


def test_a_process_function_is_switched_off_and_on_from_the_page(served, browser):
    sm, ui = served
    corner = sm.machine.process_program.function("corner_lock", "Z")
    assert corner.enabled
    page = open_page(browser, ui.url)
    try:
        tab(page, "PLC panel")
        box = page.locator(".plc-process input[type=checkbox]").first
        expect(box).to_be_checked()
        expect(box).to_be_enabled()
        box.uncheck()
        expect(page.locator(".plc-message .bk-clearfix")).to_contain_text("corner_lock on Z disabled")
        assert not corner.enabled
        box.check()
        expect(page.locator(".plc-message .bk-clearfix")).to_contain_text("corner_lock on Z enabled")
        assert corner.enabled
    finally:
        page.close()


def test_an_unknown_function_is_refused_by_the_hub(served):
    _, ui = served
    ok, message = ui.hub.set_process("void_lock", "Z", False)
    assert not ok and "no process function 'void_lock'" in message
