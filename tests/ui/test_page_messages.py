"""What a live page sends into the page server's thread (issue 39): beside the 1 ms cycle every message
costs Bokeh's decoding and its answer. A page sends only its acknowledgements, one for every second
frame it draws; the plots' automatic ranges stay in the browser (Bokeh sent each change of the scope's
time axis, every frame drawn, to a server that never reads it)."""
from __future__ import annotations

import collections
import time
from pathlib import Path

from bokeh.protocol.messages import patch_doc

from distctrl.ui import live as live_module
from tests.ui.conftest import open_page, serve_with_page_server

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "serve_z.toml"


def test_a_page_sends_only_its_acknowledgements_every_second_frame(browser, monkeypatch):
    received: collections.Counter = collections.Counter()
    apply = patch_doc.apply_to_document

    def counting_apply(self, doc, setter=None):
        content = getattr(self.payload, "content", self.payload)
        for event in content.get("events", []):
            model = doc.get_model_by_id(event.get("model", {}).get("id", ""))
            received[(type(model).__name__, event.get("attr"))] += 1
        return apply(self, doc, setter)
    monkeypatch.setattr(patch_doc, "apply_to_document", counting_apply)
    frames = [0]
    push = live_module.Live.push

    def counting_push(self, *args, **kwargs):
        frames[0] += 1
        return push(self, *args, **kwargs)
    monkeypatch.setattr(live_module.Live, "push", counting_push)
    with serve_with_page_server(SCN) as (_served, ui):
        page = open_page(browser, ui.url)
        try:
            time.sleep(1.0)
            received.clear()
            frames[0] = 0
            time.sleep(4.0)
        finally:
            page.close()
    assert frames[0] >= 10, frames                      # the page was streaming
    assert set(received) == {("LiveValues", "ack")}, received
    assert received[("LiveValues", "ack")] <= frames[0] / live_module.ACK_EVERY + 2, (received, frames)
