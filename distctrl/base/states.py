"""States, transitions and codes of the axis distance control (HLI DistanceControl, FCT-M3 §8, SPEC §8)."""
from __future__ import annotations

from enum import IntEnum


class HliState(IntEnum):
    """HLI_DIST_CTRL_STATE_* as reported in ``state_r.actual_state``."""

    INACTIVE = 0
    ACTIVE = 1
    FREEZE = 2
    TURNING_OFF = 3
    ACTIVE_CONST_DIST = 4
    ERROR = 5
    DRYRUN_CONST_DIST = 6
    DRYRUN_SETPOS = 7


#: HLI_DIST_CTRL_STATE_* names by value (docs/states.md), used to label ``*.dc.state`` changes
HLI_STATE_NAMES: dict[int, str] = {int(s): s.name for s in HliState}


class HliTransition(IntEnum):
    """HLI_DIST_CTRL_* transitions a PLC may command through ``command_w.transition``."""

    OFF = 0
    ON = 1
    FREEZE = 2
    REF = 3
    ON_CONST_DIST = 4
    DRYRUN = 5
    CONST_DIST = 6   # dry run with distance specification


class InternalState(IntEnum):
    """Values of the CNC object ``DIST_CTRL::state`` (FCT-M3 §9.4)."""

    IDLE = 0
    ACTIVE = 2
    FREEZE = 3
    OFF = 4
    OFF_NO_MOVE = 5
    ERROR_SENSOR_JUMP = 6        # 70329
    ERROR_SENSOR_MAX = 7         # 70330
    ERROR_SENSOR_MIN = 8         # 70576
    ERROR_MAX_DEVIATION = 9      # 70331
    ERROR_COMMAND = 10           # 70333, 70334, invalid transition, source change
    ERROR_NO_SET_VALUE = 11      # 70335
    ERROR_OTHER = 12             # project-range errors (non-finite input, software limit, ...)
    DRYRUN = 15


#: error ID -> internal ERROR code (6..12); the project's choice, documented in docs/states.md
ERROR_CODE_BY_ID: dict[int, InternalState] = {
    70329: InternalState.ERROR_SENSOR_JUMP,
    70330: InternalState.ERROR_SENSOR_MAX,
    70576: InternalState.ERROR_SENSOR_MIN,
    70331: InternalState.ERROR_MAX_DEVIATION,
    70333: InternalState.ERROR_COMMAND,
    70334: InternalState.ERROR_COMMAND,
    900003: InternalState.ERROR_COMMAND,
    900004: InternalState.ERROR_COMMAND,
    70335: InternalState.ERROR_NO_SET_VALUE,
}


class Mode(IntEnum):
    """What the select specifies: the workpiece surface or a constant distance."""

    SET_POS = 0
    CONST_DIST = 1


class CommandSource(IntEnum):
    """``state_r`` command source: who selected the current distance control."""

    NC = 0
    PLC = 1


#: the states in which distance control is running (monitoring active, SPEC §7)
MONITORED_STATES = frozenset({HliState.ACTIVE, HliState.ACTIVE_CONST_DIST,
                              HliState.DRYRUN_SETPOS, HliState.DRYRUN_CONST_DIST})
#: the states that may be left towards another running state only through FREEZE or INACTIVE
RUNNING_STATES = MONITORED_STATES


def running_state(mode: Mode, dryrun: bool) -> HliState:
    if dryrun:
        return HliState.DRYRUN_CONST_DIST if mode == Mode.CONST_DIST else HliState.DRYRUN_SETPOS
    return HliState.ACTIVE_CONST_DIST if mode == Mode.CONST_DIST else HliState.ACTIVE
