"""Void / kerf-crossing lock: FREEZE while the sensor signal changes faster than a plate can.

Over a hole, a kerf or the sheet edge the arc voltage of a plasma torch jumps up (the arc reaches
further) and a distance sensor reads "too far"; a height control that follows it dives into the
void. Warp and waviness change the signal far more slowly. The lock watches the signal's rate of
change over a window of ``window`` seconds,

    rate = (x[k] - x[k - N]) / (N · T)      N = round(window / T), T the PLC (GEO) cycle time,

and holds the height (FREEZE) after ``on_cycles`` consecutive cycles with ``|rate| > threshold``. It
re-activates distance control (FREEZE -> ON / ON_CONST_DIST, :mod:`.hold`) after ``off_cycles``
consecutive cycles in which the signal is steady again: ``|rate| <= threshold`` and the window's
mean at most ``release_band`` above the level before the void (below it the head is closer than
before: re-activating moves it away from the sheet) (the window's mean N cycles before the
cycle that locked; within 2·N cycles of the select ``x[k - N]``). A window of 20 ms (a whole 50 Hz
period) cancels the mains ripple of an arc voltage, in the rate and in the means. The window starts
afresh at every select.

It follows QtPlasmaC's void lock ("void anti-dive": a voltage slope in V/s with on/off cycle counts,
500 V/s by default) and LinuxCNC's kerfcross component (a voltage change per sample period and a
lockout of a number of periods). The signal is a V.E. variable (the arc voltage in V, or a
distance sensor's distance in mm; ``threshold`` and ``release_band`` are in its unit per second and
its unit), or, without a variable, ``state_r.actual_distance`` (DINT 0.1 µm -> mm) of the axis's
control unit (a probe on encoder 2). A NaN sample counts as unsteady and is not stored.

ST equivalent (``aBuf`` a ring buffer of N LREAL, ``i`` its index)::

    x := V_E_SIGNAL;
    IF NOT fbHold.bTrackingOrHeld THEN          (* the window starts afresh at the select *)
        nFill := 0; nMFill := 0; lrSum := 0.0; bLock := FALSE; nOn := 0; nOff := 0;
    ELSE
        lrOld := aBuf[i]; bFull := nFill >= N;
        lrMeanOld := aMean[i]; bMFull := nMFill >= N;       (* the window mean N cycles ago *)
        aBuf[i] := x; lrSum := lrSum + x - SEL(bFull, 0.0, lrOld);
        IF NOT bFull THEN nFill := nFill + 1; END_IF
        IF nFill >= N THEN
            lrMean := lrSum / N; aMean[i] := lrMean;
            IF nMFill < N THEN nMFill := nMFill + 1; END_IF
        END_IF
        i := (i + 1) MOD N;
        IF NOT bFull THEN
            bLock := FALSE; nOn := 0; nOff := 0;
        ELSE
            lrRate := (x - lrOld) / (N * lrT);
            IF NOT bLock THEN
                IF ABS(lrRate) > lrThreshold THEN nOn := nOn + 1; ELSE nOn := 0; END_IF
                IF nOn >= nOnCycles THEN
                    bLock := TRUE; lrLevel := SEL(bMFull, lrOld, lrMeanOld); nOff := 0;
                END_IF
            ELSE
                IF ABS(lrRate) <= lrThreshold AND lrMean - lrLevel <= lrBand THEN nOff := nOff + 1;
                ELSE nOff := 0; END_IF
                IF nOff >= nOffCycles THEN bLock := FALSE; nOn := 0; END_IF
            END_IF
        END_IF
    END_IF
    fbHold.bReqVoid := bLock;
"""
from __future__ import annotations

import math

from ...errors.config import require_number
from ..variables import ve_name
from .base import Key, ProcessFunction, ProcessTable, tracking_or_held, ve_key

__all__ = ["VoidLock", "VOID_DEFAULTS", "VOID_THRESHOLD_V_S", "VOID_THRESHOLD_MM_S", "VOID_WINDOW_DISTANCE_S"]

#: V/s: the default threshold on an arc voltage (QtPlasmaC's void slope default)
VOID_THRESHOLD_V_S = 500.0
#: mm/s: the default threshold on a distance (500 V/s at a typical arc gradient of 6 V/mm ~ 83 mm/s)
VOID_THRESHOLD_MM_S = 80.0
VOID_DEFAULTS = {"window": 0.02, "on_cycles": 3, "off_cycles": 20}
#: s: the default window on a distance (no mains ripple to average over; at 20 m/min it spans 1.7 mm,
#: so a void is seen while a capacitive electrode slides onto it)
VOID_WINDOW_DISTANCE_S = 0.005
_MM_PER_UNIT = 1e-4


class VoidLock(ProcessFunction):
    """``threshold`` (signal unit / s), ``window`` (s), ``on_cycles``, ``off_cycles``,
    ``release_band`` (signal unit; default ``threshold · window / 2``), ``variable`` (a V.E. name, or
    None for ``state_r.actual_distance``), ``cycle_time`` (s, the PLC cycle)."""

    name = "void_lock"
    KEYS = {
        "variable": Key(None, "V.E. variable of the signal; default the arc-voltage sensor's voltage, else the "
                        "distance sensor's variable, else state_r.actual_distance", kind="name"),
        "threshold": Key(None, "signal unit/s of a void; default VOID_THRESHOLD_V_S on a voltage, else "
                         "VOID_THRESHOLD_MM_S", lo=0.0, lo_open=True),
        "window": Key(VOID_DEFAULTS["window"], "s the rate is averaged over (at least one cycle; default on a "
                      "distance VOID_WINDOW_DISTANCE_S)", hi=1.0),
        "on_cycles": Key(VOID_DEFAULTS["on_cycles"], "cycles over the threshold before the lock", kind="int",
                         lo=1, hi=10000),
        "off_cycles": Key(VOID_DEFAULTS["off_cycles"], "cycles inside the release band before the release",
                          kind="int", lo=1, hi=100000),
        "release_band": Key(None, "signal unit; default threshold · window / 2", lo=0.0, lo_open=True),
    }

    @classmethod
    def from_config(cls, table: ProcessTable) -> dict:
        sensor, cycle_time, k = table.sensor, table.cycle_time, table.prefix
        voltage = sensor.voltage_variable if sensor is not None and sensor.kind == "arc_voltage" else None
        default_var = voltage or (sensor.variable if sensor is not None and sensor.kind == "distance" else None)
        var = table.get("variable", default_var)
        if var is not None:
            var = ve_key(var, k + "variable", "a V.E. variable name (e.g. \"ARC_VOLTAGE\" or \"SENSOR\")")
        is_voltage = var is not None and var == voltage
        threshold = table.read(cls, "threshold", VOID_THRESHOLD_V_S if is_voltage else VOID_THRESHOLD_MM_S)
        # a mains period on an arc voltage; on a distance (no ripple) a short window (issue 16's laser sheet)
        window = table.read(cls, "window", VOID_DEFAULTS["window"] if is_voltage
                            else max(VOID_WINDOW_DISTANCE_S, cycle_time), lo=cycle_time)
        band = table.read(cls, "release_band", 0.5 * threshold * window)
        return {"variable": var, "threshold": threshold, "window": window,
                "on_cycles": table.read(cls, "on_cycles"), "off_cycles": table.read(cls, "off_cycles"),
                "release_band": band}

    def __init__(self, axis: str, cycle_time: float, threshold: float, *, variable: str | None = None,
                 window: float = VOID_DEFAULTS["window"], on_cycles: int = VOID_DEFAULTS["on_cycles"],
                 off_cycles: int = VOID_DEFAULTS["off_cycles"], release_band: float | None = None,
                 enabled: bool = True):
        super().__init__(axis, enabled)
        self.cycle_time = require_number(cycle_time, "void_lock.cycle_time", lo=0.0, lo_open=True)
        keys = self.KEYS
        self.threshold = keys["threshold"].check(threshold, "void_lock.threshold")
        self.window = keys["window"].check(window, "void_lock.window", lo=self.cycle_time)
        self.on_cycles = keys["on_cycles"].check(on_cycles, "void_lock.on_cycles")
        self.off_cycles = keys["off_cycles"].check(off_cycles, "void_lock.off_cycles")
        if release_band is None:
            release_band = 0.5 * self.threshold * self.window
        self.release_band = keys["release_band"].check(release_band, "void_lock.release_band")
        self.variable = None if variable is None else ve_name(variable)
        self.n = max(1, round(self.window / self.cycle_time))
        self._rate_scale = 1.0 / (self.n * self.cycle_time)
        self.reset()

    def reset(self) -> None:
        self._buf = [0.0] * self.n
        self._i = 0
        self._fill = 0
        self._sum = 0.0                        # of the samples in the window
        self._means = [0.0] * self.n           # the window means of the last N cycles (ring, index _i)
        self._mfill = 0
        #: the mean of the signal over the window (signal unit; NaN until the window is full)
        self.mean = math.nan
        self.locked = False
        self.on_count = 0
        self.off_count = 0
        self.level = math.nan
        self.rate = math.nan

    def _signal(self, machine) -> float:
        if self.variable is None:
            return machine.hli[self.axis].state_r.actual_distance * _MM_PER_UNIT
        return machine.variables.get(self.variable, math.nan)

    def step(self, machine, cycle: int) -> None:
        x = self._signal(machine)
        finite = math.isfinite(x)
        if not tracking_or_held(machine.hli[self.axis].state_r.actual_state, self.hold):
            # the window starts afresh at the select: a sample from before it (the head coming down
            # to the cut height with distance control off) is no void (issue 16's plates)
            self._fill = self._mfill = 0
            self._sum = 0.0
            self.mean = math.nan
            self.locked = False
            self.on_count = self.off_count = 0
            return
        i = self._i
        old = self._buf[i]
        full = self._fill >= self.n                    # old is a sample taken N cycles ago
        mean_old = self._means[i]                      # the window mean N cycles ago
        mean_full = self._mfill >= self.n
        if finite:
            self._buf[i] = x
            self._sum += x - old if full else x
            if not full:
                self._fill += 1
            if self._fill >= self.n:
                self.mean = self._sum / self.n
                self._means[i] = self.mean
                if self._mfill < self.n:
                    self._mfill += 1
            self._i = (i + 1) % self.n
        if not full:
            self.locked = False
            self.on_count = self.off_count = 0
            return
        rate = (x - old) * self._rate_scale if finite else math.inf
        self.rate = rate
        steady = abs(rate) <= self.threshold
        if not self.locked:
            self.on_count = 0 if steady else self.on_count + 1
            if self.on_count >= self.on_cycles:
                self.locked = True
                # the level before the void: the window mean N cycles ago (a whole mains period: the
                # ripple averages out); right after the select the sample N cycles ago
                self.level = mean_old if mean_full else old
                self.off_count = 0
        else:
            # back within the band of the level, or below it (the head closer than before the void:
            # re-activating moves it away from the sheet; a signal above it keeps the hold)
            if steady and self.mean - self.level <= self.release_band:
                self.off_count += 1
            else:
                self.off_count = 0
            if self.off_count >= self.off_cycles:
                self.locked = False
                self.on_count = 0
        if self.locked:
            self.hold.request(self.name)
