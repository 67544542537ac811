"""What every process function shares: the axis, its FREEZE hold, the HLI state it reads, and the
switch that turns it on and off while the machine runs."""
from __future__ import annotations

from ...base.states import HliState
from ...errors.config import ConfigError
from .hold import RUNNING_TRACKING, FreezeHold

__all__ = ["ProcessFunction", "tracking_or_held", "require_bool"]

_FREEZE = int(HliState.FREEZE)


def tracking_or_held(state: int, hold: FreezeHold) -> bool:
    """Distance control tracks (ACTIVE, ACTIVE_CONST_DIST), or is in a FREEZE this hold commanded."""
    return state in RUNNING_TRACKING or (state == _FREEZE and hold.held_by_us)


def require_bool(value: object, key: str) -> bool:
    """``value`` if it is a boolean; else :class:`ConfigError` naming ``key``."""
    if not isinstance(value, bool):
        raise ConfigError(key, value, "true or false", "not a boolean:")
    return value


class ProcessFunction:
    """One process function on one distance-controlled axis. :meth:`step` runs once per PLC cycle
    (the GEO cycle) while :attr:`enabled` and may call ``self.hold.request(self.name)``; the
    :class:`~distctrl.plc.process.program.ProcessProgram` binds the hold, runs the enabled functions
    and then the holds after every cycle, and switches functions on and off
    (:meth:`~distctrl.plc.process.program.ProcessProgram.set_enabled`).

    Every function implements :meth:`reset` (back to the state it was built in; the program calls it
    whenever the function is switched on or off, so a function switched on again starts afresh).
    """

    name = "process"

    def __init__(self, axis: str, enabled: bool = True):
        self.axis = axis
        self.hold: FreezeHold | None = None
        #: what the switch says (``[[process]]`` key ``enabled``, ADS ``Process.<axis>.<name>.enabled``,
        #: :meth:`~distctrl.plc.process.program.ProcessProgram.set_enabled`)
        self.switched_on = require_bool(enabled, f"{self.name}.enabled")

    @property
    def finishing(self) -> bool:
        """Switched off, the function still runs while this is true: a motion of its own under way
        that must end first (a lift landing, a touch-off ending safely, a retract). None here."""
        return False

    @property
    def enabled(self) -> bool:
        """The function runs: switched on, or switched off while it is :attr:`finishing`."""
        return self.switched_on or self.finishing

    @enabled.setter
    def enabled(self, on: bool) -> None:
        self.switched_on = bool(on)

    def bind(self, hold: FreezeHold) -> None:
        self.hold = hold

    def step(self, machine, cycle: int) -> None:  # pragma: no cover - every function overrides it
        raise NotImplementedError

    def reset(self) -> None:  # pragma: no cover - every function overrides it
        raise NotImplementedError

    @property
    def requesting_hold(self) -> bool:
        """The function requested the FREEZE hold in the last cycle it ran (it still wants it)."""
        return self.hold is not None and self.hold.requested_by(self.name)

    def status(self) -> dict:
        """What a UI shows of the function: ``name``, ``axis``, ``enabled``, ``requesting_hold``."""
        return {"name": self.name, "axis": self.axis, "enabled": self.enabled,
                "requesting_hold": self.requesting_hold}
