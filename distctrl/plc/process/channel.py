"""The channel's path status as a PLC reads it (TwinCAT CNC HLI, "Status information of a channel").

``pMC[channel_idx]^.addr^.StateBahn_Data.D_CommandFeed`` (DINT, 1 µm/s): the path velocity
programmed with the F word; ``...StateBahn_Data.D_ActiveFeed`` (DINT, 1 µm/s): the current path
feed of the interpolation. Read-only for the PLC. distctrl computes them when they are read, from the
NC's modal F and the interpolator's path velocity of the last cycle (0 while no G0/G1 block runs),
so a PLC program at the start of cycle k sees the values the CNC published at the end of cycle k-1.

``override`` is the path override in force (1.0 = 100 %): on a TwinCAT CNC the PLC writes it itself
(``gpCh[i]^.bahn_mc_control.override``), so a PLC program knows it; in the simulation scenario events
set it (``override``, ``feed_hold``).
"""
from __future__ import annotations

__all__ = ["ChannelPathStatus", "UM_PER_S_PER_MM_MIN"]

#: 1 mm/min = 1000/60 µm/s
UM_PER_S_PER_MM_MIN = 1000.0 / 60.0
_INT32_MAX = 2147483647


def _dint(x: float) -> int:
    n = int(round(x))
    return _INT32_MAX if n > _INT32_MAX else (-_INT32_MAX - 1 if n < -_INT32_MAX - 1 else n)


class ChannelPathStatus:
    """``StateBahn_Data`` of one channel (read-only): ``D_CommandFeed``, ``D_ActiveFeed`` in µm/s."""

    def __init__(self, machine):
        self._m = machine

    @property
    def D_CommandFeed(self) -> int:
        """The F word in force (µm/s, DINT); 0 before the program programmed one."""
        nc = self._m.nc
        feed = nc.feed if nc is not None else None
        return 0 if feed is None else _dint(feed * UM_PER_S_PER_MM_MIN)

    @property
    def D_ActiveFeed(self) -> int:
        """The current path velocity of the interpolation (µm/s, DINT); 0 while no G0/G1 block runs."""
        interp = self._m.interp
        if interp.block not in ("linear", "rapid"):
            return 0
        return _dint(interp.path_velocity * 1000.0)

    @property
    def override(self) -> float:
        """The path override in force (1.0 = 100 %), a value the PLC commands itself."""
        return float(self._m.channel_override)

    def __repr__(self) -> str:
        return f"ChannelPathStatus(D_CommandFeed={self.D_CommandFeed}, D_ActiveFeed={self.D_ActiveFeed})"
