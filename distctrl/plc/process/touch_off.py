"""Initial height sense (touch-off): probe down slowly until the signal reports the surface, then back
off to the pierce height.

The NC program does not know where the sheet is (warp, a sheet lying on slats, a plate thicker than
drawn). Before the pierce it asks the PLC to find the surface, as QtPlasmaC's probing does (probe
speed, probe height, float switch travel, pierce height) and a laser head's initial height sense
does with the capacitive sensor. The handshake is a V.E. variable (``request``, default
``V.E.TOUCH_OFF``) and ``#WAIT FOR`` (docs/nc.md)::

    N10 G0 X100 Y50 Z40                    ; over the pierce point, somewhere above the sheet
    N20 Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]
    N30 V.E.TOUCH_OFF = 1                  ; PLC: touch off
    N40 #WAIT FOR V.E.TOUCH_OFF == 0       ; done: the head is at the pierce height, FREEZE
    N50 #TIME 0.4                          ; pierce delay
    N60 Z[DIST_CTRL ON CONST_DIST SET_DIST=1.5]
    N70 G1 X300 F3000

The PLC moves Z only through distance control (HLI control unit, CNC objects):

1. request (``V.E.TOUCH_OFF`` > 0.5) while ``state_r.actual_state`` is INACTIVE (0) or FREEZE (2):
   read ``DIST_CTRL_PARAM[0]::v_max`` (µm/s), write it with ``probe_speed`` (pending, adopted on the
   select), select ON_CONST_DIST (4) with SET_DIST = 0: the offset lowers the head at the probe
   speed. Any other state: error 900052.
2. PROBING: the signal (the sensor's distance variable, or ``state_r.actual_distance``) at or below
   ``detect`` reports the surface -> FREEZE (2; braked within a_max). The offset's travel
   (``state_r.actual_offset`` since the start) beyond ``stroke`` without it -> error 900050. A probe
   that takes longer than twice the stroke at the probe speed plus 1 s (the axis does not read the
   sensor the signal comes from, e.g. no ``SENSOR_SOURCE=VARIABLE``) -> error 900052.
3. VERIFY: once the offset stands, after ``verify_time`` the signal must still be at or below
   ``detect + verify_band``; otherwise the detection was false (a spike, a spark): probe on
   (FREEZE -> ON_CONST_DIST, SET_DIST = 0) up to ``retries`` times, then error 900051.
4. BACK-OFF: write ``v_max`` back to the value read in 1 and select ON_CONST_DIST with SET_DIST =
   ``pierce_height`` (FREEZE -> active adopts the write: the back-off runs at the normal limits);
   once ``|DIST_CTRL::target_deviation|`` (0x3111, the filtered distance minus the set distance)
   stays within ``tolerance`` for 5 cycles with the offset (nearly) standing (it moves less than
   ``tolerance`` per 10 ms) -> FREEZE; more than 2 s -> error 900052.
5. DONE: in FREEZE, once the drive is in position (its following error, CNC objects
   ``dig cmd pos high_res`` - ``dig act pos`` in drive increments, within ``tolerance``; at most
   2 s, else 900052), the PLC writes ``V.E.TOUCH_OFF = 0``: the program goes on. ``result`` holds the
   surface found (``state_r.actual_position``, mm), the distance held, the travel and the attempts.

While it runs the axis's FREEZE hold is inhibited: the locks (void lock, corner lock) freeze neither
the probe nor the back-off. Switched off (or reset) while it runs, it ends the touch-off as an error
(900052) in its next cycle; switched off while idle it does not answer a request (the NC program
waits at ``#WAIT FOR``). An error writes ``V.E.TOUCH_OFF = -1``, writes ``v_max`` back, switches distance control OFF (the
offset runs out at the probe speed: the head returns to the programmed height it started from; the
written-back v_max is adopted only by the next select), reports the error with
the NC line and stops the program. Every command goes through the semaphore handshake (FCT-M3 §8.2).

ST equivalent (``SEND(t, pos)`` = the semaphore handshake of docs/process.md; mm on the HLI x 10000)::

    lrSig := V_E_SIGNAL;                                  (* or DINT_TO_LREAL(stState.actual_distance) * 0.0001 *)
    lrOffs := DINT_TO_LREAL(stState.actual_offset) * 0.0001;
    CASE eTouch OF
    IDLE:      IF V_E_TOUCH_OFF > 0.5 THEN
                   IF stState.actual_state <> 0 AND stState.actual_state <> 2 THEN FAIL(900052);
                   ELSE nVmaxSaved := DIST_CTRL_PARAM_v_max;                  (* CNC object 0x3500, um/s *)
                        DIST_CTRL_PARAM_v_max := LREAL_TO_DINT(lrProbeSpeed * 1000.0);
                        lrOffs0 := lrOffs; nAttempt := 0; nCnt := 0; SEND(4, 0.0); eTouch := PROBING; END_IF
               END_IF
    PROBING:   nCnt := nCnt + 1;
               IF stState.actual_state <> 4 THEN FAIL(900052);
               ELSIF lrSig <= lrDetect THEN SEND(2, 0.0); eTouch := BRAKING;
               ELSIF lrOffs0 - lrOffs > lrStroke THEN FAIL(900050);
               ELSIF nCnt > nProbeCycles THEN FAIL(900052); END_IF
    BRAKING:   IF stState.actual_state <> 2 THEN FAIL(900052);
               ELSIF lrOffs = lrOffsLast THEN nCnt := 0; eTouch := VERIFY; END_IF
    VERIFY:    nCnt := nCnt + 1;
               IF nCnt >= nVerifyCycles THEN
                   IF lrSig <= lrDetect + lrVerifyBand THEN
                       DIST_CTRL_PARAM_v_max := nVmaxSaved; SEND(4, lrPierce); eTouch := BACKING_OFF; nCnt := 0;
                   ELSIF nAttempt >= nRetries THEN FAIL(900051);
                   ELSE nAttempt := nAttempt + 1; nCnt := 0; SEND(4, 0.0); eTouch := PROBING; END_IF
               END_IF
    BACKING_OFF: IF stState.actual_state <> 4 THEN FAIL(900052);
               ELSIF ABS(DIST_CTRL_target_deviation * 1.0E-8) <= lrTol
                     AND ABS(lrOffs - lrOffsLast) <= lrTol * lrT / 0.01 THEN nOk := nOk + 1; ELSE nOk := 0; END_IF
               IF nOk >= 5 THEN SEND(2, 0.0); eTouch := HOLDING; nCnt := 0;
               ELSIF nCnt > nTimeoutCycles THEN FAIL(900052); END_IF; nCnt := nCnt + 1;
    HOLDING:   nCnt := nCnt + 1;
               IF stState.actual_state = 2 AND ABS(DINT_TO_LREAL(nDigCmdPos - nDigActPos) * lrIncr) <= lrTol THEN
                   V_E_TOUCH_OFF := 0; eTouch := IDLE;                   (* in position: the NC goes on *)
               ELSIF nCnt > nTimeoutCycles THEN FAIL(900052); END_IF
    END_CASE
    lrOffsLast := lrOffs;
    (* FAIL(id): DIST_CTRL_PARAM_v_max := nVmaxSaved; SEND(0, 0.0) if running; V_E_TOUCH_OFF := -1;
       report id with the NC line; stop the program; eTouch := IDLE *)
"""
from __future__ import annotations

import math

from ...base.states import HliState, HliTransition
from ...errors import ErrorId
from ...errors.config import require_number
from ..variables import ve_name
from .base import Key, ProcessFunction, ProcessTable, signal_variable, ve_key
from .plc_io import (
    MM_PER_UNIT,
    HliCommandSender,
    following_error,
    read_object,
    read_signal,
    report_error,
    write_object,
)

__all__ = ["TouchOff", "TOUCH_DEFAULTS", "BACKOFF_TIMEOUT_S"]

TOUCH_DEFAULTS = {"request": "TOUCH_OFF", "probe_speed": 10.0, "detect": 0.5, "pierce_height": 3.0,
                  "stroke": 10.0, "retries": 2, "verify_time": 0.02, "verify_band": 0.5, "tolerance": 0.05}
#: s: the back-off must reach the pierce height within this long
BACKOFF_TIMEOUT_S = 2.0
#: cycles within ``tolerance`` before the back-off counts as done
BACKOFF_OK_CYCLES = 5
#: s: the back-off is done once the offset would need longer than this to move by ``tolerance``
STILL_S = 0.01
#: s: at most this long waiting for the FREEZE to brake
BRAKE_TIMEOUT_S = 1.0
_V_MAX = "DIST_CTRL_PARAM[0]::v_max"
_TARGET_DEV = "DIST_CTRL::target_deviation"
_MM_PER_NM001 = 1e-8
_INACTIVE, _ACTIVE, _FREEZE = int(HliState.INACTIVE), int(HliState.ACTIVE), int(HliState.FREEZE)
_ACTIVE_CD = int(HliState.ACTIVE_CONST_DIST)
_T_OFF, _T_FREEZE, _T_ON_CD = int(HliTransition.OFF), int(HliTransition.FREEZE), int(HliTransition.ON_CONST_DIST)
IDLE, PROBING, BRAKING, VERIFY, BACKING_OFF, HOLDING = ("IDLE", "PROBING", "BRAKING", "VERIFY", "BACKING_OFF",
                                                       "HOLDING")


def _state_name(state: int) -> str:
    try:
        return f"{HliState(state).name} ({state})"
    except ValueError:
        return str(state)


class TouchOff(HliCommandSender, ProcessFunction):
    """Touch-off on ``axis`` (module docstring). Lengths mm, speeds mm/s, times s; ``variable`` the
    V.E. signal in mm (None: ``state_r.actual_distance``), ``request`` the V.E. handshake variable."""

    name = "touch_off"
    KEYS = {
        "variable": Key(None, "V.E. distance in mm; default the sensor's, else state_r.actual_distance",
                        kind="name"),
        "request": Key(TOUCH_DEFAULTS["request"], "V.E. variable of the NC handshake", kind="name"),
        "probe_speed": Key(TOUCH_DEFAULTS["probe_speed"], "mm/s of the probe move (at most the axis's v_max)",
                           lo=0.001, hi=1000.0),
        "detect": Key(TOUCH_DEFAULTS["detect"], "mm: the reading at which the surface counts as found",
                      lo=0.0, hi=100.0),
        "pierce_height": Key(TOUCH_DEFAULTS["pierce_height"], "mm above the surface after the touch-off",
                             lo=0.0, hi=100.0, lo_open=True),
        "stroke": Key(TOUCH_DEFAULTS["stroke"], "mm the probe may travel (below the axis's max_deviation; "
                      "default at most 0.9 max_deviation)", lo=0.0, hi=1000.0, lo_open=True),
        "retries": Key(TOUCH_DEFAULTS["retries"], "further attempts after a failed verify", kind="int", lo=0, hi=10),
        "verify_time": Key(TOUCH_DEFAULTS["verify_time"], "s the reading is verified at the pierce height",
                           lo=0.0, hi=1.0),
        "verify_band": Key(TOUCH_DEFAULTS["verify_band"], "mm the reading may move while verified", lo=0.0, hi=100.0),
        "tolerance": Key(TOUCH_DEFAULTS["tolerance"], "mm of the back-off target", lo=0.0, hi=10.0, lo_open=True),
    }

    @classmethod
    def from_config(cls, table: ProcessTable) -> dict:
        axis_cfg, k = table.axis_cfg, table.prefix
        request = ve_key(table.get("request", TOUCH_DEFAULTS["request"]), k + "request",
                         "a V.E. variable name (the NC handshake, e.g. \"TOUCH_OFF\")")
        max_dev = axis_cfg.params.max_deviation
        stroke = table.read(cls, "stroke", min(TOUCH_DEFAULTS["stroke"], 0.9 * max_dev), hi=max_dev, hi_open=True)
        return {"variable": signal_variable(table), "request": request,
                "probe_speed": table.read(cls, "probe_speed", hi=min(1000.0, axis_cfg.v_max)),
                "detect": table.read(cls, "detect"), "pierce_height": table.read(cls, "pierce_height"),
                "stroke": stroke, "retries": table.read(cls, "retries"), "verify_time": table.read(cls, "verify_time"),
                "verify_band": table.read(cls, "verify_band"), "tolerance": table.read(cls, "tolerance")}

    def __init__(self, axis: str, cycle_time: float, *, variable: str | None = None,
                 request: str = TOUCH_DEFAULTS["request"], probe_speed: float = TOUCH_DEFAULTS["probe_speed"],
                 detect: float = TOUCH_DEFAULTS["detect"], pierce_height: float = TOUCH_DEFAULTS["pierce_height"],
                 stroke: float = TOUCH_DEFAULTS["stroke"], retries: int = TOUCH_DEFAULTS["retries"],
                 verify_time: float = TOUCH_DEFAULTS["verify_time"],
                 verify_band: float = TOUCH_DEFAULTS["verify_band"], tolerance: float = TOUCH_DEFAULTS["tolerance"]):
        super().__init__(axis)
        n = "touch_off."
        self.cycle_time = require_number(cycle_time, n + "cycle_time", lo=0.0, lo_open=True)
        keys = self.KEYS
        self.probe_speed = keys["probe_speed"].check(probe_speed, n + "probe_speed")
        self.detect = keys["detect"].check(detect, n + "detect")
        self.pierce_height = keys["pierce_height"].check(pierce_height, n + "pierce_height")
        self.stroke = keys["stroke"].check(stroke, n + "stroke")
        self.retries = keys["retries"].check(retries, n + "retries")
        self.verify_time = keys["verify_time"].check(verify_time, n + "verify_time")
        self.verify_band = keys["verify_band"].check(verify_band, n + "verify_band")
        self.tolerance = keys["tolerance"].check(tolerance, n + "tolerance")
        self.variable = None if variable is None else ve_name(variable)
        self.request = ve_name(request)
        #: the V.E. variables the machine creates (0) at the start: the handshake
        self.declares = (self.request,)
        self.verify_cycles = max(1, round(self.verify_time / self.cycle_time))
        self.timeout_cycles = round(BACKOFF_TIMEOUT_S / self.cycle_time)
        self.brake_cycles = round(BRAKE_TIMEOUT_S / self.cycle_time)
        #: the longest a probe may take: the stroke at the probe speed, twice, plus 1 s
        self.probe_cycles = round((2.0 * self.stroke / self.probe_speed + 1.0) / self.cycle_time)
        #: every completed touch-off: {"cycle", "surface", "distance", "travel", "attempts"} (mm)
        self.log: list[dict] = []
        #: the errors this function reported (ErrorEvent)
        self.errors: list = []
        self.reset()

    @property
    def finishing(self) -> bool:
        """Switched off during a touch-off, it ends that touch-off safely in its next cycle (900052,
        OFF, the program stops; dropping it would leave distance control lowering the head at
        SET_DIST = 0)."""
        return getattr(self, "phase", IDLE) != IDLE

    def reset(self) -> None:
        """Back to the initial state: idle, no command waiting, no attempt counted (the logs stay). A
        touch-off under way is not dropped: it ends safely in the next cycle (see :attr:`enabled`)."""
        if getattr(self, "phase", IDLE) != IDLE:
            self._abort = True
            return
        self._abort = False
        self.phase = IDLE
        if self.hold is not None:
            self.hold.inhibitors.discard(self.name)
        self._pending: tuple[int, float] | None = None
        self._sent = -1                   # the cycle the last command was taken
        self._count = 0
        self._ok = 0
        self.attempts = 0
        self._offset0 = 0.0
        self._last_offset = math.nan
        self._v_max_saved: int | None = None
        self.result: dict | None = None

    # ------------------------------------------------------------------ helpers
    def _fail(self, machine, cycle: int, error_id: int, detail: str) -> None:
        unit = machine.hli[self.axis]
        if self._v_max_saved is not None:
            write_object(machine, self.axis, _V_MAX, self._v_max_saved)
            self._v_max_saved = None
        if unit.state_r.actual_state in (_ACTIVE, _ACTIVE_CD, _FREEZE):
            self._send(unit, cycle, _T_OFF)          # the head returns to the programmed height
        machine.variables[self.request] = -1.0
        self.errors.append(report_error(machine, cycle, error_id, detail))
        self._set_phase(IDLE)

    # ------------------------------------------------------------------ once per PLC cycle
    def step(self, machine, cycle: int) -> None:
        unit = machine.hli[self.axis]
        if self._pending is not None:
            self._flush(unit, cycle)
            if self._pending is not None:
                return                                # the semaphore is busy: the command waits
        phase = self.phase
        state = unit.state_r.actual_state
        if self._abort:
            self._abort = False
            if phase != IDLE:
                self._fail(machine, cycle, ErrorId.TOUCH_OFF_FAILED,
                           f"the touch-off was switched off or reset while {phase}")
            return
        if phase == IDLE:
            if not self.switched_on:
                return
            req = machine.variables.get(self.request, 0.0)
            if req == req and req > 0.5:
                self._start(machine, unit, cycle, state)
            return
        if cycle <= self._sent:                       # the state shows a command one cycle later
            return
        offset = unit.state_r.actual_offset * MM_PER_UNIT
        signal = read_signal(machine, self.axis, self.variable)
        if phase == PROBING:
            if state != _ACTIVE_CD:
                self._fail(machine, cycle, ErrorId.TOUCH_OFF_FAILED,
                           f"the probing select ended: distance control is {_state_name(state)}")
            elif signal <= self.detect:
                self._send(unit, cycle, _T_FREEZE)
                self.phase = BRAKING
                self._count = 0
            elif self._offset0 - offset > self.stroke:
                self._fail(machine, cycle, ErrorId.TOUCH_OFF_NO_SURFACE,
                           f"probed {self._offset0 - offset:.3f} mm down (stroke {self.stroke:g} mm) at "
                           f"{self.probe_speed:g} mm/s, the signal still reads {signal:.3f} mm "
                           f"(surface at <= {self.detect:g} mm)")
            else:
                self._count += 1
                if self._count > self.probe_cycles:
                    self._fail(machine, cycle, ErrorId.TOUCH_OFF_FAILED,
                               f"the head went only {self._offset0 - offset:.3f} mm down in "
                               f"{self._count * self.cycle_time:.3f} s (stroke {self.stroke:g} mm at "
                               f"{self.probe_speed:g} mm/s); distance control reads "
                               f"{unit.state_r.actual_distance * MM_PER_UNIT:.3f} mm, the signal "
                               f"{signal:.3f} mm: does the axis read the sensor (SENSOR_SOURCE, SENSOR_VAR)?")
        elif phase == BRAKING:
            self._count += 1
            if state != _FREEZE:
                self._fail(machine, cycle, ErrorId.TOUCH_OFF_FAILED,
                           f"the FREEZE after the detection was not taken: distance control is {_state_name(state)}")
            elif offset == self._last_offset or self._count > self.brake_cycles:
                self.phase = VERIFY
                self._count = 0
        elif phase == VERIFY:
            self._count += 1
            if self._count >= self.verify_cycles:
                if signal <= self.detect + self.verify_band:
                    write_object(machine, self.axis, _V_MAX, self._v_max_saved)
                    self._v_max_saved = None
                    self._send(unit, cycle, _T_ON_CD, self.pierce_height)
                    self.phase = BACKING_OFF
                    self._count = self._ok = 0
                elif self.attempts >= self.retries:
                    self._fail(machine, cycle, ErrorId.TOUCH_OFF_RETRIES,
                               f"{self.attempts + 1} detection(s), none stayed: the signal read {signal:.3f} mm "
                               f"with the head stopped (surface at <= {self.detect + self.verify_band:g} mm); "
                               f"retries {self.retries}")
                else:
                    self.attempts += 1
                    self._send(unit, cycle, _T_ON_CD, 0.0)
                    self.phase = PROBING
                    self._count = 0
        elif phase == BACKING_OFF:
            self._count += 1
            if state != _ACTIVE_CD:
                self._fail(machine, cycle, ErrorId.TOUCH_OFF_FAILED,
                           f"the back-off select ended: distance control is {_state_name(state)}")
            else:
                dev = read_object(machine, self.axis, _TARGET_DEV) * _MM_PER_NM001
                # on target and the offset (nearly) standing: it moves less than the tolerance in
                # STILL_S, so the FREEZE that follows brakes it within a fraction of the tolerance
                still = abs(offset - self._last_offset) <= self.tolerance * self.cycle_time / STILL_S
                self._ok = self._ok + 1 if abs(dev) <= self.tolerance and still else 0
                if self._ok >= BACKOFF_OK_CYCLES:
                    self._send(unit, cycle, _T_FREEZE)
                    self.phase = HOLDING
                    self._count = 0
                elif self._count > self.timeout_cycles:
                    self._fail(machine, cycle, ErrorId.TOUCH_OFF_FAILED,
                               f"the back-off did not reach the pierce height {self.pierce_height:g} mm within "
                               f"{BACKOFF_TIMEOUT_S:g} s (target deviation {dev:.3f} mm)")
        elif phase == HOLDING:
            self._count += 1
            if state == _FREEZE and abs(following_error(machine, self.axis)) <= self.tolerance:
                self.result = {"cycle": cycle, "surface": unit.state_r.actual_position * MM_PER_UNIT,
                               "distance": unit.state_r.actual_distance * MM_PER_UNIT,
                               "travel": self._offset0 - offset, "attempts": self.attempts + 1}
                self.log.append(self.result)
                machine.variables[self.request] = 0.0
                self._set_phase(IDLE)
            elif state not in (_ACTIVE_CD, _FREEZE):
                self._fail(machine, cycle, ErrorId.TOUCH_OFF_FAILED,
                           f"the FREEZE at the pierce height was not taken: distance control is {_state_name(state)}")
            elif self._count > self.timeout_cycles:
                self._fail(machine, cycle, ErrorId.TOUCH_OFF_FAILED,
                           f"the drive did not reach the pierce height within {BACKOFF_TIMEOUT_S:g} s "
                           f"(following error {following_error(machine, self.axis):.3f} mm)")
        self._last_offset = offset

    def _start(self, machine, unit, cycle: int, state: int) -> None:
        self.attempts = 0
        self.result = None
        if state not in (_INACTIVE, _FREEZE):
            self._fail(machine, cycle, ErrorId.TOUCH_OFF_FAILED,
                       f"requested while distance control is {_state_name(state)}: a touch-off starts from "
                       "INACTIVE or FREEZE")
            return
        self._v_max_saved = int(read_object(machine, self.axis, _V_MAX))
        write_object(machine, self.axis, _V_MAX, max(1, round(self.probe_speed * 1000.0)))
        self._offset0 = unit.state_r.actual_offset * MM_PER_UNIT
        self._last_offset = math.nan
        self._send(unit, cycle, _T_ON_CD, 0.0)
        self._count = 0
        self._set_phase(PROBING)

    def _set_phase(self, phase: str) -> None:
        """The phase; while not IDLE the axis's FREEZE hold is inhibited (the locks must not freeze the
        probe or the back-off)."""
        self.phase = phase
        if self.hold is not None:
            (self.hold.inhibitors.discard if phase == IDLE else self.hold.inhibitors.add)(self.name)

