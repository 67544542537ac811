"""What every process function shares: the axis, its FREEZE hold, and the HLI state it reads."""
from __future__ import annotations

from ...control.states import HliState
from .hold import RUNNING_TRACKING, FreezeHold

__all__ = ["ProcessFunction", "tracking_or_held"]

_FREEZE = int(HliState.FREEZE)


def tracking_or_held(state: int, hold: FreezeHold) -> bool:
    """Distance control tracks (ACTIVE, ACTIVE_CONST_DIST), or is in a FREEZE this hold commanded."""
    return state in RUNNING_TRACKING or (state == _FREEZE and hold.held_by_us)


class ProcessFunction:
    """One process function on one distance-controlled axis. :meth:`step` runs once per PLC cycle
    (the GEO cycle) and may call ``self.hold.request(self.name)``; the
    :class:`~distctrl.plc.process.program.ProcessProgram` binds the hold and runs the holds after
    every function."""

    name = "process"

    def __init__(self, axis: str):
        self.axis = axis
        self.hold: FreezeHold | None = None

    def bind(self, hold: FreezeHold) -> None:
        self.hold = hold

    def step(self, machine, cycle: int) -> None:  # pragma: no cover - every function overrides it
        raise NotImplementedError
