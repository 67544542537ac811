"""``distctrl identify``: the plant (drive and sensor) fitted to recordings of the real machine.

A recording is a CSV at the interpolation cycle with four signals: time, the set position sent to
the drive (*command*), the motor encoder (*actual*) and the height sensor (*sensor*). Three kinds of
file load (docs/identify.md): a plain CSV with a header row, a distctrl trace (docs/trace.md, with
its ``.meta.json`` sidecar) and a TwinCAT Scope CSV export (metadata rows before the data, ``;``,
TAB or ``,`` separated, decimal comma possible, one time column per group of channels).

The model (the one ``distctrl run`` simulates, docs/sim-models.md, in continuous time)::

    command --(dead time)--> P loop kv, |v| <= v_max, |dv/dt| <= a_max --> motor x (actual column)
    motor --(mode f0, zeta: e'' = -w0^2 e - 2 zeta w0 e' - x'')--> nozzle n = x + e
    sensor = sign * characteristic(n(t - delay) - surface) + noise

and the classic tools fit it:

* drive: the one-step equation of the sampled P loop, ``x_{k+1} - x_k = (1 - exp(-kv T)) (c_k - x_k)``
  with ``c_k`` the command delayed by the dead time (fractional, interpolated), by robust least
  squares (:func:`scipy.optimize.least_squares`, soft-L1) on a grid of dead times, then refined;
  ``v_max`` and ``a_max`` from the samples where the loop demands more than the motor does;
* resonance, damping, sensor delay, noise and characteristic: the path that sees the nozzle, motor
  encoder -> sensor. The frequency response motor -> sensor ``H = Pxy / Pxx``
  (:func:`scipy.signal.csd`, :func:`scipy.signal.welch`) gives the coherent band, the gain and a
  first guess; then the complete model (mode, delay, piecewise-linear characteristic) is fitted to
  every sample in the time domain (:mod:`.nozzle`); the noise is what it leaves over;
* each identified figure gets a standard deviation (``Identification.uncertainty``); recordings not
  used for the fit (``validate``) give the prediction error (``Identification.validation``).

A figure that the recordings cannot determine is ``None`` with a warning that says what to record.
Errors are :class:`IdentifyError` (a ``DistCtrlError``) whose message names the file, the column or
what to record.
"""
from __future__ import annotations

from .common import (
                     MIN_SAMPLES,
                     MIN_SECONDS,
                     RECORD_CHIRP,
                     RECORD_LARGE_STEP,
                     RECORD_RAMP,
                     RECORD_STANDSTILL,
                     RECORD_STEPS,
                     IdentifyError,
                     IdentifyWarning,
)
from .fit import Identification, identify, nozzle_from_motor, simulate_drive
from .output import format_summary, result_json, write_report, write_scenario
from .recordings import Signals, is_scope_export, load_signals

__all__ = ["IdentifyError", "IdentifyWarning", "Signals", "Identification", "load_signals", "identify",
           "result_json", "format_summary", "write_scenario", "write_report", "MIN_SECONDS", "MIN_SAMPLES",
           "RECORD_STEPS", "RECORD_LARGE_STEP", "RECORD_CHIRP", "RECORD_RAMP", "RECORD_STANDSTILL",
           "is_scope_export", "nozzle_from_motor", "simulate_drive"]
