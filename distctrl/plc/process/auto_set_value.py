"""Automatic set value: sample the sensor after the cut starts and take the mean as SET_DIST / SET_POS.

A plasma torch's arc voltage at the cut height depends on the consumables' wear and the material,
so a fixed calibration drifts. QtPlasmaC's "auto volts" and Hypertherm's voltage sampling take the
set value from the cut itself: the torch is brought to the cut height, the voltage is sampled for a
short time, and its mean becomes the value the height control holds. distctrl does the same on the
distance the controller reads:

* **the cut starts** when ``state_r.actual_state`` goes from INACTIVE (0) to ACTIVE (1) or
  ACTIVE_CONST_DIST (4): the NC program (``Z[DIST_CTRL ON ...]``) or the PLC selected distance
  control. A re-activation out of FREEZE (the locks) is not a new cut.
* at once it requests the hold (FREEZE, :mod:`.hold`), so the head stays at the height it was
  brought to (the pierce / cut height of the program);
* it waits ``delay`` seconds (the arc and the FREEZE braking settle), then averages for
  ``sample_time`` seconds ``state_r.actual_distance`` (CONST_DIST: the measured distance d) or
  ``state_r.actual_position`` (SET_POS: the measured surface a - d), DINT 0.1 µm -> mm;
* it puts the mean into the hold's set value and releases its request: distance control is
  re-activated with ``ON_CONST_DIST`` (SET_DIST = mean) or ``ON`` (SET_POS = mean) once no other
  lock holds it. ``state_r.command_source`` then shows the PLC (1).

The set value the NC program selected with is only a placeholder then. Where the sensor's
calibration is off (a plasma linearisation with the wrong V0), the held *true* height is the one
the head had while sampling, not set value + calibration error. ``result`` keeps the last mean (mm).

ST equivalent::

    bRun := stState.actual_state = 1 OR stState.actual_state = 4;
    IF bRun AND nLastState = 0 THEN eAuto := WAITING; nCnt := 0; lrSum := 0.0; END_IF
    nLastState := stState.actual_state;
    CASE eAuto OF
    WAITING:  fbHold.bReqAuto := TRUE;
              IF nCnt >= nDelayCycles THEN eAuto := SAMPLING; nCnt := 0; ELSE nCnt := nCnt + 1; END_IF
    END_CASE
    IF eAuto = SAMPLING THEN
        fbHold.bReqAuto := TRUE;
        lrSum := lrSum + DINT_TO_LREAL(SEL(bConstDist, stState.actual_position,
                                           stState.actual_distance)) * 0.0001;
        nCnt := nCnt + 1;
        IF nCnt >= nSampleCycles THEN
            fbHold.lrSet := lrSum / nCnt; fbHold.bReqAuto := FALSE; eAuto := DONE;
        END_IF
    END_IF
    (* leaving the running states and the hold (OFF, RESET, ERROR) ends the sampling: eAuto := DONE *)
"""
from __future__ import annotations

import math

from ...base.states import HliState
from ...errors.config import require_number
from .base import Key, ProcessFunction, ProcessTable, tracking_or_held

__all__ = ["AutoSetValue", "AUTO_DEFAULTS"]

AUTO_DEFAULTS = {"delay": 0.1, "sample_time": 0.2}
_INACTIVE = int(HliState.INACTIVE)
_MM_PER_UNIT = 1e-4
DONE, WAITING, SAMPLING = "DONE", "WAITING", "SAMPLING"


class AutoSetValue(ProcessFunction):
    """``delay`` (s, >= 0) and ``sample_time`` (s, > 0) after the cut starts; ``cycle_time`` (s)."""

    name = "auto_set_value"
    KEYS = {
        "delay": Key(AUTO_DEFAULTS["delay"], "s after the cut starts before sampling", lo=0.0, hi=10.0),
        "sample_time": Key(AUTO_DEFAULTS["sample_time"], "s of sampling (at least one cycle)", hi=10.0),
    }

    @classmethod
    def from_config(cls, table: ProcessTable) -> dict:
        return {"delay": table.read(cls, "delay"), "sample_time": table.read(cls, "sample_time", lo=table.cycle_time)}

    def __init__(self, axis: str, cycle_time: float, delay: float = AUTO_DEFAULTS["delay"],
                 sample_time: float = AUTO_DEFAULTS["sample_time"], enabled: bool = True):
        super().__init__(axis, enabled)
        self.cycle_time = require_number(cycle_time, "auto_set_value.cycle_time", lo=0.0, lo_open=True)
        self.delay = self.KEYS["delay"].check(delay, "auto_set_value.delay")
        self.sample_time = self.KEYS["sample_time"].check(sample_time, "auto_set_value.sample_time", lo=self.cycle_time)
        self.delay_cycles = round(self.delay / self.cycle_time)
        self.sample_cycles = max(1, round(self.sample_time / self.cycle_time))
        #: (cycle, mean mm) of every sampling that completed (kept by reset())
        self.log: list[tuple[int, float]] = []
        #: the last sampled mean (mm), NaN before the first (kept by reset())
        self.result = math.nan
        self.reset()
        #: the HLI state seen in the last cycle (the PLC's nLastState; None after reset()): an
        #: INACTIVE -> active change starts a sampling
        self.last_state: int | None = _INACTIVE        # the PLC starts with nLastState = 0 (INACTIVE)

    def reset(self) -> None:
        """No sampling under way, and the state seen last forgotten: a function switched on (or off
        and on again) while distance control already runs waits for the next cut (INACTIVE ->
        ACTIVE) instead of taking the running one for a new cut. ``result`` and ``log`` are kept."""
        self.phase = DONE
        self.last_state = None
        self._count = 0
        self._sum = 0.0
        self.const_dist = False

    def step(self, machine, cycle: int) -> None:
        state_r = machine.hli[self.axis].state_r
        state = state_r.actual_state
        hold = self.hold
        if self.last_state == _INACTIVE and state in (int(HliState.ACTIVE), int(HliState.ACTIVE_CONST_DIST)):
            self.phase = WAITING
            self.const_dist = state == int(HliState.ACTIVE_CONST_DIST)
            self._count = 0
            self._sum = 0.0
        self.last_state = state
        if self.phase == DONE:
            return
        if not tracking_or_held(state, hold):
            self.phase = DONE                          # switched off, reset or an error: no set value
            return
        hold.request(self.name)
        if self.phase == WAITING:
            if self._count >= self.delay_cycles:
                self.phase = SAMPLING
                self._count = 0
            else:
                self._count += 1
                return
        value = state_r.actual_distance if self.const_dist else state_r.actual_position
        self._sum += value * _MM_PER_UNIT
        self._count += 1
        if self._count >= self.sample_cycles:
            self.result = self._sum / self._count
            self.log.append((cycle, self.result))
            hold.set_value = self.result
            hold.const_dist = self.const_dist
            hold.withdraw(self.name)                   # released in this very cycle
            self.phase = DONE
