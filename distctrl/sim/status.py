"""What consumers of a running machine read, in one place (Klipper's ``get_status`` is the model):
:func:`machine_status`, a snapshot of plain values, and :class:`EventCursor`, the machine's errors and
warnings each taken once. :func:`activity` is the cheap part a consumer that looks every cycle (the
session log) compares, to take the whole snapshot only when something happened.

The session log of ``distctrl serve`` (:class:`~distctrl.serve.machine.SessionLog`), the live page
(:class:`~distctrl.ui.hub.MachineHub`) and the run summary (:func:`~distctrl.sim.runner.run`) read the
machine through these two instead of its internals. :meth:`Machine.status
<distctrl.sim.machine.Machine.status>` and :meth:`Machine.event_cursor
<distctrl.sim.machine.Machine.event_cursor>` give them.
"""
from __future__ import annotations

from ..errors import ErrorEvent

__all__ = ["EventCursor", "machine_status", "axis_status", "activity", "REJECTED_SHOWN"]

#: how many of an axis's last refused PLC commands the status names (``rejected``)
REJECTED_SHOWN = 3


class EventCursor:
    """The machine's events ``(t, ErrorEvent)`` in the order they happened, each taken once:
    ``cursor = machine.event_cursor(); new = cursor.take()`` gives those added since the last take
    (an empty list costs one comparison). Every consumer keeps its own cursor."""

    __slots__ = ("_machine", "seen")

    def __init__(self, machine, start: int = 0):            # machine: a sim.machine.Machine
        self._machine = machine
        #: how many events were taken so far (the index of the next one)
        self.seen = start

    def take(self) -> list[tuple[float, ErrorEvent]]:
        """The events added since the last :meth:`take` (or since the cursor was made)."""
        events = self._machine.events
        n = len(events)
        if n == self.seen:
            return []
        new = events[self.seen:n]
        self.seen = n
        return new

    @property
    def pending(self) -> bool:
        """There are events the next :meth:`take` returns."""
        return len(self._machine.events) != self.seen


def axis_status(machine, name: str) -> dict:
    """One axis: its HLI control unit as the PLC sees it (command_w, enable_w, the semaphore, state_r),
    the commands the CNC took (``consumed``, a count) and refused (``rejected_count``; ``rejected``, the
    reasons of the last :data:`REJECTED_SHOWN`),
    distance control's state and offset, and the drive's actual position."""
    u = machine.hli[name]
    s = u.state_r
    c = u.command_w
    out = machine.outputs[name]
    rejected = u.rejected
    return {"index": u.axis_index, "transition": c.transition, "position": c.position, "enable_w": u.enable_w,
            "semaphore": u.command_semaphore_rw, "actual_state": s.actual_state,
            "actual_position": s.actual_position, "actual_offset": s.actual_offset,
            "command_source": s.command_source, "actual_distance": s.actual_distance,
            "consumed": u.consumed, "rejected": [r.reason for r in rejected[-REJECTED_SHOWN:]],
            "rejected_count": len(rejected),
            "dc_on": u.distance_control_on, "state": int(out.hli_state), "offset": out.offset,
            "act": machine.drives[name].actual}


def machine_status(machine) -> dict:
    """A snapshot of plain values (no references into the machine):

    * ``cycle`` (cycles run), ``t`` (s, the time of the last cycle run), ``cycle_time`` (s);
    * ``axes``: per axis name :func:`axis_status`;
    * ``nc``: ``line`` (the NC line running, None without a program) and ``state`` (``none``,
      ``running``, ``ended``, ``aborted``);
    * ``override`` (the channel's path override), ``x`` (mm, the X nozzle position, 0 without X),
      ``true_surface`` / ``true_distance`` (mm, the head over the surface);
    * ``process``: ``(name, axis, enabled)`` of every ``[[process]]`` function;
    * ``events``: how many errors and warnings the machine has had (an :class:`EventCursor` takes them).
    """
    nc = machine.nc
    proc = machine.process_program
    drives = machine.drives
    return {
        "cycle": machine.cycle, "t": max(machine.cycle - 1, 0) * machine.T, "cycle_time": machine.T,
        "axes": {n: axis_status(machine, n) for n in machine.axis_names},
        "nc": {"line": nc.line if nc is not None else None, "state": _nc_state(nc)},
        "override": machine.channel_override,
        "x": drives["X"].nozzle if "X" in drives else 0.0,
        "true_surface": machine.true_surface, "true_distance": machine.true_distance,
        "process": [] if proc is None else [(f.name, f.axis, f.enabled) for f in proc.functions],
        "events": len(machine.events),
    }


def _nc_state(nc) -> str:
    return "none" if nc is None else "aborted" if nc.aborted else "ended" if nc.ended else "running"


def activity(machine) -> tuple:
    """What changes when something the session log reports happens: the NC program's state, then per
    axis the PLC commands taken, the commands refused and distance control's HLI state. A few
    comparisons a cycle; equal values mean :func:`machine_status` has nothing new in those fields."""
    hli, outputs = machine.hli, machine.outputs
    nc = machine.nc
    # _nc_state written out: the served cycle calls this every cycle, and a call costs more than the test
    out = ["none" if nc is None else "aborted" if nc.aborted else "ended" if nc.ended else "running"]
    for n in machine.axis_names:
        u = hli[n]
        out += (u.consumed, len(u.rejected), outputs[n].hli_state)
    return tuple(out)
