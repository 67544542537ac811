"""The plant's arithmetic as plain functions: drive loop, resonance, encoder quantisation, the probe's and
the distance sensor's conversion.

Like :mod:`distctrl.control.law` for the controller, this is the only copy. The virtual machine
(:class:`~distctrl.sim.drive.Drive`, :class:`~distctrl.sim.sensors.EncoderProbe`,
:class:`~distctrl.sim.sensors.DistanceSensor`) calls these
functions in CPython; the batch kernels (:mod:`distctrl.batch.closed_loop`,
:mod:`distctrl.batch.soa`) call the same functions compiled with numba (registered by
:mod:`distctrl.batch.kernel`), so the replay equals the machine bit for bit. Scalars only. Units: mm,
mm/s, s.
"""
from __future__ import annotations

import math
from math import floor


def limit_velocity(v, v_max, v_prev, dv_max):
    """The drive's velocity limits: |v| <= v_max, then |v - v_prev| <= dv_max (= a_max * T)."""
    if v > v_max:
        v = v_max
    elif v < -v_max:
        v = -v_max
    if v > v_prev + dv_max:
        v = v_prev + dv_max
    elif v < v_prev - dv_max:
        v = v_prev - dv_max
    return v


def floor_float(x):
    """floor(x) as a float. Compiled (distctrl.batch.kernel) it is one rounding instruction
    (``np.floor``); ``math.floor`` there goes through a 64-bit integer and back."""
    return float(floor(x))


def quantise(x, resolution, inv_resolution):
    """A position (mm) as the encoder reads it: rounded to ``resolution`` (> 0; ``inv_resolution``
    = 1/resolution)."""
    return floor_float(x * inv_resolution + 0.5) * resolution


def probe_increments(x, range_min, range_max, ref_offset, increments_per_mm):
    """The probe's raw reading of the geometric value x (mm, not NaN): clamped to the stroke,
    shifted by the reference offset and rounded to whole increments."""
    if x < range_min:
        x = range_min
    elif x > range_max:
        x = range_max
    return floor_float((x - ref_offset) * increments_per_mm + 0.5)


def round_to(x, resolution):
    """``x`` rounded to a multiple of ``resolution`` (> 0) by ``floor(x / resolution + 0.5)``: the
    distance sensor's quantisation (a division, as the sensor has always computed it)."""
    return floor_float(x / resolution + 0.5) * resolution


def characteristic_value(d, xs, ys):
    """The distance sensor's static characteristic: the reported value (mm) at the true distance
    ``d`` (mm), linear between the points ``(xs[i], ys[i])`` (``xs`` strictly increasing, at least
    two points); beyond the table the end values hold. ``xs``, ``ys``: sequences of floats (lists
    in the simulator, arrays in the kernels)."""
    n = len(xs)
    if d <= xs[0]:
        return ys[0]
    if d >= xs[n - 1]:
        return ys[n - 1]
    i = 1
    while xs[i] < d:  # tables are short (a handful of points): a linear scan beats bisect
        i += 1
    x0 = xs[i - 1]
    x1 = xs[i]
    return ys[i - 1] + (ys[i] - ys[i - 1]) * (d - x0) / (x1 - x0)


def distance_reading(x, range_max, xs, ys, resolution):
    """What the distance sensor reports for the distance ``x`` (mm, not NaN; noise included):
    saturated to its range ``[0, range_max]``, through the characteristic (``xs``/``ys``; empty:
    none, :func:`characteristic_value`), then quantised to ``resolution`` mm (0: not quantised)."""
    if x < 0.0:
        x = 0.0
    elif x > range_max:
        x = range_max
    if len(xs) > 0:
        x = characteristic_value(x, xs, ys)
    if resolution != 0.0:
        x = round_to(x, resolution)
    return x


def resonance_step(e, de, dv, p11, p12, p21, p22):
    """One cycle of the mechanical mode between motor and nozzle (docs/sim-models.md "Drive").

    ``e`` (mm) and ``de`` (mm/s) are the nozzle's deflection from the motor and its rate at the end
    of the last cycle, ``dv`` = v_k - v_(k-1) the change of the motor velocity at the start of this
    cycle (mm/s), ``p11 .. p22`` = expm(A T) with A = [[0, 1], [-w0^2, -2 zeta w0]]
    (:func:`resonance_coefficients`). The motor velocity is constant within a cycle, so its
    acceleration is an impulse at the cycle start: ``de`` jumps by ``-dv``, then (e, de) move freely
    for one cycle -- exact, whatever f0 and T. Returns the new ``(e, de)``."""
    de = de - dv
    return p11 * e + p12 * de, p21 * e + p22 * de


def resonance_coefficients(resonance_hz, damping, cycle_time):
    """``(p11, p12, p21, p22)`` = expm(A T), A = [[0, 1], [-w0^2, -2 zeta w0]], w0 = 2 pi f0 (set-up
    only, not compiled: scipy)."""
    # set-up only: numpy and scipy stay off the import path of the functions numba compiles from here
    import numpy as np
    from scipy.linalg import expm

    w0 = 2.0 * math.pi * resonance_hz
    a = np.array([[0.0, 1.0], [-w0 * w0, -2.0 * damping * w0]])
    phi = expm(a * cycle_time)
    return float(phi[0, 0]), float(phi[0, 1]), float(phi[1, 0]), float(phi[1, 1])


#: the functions numba compiles for the batch kernels (registered by distctrl.batch.kernel)
PHYSICS_FUNCTIONS = (limit_velocity, quantise, probe_increments, resonance_step, round_to, characteristic_value,
                     distance_reading)
