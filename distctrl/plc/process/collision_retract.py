"""Collision (touch) detection and retract: when the sensor reports contact, stop, lift the head at the
axis limits, switch distance control off with the head up and stop the program with an error that
names the place.

A tipped-up part, a slug standing on the sheet, a clamp: where the head meets an obstacle faster
than distance control can lift it, the nozzle touches. A capacitive sensor then reads (almost) 0 mm
or jumps to its short-circuit value; laser controllers (BCS100, Weihong) and plasma THCs stop and
retract. As a PLC program on the HLI control unit and the CNC objects:

1. WATCH (distance control ACTIVE, ACTIVE_CONST_DIST or FREEZE, and no touch-off of this axis
   running): the signal (the sensor's distance variable, or ``state_r.actual_distance``) at or
   below ``threshold`` - or equal to ``short_circuit`` when given - for ``confirm_cycles``
   consecutive cycles is a contact. The PLC notes the place (the NC line, the X/Y actual positions
   of the axes, the reading) and stops the program at once (the path decelerates at the axis
   limits and holds). From now on the axis's FREEZE hold is inhibited: no lock freezes the retract.
2. FREEZE (2) if distance control tracks, and write ``DIST_CTRL_PARAM[0]::v_max`` = ``retract_speed``
   (µm/s) and ``a_max`` = ``retract_accel`` (mm/s²): pending, adopted by the next select.
3. In FREEZE: select ON_CONST_DIST (4) with SET_DIST = the reading at the contact + ``retract`` +
   :data:`RETRACT_MARGIN` (1 mm): above every reading while the head rises by ``retract``, so the
   offset rises at the retract limits whatever the sensor reads while it touches, a short-circuit
   value included.
4. RETRACTING: once the offset (``state_r.actual_offset``) has risen by ``retract`` minus the
   braking distance ``v²/(2·retract_accel)`` at its current velocity: FREEZE; the head stops about
   ``retract`` above the contact.
5. Stopped (the offset stands, or 1 s): a channel reset deselects distance control with the offset
   absorbed (docs/states.md: RESET -> INACTIVE at once, the channel takes the offset as its
   position): the head stays up. OFF would run the offset out and put the head back onto the
   obstacle. The error 900053 is reported with the cycle and NC line of the contact and names the
   X/Y position, the reading, the retract distance and time. The function watches again (the hold
   is no longer inhibited): the next select arms it.

A state that leaves the sequence (ERROR, e.g. the offset reached max_deviation, P-AXIS-00414)
ends the retract where it is: the reset and the error follow at once. Switched off (or reset) during a
retract, the function finishes it first (``enabled`` reads true until then); switched off while
watching, it stops watching.

ST equivalent::

    lrSig := V_E_SIGNAL;                        (* or DINT_TO_LREAL(stState.actual_distance) * 0.0001 *)
    lrOffs := DINT_TO_LREAL(stState.actual_offset) * 0.0001;
    CASE eColl OF
    WATCH:   bArmed := (stState.actual_state = 1 OR stState.actual_state = 4 OR stState.actual_state = 2)
                       AND NOT bTouchOffBusy;
             IF bArmed AND (lrSig <= lrThreshold OR (bShortCircuit AND ABS(lrSig - lrShortCircuit) <= 0.001))
             THEN nHit := nHit + 1; ELSE nHit := 0; END_IF
             IF nHit >= nConfirm THEN
                 nLine := NC_LINE; lrX := X_ACT; lrY := Y_ACT; lrHit := lrSig;   (* the place *)
                 STOP_PROGRAM();
                 DIST_CTRL_PARAM_v_max := LREAL_TO_DINT(lrRetractSpeed * 1000.0);   (* um/s *)
                 DIST_CTRL_PARAM_a_max := LREAL_TO_DINT(lrRetractAccel);            (* mm/s2 *)
                 IF stState.actual_state <> 2 THEN SEND(2, 0.0); END_IF
                 eColl := FREEZING;
             END_IF
    FREEZING: IF stState.actual_state = 2 THEN lrOffs0 := lrOffs; SEND(4, MAX(lrHit, 0.0) + lrRetract + 1.0);
                  eColl := RETRACTING;
              ELSE STOP_AND_REPORT(); END_IF
    RETRACTING: lrV := (lrOffs - lrOffsLast) / lrT;
              IF stState.actual_state <> 4 THEN STOP_AND_REPORT();
              ELSIF lrOffs - lrOffs0 >= lrRetract - lrV * lrV / (2.0 * lrRetractAccel) THEN
                  SEND(2, 0.0); eColl := STOPPING; END_IF
    STOPPING: IF lrOffs = lrOffsLast OR nCnt > nOneSecond THEN STOP_AND_REPORT(); END_IF
    END_CASE
    lrOffsLast := lrOffs;
    (* STOP_AND_REPORT: channel reset (INACTIVE, offset absorbed: the head stays up);
       report 900053 with the contact's cycle, NC line, X/Y, reading, retract distance and time;
       fbHold.bInhibit := FALSE; nHit := 0; eColl := WATCH (a new select arms it again) *)
"""
from __future__ import annotations

import math

from ...base.states import HliState, HliTransition
from ...errors import ErrorId, make_event
from ...errors.config import require_number
from ..variables import ve_name
from .base import Key, ProcessFunction, ProcessTable, signal_variable
from .plc_io import MM_PER_UNIT, HliCommandSender, read_signal, write_object

__all__ = ["CollisionRetract", "COLLISION_DEFAULTS", "RETRACT_MARGIN"]

#: threshold mm, confirm_cycles, retract mm; retract_speed / retract_accel default to the axis's limits
COLLISION_DEFAULTS = {"threshold": 0.2, "confirm_cycles": 2, "retract": 5.0, "short_circuit": None}
#: mm: SET_DIST of the retract select = the reading at the contact + retract + this: above every reading
#: while the head rises by ``retract`` (the reading grows by at most the rise), so the offset rises at
#: the retract limits whatever the sensor reads while it touches
RETRACT_MARGIN = 1.0
#: s: the longest the head may take to stop after the retract
STOP_TIMEOUT_S = 1.0
_SHORT_BAND = 1e-3
_ACTIVE, _FREEZE = int(HliState.ACTIVE), int(HliState.FREEZE)
_ACTIVE_CD = int(HliState.ACTIVE_CONST_DIST)
_ARMED = (_ACTIVE, _ACTIVE_CD, _FREEZE)
_T_FREEZE, _T_ON_CD = int(HliTransition.FREEZE), int(HliTransition.ON_CONST_DIST)
WATCH, FREEZING, RETRACTING, STOPPING = "WATCH", "FREEZING", "RETRACTING", "STOPPING"


#: the retract's speed (mm/s) and acceleration (mm/s²) at most; a scenario's defaults (the axis's
#: v_max / a_max) are capped to these
MAX_RETRACT_SPEED = 2_000_000.0
MAX_RETRACT_ACCEL = 2_000_000_000.0


class CollisionRetract(HliCommandSender, ProcessFunction):
    """Contact detection and retract on ``axis`` (module docstring). ``retract_speed`` (mm/s) and
    ``retract_accel`` (mm/s²) are the retract's limits (the axis's v_max / a_max in a scenario);
    ``variable`` the V.E. signal in mm (None: ``state_r.actual_distance``)."""

    name = "collision_retract"
    KEYS = {
        "variable": Key(None, "V.E. distance in mm; default the sensor's, else state_r.actual_distance",
                        kind="name"),
        "threshold": Key(COLLISION_DEFAULTS["threshold"], "mm: a reading at or below it is a contact",
                         lo=0.0, hi=100.0),
        "short_circuit": Key(COLLISION_DEFAULTS["short_circuit"], "a reading that means a short circuit "
                             "(None: none)", kind="any"),
        "confirm_cycles": Key(COLLISION_DEFAULTS["confirm_cycles"], "cycles a contact must last", kind="int",
                              lo=1, hi=1000),
        "retract": Key(COLLISION_DEFAULTS["retract"], "mm the head retracts", lo=0.0, hi=1000.0, lo_open=True),
        "retract_speed": Key(None, "mm/s; default and upper bound the axis's v_max", lo=0.001, hi=MAX_RETRACT_SPEED),
        "retract_accel": Key(None, "mm/s²; default and upper bound the axis's a_max", lo=1.0, hi=MAX_RETRACT_ACCEL),
    }

    @classmethod
    def from_config(cls, table: ProcessTable) -> dict:
        axis_cfg, k = table.axis_cfg, table.prefix
        sc = table.get("short_circuit", COLLISION_DEFAULTS["short_circuit"])
        return {"variable": signal_variable(table), "threshold": table.read(cls, "threshold"),
                "short_circuit": None if sc is None else require_number(sc, k + "short_circuit"),
                "confirm_cycles": table.read(cls, "confirm_cycles"), "retract": table.read(cls, "retract"),
                # the retract runs at the axis's limits unless slower ones are given
                # the retract runs at the axis's limits unless slower ones are given (and never beyond the
                # function's own bounds: an axis may be configured faster than any retract)
                "retract_speed": table.read(cls, "retract_speed", min(axis_cfg.v_max, MAX_RETRACT_SPEED),
                                            hi=min(axis_cfg.v_max, MAX_RETRACT_SPEED)),
                "retract_accel": table.read(cls, "retract_accel", min(axis_cfg.a_max, MAX_RETRACT_ACCEL),
                                            hi=min(axis_cfg.a_max, MAX_RETRACT_ACCEL))}

    def __init__(self, axis: str, cycle_time: float, retract_speed: float, retract_accel: float, *,
                 variable: str | None = None, threshold: float = COLLISION_DEFAULTS["threshold"],
                 confirm_cycles: int = COLLISION_DEFAULTS["confirm_cycles"],
                 retract: float = COLLISION_DEFAULTS["retract"], short_circuit: float | None = None):
        super().__init__(axis)
        n = "collision_retract."
        self.cycle_time = require_number(cycle_time, n + "cycle_time", lo=0.0, lo_open=True)
        keys = self.KEYS
        self.retract_speed = keys["retract_speed"].check(retract_speed, n + "retract_speed")
        self.retract_accel = keys["retract_accel"].check(retract_accel, n + "retract_accel")
        self.threshold = keys["threshold"].check(threshold, n + "threshold")
        self.confirm_cycles = keys["confirm_cycles"].check(confirm_cycles, n + "confirm_cycles")
        self.retract = keys["retract"].check(retract, n + "retract")
        self.short_circuit = None if short_circuit is None else require_number(short_circuit, n + "short_circuit")
        self.variable = None if variable is None else ve_name(variable)
        self.stop_cycles = round(STOP_TIMEOUT_S / self.cycle_time)
        #: every contact: {"cycle", "line", "x", "y", "reading", "retract", "retract_time"} (mm, s)
        self.log: list[dict] = []
        #: the errors this function reported (ErrorEvent)
        self.errors: list = []
        self.reset()

    @property
    def busy(self) -> bool:
        """A retract is under way (the function moves the axis)."""
        return getattr(self, "phase", WATCH) in (FREEZING, RETRACTING, STOPPING)

    @property
    def finishing(self) -> bool:
        """Switched off during a retract, the retract is finished (stopped half-way the head would
        stay on the obstacle, distance control in the retract's select)."""
        return self.busy

    def reset(self) -> None:
        """Back to the initial state: watching, no contact counted, no command waiting (logs stay). A
        retract under way is finished first (see :attr:`enabled`)."""
        if self.busy:
            return
        self.phase = WATCH
        if self.hold is not None:
            self.hold.inhibitors.discard(self.name)
        self.hits = 0
        self.contact: dict | None = None
        self._pending: tuple[int, float] | None = None
        self._sent = -1
        self._count = 0
        self._offset0 = 0.0
        self._last_offset = math.nan

    # ------------------------------------------------------------------ helpers
    def _touch_off_busy(self, machine) -> bool:
        program = getattr(machine, "process_program", None)
        touch = program.function("touch_off", self.axis) if program is not None else None
        return touch is not None and touch.phase != "IDLE"

    def _is_contact(self, signal: float) -> bool:
        if signal <= self.threshold:
            return True
        return self.short_circuit is not None and abs(signal - self.short_circuit) <= _SHORT_BAND

    # ------------------------------------------------------------------ once per PLC cycle
    def step(self, machine, cycle: int) -> None:
        unit = machine.hli[self.axis]
        if self._pending is not None:
            self._flush(unit, cycle)
            if self._pending is not None:
                return
        phase = self.phase
        state = unit.state_r.actual_state
        offset = unit.state_r.actual_offset * MM_PER_UNIT
        if phase == WATCH:
            if not self.switched_on:
                return
            signal = read_signal(machine, self.axis, self.variable)
            armed = state in _ARMED and not self._touch_off_busy(machine)
            self.hits = self.hits + 1 if armed and self._is_contact(signal) else 0
            if self.hits >= self.confirm_cycles:
                self._contact(machine, unit, cycle, state, signal)
        elif cycle <= self._sent:
            pass                                       # the state shows a command one cycle later
        elif phase == FREEZING:
            if state == _FREEZE:
                self._offset0 = offset
                set_dist = max(self.contact["reading"], 0.0) + self.retract + RETRACT_MARGIN
                self._send(unit, cycle, _T_ON_CD, set_dist if set_dist == set_dist else self.retract + RETRACT_MARGIN)
                self.phase = RETRACTING
                self._count = 0
            else:
                self._finish(machine, cycle, offset, f"distance control is {_name(state)}, not FREEZE")
        elif phase == RETRACTING:
            self._count += 1
            v = (offset - self._last_offset) / self.cycle_time if self._last_offset == self._last_offset else 0.0
            if state != _ACTIVE_CD:
                self._finish(machine, cycle, offset, f"the retract ended in {_name(state)}")
            elif offset - self._offset0 >= self.retract - v * v / (2.0 * self.retract_accel) \
                    or self._count > self.stop_cycles:
                self._send(unit, cycle, _T_FREEZE)
                self.phase = STOPPING
                self._count = 0
        elif phase == STOPPING:
            self._count += 1
            if offset == self._last_offset or state != _FREEZE or self._count > self.stop_cycles:
                self._finish(machine, cycle, offset, None)
        self._last_offset = offset

    def _contact(self, machine, unit, cycle: int, state: int, signal: float) -> None:
        drives = getattr(machine, "drives", {})
        x = drives["X"].actual if "X" in drives else math.nan
        y = drives["Y"].actual if "Y" in drives else math.nan
        nc = getattr(machine, "nc", None)
        self.contact = {"cycle": cycle, "line": nc.line if nc is not None else None, "x": x, "y": y,
                        "reading": signal}
        machine.stop_program(None)                      # the path decelerates at the axis limits
        self.hold.inhibitors.add(self.name)             # the locks must not freeze the retract
        write_object(machine, self.axis, "DIST_CTRL_PARAM[0]::v_max", max(1, round(self.retract_speed * 1000.0)))
        write_object(machine, self.axis, "DIST_CTRL_PARAM[0]::a_max", max(1, round(self.retract_accel)))
        self.phase = FREEZING
        if state != _FREEZE:
            self._send(unit, cycle, _T_FREEZE)
        else:
            self._sent = cycle - 1                      # already in FREEZE: select at once next step

    def _finish(self, machine, cycle: int, offset: float, problem: str | None) -> None:
        machine.reset()                                 # INACTIVE, offset absorbed: the head stays up
        c = self.contact
        rise = offset - self._offset0 if self.phase in (RETRACTING, STOPPING) else 0.0
        seconds = (cycle - c["cycle"]) * self.cycle_time
        c["retract"], c["retract_time"] = rise, seconds
        where = f"X={c['x']:.3f} mm Y={c['y']:.3f} mm" if c["y"] == c["y"] else f"X={c['x']:.3f} mm"
        detail = (f"at {where} the sensor read {c['reading']:.3f} mm (threshold {self.threshold:g} mm); the head "
                  f"retracted {rise:.3f} mm in {seconds:.3f} s at <= {self.retract_speed:g} mm/s, "
                  f"distance control is off")
        if problem:
            detail += f" (the retract stopped early: {problem})"
        event = make_event(int(ErrorId.COLLISION_RETRACT), c["cycle"], c["line"], detail)
        machine.events.append((c["cycle"] * machine.T, event))
        self.errors.append(event)
        self.log.append(dict(c))
        self.phase = WATCH                              # distance control is INACTIVE: a new select arms it
        self.hits = 0
        self.hold.inhibitors.discard(self.name)


def _name(state: int) -> str:
    try:
        return f"{HliState(state).name} ({state})"
    except ValueError:
        return str(state)
