"""One served machine, many pages: what every page of ``distctrl serve --ui`` reads and does.

:class:`MachineHub` hangs two hooks into the served machine's cycle (they run in the cycle thread,
under the machine's lock, right after the step, inside the cycle's slack, so the page never takes the
lock at a time the cycle is due):

* every cycle one trace row (the columns of ``distctrl run --trace``, :func:`~distctrl.sim.signals.trace_columns`)
  goes into a queue; the page thread moves the rows into a ring buffer of ``buffer_s`` seconds;
* every ``snapshot_every`` cycles (10: 100 per second at 1 ms, about 60 µs for two axes) a snapshot of plain values: every CNC
  object of every axis (raw value and pending write), each HLI control unit, the machine's events,
  the NC line, override and the head over the surface. Objects sampled this way are the scope's
  CNC-object signals (a second, slower ring buffer).

Actions of a page (PLC commands, override, feed hold, reset, sensor faults, object writes, process
functions) take the lock for the few microseconds of the write, as an ADS write does. Every action
returns ``(ok, message)``; nothing a page sends raises into the server. The override, feed hold, reset
and sensor faults are logged on serve's console (``t=12.340 s page: ...``); PLC commands, object writes
and process-function switches by the session log when the machine takes them (R18).
"""
from __future__ import annotations

import collections
import math
import threading
from pathlib import Path

import numpy as np

from ..base.states import HliTransition
from ..errors import DistCtrlError
from ..objects.channel3d import (CHANNEL3D_OBJECTS, Channel3DObjectContext, find_spec_3d, read_value_3d,
                                 write_value as write_value_3d)
from ..objects.registry import (SERVED_OBJECTS, ObjectAccessError, ObjectValueError, find_spec, index_offset,
                                read_value, write_value)
from ..sim.signals import row_builder, trace_columns
from ..sim.scenario import OVERRIDE_PATH_MAX, Event
from ..trace import Trace
from .ring import program_lines, ring_put, ring_since
from .tables import CHANNEL, object_table, state_name  # noqa: F401 - the page's modules import them here

#: the fault buttons of the PLC panel: kind -> (default value, unit, what it does)
FAULTS = {"jump": (30.0, "mm", "adds the value to the reading"),
          "dropout": (0.0, "mm", "the sensor reports the value instead of the distance"),
          "noise_burst": (0.5, "mm", "adds Gaussian noise of this std")}
NUMERIC_TYPES = ("REAL64", "SGN64", "SGN32", "UNS32", "BOOLEAN")
TRANSITIONS = ("ON", "ON_CONST_DIST", "DRYRUN", "CONST_DIST", "FREEZE", "REF", "OFF")


class MachineHub:
    """The shared state of the live pages over one :class:`~distctrl.serve.machine.ServedMachine`: reads
    it through its status snapshot, event cursor and CNC-object contexts (:mod:`distctrl.sim.status`)."""

    def __init__(self, served, *, buffer_s: float = 60.0, snapshot_every: int = 10):
        m = self.machine = served.machine
        self.served, self.lock, self.T = served, served.lock, m.T
        self.columns, self.units = trace_columns(m)
        self._build_row = row_builder(m)
        self.capacity = max(2, int(round(buffer_s / m.T)))
        self.data = np.full((self.capacity, len(self.columns)), np.nan)
        self.rows = 0                                   # rows written into the ring so far
        self._queue: collections.deque = collections.deque(maxlen=self.capacity)
        self.snapshot_every = max(1, int(snapshot_every))
        self.contexts = served.contexts                 # axis_id -> AxisObjectContext
        #: the numeric CNC objects as scope signals: "<axis>.obj.<name>" -> (axis_id, spec); the channel's
        #: 3D objects (3D distance control, docs/objects-3d.md) as "ch1.obj.<name>" with axis_id 0
        self.object_signals = {f"{c.axis_name}.obj.{s.name}": (i, s) for i, c in self.contexts.items()
                               for s in SERVED_OBJECTS if s.type in NUMERIC_TYPES}
        self.channel_objects = CHANNEL3D_OBJECTS if m.ch3d is not None else ()
        self.object_signals.update({f"ch1.obj.{s.name}": (CHANNEL, s) for s in self.channel_objects
                                    if s.type in NUMERIC_TYPES})
        self._obj_keys = list(self.object_signals)
        self.obj_capacity = max(2, int(round(buffer_s / (m.T * self.snapshot_every))))
        self.obj_data = np.full((self.obj_capacity, 1 + len(self._obj_keys)), np.nan)
        self.obj_rows = 0
        self._obj_queue: collections.deque = collections.deque(maxlen=self.obj_capacity)
        self.snapshot: dict = {}
        self._snapshots = 0
        self._k0 = m.cycle                              # the first cycle recorded is row 0
        self.events: list[dict] = []                    # every event of the machine, as dicts
        self._event_cursor = served.event_cursor()
        self.override = 1.0
        self.feed_hold = False
        self.exports: dict[str, Path] = {}              # file name -> path, served by the page's download route
        self._export_lock = threading.Lock()
        self.program_lines = program_lines(served.scenario)
        #: every open page's status check (:meth:`check_pages`), by document
        self._status_checks: dict = {}
        served.observers.append(self._after_cycle)
        with self.lock:
            self._take_snapshot()

    # ------------------------------------------------------------------ the cycle thread (under the lock)
    def _after_cycle(self) -> None:
        m = self.machine
        k = m.cycle - 1
        nc = m.nc
        line = nc.line if nc is not None else None
        self._queue.append((k, self._build_row(k * self.T, -1 if line is None else line)))
        if k % self.snapshot_every == 0:
            self._take_snapshot()

    def _take_snapshot(self) -> None:
        m = self.machine
        status = self.served.status()
        t = status["t"]
        objects = {}
        for axis_id, ctx in self.contexts.items():
            for spec in SERVED_OBJECTS:
                pending = ctx.pending(spec.write_name) if spec.writable else None
                objects[(axis_id, spec.name)] = (read_value(spec, ctx), pending)
        if self.channel_objects:
            values = m.channel3d_values()                         # with the writes waiting for adoption
            ctx3 = Channel3DObjectContext(1, values)
            for spec in self.channel_objects:
                pending = ctx3.pending(spec.write_name) if spec.writable else None
                objects[(CHANNEL, spec.name)] = (read_value_3d(spec, ctx3), pending)
        self._snapshots += 1
        self._obj_queue.append((self._snapshots - 1, t,
                                [float(objects[(i, s.name)][0]) for i, s in self.object_signals.values()]))
        new_events = [{"t": when, "id": int(ev.id), "severity": ev.severity, "line": ev.line,
                       "message": ev.message} for when, ev in self._event_cursor.take()]
        nc = status["nc"]
        self.snapshot = {
            "t": t, "cycle": status["cycle"], "objects": objects, "units": status["axes"], "new_events": new_events,
            "line": nc["line"], "nc_state": nc["state"], "override": status["override"], "paused": status["paused"],
            "x": status["x"], "true_surface": status["true_surface"], "true_distance": status["true_distance"],
            "process": status["process"],
        }
        if new_events:
            self.events.extend(new_events)

    # ------------------------------------------------------------------ the page thread
    def pump(self) -> None:
        """Move the queued rows into the ring buffers (the page thread, every frame)."""
        q = self._queue
        n = len(q)
        if n:
            items = [q.popleft() for _ in range(n)]
            block = np.array([row for _, row in items], dtype=np.float64)
            # a row's index is its cycle: rows the queue dropped while this thread was held up (more
            # than a buffer) leave the ring's older rows behind, not shifted
            self.rows = ring_put(self.data, self.capacity, items[0][0] - self._k0, block)
        q2 = self._obj_queue
        n2 = len(q2)
        if n2:
            items = [q2.popleft() for _ in range(n2)]
            block = np.array([[t, *v] for _, t, v in items], dtype=np.float64)
            self.obj_rows = ring_put(self.obj_data, self.obj_capacity, items[0][0], block)

    def watch_page(self, doc, check) -> None:
        """Run ``check()`` of the page ``doc`` with :meth:`check_pages` until its session ends."""
        self._status_checks[doc] = check
        doc.on_session_destroyed(lambda _context: self.forget_page(doc))

    def forget_page(self, doc) -> None:
        """No more status checks of the page ``doc`` (its session has ended)."""
        self._status_checks.pop(doc, None)

    def check_pages(self) -> None:
        """The status check of every open page (the page thread, every 20 ms: one timer for all)."""
        for check in list(self._status_checks.values()):
            check()

    def rows_since(self, cursor: int, step: int = 1) -> tuple[int, np.ndarray]:
        """``(new cursor, rows)``: the trace rows written since ``cursor`` (every ``step``-th row by its
        absolute index, so that every page thins the same rows), at most one buffer."""
        return ring_since(self.data, self.capacity, self.rows, cursor, step)

    def object_rows_since(self, cursor: int) -> tuple[int, np.ndarray]:
        return ring_since(self.obj_data, self.obj_capacity, self.obj_rows, cursor, 1)

    def column(self, name: str) -> int:
        return self.columns.index(name)

    def object_column(self, name: str) -> int:
        return 1 + self._obj_keys.index(name)

    def signal_unit(self, name: str) -> str:
        if name in self.object_signals:
            spec = self.object_signals[name][1]
            return spec.unit
        return self.units.get(name, "")

    # ------------------------------------------------------------------ actions of a page
    def plc_command(self, axis: str, transition: str, position_mm: float) -> tuple[bool, str]:
        """command_w (transition, position), enable_w and the semaphore, as a PLC writes them; refused
        while the semaphore is still TRUE (the CNC has not taken the last command)."""
        if axis not in self.machine.hli or transition not in HliTransition.__members__:
            return False, f"unknown axis {axis!r} or transition {transition!r}"
        if not isinstance(position_mm, (int, float)) or not math.isfinite(position_mm):
            return False, f"position {position_mm!r} mm is not a finite number"
        with self.lock:
            ok = self.machine.hli[axis].plc_command(transition, float(position_mm))
        if not ok:
            return False, f"{axis}: command_semaphore_rw is still TRUE, the CNC has not taken the last command"
        return True, f"{axis}: {transition} {position_mm:.4f} mm written, command_semaphore_rw TRUE"

    def set_override(self, value: float) -> tuple[bool, str]:

        if not (isinstance(value, (int, float)) and 0.0 <= value <= OVERRIDE_PATH_MAX):
            return False, f"override {value!r}: allowed 0 .. {OVERRIDE_PATH_MAX:g}"
        self.override = float(value)
        with self.lock:
            if not self.feed_hold:
                self.machine.channel_override = self.override
        self.served.note(f"page: path override {value * 100:.0f} %")
        return True, f"override {value * 100:.0f} %"

    def set_feed_hold(self, on: bool) -> tuple[bool, str]:
        self.feed_hold = bool(on)
        with self.lock:
            self.machine.channel_override = 0.0 if on else self.override
        message = ("feed hold ON (path override 0 %)" if on
                   else f"feed hold OFF (override {self.override * 100:.0f} %)")
        self.served.note(f"page: {message}")
        return True, message

    def reset(self) -> tuple[bool, str]:
        with self.lock:
            self.machine.reset()
        message = "CNC reset: the program stops, distance control is deselected"
        self.served.note(f"page: {message}")
        return True, message

    def sensor_fault(self, kind: str, value: float, duration_s: float | None) -> tuple[bool, str]:

        if self.machine.sensor is None:
            return False, "this scenario has no [sensor]: no sensor fault to inject"
        if kind not in FAULTS:
            return False, f"unknown fault {kind!r}; allowed: {', '.join(FAULTS)}"
        data = {"kind": kind, "value": float(value)}
        if duration_s is not None:
            data["duration"] = float(duration_s)
        try:
            with self.lock:
                self.machine.apply_event(Event(self.machine.cycle * self.T, "sensor_fault", data))
        except DistCtrlError as exc:
            return False, str(exc)
        until = "until cleared" if duration_s is None else f"for {duration_s:g} s"
        message = f"sensor fault {kind} {value:g} mm {until}"
        self.served.note(f"page: {message}")
        return True, message

    def clear_faults(self) -> tuple[bool, str]:
        if self.machine.sensor is None:
            return False, "this scenario has no [sensor]"
        with self.lock:
            self.machine.sensor.clear_faults()
        self.served.note("page: sensor faults cleared")
        return True, "sensor faults cleared"

    def write_object(self, axis_id: int, name: str, value: float) -> tuple[bool, str]:
        """A write to a read/write CNC object, range-checked as over ADS; queued into the axis's
        controller, pending until the next INACTIVE→active or FREEZE→active transition."""
        if axis_id == CHANNEL:
            return self._write_channel_object(name, value)
        ctx = self.contexts.get(axis_id)
        try:
            spec = find_spec(name)
        except (KeyError, DistCtrlError, ValueError):
            return False, f"no CNC object {name!r}"
        if ctx is None:
            return False, f"no axis {axis_id}"
        try:
            command = write_value(spec, ctx, value)
        except (ObjectAccessError, ObjectValueError) as exc:
            return False, str(exc)
        with self.lock:
            self.machine.inputs[ctx.axis_name].commands.append(command)
        return True, (f"{name} (axis {axis_id} {ctx.axis_name}, 0x{spec.index_group:X}:"
                      f"0x{index_offset(axis_id, spec):X}) = {value:g} {spec.unit}: pending until "
                      "INACTIVE→active or FREEZE→active")

    def _write_channel_object(self, name: str, value: float) -> tuple[bool, str]:
        """A write to a read/write 3D object of channel 1, adopted by the 3D controller's rule."""
        if not self.channel_objects:
            return False, "this channel has no 3D distance control (FCT_3D_DIST_CTRL)"
        try:
            spec = find_spec_3d(name)
        except (KeyError, DistCtrlError, ValueError):
            return False, f"no 3D CNC object {name!r}"
        ctx3 = Channel3DObjectContext(1, None)
        try:
            command = write_value_3d(spec, ctx3, value)
        except (ObjectAccessError, ObjectValueError) as exc:
            return False, str(exc)
        with self.lock:
            self.machine.in3d.commands.append(command)
        return True, (f"{name} (channel 1, 0x{ctx3.index_group:X}:0x{spec.low_offset:X}) = {value:g} {spec.unit}: "
                      "pending until INACTIVE→active or FREEZE→active")

    def set_process(self, name: str, axis: str, on: bool) -> tuple[bool, str]:
        proc = self.machine.process_program
        if proc is None:
            return False, "this scenario has no [[process]] functions"
        try:
            with self.lock:
                proc.set_enabled(name, axis, bool(on))
        except (KeyError, ValueError, DistCtrlError) as exc:
            return False, str(exc.args[0]) if exc.args else str(exc)
        return True, f"process function {name} on {axis} {'enabled' if on else 'disabled'}"

    # ------------------------------------------------------------------ export
    def export_csv(self, folder: Path, signals: list[str] | None = None) -> Path:
        """The ring buffer as a trace CSV with its ``.meta.json`` (what ``distctrl plot`` reads): every
        trace column at every cycle, plus the chosen CNC objects held between their samples."""

        self.pump()
        n = min(self.rows, self.capacity)
        start = self.rows - n
        idx = np.arange(start, self.rows) % self.capacity
        data = self.data[idx]
        columns, units = list(self.columns), dict(self.units)
        for s in signals or ():
            if s in self.object_signals:
                on = min(self.obj_rows, self.obj_capacity)
                oidx = np.arange(self.obj_rows - on, self.obj_rows) % self.obj_capacity
                ot, ov = self.obj_data[oidx, 0], self.obj_data[oidx, self.object_column(s)]
                pos = np.searchsorted(ot, data[:, 0], side="right") - 1
                col = np.where(pos >= 0, ov[np.clip(pos, 0, None)], np.nan) if on else np.full(n, np.nan)
                name = s.replace("::", ".").replace(" ", "_")
                columns.append(name)
                units[name] = self.signal_unit(s)
                data = np.column_stack([data, col])
        meta = {"scenario": self.served.scenario.name, "source": "distctrl serve --ui (scope buffer)",
                "cycle_time": self.T, "errors": [e for e in self.events if e["severity"] == "error"],
                "warnings": [e for e in self.events if e["severity"] != "error"]}
        folder.mkdir(parents=True, exist_ok=True)
        t0 = data[0, 0] if n else 0.0
        with self._export_lock:
            path = folder / f"scope_{len(self.exports) + 1:03d}_t{t0:.0f}s.csv"
            Trace(columns, data, units, meta).to_csv(path)
            self.exports[path.name] = path
            self.exports[path.name + ".meta.json"] = Path(str(path) + ".meta.json")
        return path
