"""The ADS client side of commissioning (issue 28): a real TwinCAT CNC (or ``distctrl serve``) read,
recorded and written through its CNC objects with pyads (the ``[ads]`` extra).

* :mod:`.target` — the connection (``--ads NETID[:PORT]``, ``--ip HOST``), bounded timeouts, and ADS
  errors as one-line :class:`MachineError` messages with the code and its meaning.
* :mod:`.axes` — the axes found on the target and their distance-control objects in the documents'
  user units (the parameter list's units), as ``distctrl params`` prints them.
* :mod:`.writer` — ``machine write``: the change plan, the backup, the writes, read back and verify,
  and the rollback from the backup when anything fails half way.
* :mod:`.recorder` — ``machine record``: cyclic device notifications at the CNC cycle with the
  target's timestamps, gaps counted, written as a distctrl trace.

Nothing here is imported by the cycle core; pyads is imported when a connection is opened.
"""
from __future__ import annotations

from .target import MachineError, Target, parse_target

__all__ = ["MachineError", "Target", "parse_target"]
