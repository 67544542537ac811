"""The PLC task of the virtual machine: its programs run one after another in every GEO cycle.

A PLC program is a callable ``program(machine, cycle)`` (docs/plc.md). The machine runs the
sensor's program (the arc-voltage linearisation), the scenario's process functions and a run's own
program in that order, as one task: :func:`chain` puts them together.
"""
from __future__ import annotations

__all__ = ["PlcChain", "chain"]


class PlcChain:
    """Runs ``programs`` in order, each with the same machine and cycle."""

    __slots__ = ("programs",)

    def __init__(self, programs) -> None:
        self.programs = tuple(programs)

    def __call__(self, machine, cycle: int) -> None:
        for program in self.programs:
            program(machine, cycle)

    def __repr__(self) -> str:
        return "PlcChain(" + ", ".join(map(repr, self.programs)) + ")"


def chain(*programs):
    """The given programs that are not None, run in order: None if there are none, the program
    itself if there is one, else a :class:`PlcChain`."""
    present = [p for p in programs if p is not None]
    if not present:
        return None
    return present[0] if len(present) == 1 else PlcChain(present)
