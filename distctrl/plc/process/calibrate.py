"""Capacitive calibration run: move the head slowly down over a flat sheet and back, record the
sensor's reading against the axis position; ``distctrl calibrate`` turns the records into the
linearisation table the PLC uses (:mod:`distctrl.plc.linearisation`) and checks its repeatability.

A capacitive sensor's amplifier reports a distance that deviates from the true one by a few per cent
and not linearly (docs/sim-models.md, *Capacitive sensor*); FCT-M3 §12.3 gives the PLC the job of
removing the non-linearity ("The PLC must remove non-linear dependencies from the sensor value").
Height controls of laser heads (Precitec, Lasermech, BCS100, Weihong) calibrate it over a flat
sheet: the head moves down slowly from its start height to just above the sheet, the reading is
recorded against the axis position, and the table "reading -> distance" is stored. This function is
that run, as a PLC program using only the HLI control unit of the axis:

* **waits** until it is enabled, distance control is INACTIVE, the path is at rest
  (``StateBahn_Data.D_ActiveFeed`` = 0) and the axis stands still for ``settle`` seconds (the NC
  program has put the head above the sheet, selected the sensor with ``SENSOR_SOURCE=VARIABLE`` and
  waits with ``#TIME``, or has ended);
* **selects** CONST_DIST from the PLC (``command_w`` transition 4 ON_CONST_DIST) with SET_DIST = the
  measured distance ``d0`` (``state_r.actual_distance``), and writes the same value as the first
  cyclic ``D_Distance``: the head does not move on the select;
* **drives down**: every cycle ``D_Distance`` decreases by ``speed · T`` until ``bottom`` (measured
  distance); distance control follows, so the head moves down at about ``speed`` (exactly, where the
  sensor's slope is 1); it waits ``settle`` seconds there and **drives up** to ``d0`` the same way;
  ``runs`` times (down and up each time), waiting ``settle`` at the top between runs;
* **records** every cycle while driving (down and up) the pair (axis position, reading): the axis
  position is ``state_r.actual_position + state_r.actual_distance`` (``a − d + d``, 0.1 µm, the
  motor encoder of the last cycle), the reading the V.E. variable the sensor writes (``variable``;
  with a linearisation in force its raw reading, not the linearised one), of the same cycle;
* **ends** with OFF (transition 0: the tiny offset left runs out) and stops the cyclic command.
  Distance control leaving ACTIVE_CONST_DIST during the run (an error, a reset, another command)
  ends it as FAILED (``error`` says why); so does a select that is not taken within 0.1 s or a head
  that starts at or below ``bottom``.

The table is built outside the PLC (:func:`distctrl.workbench.calibrate.calibration_table`), as an
engineering tool reads the recorded array from the PLC. Driving down and up and averaging both
directions cancels the lag of the reading (the sensor's dead time) at the recording speed.

ST equivalent (``fbCal`` one instance per axis; ``dc`` the axis's control unit, ``rT`` the cycle time)::

    lrAxis := DINT_TO_LREAL(dc.state_r.actual_position + dc.state_r.actual_distance) * 0.0001;
    CASE eCal OF
    WAITING:   IF dc.state_r.actual_state = 0 AND pMC^.addr^.StateBahn_Data.D_ActiveFeed = 0
                  AND ABS(lrAxis - lrAxisOld) < 0.001 THEN nRest := nRest + 1; ELSE nRest := 0; END_IF
               IF nRest >= nSettle THEN
                   lrTop := DINT_TO_LREAL(dc.state_r.actual_distance) * 0.0001;
                   IF lrTop <= lrBottom THEN eCal := FAILED;
                   ELSIF NOT dc.command_semaphore_rw THEN
                       dc.command_w.transition := 4; dc.command_w.position := LREAL_TO_DINT(lrTop * 10000.0);
                       dc.enable_w := TRUE; dc.command_semaphore_rw := TRUE;
                       pCyc^.D_Distance := LREAL_TO_DINT(lrTop * 10000.0); lrSet := lrTop;
                       eCal := SELECTING; nCnt := 0;
                   END_IF
               END_IF
    SELECTING: IF dc.state_r.actual_state = 4 THEN eCal := DOWN; nRun := 1;
               ELSIF nCnt > nSelectTimeout THEN eCal := FAILED; ELSE nCnt := nCnt + 1; END_IF
    DOWN, UP:  IF dc.state_r.actual_state <> 4 THEN eCal := FAILED;
               ELSE
                   aAxis[nRec] := lrAxis; aRead[nRec] := V_E_SENSOR_RAW; aRun[nRec] := nRun; nRec := nRec + 1;
                   IF eCal = DOWN THEN lrSet := MAX(lrBottom, lrSet - lrSpeed * rT);
                   ELSE lrSet := MIN(lrTop, lrSet + lrSpeed * rT); END_IF
                   pCyc^.D_Distance := LREAL_TO_DINT(lrSet * 10000.0);
                   IF lrSet = lrBottom OR lrSet = lrTop THEN eNext := SEL(eCal = DOWN, DOWN, UP); eCal := DWELL; nCnt := 0; END_IF
               END_IF
    DWELL:     IF dc.state_r.actual_state <> 4 THEN eCal := FAILED;
               ELSIF nCnt >= nSettle THEN
                   IF eNext = UP THEN eCal := UP;
                   ELSIF nRun < nRuns THEN nRun := nRun + 1; eCal := DOWN;
                   ELSIF NOT dc.command_semaphore_rw THEN
                       dc.command_w.transition := 0; dc.enable_w := TRUE; dc.command_semaphore_rw := TRUE;
                       eCal := DONE;
                   END_IF
               ELSE nCnt := nCnt + 1; END_IF
    END_CASE
    lrAxisOld := lrAxis;
"""
from __future__ import annotations

import math

from ...base.states import HliState, HliTransition
from ...errors.config import ConfigError, require_number
from ..variables import ve_name
from .base import Key, ProcessFunction, ProcessTable, ve_key

__all__ = ["Calibrate", "CALIBRATE_DEFAULTS", "CalibrationRecord"]

#: documented defaults (docs/process.md)
CALIBRATE_DEFAULTS = {"speed": 1.0, "bottom": 0.3, "settle": 0.2, "runs": 2}
#: s: a select not taken within this is a failure
SELECT_TIMEOUT = 0.1
#: mm per cycle: the axis counts as standing still below this
REST_STEP = 1e-3
_MM_PER_UNIT = 1e-4
_INACTIVE = int(HliState.INACTIVE)
_ACTIVE_CD = int(HliState.ACTIVE_CONST_DIST)
_T_ON_CD = int(HliTransition.ON_CONST_DIST)
_T_OFF = int(HliTransition.OFF)
WAITING, SELECTING, DOWN, DWELL, UP, ENDING, DONE, FAILED = (
    "WAITING", "SELECTING", "DOWN", "DWELL", "UP", "ENDING", "DONE", "FAILED")


class CalibrationRecord:
    """What one calibration recorded: per sample the axis position (mm), the reading (mm), the run
    (1, 2, ...) and the direction (-1 down, +1 up); ``top`` the measured distance it started at."""

    def __init__(self):
        self.axis: list[float] = []
        self.reading: list[float] = []
        self.run: list[int] = []
        self.direction: list[int] = []
        self.top = math.nan
        self.start_cycle = -1
        self.end_cycle = -1

    def __len__(self) -> int:
        return len(self.axis)

    def __repr__(self) -> str:
        return f"CalibrationRecord({len(self)} samples, runs={max(self.run, default=0)})"


class Calibrate(ProcessFunction):
    """``speed`` (mm/s of set distance), ``bottom`` (mm, measured), ``settle`` (s), ``runs``,
    ``variable`` (the V.E. variable with the reading), ``cycle_time`` (s)."""

    name = "calibrate"
    KEYS = {
        "speed": Key(CALIBRATE_DEFAULTS["speed"], "mm/s of set distance", lo=0.0, hi=20.0, lo_open=True),
        "bottom": Key(CALIBRATE_DEFAULTS["bottom"], "mm measured, the lowest point (below the sensor's range_max)",
                      lo=0.0, hi=100.0, lo_open=True),
        "settle": Key(CALIBRATE_DEFAULTS["settle"], "s of rest before a point is taken (at least one cycle)",
                      hi=10.0),
        "runs": Key(CALIBRATE_DEFAULTS["runs"], "runs down and up", kind="int", lo=1, hi=10),
        "variable": Key(None, "V.E. variable with the reading; default the one the sensor writes", kind="name"),
    }

    @classmethod
    def from_config(cls, table: ProcessTable) -> dict:
        """The calibration run's keys: it records a distance sensor's reading on the axis it measures."""
        sensor, k, axis = table.sensor, table.prefix, table.axis
        if sensor is None or sensor.kind != "distance" or sensor.axis != axis:
            what = "no [sensor]" if sensor is None else f"a {sensor.kind!r} sensor on {sensor.axis}"
            raise ConfigError(k + "axis", axis, "the axis of a [sensor] with kind = 'distance' (the calibration "
                              f"run records a distance sensor's reading; the scenario has {what})",
                              "no distance sensor on")
        default_var = sensor.output_variable          # the raw reading when a linearisation is in force
        var = ve_key(table.get("variable", default_var), k + "variable",
                     "a V.E. variable name (default: the one the sensor writes)")
        return {"speed": table.read(cls, "speed"),
                "bottom": table.read(cls, "bottom", hi=sensor.range_max, hi_open=True),
                "settle": table.read(cls, "settle", lo=table.cycle_time), "runs": table.read(cls, "runs"),
                "variable": var}

    def __init__(self, axis: str, cycle_time: float, variable: str = "SENSOR", *,
                 speed: float = CALIBRATE_DEFAULTS["speed"], bottom: float = CALIBRATE_DEFAULTS["bottom"],
                 settle: float = CALIBRATE_DEFAULTS["settle"], runs: int = CALIBRATE_DEFAULTS["runs"],
                 enabled: bool = True):
        super().__init__(axis, enabled)
        self.cycle_time = require_number(cycle_time, "calibrate.cycle_time", lo=0.0, lo_open=True)
        keys = self.KEYS
        self.speed = keys["speed"].check(speed, "calibrate.speed")
        self.bottom = keys["bottom"].check(bottom, "calibrate.bottom")
        self.settle = keys["settle"].check(settle, "calibrate.settle", lo=self.cycle_time)
        self.runs = keys["runs"].check(runs, "calibrate.runs")
        self.variable = ve_name(variable)
        self.settle_cycles = max(1, round(self.settle / self.cycle_time))
        self.select_cycles = max(1, round(SELECT_TIMEOUT / self.cycle_time))
        self.step_mm = self.speed * self.cycle_time
        #: the last calibration that ended (DONE or FAILED), None before; kept by reset()
        self.completed: CalibrationRecord | None = None
        self.reset()

    def reset(self) -> None:
        """Back to WAITING with nothing recorded (an enabled function calibrates again); ``completed``
        is kept. A run under way is abandoned as it stands: distance control stays where the PLC left
        it (ACTIVE_CONST_DIST at the distance reached) until the NC program or the PLC switches it off."""
        self._set_phase(WAITING)
        self.error: str | None = None
        self.record = CalibrationRecord()
        self.run_no = 0
        self._next = DOWN
        self._count = 0
        self._set = math.nan
        self._axis_old = math.nan

    def _set_phase(self, phase: str) -> None:
        """The phase; from the select to the OFF the axis's FREEZE hold is inhibited
        (``FreezeHold.inhibitors``): the locks must not freeze the calibration's motion."""
        self.phase = phase
        if self.hold is not None:
            moving = phase not in (WAITING, DONE, FAILED)
            (self.hold.inhibitors.add if moving else self.hold.inhibitors.discard)(self.name)

    def status(self) -> dict:
        st = super().status()
        st.update(phase=self.phase, run=self.run_no, samples=len(self.record), error=self.error)
        return st

    def _fail(self, unit, cycle: int, why: str) -> None:
        self._set_phase(FAILED)
        self.error = why
        unit.plc_cyclic_stop()
        self._finish(cycle)

    def _finish(self, cycle: int) -> None:
        self.record.end_cycle = cycle
        self.completed = self.record

    def step(self, machine, cycle: int) -> None:
        phase = self.phase
        if phase == DONE or phase == FAILED:
            return
        unit = machine.hli[self.axis]
        s = unit.state_r
        state = s.actual_state
        axis = (s.actual_position + s.actual_distance) * _MM_PER_UNIT
        if phase == WAITING:
            still = abs(axis - self._axis_old) < REST_STEP
            self._axis_old = axis
            at_rest = state == _INACTIVE and machine.channel_path.D_ActiveFeed == 0 and still
            self._count = self._count + 1 if at_rest else 0
            if self._count < self.settle_cycles:
                return
            top = s.actual_distance * _MM_PER_UNIT
            if not top > self.bottom:
                self._fail(unit, cycle, f"the measured distance at the start ({top:.4f} mm) is not above bottom "
                                        f"({self.bottom:g} mm): put the head higher above the sheet, and select "
                                        "the sensor (SENSOR_SOURCE=VARIABLE) before")
                return
            if unit.plc_command(_T_ON_CD, top):
                unit.plc_cyclic(distance_mm=top)
                self._set = top
                self.record.top = top
                self.record.start_cycle = cycle
                self._set_phase(SELECTING)
                self._count = 0
            return
        if phase == SELECTING:
            if state == _ACTIVE_CD:
                self._set_phase(DOWN)
                self.run_no = 1
            elif self._count >= self.select_cycles:
                self._fail(unit, cycle, f"the PLC's select ON_CONST_DIST was not taken within {SELECT_TIMEOUT:g} s "
                                        f"(state {state})")
                return
            else:
                self._count += 1
                return
        if phase == ENDING:
            if unit.plc_command(_T_OFF, 0.0):
                unit.plc_cyclic_stop()
                self._set_phase(DONE)
                self._finish(cycle)
            return
        if state != _ACTIVE_CD:
            self._fail(unit, cycle, f"distance control left ACTIVE_CONST_DIST during run {self.run_no} "
                                    f"(state {state}; an error, a reset or another command)")
            return
        if self.phase == DWELL:
            if self._count < self.settle_cycles:
                self._count += 1
                return
            if self._next == UP:
                self._set_phase(UP)
            elif self.run_no < self.runs:
                self.run_no += 1
                self._set_phase(DOWN)
            else:
                self._set_phase(ENDING)
                self.step(machine, cycle)
                return
        rec = self.record
        rec.axis.append(axis)
        rec.reading.append(machine.variables.get(self.variable, math.nan))
        rec.run.append(self.run_no)
        if self.phase == DOWN:
            rec.direction.append(-1)
            self._set = max(self.bottom, self._set - self.step_mm)
            end = self._set <= self.bottom
        else:
            rec.direction.append(1)
            self._set = min(rec.top, self._set + self.step_mm)
            end = self._set >= rec.top
        unit.plc_cyclic(distance_mm=self._set)
        if end:
            self._next = UP if self.phase == DOWN else DOWN
            self._set_phase(DWELL)
            self._count = 0
