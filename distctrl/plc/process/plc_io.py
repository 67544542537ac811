"""What the motion process functions (touch-off, collision retract) read and write besides the HLI
control unit, each as a TwinCAT PLC does it:

* CNC objects of the axis (docs/objects.md): read with :func:`read_object`, written with
  :func:`write_object` (an ADS write of the object; the controller keeps it pending and adopts it on
  INACTIVE -> active or FREEZE -> active, FCT-M3 §7.6);
* the distance signal: a V.E. variable in mm, or ``state_r.actual_distance`` (DINT 0.1 µm);
* an application error: the PLC reports it (with the NC line the channel shows) and stops the
  program (:func:`report_error`), as an integrator's error handler does.
"""
from __future__ import annotations

import math

from ...errors import make_event
from ...objects.registry import AxisObjectContext, find_spec, read_value, write_value

__all__ = ["read_object", "write_object", "read_signal", "report_error", "following_error", "MM_PER_UNIT",
           "HliCommandSender"]

#: DINT 0.1 µm -> mm
MM_PER_UNIT = 1e-4


def _ctx(machine, axis: str) -> AxisObjectContext:
    """The axis's object context; the drive resolution (mm per increment, the axis parameters a PLC
    knows) scales the objects in increments."""
    unit = machine.hli[axis]
    drive = getattr(machine, "drives", {}).get(axis)
    res = getattr(drive, "resolution", 0.0) or 1e-4
    return AxisObjectContext(unit.axis_index, axis, machine.controllers[axis], machine.outputs[axis],
                             drive_resolution_mm=res)


def following_error(machine, axis: str) -> float:
    """The drive's following error in mm: CNC objects ``dig cmd pos high_res`` (0x3A02) minus
    ``dig act pos`` (0x3A03), both in drive increments."""
    ctx = _ctx(machine, axis)
    incr = read_value(find_spec("dig cmd pos high_res"), ctx) - read_value(find_spec("dig act pos"), ctx)
    return incr * ctx.drive_resolution_mm


def read_object(machine, axis: str, name: str):
    """The value of CNC object ``name`` of ``axis`` in the object's unit (e.g. µm/s for v_max)."""
    return read_value(find_spec(name), _ctx(machine, axis))


def write_object(machine, axis: str, name: str, value) -> None:
    """Write CNC object ``name`` of ``axis`` (object unit); adopted on the next INACTIVE/FREEZE -> active."""
    machine.inputs[axis].commands.append(write_value(find_spec(name), _ctx(machine, axis), value))


def read_signal(machine, axis: str, variable: str | None) -> float:
    """The distance signal in mm: V.E. ``variable`` (NaN if missing), else ``state_r.actual_distance``."""
    if variable is None:
        return machine.hli[axis].state_r.actual_distance * MM_PER_UNIT
    return machine.variables.get(variable, math.nan)


def report_error(machine, cycle: int, error_id: int, detail: str):
    """Report an application error of cycle ``cycle`` with the NC line the channel is in, and stop the
    program (the path decelerates at the axis limits and holds). Returns the event."""
    nc = getattr(machine, "nc", None)
    line = nc.line if nc is not None else None
    event = make_event(int(error_id), cycle, line, detail)
    machine.events.append((cycle * machine.T, event))
    machine.stop_program(None)
    return event


class HliCommandSender:
    """A command for the axis's HLI control unit, kept until the handshake takes it: ``_send`` writes
    it now if the semaphore is free, ``_flush`` retries a command still waiting (each cycle, before
    anything else). ``_pending`` is the (transition, position mm) waiting, ``_sent`` the cycle the
    last one was taken. Shared by the functions that move the axis (touch-off, collision retract)."""

    _pending: tuple[int, float] | None = None
    _sent: int = -1

    def _send(self, unit, cycle: int, transition: int, position: float = 0.0) -> None:
        self._pending = (transition, position)
        self._flush(unit, cycle)

    def _flush(self, unit, cycle: int) -> None:
        transition, position = self._pending
        if unit.plc_command(transition, position):
            self._pending = None
            self._sent = cycle
