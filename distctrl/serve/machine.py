"""The served machine: the virtual machine paced to wall-clock time (``distctrl serve``, docs/serve.md).

:class:`ServedMachine` owns the :class:`~distctrl.sim.machine.Machine`, the lock every reader and
writer holds, the real-time cycle thread (:class:`~distctrl.serve.realtime.RealTimeLoop`), the run/stop
switch and the session log. What serves it attaches to it as an equal:

* ADS (:class:`distctrl.ads.devices.AdsEndpoint`) as the service ``"ads"`` (:meth:`ServedMachine.attach`:
  started and stopped with the machine);
* the live page (:class:`distctrl.ui.app.UiServer`), which hangs an observer into the cycle.

Both read the machine through its status snapshot and event cursor (:mod:`distctrl.sim.status`) and the
CNC-object contexts of :attr:`ServedMachine.contexts`, and take :attr:`ServedMachine.lock` around it.
"""
from __future__ import annotations

import logging
import threading
import time

from ..base.states import HLI_STATE_NAMES
from ..objects.registry import SERVED_OBJECTS, AxisObjectContext
from ..sim.machine import Machine
from ..sim.runner import load_program
from .realtime import RealTimeLoop

__all__ = ["ServedMachine", "SessionLog", "log"]

log = logging.getLogger("distctrl.serve")


#: the CNC object of each writable value (the first of its aliases: DIST_CTRL_PARAM[0]::v_max, ...)
_WRITABLE = {}
for _spec in SERVED_OBJECTS:
    if _spec.writable:
        _WRITABLE.setdefault(_spec.write_name, _spec)


def _show(internal: float, spec) -> str:
    """A value in the object's unit, as the object browser shows it (``0.3``, ``250000 0.01 nm/s``)."""
    text = f"{internal / spec.write_scale:.10g}"
    return text if spec.unit in ("", "-") else f"{text} {spec.unit}"


class SessionLog:
    """What a served session tells its console (logger ``distctrl.serve``): per axis the HLI commands
    the CNC took from the PLC and the distance-control state changes, every error and warning with its
    ID (e.g. 70336 for a command to an axis without distance control, P-AXIS-00328 = 0), the end of
    the NC program, every CNC-object write the controller took (over ADS or from the page: the object,
    the value in effect -> the written one, pending; then adopted) and every process function switched
    on or off (R18 of the new-user audit). Checked after every cycle from the machine's event cursor
    and its activity, the status snapshot taken when the activity changed (:mod:`distctrl.sim.status`);
    the writes and switches by a comparison of the controllers' pending writes and the functions'
    switches (empty and unchanged: a few attribute reads)."""

    def __init__(self, machine, logger: logging.Logger = log):
        self.machine, self.log, self.names = machine, logger, HLI_STATE_NAMES
        axes = machine.status()["axes"]
        self.states = {n: a["state"] for n, a in axes.items()}
        self.consumed = {n: a["consumed"] for n, a in axes.items()}
        self.rejected = {n: a["rejected_count"] for n, a in axes.items()}
        self.events = machine.event_cursor(from_now=True)
        self.activity = machine.activity()
        self.program_ended = False
        self.pending = {n: dict(c.state.pending) for n, c in machine.controllers.items()}
        #: the values in effect when the pending writes were taken (the "was" of an adoption)
        self.in_effect = {n: {} for n in machine.controllers}
        proc = machine.process_program
        self.functions = list(proc.functions) if proc is not None else []
        self.switched = [f.switched_on for f in self.functions]

    def axis_lines(self) -> list[str]:
        """``axis 1 = X (no distance control, P-AXIS-00328 = 0)`` ...: the gpAx index of every axis."""
        m = self.machine
        return [f"axis {a['index']} = {n} "
                + ("(distance control)" if m.scenario.axes[n].params.enabled else
                   "(no distance control, P-AXIS-00328 = 0: PLC commands are refused with 70336)")
                for n, a in m.status()["axes"].items()]

    def after_cycle(self) -> None:
        m, log_ = self.machine, self.log
        t = m.cycle * m.T
        activity = m.activity()                 # a few comparisons; the snapshot only when it changed
        if activity != self.activity:
            self.activity = activity
            self._report_axes(m.status()["axes"], t)
        for when, ev in self.events.take():
            level = logging.ERROR if ev.severity == "error" else logging.WARNING
            line = f", NC line {ev.line}" if ev.line not in (None, -1) else ""
            log_.log(level, "t=%.3f s %s %d%s: %s", when, ev.severity, ev.id, line, ev.message)
        for n, c in m.controllers.items():
            pending = c.state.pending
            if pending or self.pending[n]:
                if pending != self.pending[n]:
                    self._report_writes(n, c, t)
        if self.functions:
            switched = [f.switched_on for f in self.functions]
            if switched != self.switched:
                for f, was, now in zip(self.functions, self.switched, switched):
                    if was != now:
                        log_.info("t=%.3f s process function %s on %s switched %s", t, f.name, f.axis,
                                  "on" if now else "off")
                self.switched = switched
        nc_state = activity[0]
        if not self.program_ended and nc_state in ("ended", "aborted"):
            self.program_ended = True
            log_.info("t=%.3f s NC program %s", t, "aborted" if nc_state == "aborted" else "ended (M30)")

    def _report_writes(self, axis: str, controller, t: float) -> None:
        """CNC-object writes the controller took since the last cycle (pending) and the ones it adopted
        or dropped, in the objects' units (docs/objects.md)."""
        before, now = self.pending[axis], dict(controller.state.pending)
        for name, value in now.items():
            if before.get(name) != value:
                spec = _WRITABLE[name]
                self.log.info("t=%.3f s axis %s: %s %s -> %s pending (adopted on the next "
                              "INACTIVE->active or FREEZE->active)", t, axis, spec.name,
                              _show(getattr(controller.tuning, name), spec), _show(value, spec))
        for name, value in before.items():
            if name not in now:
                spec = _WRITABLE[name]
                in_effect = getattr(controller.tuning, name)
                if in_effect == value:
                    self.log.info("t=%.3f s axis %s: %s %s adopted (was %s)", t, axis, spec.name,
                                  _show(value, spec), _show(self.in_effect[axis].get(name, value), spec))
                else:
                    self.log.info("t=%.3f s axis %s: %s pending %s dropped, %s in effect", t, axis, spec.name,
                                  _show(value, spec), _show(in_effect, spec))
        self.pending[axis] = now
        self.in_effect[axis] = {name: getattr(controller.tuning, name) for name in now}

    def _report_axes(self, axes: dict, t: float) -> None:
        """The PLC commands taken and refused and the state changes since the last report."""
        log_ = self.log
        for n, a in axes.items():
            if a["consumed"] != self.consumed[n]:
                self.consumed[n] = a["consumed"]
                log_.info("t=%.3f s axis %s (gpAx[%d]): PLC command transition %d, position %.4f mm taken",
                          t, n, a["index"], a["transition"], a["position"] * 1e-4)
            new_refused = a["rejected_count"] - self.rejected[n]
            if new_refused:
                for reason in a["rejected"][-new_refused:]:
                    log_.warning("t=%.3f s axis %s: PLC command refused: %s", t, n, reason)
                self.rejected[n] = a["rejected_count"]
            state = a["state"]
            if state != self.states[n]:
                log_.info("t=%.3f s axis %s: distance control %s -> %s", t, n,
                          self.names.get(int(self.states[n]), self.states[n]), self.names.get(int(state), state))
                self.states[n] = state


class ServedMachine:
    """A machine stepped in real time in a background thread (:meth:`start` / :meth:`stop`, or a
    ``with`` block). Services that serve it (ADS) :meth:`attach` to it and are started and stopped with
    it; observers (the live page's recorder) run after every cycle, under the lock."""

    def __init__(self, scenario, *, rt_priority: int = 0, speed: float = 1.0):
        self.scenario = scenario
        self.machine = Machine(scenario, load_program(scenario), publish_hli=True)
        #: held by the cycle and by every reader and writer (ADS requests, the page's actions)
        self.lock = threading.Lock()
        self.paused = False
        #: axis_id (from 1, scenario order) -> the axis's CNC-object context (docs/objects.md)
        self.contexts = {i + 1: AxisObjectContext(i + 1, n, self.machine.controllers[n], self.machine.outputs[n],
                                                  scenario.axes[n].resolution or 1e-4)
                         for i, n in enumerate(self.machine.axis_names)}
        self.session = SessionLog(self.machine)
        #: called after every cycle in the cycle thread, under the lock (the live page's recorder,
        #: distctrl/ui/hub.py): keep them to a few microseconds
        self.observers: list = []
        #: name -> an attached service (``start()``, ``stop()``), e.g. ``"ads"``
        self.services: dict = {}
        #: machine seconds per wall-clock second (1: real time; more: faster, as far as the CPU allows)
        self.speed = float(speed)
        if not (self.speed > 0 and self.speed < float("inf")):
            raise ValueError(f"speed = {speed!r}; allowed: a finite value > 0")
        #: the wall-clock time of the start as a Windows FILETIME (100 ns since 1601): the stamps of
        #: cycle-synchronous notifications are this + cycle x T (machine time)
        self.start_filetime = 0
        self.loop = RealTimeLoop(self.step, scenario.cycle_time / self.speed, lock=self.lock,
                                 rt_priority=rt_priority)

    def attach(self, name: str, service):
        """Serve the machine with ``service`` too (started before the cycle, stopped after it)."""
        if name in self.services:
            raise ValueError(f"a service {name!r} is attached already")
        self.services[name] = service
        return service

    def status(self) -> dict:
        """The machine's status snapshot (:func:`distctrl.sim.status.machine_status`) and ``paused``;
        take :attr:`lock` around it outside the cycle thread."""
        return {**self.machine.status(), "paused": self.paused}

    def event_cursor(self, *, from_now: bool = False):
        """An event cursor over the machine's errors and warnings (:class:`~distctrl.sim.status.EventCursor`)."""
        return self.machine.event_cursor(from_now=from_now)

    def step(self) -> None:
        """One cycle of the machine, then the session log (under the loop's lock); nothing while the
        PLC runtime is stopped (WriteControl STOP on port 851)."""
        if self.paused:
            return
        self.machine.step()
        self.session.after_cycle()
        for observer in self.observers:
            observer()

    def note(self, what: str) -> None:
        """One console line with the machine time: what a client did to the machine (the live page's
        sensor faults, Reset, Feed hold, ...; R18)."""
        log.info("t=%.3f s %s", self.machine.cycle * self.machine.T, what)

    def set_paused(self, paused: bool) -> None:
        if paused != self.paused:
            self.paused = paused
            log.info("t=%.3f s PLC runtime %s (WriteControl)", self.machine.cycle * self.machine.T,
                     "STOP: the machine holds" if paused else "RUN: the machine runs on")

    def cycle_filetime(self) -> int:
        """The time stamp of the machine's current cycle (FILETIME, 100 ns): start + cycle x T."""
        return self.start_filetime + int(round(self.machine.cycle * self.machine.T * 1e7))

    def start(self) -> None:
        self.start_filetime = int((time.time() + 11644473600) * 10_000_000)
        started = []
        try:
            for service in self.services.values():
                service.start()
                started.append(service)
            self.loop.start()
        except BaseException:
            for service in reversed(started):
                service.stop()
            raise
        for line in self.session.axis_lines():
            log.info("%s", line)
        if self.loop.rt_priority > 0:
            deadline = time.monotonic() + 1.0
            while self.loop.scheduling == "normal" and time.monotonic() < deadline and self.loop.running:
                time.sleep(0.001)
            log.log(logging.INFO if self.loop.scheduling.startswith("SCHED") else logging.WARNING,
                    "cycle thread: %s", self.loop.scheduling)

    def stop(self) -> dict:
        """Stop the cycle and the attached services; the cycle's lateness statistics."""
        self.loop.stop()
        for service in reversed(list(self.services.values())):
            service.stop()
        return self.loop.stats.summary()

    def __enter__(self):
        self.start()
        return self

    def __exit__(self, *exc):
        self.stop()
