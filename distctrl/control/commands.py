"""Commands the cycle core consumes at the start of a cycle.

Every way of commanding distance control maps onto these values: an NC block
``Z[DIST_CTRL ON SET_POS=30 KP=0.5]`` becomes one :class:`Command` with ``action=ON``,
``set_pos=30.0`` and ``kp=0.5``; a PLC ``command_w`` with transition 1 becomes
``Command.from_hli(1, position)``; a CNC object write becomes an :class:`ObjectWrite`.
All lengths are mm, times s (SPEC §1); conversion from interface units happens before.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

from ..base.kinds import FilterType, SensorSource
from ..base.states import CommandSource, HliTransition


class Action(IntEnum):
    """What a command asks for. NONE only sets values (e.g. ``Z[DIST_CTRL SET_POS=30]``)."""

    NONE = 0
    ON = 1            # select (SET_POS, or CONST_DIST with const_dist=True)
    DRYRUN = 2        # select without tracking the axis (with const_dist: distance dry run)
    FREEZE = 3
    OFF = 4           # with no_move=True: OFF NO_MOVE
    CHECK_POS = 5
    REF = 6
    RESET = 7         # CNC reset: deselect at once, offset absorbed, set values forgotten
    AXIS_ERROR = 8    # axis error: as reset for this axis
    PROGRAM_END = 9   # M30/M2: stays active (warning 70332), set values forgotten for the next select
    AXIS_RELEASE = 10  # the axis is to be released from the channel (70333 while active)
    CHANNEL_ERROR = 11  # the channel stopped with an error (NC run-time error): a running distance
    #                     control goes to ERROR holding its offset (the channel reports the error)


@dataclass(frozen=True, slots=True)
class Command:
    """One distance-control command (NC block, PLC transition or system event).

    Optional fields left at ``None`` are not changed. ``line`` is the NC line for error reports.
    """

    action: Action = Action.NONE
    const_dist: bool = False
    no_move: bool = False
    set_pos: float | None = None        # mm, absolute position of the workpiece surface
    set_dist: float | None = None       # mm, distance to the workpiece surface
    ref_position: float | None = None   # mm, REF: position of the workpiece surface now (REF_POS; None: sensor zero)
    # tuning, adopted with the command (bumpless)
    kp: float | None = None
    i_tn: float | None = None           # s
    d_tv: float | None = None           # s
    filter_type: FilterType | None = None
    n_cycles: int | None = None
    fg_f0: float | None = None          # Hz
    order: int | None = None
    smooth_fact: float | None = None
    kalman_sigma: float | None = None
    sensor_source: SensorSource | None = None
    sensor_var: str | None = None
    vals: tuple[float | None, ...] = (None, None, None, None, None)   # VAL1..VAL5
    source: CommandSource = CommandSource.NC
    line: int | None = None

    @staticmethod
    def from_hli(transition: int, position_mm: float = 0.0, *, line: int | None = None) -> "Command":
        """Map a PLC ``command_w`` (transition number, position already converted to mm)."""
        t = HliTransition(int(transition))
        plc = CommandSource.PLC
        if t == HliTransition.OFF:
            return Command(Action.OFF, source=plc, line=line)
        if t == HliTransition.ON:
            return Command(Action.ON, set_pos=position_mm, source=plc, line=line)
        if t == HliTransition.FREEZE:
            return Command(Action.FREEZE, source=plc, line=line)
        if t == HliTransition.REF:
            return Command(Action.REF, ref_position=position_mm, source=plc, line=line)
        if t == HliTransition.ON_CONST_DIST:
            return Command(Action.ON, const_dist=True, set_dist=position_mm, source=plc, line=line)
        if t == HliTransition.DRYRUN:
            return Command(Action.DRYRUN, set_pos=position_mm, source=plc, line=line)
        return Command(Action.DRYRUN, const_dist=True, set_dist=position_mm, source=plc, line=line)


#: CNC objects that accept writes (FCT-M3 §7.6); adopted on INACTIVE->active / FREEZE->active
WRITABLE_OBJECTS = ("kp", "i_tn", "d_tv", "v_max", "a_max")


@dataclass(frozen=True, slots=True)
class ObjectWrite:
    """A write to a read/write CNC object, in internal units.

    ``name`` is one of :data:`WRITABLE_OBJECTS`: ``kp`` (-), ``i_tn`` / ``d_tv`` (s),
    ``v_max`` (mm/s, object DIST_CTRL_PARAM[0]::v_max is µm/s), ``a_max`` (mm/s²).
    The value becomes effective only on the next INACTIVE->active or FREEZE->active transition.
    """

    name: str
    value: float
    line: int | None = None
    meta: dict = field(default_factory=dict, compare=False)
