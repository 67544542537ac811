"""The page's frames without a browser (issue 24): what a frame changes in the page's document, the
flow control, and the PLC panel's rough edges (R8), on a served machine stepped by hand."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
from bokeh.document import Document
from bokeh.models import Button, ColumnDataSource, NumericInput

from distctrl.ads.devices import serve_over_ads
from distctrl.sim.scenario import load_scenario
from distctrl.ui.hub import MachineHub
from distctrl.ui.page import TAB_MACHINE, TAB_OBJECTS, TAB_PLC, TAB_SCOPE, build_page

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


class Page:
    """One page's document, its frame callback and every change a frame makes in it."""

    def __init__(self, hub: MachineHub):
        self.hub = hub
        self.doc = Document()
        build_page(self.doc, hub, Path("."), 50)
        self.live = getattr(self.doc, "live", None)
        [callback] = self.doc.session_callbacks                          # the frame, every 50 ms
        self.frame = callback.callback
        self.tabs = self.doc.roots[0].children[1]
        self.changes: list = []
        self.doc.on_change(lambda event: self.changes.append(event))

    def status(self) -> None:
        """The 20 ms status check (MachineHub.check_pages schedules the push in the page's next tick)."""
        values = self.doc.status_due()
        if values is not None:
            self.live.push(values)

    def run(self, cycles: int, frames: int = 1, ack: bool = True) -> None:
        for _ in range(frames):
            for _ in range(cycles):
                self.hub.served.step()
            self.hub.pump()
            self.frame()
            if ack and self.live is not None:
                self.live.model.ack = self.live.seq

    def changed_models(self) -> set[str]:
        return {type(getattr(e, "model", None) or getattr(e, "column_source", None)).__name__ for e in self.changes}


@pytest.fixture()
def hub():
    served = serve_over_ads(load_scenario(SCN / "serve_z.toml"), port=0, discovery_port=None)
    return MachineHub(served, buffer_s=5.0)


@pytest.mark.parametrize("active", [TAB_SCOPE, TAB_OBJECTS, TAB_PLC, TAB_MACHINE])
def test_a_frame_changes_no_layout_model_only_data(hub, active):
    """A Div, a button or any other laid-out model whose property changes is rendered anew and makes
    Bokeh lay out the whole page: frames change only data (the live values, the plots' sources)."""
    page = Page(hub)
    page.tabs.active = active
    page.run(5)
    page.changes.clear()
    assert hub.plc_command("Z", "ON", 40.0)[0]          # values change: state, semaphore, offset, ...
    page.run(10, frames=20)
    assert page.changes
    assert page.changed_models() <= {"LiveValues", "ColumnDataSource", "Range1d"}, page.changed_models()


def test_the_plc_panel_values_follow_the_control_unit(hub):
    page = Page(hub)
    page.tabs.active = TAB_PLC
    assert hub.plc_command("Z", "ON", 40.0)[0]
    page.run(20, frames=2)
    shown = page.live.shown
    assert shown["Z.state"] == "ACTIVE" and shown["Z.src"] == "1 (PLC)" and shown["Z.sem"] == "FALSE"
    assert shown["state.Z"] == "ACTIVE"                                  # the status line
    assert float(shown["t"]) == pytest.approx(hub.snapshot["t"])


def test_a_page_that_has_not_drawn_its_frames_gets_no_more_until_it_has(hub):
    from distctrl.ui.live import MAX_IN_FLIGHT

    page = Page(hub)
    page.tabs.active = TAB_SCOPE
    page.run(10, frames=2)
    sent = page.live.seq
    page.run(10, frames=10, ack=False)                   # the browser is busy
    assert page.live.seq == sent + MAX_IN_FLIGHT
    page.changes.clear()
    page.run(10, frames=3, ack=False)
    assert page.changes == []                            # nothing queued for a page that is behind
    page.live.model.ack = page.live.seq                  # it has caught up
    scope = page.doc.roots[0].children[1].tabs[0].child.children[2]
    source = next(r.data_source for r in scope.renderers if isinstance(r.data_source, ColumnDataSource)
                  and "c0" in r.data_source.data)
    before = page.live.last["__rows"][0][1]["t"][-1]
    page.run(10)
    # the rows it missed come in one go (into the scope's source, by the page's script): the scope's
    # time goes on where it was
    [[source_id, rows, rollover]] = page.live.last["__rows"]
    assert source_id == source.id and rollover == page.doc.scope.rollover and set(rows) == set(source.data)
    assert rows["t"][0] == pytest.approx(before + 0.01)            # none lost, none twice
    assert rows["t"][-1] == pytest.approx(hub.snapshot["t"], abs=0.011) and rows["t"][-1] > before + 0.1
    assert page.live.seq == sent + MAX_IN_FLIGHT + 1


def test_the_override_slider_shows_an_override_the_cnc_set(hub):
    page = Page(hub)
    page.tabs.active = TAB_PLC
    plc = page.doc.select_one({"css_classes": ["plc-override"]})
    assert plc.value == 100
    with hub.lock:
        hub.machine.channel_override = 0.0             # as stop_program does after an error
    page.run(20, frames=2)
    assert plc.value == 0


def test_an_axis_without_distance_control_gets_no_buttons(hub):
    page = Page(hub)
    classes = {c for m in page.doc.select({"type": Button}) for c in m.css_classes}
    assert "plc-Z-ON" in classes and not any(c.startswith("plc-X-") for c in classes)


def test_the_set_distance_field_is_not_the_axis_start(hub):
    page = Page(hub)
    fields = {c: m for m in page.doc.select({"type": NumericInput}) for c in m.css_classes}
    assert fields["plc-pos-Z"].value == pytest.approx(40.0)          # the surface under the head
    assert fields["plc-dist-Z"].value is None                        # serve_z's program has no SET_DIST
    page.tabs.active = TAB_PLC
    fields["plc-Z-ON_CONST_DIST"] = page.doc.select_one({"css_classes": ["plc-Z-ON_CONST_DIST"]})
    for cb in fields["plc-Z-ON_CONST_DIST"]._event_callbacks["button_click"]:
        cb(None)
    page.run(5)
    assert page.live.shown["plc.msg"] == ["Z: ON_CONST_DIST needs SET_DIST (mm): enter it first", "err"]
    assert hub.machine.hli["Z"].consumed == 0


def test_the_object_table_has_a_value_for_unitless_objects(hub):
    from distctrl.ui.hub import object_table

    table = object_table(hub)
    kp = next(i for i, (a, n) in enumerate(zip(table["axis"], table["name"])) if a == "2 Z" and n == "DIST_CTRL::kp")
    assert table["unit"][kp] == "-" and table["value"][kp] == table["raw"][kp] != ""
    assert all(v != "" for v in table["value"]), [n for n, v in zip(table["name"], table["value"]) if v == ""]


def test_the_object_browser_shows_one_axis_at_a_time(hub):
    from distctrl.ui.objects_view import ObjectBrowser

    browser = ObjectBrowser(hub)
    shown = lambda: set(browser.source.data["axis"])  # noqa: E731  (the source holds the shown rows)
    assert browser.show.value == "2 Z" and shown() == {"2 Z"}          # the distance-controlled axis first
    browser.show.value = "1 X"
    assert shown() == {"1 X"}
    browser.show.value = "all axes"
    assert shown() == {"1 X", "2 Z"}


def test_scope_ticks_are_plain_numbers_and_states_have_names(hub):
    from bokeh.models import FixedTicker

    from distctrl.ui.scope import Scope

    scope = Scope(hub, Path("."))
    scope.choice.value = ["true.distance", "Z.dc.state"]
    axes = {a.axis_label: a for a in scope.plot.left + scope.plot.right if hasattr(a, "formatter")}
    assert axes["mm"].formatter.use_scientific is False
    state = axes["-"]
    assert isinstance(state.ticker, FixedTicker) and state.major_label_overrides[1] == "ACTIVE"


def test_the_machine_view_shows_a_z_range_where_the_distance_is_readable():
    """R8: on the plate the plot's Z range was the surface's (-10 .. 35 mm, with the holes): the
    1.5 mm distance lines were invisible."""
    from distctrl.ui.machine_view import MachineView

    served = serve_over_ads(load_scenario(SCN / "plasma_plate_short.toml"), port=0, discovery_port=None)
    hub = MachineHub(served, buffer_s=1.0)
    view = MachineView(hub)
    for _ in range(50):
        served.step()
    hub.pump()
    view.update()
    r = view.plot.y_range
    snap = hub.snapshot
    head = snap["true_surface"] + snap["true_distance"]
    assert r.start is not None and r.end - r.start <= 3 * max(2.0, abs(snap["true_distance"])) + 1e-9
    assert r.start < snap["true_surface"] and head < r.end


def test_a_page_gets_every_value_until_it_has_drawn_one_frame(hub):
    """Between the page's document and its connection frames may go by: the page would miss the
    values they changed (they are sent only once), so until it has acknowledged a frame every frame
    carries all values."""
    page = Page(hub)
    page.tabs.active = TAB_PLC
    page.run(5, frames=1, ack=False)
    assert {"Z.state", "Z.sem", "state.Z", "t", "plc.events"} <= set(json.loads(page.live.model.values))
    page.live.model.ack = page.live.seq
    page.run(20, frames=1)
    assert "Z.state" not in page.live.last and "t" in page.live.last


def test_a_state_change_on_the_plc_panel_goes_out_with_the_status_check(hub):
    """The panel's discrete values (state, semaphore, command taken) are as urgent as the status line:
    they go with its 20 ms check, also when the page is 2 frames behind (a click's effect shows at once)."""
    from distctrl.ui.live import MAX_IN_FLIGHT

    page = Page(hub)
    page.tabs.active = TAB_PLC
    page.run(5)
    page.run(5, frames=MAX_IN_FLIGHT, ack=False)        # frames wait for the page now
    assert hub.plc_command("Z", "ON", 40.0)[0]
    for _ in range(20):
        hub.served.step()
    page.status()
    values = page.live.last
    assert values.get("Z.state") == "ACTIVE" and values.get("Z.taken") == "1" and "Z.apos" not in values


def test_a_frame_is_one_message_with_the_scopes_rows(hub):
    """Issue 39: a frame on the scope was two messages (Bokeh's stream of the scope's source, then the
    live values), each costing the page's thread Bokeh's whole serialisation beside the 1 ms cycle. The
    scope's rows now go with the live values, one message, and the page's script streams them."""
    page = Page(hub)
    page.tabs.active = TAB_SCOPE
    page.run(10, frames=3)
    page.changes.clear()
    page.run(10, frames=5)
    sent = [e for e in page.changes if getattr(e, "attr", None) != "ack"]      # (the page's own acks)
    assert [type(e).__name__ for e in sent] == ["ModelChangedEvent"] * 5, [type(e).__name__ for e in sent]
    assert all(e.model is page.live.model and e.attr == "values" for e in sent)
    assert page.live.last["__rows"][0][1]["t"][-1] == pytest.approx(hub.snapshot["t"], abs=0.011)


def test_the_status_check_is_no_periodic_callback_of_each_page(hub):
    """Issue 39: every page had a Bokeh periodic callback every 20 ms for its status check (Bokeh's
    locking and task machinery 50 times a second per page); one timer of the page server checks every
    page now, and only a change is pushed (in the page's next tick)."""
    page = Page(hub)
    assert [c.period for c in page.doc.session_callbacks] == [50]
    assert page.doc in hub._status_checks
    hub.check_pages()
    assert not page.doc.session_callbacks[1:]                      # nothing changed: nothing scheduled
    page.run(5)
    assert hub.plc_command("Z", "ON", 40.0)[0]
    for _ in range(20):                                            # the hub's snapshot: every 10 cycles
        hub.served.step()
    hub.check_pages()
    assert len(page.doc.session_callbacks) == 2                     # the push, in the next tick


def test_the_status_check_leaves_a_page_whose_session_bokeh_has_just_destroyed(hub):
    """Bokeh destroys an unused session's document first and runs its on_session_destroyed hooks
    later (after an await); the page server's 20 ms status check in between scheduled a push on the
    destroyed document and raised AttributeError in Tornado's callback, a traceback on serve's console
    (seen while looking for the page campaign's traceback, issue 39). The check now forgets a page whose
    session has ended."""
    import asyncio
    import weakref

    from bokeh.server.contexts import BokehSessionContext
    from bokeh.server.session import ServerSession
    from tornado.ioloop import IOLoop

    async def main():
        doc = Document()
        context = BokehSessionContext("s1", None, doc)
        doc._session_context = weakref.ref(context)               # as Bokeh's server sets up a page
        build_page(doc, hub, Path("."), 50)
        session = ServerSession("s1", doc, io_loop=IOLoop.current())
        context._set_session(session)
        assert hub.plc_command("Z", "ON", 40.0)[0]                # the status line changes
        for _ in range(20):
            hub.served.step()
        session.destroy()                                        # Bokeh's discard, before the hooks
        hub.check_pages()
        assert doc not in hub._status_checks
    asyncio.run(main())
