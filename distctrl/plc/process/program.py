"""The process functions of a machine as one chained PLC program (``program(machine, cycle)``)."""
from __future__ import annotations

from .hold import FreezeHold

__all__ = ["ProcessProgram"]


class ProcessProgram:
    """Runs every enabled function in order, then each axis's :class:`FreezeHold`.

    One :class:`FreezeHold` per axis is shared by the functions of that axis. The machine runs this
    program in its PLC task after the sensor's program and before a run's own
    (:func:`distctrl.plc.chain.chain`). :meth:`set_enabled` switches a function on or off while the
    machine runs (``distctrl serve``: the ADS symbol ``Process.<axis>.<function>.enabled``).
    """

    def __init__(self, functions):
        self.functions = list(functions)
        self.holds: dict[str, FreezeHold] = {}
        for f in self.functions:
            if f.axis not in self.holds:
                self.holds[f.axis] = FreezeHold(f.axis)
            f.bind(self.holds[f.axis])
        self._holds = list(self.holds.values())

    def __call__(self, machine, cycle: int) -> None:
        for f in self.functions:
            if f.enabled:
                f.step(machine, cycle)
        for h in self._holds:
            h.step(machine, cycle)

    def function(self, name: str, axis: str | None = None):
        """The first function called ``name`` (on ``axis``), or None."""
        for f in self.functions:
            if f.name == name and (axis is None or f.axis == axis):
                return f
        return None

    def set_enabled(self, name: str, axis: str, on: bool) -> None:
        """Switch the function ``name`` on ``axis`` on or off (between two cycles, or from within a
        cycle before the holds run). A change resets the function (:meth:`ProcessFunction.reset`);
        switched off it does nothing and its hold request is withdrawn, so a FREEZE it held is
        released through the normal hold logic (FREEZE -> ON / ON_CONST_DIST with the set value
        remembered, unless another function of the axis still requests the hold). Switched on again
        it starts afresh: a lock arms as after a select, the automatic set value waits for the next
        cut. An unknown name/axis raises KeyError."""
        f = self.function(name, axis)
        if f is None:
            raise KeyError(f"no process function {name!r} on axis {axis!r}; configured: "
                           + (", ".join(f"{g.name}@{g.axis}" for g in self.functions) or "none"))
        on = bool(on)
        # the switch itself: a function still finishing reads enabled (a lift landing)
        if on == f.switched_on:
            return
        f.switched_on = on
        f.reset()
        if not on:
            f.hold.withdraw(f.name)

    def reset(self) -> None:
        """Every function and every hold back to its initial state (``enabled`` unchanged)."""
        for f in self.functions:
            f.reset()
        for h in self._holds:
            h.reset()

    def status(self) -> list[dict]:
        """Every function's :meth:`~ProcessFunction.status`, in program order."""
        return [f.status() for f in self.functions]

    def __repr__(self) -> str:
        return "ProcessProgram(" + ", ".join(f"{f.name}@{f.axis}" + ("" if f.enabled else " (off)")
                                             for f in self.functions) + ")"
