"""The process functions of a machine as one chained PLC program (``program(machine, cycle)``)."""
from __future__ import annotations

from .hold import FreezeHold

__all__ = ["ProcessProgram"]


class ProcessProgram:
    """Runs every function in order, then each axis's :class:`FreezeHold`, then the next program.

    One :class:`FreezeHold` per axis is shared by the functions of that axis. :meth:`then` chains a
    further PLC program (the run's own ``plc_program``) that runs after these in the same cycle.
    """

    def __init__(self, functions, holds: dict[str, FreezeHold] | None = None, next_program=None):
        self.functions = list(functions)
        if holds is None:
            holds = {}
            for f in self.functions:
                if f.axis not in holds:
                    holds[f.axis] = FreezeHold(f.axis)
                f.bind(holds[f.axis])
        self.holds = holds
        self._holds = list(holds.values())
        self._next = next_program

    def __call__(self, machine, cycle: int) -> None:
        for f in self.functions:
            f.step(machine, cycle)
        for h in self._holds:
            h.step(machine, cycle)
        if self._next is not None:
            self._next(machine, cycle)

    def then(self, program) -> "ProcessProgram":
        """These functions followed by ``program(machine, cycle)`` (the same function instances)."""
        return ProcessProgram(self.functions, self.holds, program)

    def function(self, name: str, axis: str | None = None):
        """The first function called ``name`` (on ``axis``), or None."""
        for f in self.functions:
            if f.name == name and (axis is None or f.axis == axis):
                return f
        return None

    def __repr__(self) -> str:
        return "ProcessProgram(" + ", ".join(f"{f.name}@{f.axis}" for f in self.functions) + ")"
