"""Error catalogue and error types.

Two kinds of error exist in distctrl, deliberately separate:

* On the cycle path errors are *values*: an :class:`ErrorEvent` carrying the documented error ID
  (FCT-M3 ch. 11, SPEC §7), the cycle number and, for NC commands, the block's line. The core
  never raises on bad cycle input.
* At the edges (files, parsing, CLI, constructing parameter sets) errors are exceptions derived
  from :class:`DistCtrlError`, each naming file, line, parameter ID, value and allowed range.

Errors the documents do not number get IDs in the project range >= 900000 (SPEC §7); they are
listed in :data:`CATALOGUE` and in docs/errors.md.
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum


class ErrorId(IntEnum):
    """Error IDs raised by the axis-specific distance control (documented and project range)."""

    SENSOR_JUMP = 70329            # actual value change of sensor signal greater than limit
    SENSOR_RUN_OUT_MAX = 70330     # sensor completely run out (upper limit - tolerance)
    MAX_DEVIATION = 70331          # excessive sensing deviation: |offset| would exceed max_deviation
    ACTIVE_AT_PROGRAM_END = 70332  # warning: distance control still active at program end
    AXIS_RELEASED_WHILE_ACTIVE = 70333
    SELECT_WHILE_TURNING_OFF = 70334
    SELECT_WITHOUT_SET_VALUE = 70335
    NOT_AVAILABLE = 70336          # P-AXIS-00328 = 0 or function not available
    SENSOR_RUN_OUT_MIN = 70576     # sensor below lower limit + tolerance
    # --- project range (not numbered by the documents) ---
    INPUT_NOT_FINITE = 900001      # a sensor or position input is NaN or infinite
    SW_LIMIT = 900002              # offset would move the axis beyond a software limit (P-AXIS-00428 = 1)
    INVALID_TRANSITION = 900003    # transition not permitted from the current state (FCT-M3 Fig. 35)
    SENSOR_SOURCE_CHANGED = 900004  # sensor source changed while active
    COMMAND_VALUE_OUT_OF_RANGE = 900005  # a programmed/commanded value outside its documented range
    OBJECT_READ_ONLY = 900006      # write to a CNC object that is not read/write
    SENSOR_NOT_REFERENCED = 900008  # select with a sensor that is not absolute before it was referenced (REF)
    NO_MOVE_IN_ERROR = 900009      # warning: OFF NO_MOVE in ERROR acts as OFF (ERROR is left only through TURNING_OFF)
    NC_RUNTIME = 900010            # NC program stopped at run time (undefined variable, value out of range)
    KIN98_MAX_INCLINATION = 900020  # 3D: tool inclination above kinematic 98's HD4 (the program aborts)
    MODE_OFF_SELECTED = 900023     # 3D warning: select with MODE=OFF, the offset is computed, not superimposed
    SET_DIST_NOT_TOOL_LENGTH = 900024  # 3D warning: CONST_DIST with a transformation on and SET_DIST != tool length
    COLLISION = 900030             # simulator: the tool went into the surface (true distance <= -collision_depth)
    OSCILLATION = 900032           # simulator warning: the distance error oscillated for whole seconds of tracking
    SENSOR_NOT_READ = 900031       # simulator warning: the distance sensor writes a V.E. variable the axis does not read
    # --- process functions (PLC programs, docs/process.md) ---
    TOUCH_OFF_NO_SURFACE = 900050  # touch-off: no surface within the stroke
    TOUCH_OFF_RETRIES = 900051     # touch-off: every detection was false (the signal did not stay), retries exhausted
    TOUCH_OFF_FAILED = 900052      # touch-off refused or ended by distance control (state, refused select, back-off timeout)
    COLLISION_RETRACT = 900053     # collision detected by the sensor: the head retracted, distance control off, program stopped


#: ID -> (severity, short text). Severity "error" puts the controller into ERROR, "warning" does not.
CATALOGUE: dict[int, tuple[str, str]] = {
    70329: ("error", "Actual value change of sensor signal greater than limit (P-AXIS-00417)"),
    70330: ("error", "Sensor completely run out: reading above max_pos - tolerance (P-AXIS-00419/00421)"),
    70331: ("error", "Excessive sensing deviation: offset would exceed max_deviation (P-AXIS-00414)"),
    70332: ("warning", "Distance control still active at program end"),
    70333: ("error", "Distance control active for axis that is to be released from the channel"),
    70334: ("error", "On repeat selection, deselection of distance control not yet complete"),
    70335: ("error", "Distance control selected without programmed position (SET_POS / SET_DIST)"),
    70336: ("error", "Function is not available (P-AXIS-00328 lr_param.distance_control_on = 0)"),
    70576: ("error", "Sensor completely run out: reading below min_pos + tolerance (P-AXIS-00420/00421)"),
    900001: ("error", "Sensor or position input is not a finite number"),
    900002: ("error", "Distance-control offset would move the axis beyond its software limit (P-AXIS-00428)"),
    900003: ("error", "Transition not permitted in the current distance-control state"),
    900004: ("error", "Sensor source changed while distance control is active"),
    900005: ("error", "Commanded value outside its documented range"),
    900006: ("error", "CNC object is read-only"),
    900008: ("error", "Sensor not referenced: a sensor that is not absolute must be referenced (REF) before a select"),
    900009: ("warning", "OFF NO_MOVE in ERROR acts as OFF: ERROR is left only through TURNING_OFF"),
    900010: ("error", "NC program stopped at run time"),
    900020: ("error", "Tool inclination exceeds the maximum angle of kinematic 98 (HD4, PARAM[3])"),
    900023: ("warning", "3D distance control selected with MODE=OFF: the offset is computed, not superimposed"),
    900030: ("warning", "Collision: the tool went into the surface (the simulator's true distance reached "
                        "-sensor.collision_depth)"),
    900032: ("warning", "Oscillation: the distance error oscillated (two whole periods or more above the "
                        "settle band, repeating itself period after period) in a whole second of tracking"),
    900031: ("warning", "The distance sensor writes a V.E. variable, but the axis reads the second encoder "
                        "(SENSOR_SOURCE is not VARIABLE): nobody reads the sensor"),
    900050: ("error", "Touch-off: no surface within the stroke"),
    900051: ("error", "Touch-off: retries exhausted (the surface reading did not stay once the head had stopped)"),
    900052: ("error", "Touch-off could not run or was ended by distance control"),
    900053: ("error", "Collision: the sensor reported contact; the head retracted and distance control was "
                      "switched off"),
    900024: ("warning", "3D distance control: the set distance differs from the tool length of the kinematic "
                        "transformation (FCT-M3 §12.1.2: tool length = set distance)"),
}


@dataclass(frozen=True, slots=True)
class ErrorEvent:
    """One error or warning produced on the cycle path (a value, never raised)."""

    id: int
    cycle: int
    line: int | None = None
    message: str = ""
    severity: str = "error"

    def __str__(self) -> str:
        where = f" (NC line {self.line})" if self.line is not None else ""
        return f"{self.severity} {self.id} at cycle {self.cycle}{where}: {self.message}"


def make_event(error_id: int, cycle: int, line: int | None, detail: str = "",
               severity: str | None = None) -> ErrorEvent:
    """An event for a catalogued ID; ``severity`` overrides the catalogue (e.g. a refused write)."""
    default_severity, text = CATALOGUE[int(error_id)]
    return ErrorEvent(int(error_id), cycle, line, f"{text}{': ' + detail if detail else ''}",
                      severity or default_severity)


class ExitCode(IntEnum):
    """The exit codes of every ``distctrl`` command, whichever layer detects the condition (docs/run.md)."""

    OK = 0                  # done: the program ran to its end, the command did what it was asked
    INVALID_INPUT = 1       # a file, value or option is invalid (also click usage errors); nothing ran
    ABORTED = 2             # a control error (ID, NC line, time) aborted the NC program
    TIME_LIMIT = 3          # stopped at the run's time limit (duration) before the program ended
    CHECK_FAILED = 4        # it ran, but a check it makes failed (calibrate: the runs differ beyond the tolerance)
    INTERRUPTED = 130       # Ctrl-C / SIGINT (128 + 2, the shell's convention)


class DistCtrlError(Exception):
    """Base of every exception distctrl raises at its edges (files, parsing, CLI, construction)."""


class ParameterError(DistCtrlError, ValueError):
    """A parameter value, key or type is invalid. The message names where and what is allowed."""

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None,
                 key: str | None = None, param_id: str | None = None, value: object = None,
                 allowed: str | None = None):
        self.file, self.line, self.key, self.param_id = file, line, key, param_id
        self.value, self.allowed = value, allowed
        where = ""
        if file is not None:
            where = f"{file}:{line}: " if line is not None else f"{file}: "
        super().__init__(where + message)
