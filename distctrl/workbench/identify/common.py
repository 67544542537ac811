"""What the parts of ``distctrl identify`` share: its errors, warnings and limits, and what to record."""
from __future__ import annotations

import numpy as np

from ...errors import DistCtrlError


class IdentifyError(DistCtrlError, ValueError):
    """Invalid recordings or options for ``identify`` (exit code 1)."""


class IdentifyWarning(UserWarning):
    """A figure that could not be identified, or a doubt about one."""


#: shortest recording identify accepts (s)
MIN_SECONDS = 1.0
#: and in samples
MIN_SAMPLES = 200
#: what to record, quoted in the messages (docs/identify.md)
RECORD_STEPS = ("steps of the set position of 0.2-0.5 mm (0.5 s apart, sensor not saturated, "
                "distance control off; NC G0 moves or raw set-position steps)")
RECORD_LARGE_STEP = ("a step large enough that the axis reaches its velocity limit (several mm, "
                     "at a safe height above the sheet)")
RECORD_CHIRP = ("a chirp of the set position 1-150 Hz, 0.02-0.05 mm amplitude, 20 s, above the sheet")
RECORD_RAMP = ("a slow ramp of the set position (0.2-0.5 mm/s) over the sensor's range, with the "
               "sensor over a flat sheet")
RECORD_STANDSTILL = "1 s or more at standstill above the sheet"
RECORD_OPEN_LOOP = "record with distance control off, above a flat sheet"

#: the identified figures, the keys of ``drive`` and ``sensor`` (issue 15 pins them)
DRIVE_KEYS = ("kv", "dead_time", "feedforward", "v_max", "a_max", "resonance_hz", "damping")
SENSOR_KEYS = ("delay", "noise_std", "characteristic")


def _mode(f: np.ndarray, f0: float, zeta: float) -> np.ndarray:
    """Motor -> nozzle: (w0^2 + 2 zeta w0 s) / (s^2 + 2 zeta w0 s + w0^2) at s = j 2 pi f."""
    s = 2j * np.pi * f
    w0 = 2.0 * np.pi * f0
    return (w0 * w0 + 2 * zeta * w0 * s) / (s * s + 2 * zeta * w0 * s + w0 * w0)
