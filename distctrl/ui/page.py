"""One page (one Bokeh session) of the live page: a status line and four tabs (scope, object browser,
PLC panel, machine view), refreshed every frame from the shared :class:`~distctrl.ui.hub.MachineHub`."""
from __future__ import annotations

import html
from pathlib import Path

from bokeh.layouts import column, row
from bokeh.models import Div, TabPanel, Tabs

from .hub import MachineHub, state_name
from .machine_view import MachineView
from .objects_view import ObjectBrowser
from .plc_panel import PlcPanel
from .scope import Scope

TAB_SCOPE, TAB_OBJECTS, TAB_PLC, TAB_MACHINE = range(4)


def status_text(hub: MachineHub) -> str:
    """The status line: what changes seldom (states, override, last event), sent only when it changes."""
    snap = hub.snapshot
    m = hub.machine
    states = " · ".join(f"{n} <b class='state-{n}'>{state_name(snap['units'][n]['state'])}</b>" for n in m.dc_axes)
    last = hub.events[-1] if hub.events else None
    err = (f" · last {html.escape(last['severity'])} <b class='last-event'>{last['id']}</b>" if last else "")
    return (f"<b>{html.escape(hub.served.scenario.name)}</b> · NC {snap['nc_state']} · {states} · "
            f"override <span class='override'>{snap['override'] * 100:.0f}</span> %"
            + (" · <b>PLC STOP</b>" if snap["paused"] else "") + err)


def clock_text(hub: MachineHub) -> str:
    snap = hub.snapshot
    return (f"t = <span class='machine-t'>{snap['t']:.2f}</span> s · NC line "
            f"{snap['line'] if snap['line'] is not None else '-'}")


#: frames between two updates of the clock and of the machine view (the browser restyles the page on
#: every change of a text: the clock runs at 4 per second, the status line changes only when it must)
CLOCK_EVERY = 5
STATUS_MS = 20
MACHINE_EVERY = 2


def build_page(doc, hub: MachineHub, export_dir: Path, frame_ms: int) -> None:
    scope = Scope(hub, export_dir)
    objects = ObjectBrowser(hub)
    plc = PlcPanel(hub)
    machine = MachineView(hub)
    status = Div(text=status_text(hub), css_classes=["dc-status"], width=900, height=22)
    clock = Div(text=clock_text(hub), css_classes=["dc-clock"], width=300, height=22)
    tabs = Tabs(tabs=[TabPanel(child=scope.layout, title="Scope"),
                      TabPanel(child=objects.layout, title="Object browser"),
                      TabPanel(child=plc.layout, title="PLC panel"),
                      TabPanel(child=machine.layout, title="Machine view")],
                sizing_mode="stretch_width", css_classes=["dc-tabs"])

    frames = [0]

    def status_line() -> None:
        text = status_text(hub)
        if status.text != text:
            status.text = text

    def frame() -> None:
        frames[0] += 1
        n = frames[0]
        if n % CLOCK_EVERY == 0:
            clock.text = clock_text(hub)
        scope.update()
        active = tabs.active
        objects.update(active == TAB_OBJECTS)
        if active == TAB_PLC:
            plc.update()
        machine.update(active == TAB_MACHINE and n % MACHINE_EVERY == 0)

    plc.update()
    doc.add_root(column(row(clock, status), tabs, sizing_mode="stretch_width"))
    doc.title = f"distctrl — {hub.served.scenario.name}"
    doc.add_periodic_callback(frame, frame_ms)
    # the status line is checked more often than the frames are drawn (it changes seldom, and then
    # should show at once: a state change, the override, an error)
    doc.add_periodic_callback(status_line, STATUS_MS)
