"""The PLC panel of the live page: the HLI DistanceControl control unit of every axis and the channel.

Per axis with distance control (``gpAx[i].lr_mc_control.distance_control``, docs/plc.md): the
transition buttons write ``command_w`` (transition, position in 0.1 µm), ``enable_w`` and
``command_semaphore_rw`` as a PLC does; the CNC takes the command in its next cycle and clears the
semaphore (the handshake is shown, and a button is refused while the semaphore is still TRUE).
``state_r`` (state, positions, command source) is shown live. An axis without distance control
(P-AXIS-00328 = 0) gets no buttons, only that note. The channel: path override (following the
machine's override, also when the CNC set it, e.g. 0 % after an error stopped the program), feed
hold, reset; sensor faults (jump, dropout, noise burst) as the scenario's ``sensor_fault`` events;
the process functions switched on and off while the program runs.

The live texts are a fixed skeleton filled by the page's script (:mod:`distctrl.ui.live`): a new
value never re-renders the panel, so its buttons stay where they are.
"""
from __future__ import annotations

import re

from bokeh.layouts import column, row
from bokeh.models import Button, CheckboxGroup, Div, NumericInput, Slider, Toggle

from ..base.states import HliTransition
from .hub import FAULTS, TRANSITIONS, MachineHub, state_name
from .live import STYLE, Live, span

MM = 1e-4          # mm per 0.1 µm (HLI lengths are DINT in 0.1 µm)
SOURCES = {0: "NC program", 1: "PLC"}
#: the transitions whose command_w.position is the set distance (the others': SET_POS / REF_POS)
DIST_TRANSITIONS = ("ON_CONST_DIST", "CONST_DIST")
NO_POSITION = ("FREEZE", "OFF")
#: the fields of a control unit that change on a command (urgent: sent with the status line's check)
DISCRETE = ("tr", "en", "sem", "taken", "state", "state_no", "src", "refused")
_SET_DIST = re.compile(r"SET_DIST\s*=\s*([-+]?\d+(?:\.\d*)?)", re.IGNORECASE)


def default_set_dist(hub: MachineHub) -> float | None:
    """The first numeric SET_DIST of the NC program (None: the field starts empty)."""
    for _, line in sorted(hub.program_lines.items()):
        m = _SET_DIST.search(line)
        if m:
            return float(m.group(1))
    return None


def default_set_pos(hub: MachineHub) -> float | None:
    """The workpiece surface under the head now (the SET_POS a PLC would give for it)."""
    m = hub.machine
    try:
        x = m.drives["X"].nozzle if "X" in m.drives else 0.0
        y = m.drives["Y"].nozzle if "Y" in m.drives else 0.0
        return round(float(m.surface.height(x, y)), 4)
    except (AttributeError, TypeError, ValueError):
        return None


def unit_values(n: str, u: dict) -> dict:
    """The live values of one control unit (keys ``<axis>.<field>``)."""
    tr = u["transition"]
    return {
        f"{n}.tr": f"{tr} ({_transition(tr)})",
        f"{n}.pos": f"{u['position'] * MM:.4f}",
        f"{n}.en": str(u["enable_w"]).upper(),
        f"{n}.sem": ["TRUE (waiting for the CNC)", "warn"] if u["semaphore"] else "FALSE",
        f"{n}.taken": str(u["consumed"]),
        f"{n}.state": state_name(u["actual_state"]),
        f"{n}.state_no": str(u["actual_state"]),
        f"{n}.src": f"{u['command_source']} ({SOURCES.get(u['command_source'], '?')})",
        f"{n}.apos": f"{u['actual_position'] * MM:.4f}",
        f"{n}.aoff": f"{u['actual_offset'] * MM:.4f}",
        f"{n}.adist": f"{u['actual_distance'] * MM:.4f}",
        f"{n}.refused": ["".join(f"\nrefused: {r}" for r in u["rejected"]), "err"] if u["rejected"] else "",
    }


def unit_html(n: str, v: dict) -> str:
    s = lambda key, cls="", tag="span": span(f"{n}.{key}", _text(v[f"{n}.{key}"]), cls, tag)  # noqa: E731
    return (f"command_w: transition {s('tr')}, position {s('pos')} mm<br>"
            f"enable_w {s('en')}, command_semaphore_rw {s('sem')}, commands taken {s('taken')}<br>"
            f"state_r: actual_state {s('state', 'state', 'b')} ({s('state_no')}), command_source {s('src')}<br>"
            f"actual_position {s('apos')} mm, actual_offset {s('aoff')} mm, actual_distance {s('adist')} mm"
            f"{s('refused', 'pre')}")


def _text(v) -> str:
    return v[0] if isinstance(v, list) else v


class PlcPanel:
    """One page's PLC panel."""

    def __init__(self, hub: MachineHub, live: Live | None = None):
        self.hub = hub
        self.live = live or Live()
        m = hub.machine
        snap = hub.snapshot
        self.message = Div(text=span("plc.msg"), css_classes=["plc-message"], width=900, height=22,
                           stylesheets=[STYLE])
        self.units: dict[str, Div] = {}
        self.dc_units = [n for n in m.axis_names if m.hli[n].distance_control_on]
        set_pos, set_dist = default_set_pos(hub), default_set_dist(hub)
        axis_blocks = []
        for n in m.axis_names:
            unit = m.hli[n]
            head = f"<b>axis {n}</b> — gpAx[{unit.axis_index}].lr_mc_control.distance_control"
            if not unit.distance_control_on:
                axis_blocks.append(Div(text=head + " <i>(no distance control, P-AXIS-00328 = 0: no PLC "
                                                   "commands; they would be refused with 70336)</i>",
                                       css_classes=[f"plc-title-{n}"]))
                continue
            pos = NumericInput(title="SET_POS / REF_POS (mm)", mode="float", width=150, value=set_pos,
                               css_classes=[f"plc-pos-{n}"])
            dist = NumericInput(title="SET_DIST (mm)", mode="float", width=110, value=set_dist,
                                css_classes=[f"plc-dist-{n}"])
            buttons = []
            for tr in TRANSITIONS:
                b = Button(label=tr, width=118, css_classes=[f"plc-{n}-{tr}"],
                           button_type="success" if tr.startswith("ON") else "danger" if tr == "OFF" else "default")
                b.on_click(lambda _e=None, n=n, tr=tr, pos=pos, dist=dist: self._command(n, tr, pos, dist))
                buttons.append(b)
            status = Div(text=unit_html(n, unit_values(n, snap["units"][n])), css_classes=[f"plc-status-{n}"],
                         width=620, height=100, stylesheets=[STYLE])
            self.units[n] = status
            axis_blocks.append(column(Div(text=head), row(pos, dist, *buttons[:3]), row(*buttons[3:]), status))
        # the channel
        self.override = Slider(title="Path override (%)", start=0, end=127, step=1,
                               value=round(snap["override"] * 100), width=300, css_classes=["plc-override"])
        self._override_seen = self.override.value
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
        procs = snap.get("process", [])
        self.proc_names = [(name, axis) for name, axis, _ in procs]
        self.procs = CheckboxGroup(labels=[f"{name} on {axis}" for name, axis, _ in procs],
                                   active=[i for i, (_, _, on) in enumerate(procs) if on],
                                   css_classes=["plc-process"])
        self.procs.on_change("active", lambda a, o, new: self._switch(o, new))
        proc_note = Div(text="<b>Process functions</b> ([[process]], docs/process.md)"
                        + ("" if procs else ": none in this scenario"))
        self.events = Div(text="<b>Errors and warnings</b><br>" + span("plc.events", self._events_text(), "pre"),
                          css_classes=["plc-events"], width=1200, height=170, stylesheets=[STYLE])
        self.layout = column(*axis_blocks, Div(text="<b>Channel</b>"), row(self.override, self.hold, reset),
                             Div(text="<b>Sensor faults</b> (the scenario's sensor_fault events, now)"),
                             self.fault_duration, *faults, clear, proc_note, self.procs, self.message, self.events)

    def _command(self, n: str, tr: str, pos: NumericInput, dist: NumericInput) -> None:
        if tr in NO_POSITION:
            value = 0.0
        else:
            field, what = (dist, "SET_DIST") if tr in DIST_TRANSITIONS else (pos, "SET_POS / REF_POS")
            if field.value is None:
                self._say(False, f"{n}: {tr} needs {what} (mm): enter it first")
                return
            value = float(field.value)
        self._say(*self.hub.plc_command(n, tr, value))

    def _say(self, ok: bool, message: str) -> None:
        self.live.stage({"plc.msg": [message, "ok" if ok else "err"]})

    def _switch(self, old: list[int], new: list[int]) -> None:
        for i in set(old) ^ set(new):
            name, axis = self.proc_names[i]
            self._say(*self.hub.set_process(name, axis, i in new))

    def _events_text(self) -> str:
        events = self.hub.events[-8:]
        return "\n".join(f"{e['severity']} {e['id']} at t = {e['t']:.3f} s"
                         + (f", NC line {e['line']}" if e["line"] not in (None, -1) else "")
                         + f": {e['message']}" for e in reversed(events)) or "none"

    def discrete(self) -> dict:
        """The control units' values that a command changes (state, semaphore, ...), not the positions."""
        snap = self.hub.snapshot
        values = {}
        for n in self.units:
            v = unit_values(n, snap["units"][n])
            values.update({f"{n}.{k}": v[f"{n}.{k}"] for k in DISCRETE})
        return values

    def update(self) -> dict:
        """The panel's live values now; the override slider follows the machine's override (not
        while feed hold holds it at 0)."""
        snap = self.hub.snapshot
        values = {}
        for n in self.units:
            values.update(unit_values(n, snap["units"][n]))
        values["plc.events"] = self._events_text()
        machine = round(snap["override"] * 100)
        if machine != self._override_seen:         # changed in the machine, not only dragged here
            self._override_seen = machine
            if not self.hub.feed_hold and self.override.value != machine:
                self.override.value = machine
        return values


def _transition(number: int) -> str:

    try:
        return HliTransition(number).name
    except ValueError:
        return "unknown"
