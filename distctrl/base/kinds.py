"""Enumerations shared by parameters, NC words and the cycle core."""
from __future__ import annotations

from enum import IntEnum


class FilterType(IntEnum):
    """P-AXIS-00782 / P-CHAN-00825 filter types. The integer is the code the law functions use."""

    DEFAULT = -1          # moving average with n = 4, whatever n_cycles says
    PASS = 0              # pass-through (n <= 1, order 0, smoothing factor 1)
    MOVING_AVERAGE = 1
    EXPO_MEAN = 2
    LOWPASS = 3
    KALMAN_MA = 4
    KALMAN_EXPO = 5

    @classmethod
    def parse(cls, name: str) -> "FilterType":
        key = name.strip().upper()
        if key == "PASS" or key not in cls.__members__:
            raise ValueError(f"unknown filter type {name!r}; allowed: {', '.join(FILTER_TYPE_NAMES)}")
        return cls[key]


#: the names the documents allow (PASS is internal only)
FILTER_TYPE_NAMES = ("DEFAULT", "MOVING_AVERAGE", "LOWPASS", "KALMAN_MA", "EXPO_MEAN", "KALMAN_EXPO")


class SensorSource(IntEnum):
    """SENSOR_SOURCE: where the distance comes from (SPEC §2)."""

    DEFAULT = 0          # SECOND_ENCODER for the axis variant, VARIABLE for the 3D variant
    SECOND_ENCODER = 1   # raw increments of encoder 2
    VARIABLE = 2         # a V.E. variable holding the distance in mm

    @classmethod
    def parse(cls, name: str) -> "SensorSource":
        key = name.strip().upper()
        if key not in cls.__members__:
            raise ValueError(f"unknown sensor source {name!r}; allowed: DEFAULT, SECOND_ENCODER, VARIABLE")
        return cls[key]
