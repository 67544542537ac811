"""The channel's path status as a PLC reads it (TwinCAT CNC HLI, "Status information of a channel").

``pMC[channel_idx]^.addr^.StateBahn_Data.D_CommandFeed`` (DINT, 1 µm/s): the path velocity
programmed with the F word; ``...StateBahn_Data.D_ActiveFeed`` (DINT, 1 µm/s): the current path
feed of the interpolation. Read-only for the PLC. distctrl computes them when they are read, from the
NC's modal F and the interpolator's path velocity of the last cycle (0 while no G0/G1 block runs),
so a PLC program at the start of cycle k sees the values the CNC published at the end of cycle k-1.

``D_CoveredDistance`` (DINT, 0.1 %): the part of the current block's path already travelled
(``StateBahn_Data.D_CoveredDistance``, same HLI section); 0 while no G0/G1 block runs.

``motion_type`` (UDINT): the motion type of the block the interpolator runs, 0 none (idle),
1 G0 (rapid), 2 G1 (linear), 3 dwell (``#TIME``). A distctrl extension without an HLI name: the
elements of ``StateBahn_Data`` in the HLI's "Status information of a channel" carry no block type
(a TwinCAT PLC learns of a positioning block from the M/H functions the program sends it, e.g. the
M5 that ends a cut); distctrl's NC has no M functions, so the PLC reads the block type here.

``override`` is the path override in force (1.0 = 100 %): on a TwinCAT CNC the PLC writes it itself
(``gpCh[i]^.bahn_mc_control.override``), so a PLC program knows it; in the simulation scenario events
set it (``override``, ``feed_hold``).
"""
from __future__ import annotations

__all__ = ["ChannelPathStatus", "UM_PER_S_PER_MM_MIN", "MOTION_NONE", "MOTION_RAPID", "MOTION_LINEAR",
           "MOTION_DWELL"]

#: 1 mm/min = 1000/60 µm/s
UM_PER_S_PER_MM_MIN = 1000.0 / 60.0
_INT32_MAX = 2147483647
#: ``motion_type``: no block, G0, G1, #TIME dwell
MOTION_NONE, MOTION_RAPID, MOTION_LINEAR, MOTION_DWELL = 0, 1, 2, 3
_MOTION = {"rapid": MOTION_RAPID, "linear": MOTION_LINEAR, "dwell": MOTION_DWELL}


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
    def D_CoveredDistance(self) -> int:
        """The travelled part of the current G0/G1 block's path (DINT, 0.1 %, 0..1000); 0 while none runs."""
        interp = self._m.interp
        if interp.block not in ("linear", "rapid") or interp.path_length <= 0.0:
            return 0
        return _dint(1000.0 * interp.path_position / interp.path_length)

    @property
    def motion_type(self) -> int:
        """The running block's motion: 0 none, 1 G0, 2 G1, 3 dwell (a distctrl extension, see above)."""
        return _MOTION.get(self._m.interp.block, MOTION_NONE)

    @property
    def override(self) -> float:
        """The path override in force (1.0 = 100 %), a value the PLC commands itself."""
        return float(self._m.channel_override)

    def __repr__(self) -> str:
        return f"ChannelPathStatus(D_CommandFeed={self.D_CommandFeed}, D_ActiveFeed={self.D_ActiveFeed})"
