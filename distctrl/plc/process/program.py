"""The process functions of a machine as one chained PLC program (``program(machine, cycle)``)."""
from __future__ import annotations

from .hold import FreezeHold

__all__ = ["ProcessProgram"]


class ProcessProgram:
    """Runs every function in order, then each axis's :class:`FreezeHold`.

    One :class:`FreezeHold` per axis is shared by the functions of that axis. The machine runs this
    program in its PLC task after the sensor's program and before a run's own
    (:func:`distctrl.plc.chain.chain`).
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
            f.step(machine, cycle)
        for h in self._holds:
            h.step(machine, cycle)

    def function(self, name: str, axis: str | None = None):
        """The first function called ``name`` (on ``axis``), or None."""
        for f in self.functions:
            if f.name == name and (axis is None or f.axis == axis):
                return f
        return None

    def __repr__(self) -> str:
        return "ProcessProgram(" + ", ".join(f"{f.name}@{f.axis}" for f in self.functions) + ")"
