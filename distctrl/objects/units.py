"""Interface-unit conversions of the CNC objects and the HLI (SPEC §1: converted once, at the boundary).

Internal values are float64 mm, mm/s, mm/s², s. The interface integers are produced by
:func:`round_saturate`: round half away from zero, then clamp to the integer type's range (a NaN
becomes 0; the cycle core never emits one, but a boundary must not raise on it).
"""
from __future__ import annotations

import math

INT32_MIN, INT32_MAX = -(1 << 31), (1 << 31) - 1
UINT32_MAX = (1 << 32) - 1
INT64_MIN, INT64_MAX = -(1 << 63), (1 << 63) - 1

#: 0.01 nm counts per mm (SGN64 position objects)
COUNTS_PER_MM_001NM = 1e8
#: 0.1 µm per mm (REAL64 "0.1 µm..." objects, HLI DINT positions)
PER_MM_01UM = 1e4
#: µm per mm (DIST_CTRL_PARAM[0]::v_max in µm/s)
UM_PER_MM = 1e3


def round_saturate(x: float, lo: int, hi: int) -> int:
    """``x`` rounded to the nearest integer (halves away from zero) and clamped to ``[lo, hi]``."""
    x = float(x)
    if x != x:
        return 0
    if x >= hi:
        return hi
    if x <= lo:
        return lo
    r = math.floor(abs(x) + 0.5)
    n = int(r) if x >= 0 else -int(r)
    return min(hi, max(lo, n))


def mm_to_nm001(mm: float) -> int:
    """mm -> SGN64 counts of 0.01 nm (1 count = 1e-8 mm)."""
    return round_saturate(float(mm) * COUNTS_PER_MM_001NM, INT64_MIN, INT64_MAX)


def mm_to_dint_01um(mm: float) -> int:
    """mm -> DINT in 0.1 µm (HLI positions), saturated to the DINT range."""
    return round_saturate(float(mm) * PER_MM_01UM, INT32_MIN, INT32_MAX)


def mm_to_increments(mm: float, mm_per_increment: float) -> int:
    """mm -> SGN32 drive increments (the drive resolution includes the gear ratio)."""
    return round_saturate(float(mm) / mm_per_increment, INT32_MIN, INT32_MAX)
