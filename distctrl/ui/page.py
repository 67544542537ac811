"""One page (one Bokeh session) of the live page: a status line and four tabs (scope, object browser,
PLC panel, machine view), refreshed every frame from the shared :class:`~distctrl.ui.hub.MachineHub`.

What changes while the page is open is sent as live values (:mod:`distctrl.ui.live`): only the keys
whose text changed, one message per frame, written by the page's script into fixed elements, so that
the browser never lays the page out again for a new number. Only the visible tab is updated; a page
that has not drawn the last frames gets no new one until it has (flow control, :class:`~distctrl.ui.live.Live`).
"""
from __future__ import annotations

import html
from pathlib import Path

from bokeh.layouts import column, row
from bokeh.models import Div, TabPanel, Tabs

from .hub import MachineHub, state_name
from .live import STYLE, Live, span
from .machine_view import MachineView
from .objects_view import ObjectBrowser
from .plc_panel import PlcPanel
from .scope import Scope

TAB_SCOPE, TAB_OBJECTS, TAB_PLC, TAB_MACHINE = range(4)

#: frames between two updates of the machine view (its surface and path: 10 per second)
MACHINE_EVERY = 2


def status_values(hub: MachineHub) -> dict:
    """The status line's live values (the NC state, every axis's HLI state, override, PLC STOP, the
    last event)."""
    snap = hub.snapshot
    values = {"nc": snap["nc_state"], "override": f"{snap['override'] * 100:.0f}",
              "paused": " · PLC STOP" if snap["paused"] else ""}
    for n in hub.machine.dc_axes:
        values[f"state.{n}"] = state_name(snap["units"][n]["state"])
    last = hub.events[-1] if hub.events else None
    values["last"] = f" · last {last['severity']} " if last else ""
    values["last.id"] = str(last["id"]) if last else ""
    return values


def status_html(hub: MachineHub) -> str:
    v = status_values(hub)
    states = " · ".join(f"{n} " + span(f"state.{n}", v[f"state.{n}"], f"state-{n}", "b") for n in hub.machine.dc_axes)
    return (f"<b>{html.escape(hub.served.scenario.name)}</b> · NC {span('nc', v['nc'])} · {states} · "
            f"override {span('override', v['override'], 'override')} %{span('paused', v['paused'])}"
            f"{span('last', v['last'])}{span('last.id', v['last.id'], 'last-event', 'b')} "
            f"{span('__lag', '', 'dc-lag')}")


def clock_values(hub: MachineHub) -> dict:
    snap = hub.snapshot
    return {"t": f"{snap['t']:.2f}", "line": str(snap["line"]) if snap["line"] is not None else "-"}


def clock_html(hub: MachineHub) -> str:
    v = clock_values(hub)
    return f"t = {span('t', v['t'], 'machine-t')} s · NC line {span('line', v['line'])}"


def build_page(doc, hub: MachineHub, export_dir: Path, frame_ms: int) -> None:
    live = Live()
    scope = Scope(hub, export_dir)
    objects = ObjectBrowser(hub, live)
    plc = PlcPanel(hub, live)
    machine = MachineView(hub)
    status = Div(text=status_html(hub), css_classes=["dc-status"], width=1000, height=22, stylesheets=[STYLE])
    clock = Div(text=clock_html(hub), css_classes=["dc-clock"], width=260, height=22, stylesheets=[STYLE])
    tabs = Tabs(tabs=[TabPanel(child=scope.layout, title="Scope"),
                      TabPanel(child=objects.layout, title="Object browser"),
                      TabPanel(child=plc.layout, title="PLC panel"),
                      TabPanel(child=machine.layout, title="Machine view")],
                sizing_mode="stretch_width", css_classes=["dc-tabs"])
    frames = [0]

    def status_due() -> dict | None:
        """The status line's values (on the PLC panel also its discrete ones: a click's effect is as
        urgent) when they or a staged message changed and the page may get them now; else None."""
        values = status_values(hub)
        if tabs.active == TAB_PLC:
            values.update(plc.discrete())
        if live.staged or any(live.shown.get(k) != v for k, v in values.items()):
            if live.can_send(urgent=True):
                return values
        return None

    scheduled = [False]
    served_page = doc.session_context is not None          # built for a session of the page server

    def status_line() -> None:
        """The 20 ms check (:meth:`MachineHub.check_pages`, one timer for all pages, outside the
        document's lock): a push only when something changed, in the next tick under the lock. A
        Bokeh periodic callback per page cost its locking and task machinery 50 times a second for
        a check that finds nothing most of the time (issue 39)."""
        if served_page and doc.session_context is None:
            # Bokeh has destroyed the session's document; its on_session_destroyed hook (which
            # forgets the page too) runs only after an await, and a push now would raise
            hub.forget_page(doc)
            return
        if scheduled[0]:
            return
        values = status_due()
        if values is not None:
            scheduled[0] = True

            def push() -> None:
                scheduled[0] = False
                live.push(values)
            doc.add_next_tick_callback(push)

    def frame() -> None:
        frames[0] += 1
        active = tabs.active
        scope.keep(active == TAB_SCOPE)            # the trigger and the markers run on every tab
        if not live.can_send():                    # the page has not drawn the last frames yet
            return
        values = clock_values(hub)
        values.update(status_values(hub))
        rows = scope.update(active == TAB_SCOPE)
        values.update(objects.update(active == TAB_OBJECTS))
        if active == TAB_PLC:
            values.update(plc.update())
        if active == TAB_MACHINE:
            values.update(machine.update(frames[0] % MACHINE_EVERY == 0))
        live.push(values, rows)

    values = clock_values(hub)
    values.update(plc.update())
    live.shown.update(values)
    live.shown.update(status_values(hub))
    root = column(row(clock, status), tabs, sizing_mode="stretch_width", tags=[live.model])
    doc.add_root(root)
    doc.title = f"distctrl — {hub.served.scenario.name}"
    doc.add_periodic_callback(frame, frame_ms)
    hub.watch_page(doc, status_line)
    doc.live = live                                # for the tests
    doc.status_due = status_due
    doc.scope = scope
