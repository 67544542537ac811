"""The PLC panel of the live page: the HLI DistanceControl control unit of every axis and the channel.

Per axis (``gpAx[i].lr_mc_control.distance_control``, docs/plc.md): the transition buttons write
``command_w`` (transition, position in 0.1 µm), ``enable_w`` and ``command_semaphore_rw`` as a PLC does;
the CNC takes the command in its next cycle and clears the semaphore (the handshake is shown, and a
button is refused while the semaphore is still TRUE). ``state_r`` (state, positions, command source)
is shown live. The channel: path override, feed hold, reset; sensor faults (jump, dropout, noise burst)
as the scenario's ``sensor_fault`` events; the process functions switched on and off while the
program runs (where the build has ``ProcessProgram.set_enabled``).
"""
from __future__ import annotations

import html

from bokeh.layouts import column, row
from bokeh.models import Button, CheckboxGroup, Div, NumericInput, Slider, Toggle

from .hub import FAULTS, TRANSITIONS, MachineHub, state_name

MM = 1e-4          # mm per 0.1 µm (HLI lengths are DINT in 0.1 µm)
SOURCES = {0: "NC program", 1: "PLC"}


class PlcPanel:
    """One page's PLC panel."""

    def __init__(self, hub: MachineHub):
        self.hub = hub
        m = hub.machine
        self.message = Div(text="", css_classes=["plc-message"], width=900, height=22)
        self.units: dict[str, Div] = {}
        axis_blocks = []
        for n in m.axis_names:
            unit = m.hli[n]
            pos = NumericInput(title=f"{n}: position / distance (mm)", mode="float", width=170,
                               value=round(m.scenario.axes[n].start, 4), css_classes=[f"plc-pos-{n}"])
            buttons = []
            for tr in TRANSITIONS:
                b = Button(label=tr, width=118, css_classes=[f"plc-{n}-{tr}"],
                           button_type="success" if tr.startswith("ON") else "danger" if tr == "OFF" else "default")
                b.on_click(lambda _e=None, n=n, tr=tr, pos=pos: self._say(
                    *hub.plc_command(n, tr, float(pos.value if pos.value is not None else 0.0))))
                buttons.append(b)
            status = Div(text="", css_classes=[f"plc-status-{n}"], width=560, height=100)
            self.units[n] = status
            title = Div(text=f"<b>axis {n}</b> — gpAx[{unit.axis_index}].lr_mc_control.distance_control"
                             + ("" if unit.distance_control_on else
                                " <i>(no distance control, P-AXIS-00328 = 0: commands are refused with 70336)</i>"))
            axis_blocks.append(column(title, row(pos, *buttons[:3]), row(*buttons[3:]), status))
        # the channel
        self.override = Slider(title="Path override (%)", start=0, end=127, step=1, value=100, width=300,
                               css_classes=["plc-override"])
        self.override.on_change("value_throttled", lambda a, o, v: self._say(*hub.set_override(v / 100.0)))
        self.hold = Toggle(label="Feed hold", width=110, css_classes=["plc-feedhold"])
        self.hold.on_change("active", lambda a, o, v: self._say(*hub.set_feed_hold(v)))
        reset = Button(label="Reset", button_type="danger", width=90, css_classes=["plc-reset"])
        reset.on_click(lambda _e=None: self._say(*hub.reset()))
        faults = []
        self.fault_duration = NumericInput(title="fault duration (s, empty: until cleared)", mode="float",
                                           value=None, width=230)
        for kind, (value, unit_, what) in FAULTS.items():
            v = NumericInput(title=f"{kind} ({unit_}): {what}", mode="float", value=value, width=260,
                             css_classes=[f"plc-fault-value-{kind}"])
            b = Button(label=f"Sensor {kind.replace('_', ' ')}", width=160, button_type="warning",
                       css_classes=[f"plc-fault-{kind}"])
            b.on_click(lambda _e=None, kind=kind, v=v: self._say(*hub.sensor_fault(
                kind, float(v.value if v.value is not None else 0.0), self.fault_duration.value)))
            faults.append(row(v, b))
        clear = Button(label="Clear sensor faults", width=160, css_classes=["plc-fault-clear"])
        clear.on_click(lambda _e=None: self._say(*hub.clear_faults()))
        procs = hub.snapshot.get("process", [])
        self.proc_names = [(name, axis) for name, axis, _ in procs]
        self.procs = CheckboxGroup(labels=[f"{name} on {axis}" for name, axis, _ in procs],
                                   active=[i for i, (_, _, on) in enumerate(procs) if on],
                                   css_classes=["plc-process"])
        self.procs.on_change("active", lambda a, o, new: self._switch(o, new))
        proc_note = Div(text="<b>Process functions</b> ([[process]], docs/process.md)"
                        + ("" if procs else ": none in this scenario"))
        self.events = Div(text="", css_classes=["plc-events"], width=1200, height=170)
        self.layout = column(*axis_blocks, Div(text="<b>Channel</b>"), row(self.override, self.hold, reset),
                             Div(text="<b>Sensor faults</b> (the scenario's sensor_fault events, now)"),
                             self.fault_duration, *faults, clear, proc_note, self.procs, self.message, self.events)

    def _say(self, ok: bool, message: str) -> None:
        colour = "green" if ok else "red"
        self.message.text = f'<span style="color:{colour}">{html.escape(message)}</span>'

    def _switch(self, old: list[int], new: list[int]) -> None:
        for i in set(old) ^ set(new):
            name, axis = self.proc_names[i]
            self._say(*self.hub.set_process(name, axis, i in new))

    def update(self) -> None:
        snap = self.hub.snapshot
        for n, div in self.units.items():
            u = snap["units"][n]
            sem = ('<b style="color:darkorange">TRUE</b> (waiting for the CNC)' if u["semaphore"]
                   else "FALSE")
            rej = "".join(f"<br>refused: {html.escape(r)}" for r in u["rejected"])
            text = (f"command_w: transition {u['transition']} ({_transition(u['transition'])}), "
                    f"position {u['position'] * MM:.4f} mm<br>"
                    f"enable_w {str(u['enable_w']).upper()}, command_semaphore_rw {sem}, "
                    f"commands taken {u['consumed']}<br>"
                    f"state_r: actual_state <b class='state'>{state_name(u['actual_state'])}</b> "
                    f"({u['actual_state']}), command_source {u['command_source']} "
                    f"({SOURCES.get(u['command_source'], '?')})<br>"
                    f"actual_position {u['actual_position'] * MM:.4f} mm, actual_offset "
                    f"{u['actual_offset'] * MM:.4f} mm, actual_distance {u['actual_distance'] * MM:.4f} mm{rej}")
            if div.text != text:
                div.text = text
        events = self.hub.events[-8:]
        text = "<b>Errors and warnings</b><br>" + ("<br>".join(
            f"{html.escape(e['severity'])} <b>{e['id']}</b> at t = {e['t']:.3f} s"
            + (f", NC line {e['line']}" if e["line"] not in (None, -1) else "")
            + f": {html.escape(e['message'])}" for e in reversed(events)) or "none")
        if self.events.text != text:
            self.events.text = text


def _transition(number: int) -> str:
    from ..base.states import HliTransition

    try:
        return HliTransition(number).name
    except ValueError:
        return "unknown"
