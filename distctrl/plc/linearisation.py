"""PLC program: linearise a distance sensor's reading through a table into the distance variable.

FCT-M3 §12.3 "CNC and PLC tasks": "The PLC must remove non-linear dependencies from the sensor value"
and supplies the idealised distance in the V.E. variable distance control reads
(``SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR``, PROG #DIST CTRL). A capacitive sensor's amplifier
reports a distance that is not quite the true one (its characteristic, docs/sim-models.md); the
calibration run (``distctrl calibrate``, docs/process.md) measures it over a flat sheet and writes
the table this program interpolates, every GEO cycle::

    (* PLC task at the GEO cycle: reading (mm) -> distance (mm), table aRead/aDist of n points *)
    x := V_E_SENSOR_RAW;
    i := 1;
    WHILE i < n - 1 AND x > aRead[i] DO i := i + 1; END_WHILE    (* the segment [i-1, i] *)
    V_E_SENSOR := aDist[i-1] + (x - aRead[i-1]) * (aDist[i] - aDist[i-1]) / (aRead[i] - aRead[i-1]);

Between the points it interpolates linearly; below the first and above the last it extends the end
segments (a reading beyond the calibrated stroke still grows with the distance rather than sticking
at the table's end). A NaN reading gives a NaN distance, which the control reports as an invalid
sensor value. Like the arc-voltage linearisation it runs before the sensor of this cycle is read:
it linearises the reading of the previous cycle (one cycle of dead time, a PLC task at the GEO cycle
that reads its analog input once per task cycle).
"""
from __future__ import annotations

import bisect
import math

import numpy as np

from ..errors.config import ConfigError
from .variables import ve_name

__all__ = ["DistanceLinearisation", "check_table"]



def check_table(table, key: str = "linearisation") -> tuple[tuple[float, float], ...]:
    """``table`` as ((reading mm, distance mm), ...): at least 2 pairs of finite numbers, readings
    strictly increasing; else :class:`ConfigError` naming ``key``."""
    allowed = "a list of at least 2 [reading_mm, distance_mm] pairs, reading_mm strictly increasing"
    if not isinstance(table, (list, tuple)) or len(table) < 2:
        raise ConfigError(key, table, allowed, "not a table:" if not isinstance(table, (list, tuple)) else
                          "too short:")
    out = []
    for n, pair in enumerate(table):
        if (not isinstance(pair, (list, tuple)) or len(pair) != 2
                or any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) for v in pair)):
            raise ConfigError(f"{key}[{n}]", pair, "a pair [reading_mm, distance_mm] of finite numbers")
        if out and not pair[0] > out[-1][0]:
            raise ConfigError(f"{key}[{n}]", pair, allowed, "reading not increasing:")
        out.append((float(pair[0]), float(pair[1])))
    return tuple(out)


class DistanceLinearisation:
    """``distance_variable := table(raw_variable)`` every cycle (module docstring). ``table``: pairs
    (reading mm, distance mm), readings strictly increasing; variable names with or without ``V.E.``."""

    def __init__(self, table, raw_variable: str = "V.E.SENSOR_RAW", distance_variable: str = "V.E.SENSOR"):
        self.table = check_table(table, "DistanceLinearisation.table")
        self.raw_variable = ve_name(raw_variable)
        self.distance_variable = ve_name(distance_variable)
        self._x = np.array([p[0] for p in self.table])
        self._y = np.array([p[1] for p in self.table])
        # end segments' slopes for the extension beyond the table
        self._lo = (self._x[0], self._y[0], (self._y[1] - self._y[0]) / (self._x[1] - self._x[0]))
        self._hi = (self._x[-1], self._y[-1], (self._y[-1] - self._y[-2]) / (self._x[-1] - self._x[-2]))
        self._xs = self._x.tolist()
        self._ys = self._y.tolist()

    def distance(self, reading):
        """The distance (mm) this table gives for ``reading`` (mm; a number or an array)."""
        x = np.asarray(reading, dtype=float)
        y = np.interp(x, self._x, self._y)
        x0, y0, s0 = self._lo
        x1, y1, s1 = self._hi
        y = np.where(x < x0, y0 + (x - x0) * s0, y)
        y = np.where(x > x1, y1 + (x - x1) * s1, y)
        return float(y) if y.ndim == 0 else y

    def _one(self, x: float) -> float:
        xs, ys = self._xs, self._ys
        if x != x:
            return math.nan
        if x <= xs[0]:
            x0, y0, s0 = self._lo
            return y0 + (x - x0) * s0
        if x >= xs[-1]:
            x1, y1, s1 = self._hi
            return y1 + (x - x1) * s1
        i = bisect.bisect_right(xs, x)
        xa, xb, ya, yb = xs[i - 1], xs[i], ys[i - 1], ys[i]
        return ya + (x - xa) * (yb - ya) / (xb - xa)

    def __call__(self, machine, cycle: int) -> None:
        variables = machine.variables
        variables[self.distance_variable] = self._one(variables.get(self.raw_variable, math.nan))

    def __repr__(self) -> str:
        return (f"DistanceLinearisation({len(self.table)} points, raw_variable={self.raw_variable!r}, "
                f"distance_variable={self.distance_variable!r})")
