"""Corner lock (velocity anti-dive): FREEZE while the path is slower than a share of the programmed feed.

Where the path slows down (a corner, a block end, a feed hold) a plasma arc's voltage rises and a
height control that follows it lowers the torch into the plate. The lock holds the height (FREEZE)
while the path velocity is below ``share`` of the programmed feed and re-activates distance control
(FREEZE -> ON / ON_CONST_DIST, :mod:`.hold`) once it is back at ``share + hysteresis``. It follows
QtPlasmaC's "velocity anti-dive" (VAD threshold, 90 % of the cut feed by default) and LinuxCNC
plasmac's corner lock.

Reads (CNC -> PLC): ``StateBahn_Data.D_ActiveFeed`` / ``D_CommandFeed`` (DINT, µm/s,
:class:`~distctrl.plc.process.channel.ChannelPathStatus`), the path override the PLC commands, and
``state_r.actual_state``. The reference is ``F · override``: at 50 % override the path is not "slow".
The lock is armed once the path has reached ``share + hysteresis`` of the reference after distance
control became ACTIVE, so a select at rest (before the first move, e.g. with ``WAIT``) is not frozen
before the cut is under way; it is disarmed when distance control leaves ACTIVE / ACTIVE_CONST_DIST
(and a FREEZE of its own).

ST equivalent (one instance per axis; ``pMC`` the channel, ``dc`` the axis's control unit)::

    lrRef := DINT_TO_LREAL(pMC^.addr^.StateBahn_Data.D_CommandFeed) * lrOverride;     (* um/s *)
    lrV   := DINT_TO_LREAL(pMC^.addr^.StateBahn_Data.D_ActiveFeed);
    IF NOT fbHold.bTrackingOrHeld THEN
        bArmed := FALSE; bLock := FALSE;
    ELSIF NOT bArmed THEN
        bArmed := lrRef > 0.0 AND lrV >= (lrShare + lrHyst) * lrRef;
    ELSIF bLock THEN
        bLock := NOT (lrRef > 0.0 AND lrV >= (lrShare + lrHyst) * lrRef);
    ELSE
        bLock := lrRef <= 0.0 OR lrV < lrShare * lrRef;
    END_IF
    fbHold.bReqCorner := bArmed AND bLock;
"""
from __future__ import annotations

from ...errors.config import ConfigError
from .base import Key, ProcessFunction, ProcessTable, tracking_or_held

__all__ = ["CornerLock", "CORNER_DEFAULTS"]

#: documented defaults (docs/process.md)
CORNER_DEFAULTS = {"share": 0.9, "hysteresis": 0.05}


class CornerLock(ProcessFunction):
    """``share`` (0..1) of the programmed feed below which the height is held; ``hysteresis`` (0..0.5,
    share + hysteresis <= 1) above it before distance control is re-activated."""

    name = "corner_lock"
    KEYS = {
        "share": Key(CORNER_DEFAULTS["share"], "share of the programmed feed below which the height is held",
                     lo=0.0, hi=1.0, lo_open=True),
        "hysteresis": Key(CORNER_DEFAULTS["hysteresis"], "above share before distance control is re-activated "
                          "(share + hysteresis <= 1)", lo=0.0, hi=0.5),
    }

    @classmethod
    def from_config(cls, table: ProcessTable) -> dict:
        share = table.read(cls, "share")
        return {"share": share, "hysteresis": table.read(cls, "hysteresis", hi=min(0.5, 1.0 - share))}

    @classmethod
    def build(cls, axis: str, cycle_time: float, params: dict) -> "CornerLock":
        return cls(axis, **params)

    def __init__(self, axis: str, share: float = CORNER_DEFAULTS["share"],
                 hysteresis: float = CORNER_DEFAULTS["hysteresis"], enabled: bool = True):
        super().__init__(axis, enabled)
        self.share = self.KEYS["share"].check(share, "corner_lock.share")
        self.hysteresis = self.KEYS["hysteresis"].check(hysteresis, "corner_lock.hysteresis")
        if self.share + self.hysteresis > 1.0:
            raise ConfigError("corner_lock.hysteresis", hysteresis,
                              f"share + hysteresis <= 1 (share = {self.share:g}): the path must be able "
                              "to reach the release level at 100 % override", "out of range:")
        self.reset()

    def reset(self) -> None:
        self.armed = False
        self.locked = False

    def step(self, machine, cycle: int) -> None:
        unit = machine.hli[self.axis]
        if not tracking_or_held(unit.state_r.actual_state, self.hold):
            self.armed = self.locked = False
            return
        path = machine.channel_path
        ref = path.D_CommandFeed * path.override
        v = path.D_ActiveFeed
        back = ref > 0.0 and v >= (self.share + self.hysteresis) * ref
        if not self.armed:
            self.armed = back
        elif self.locked:
            self.locked = not back
        else:
            self.locked = ref <= 0.0 or v < self.share * ref
        if self.armed and self.locked:
            self.hold.request(self.name)
