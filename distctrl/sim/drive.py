"""Per-axis drive model: fieldbus delay, P position loop, velocity/acceleration limits, encoder.

Discretisation (one step per GEO cycle ``T``)::

    c_k   = setpoint delayed by bus_delay_cycles          (fieldbus: the drive sees an old setpoint)
    v*    = kv * (c_k - a_k) + ff * (c_k - c_{k-1}) / T    (P loop on the encoder position a_k,
                                                            optional velocity feed-forward ff)
    v_k   = clamp(v*, -v_max, v_max), then clamp(v_k, v_{k-1} - a_max*T, v_{k-1} + a_max*T)
    x_k+1 = x_k + v_k * T                                  (ideal velocity loop, forward Euler)
    a_k+1 = round(x_k+1 / resolution) * resolution         (encoder quantisation)

Without saturation this is ``x_k+1 = (1 - kv*T) x_k + kv*T c_k``: a first-order lag with a pole
at ``1 - kv*T``. It is stable for ``0 < kv*T < 2`` and, more to the point, monotone (no ringing,
like the continuous lag ``1/(1 + s/kv)``) for ``kv*T < 1``, which the constructor enforces.
The bus delay sits in the setpoint path, not in the loop, so it does not affect stability.
The time constant is ``tau = -T / ln(1 - kv*T)`` (``~ 1/kv`` for ``kv*T << 1``). ``step`` returns
the position at the end of the cycle, so at constant setpoint speed ``v`` the setpoint of a call
minus the position it returns is ``v * (1 - ff) / kv + (bus_delay_cycles - 1) * v * T``, i.e.
exactly ``v * (1 - ff) / kv`` with the default one-cycle bus delay.

Large setpoint steps saturate velocity and acceleration; the loop then overshoots, as a real
position loop without a trajectory generator would. The interpolator upstream keeps the setpoints
feasible. Hard travel limits (``min_pos``/``max_pos``) are end stops: the axis stops there at once
(velocity 0, ``at_limit`` set).

Mechanical resonance (``resonance_hz`` f0 > 0, damping ratio ``damping`` zeta): the loop above
moves the motor ``x``; the nozzle (what the sensor and the workpiece see) is ``x + e``, where the
deflection ``e`` of a second-order mode obeys ``e'' = -w0^2 e - 2 zeta w0 e' - x''`` (w0 = 2 pi f0).
The motor velocity is constant within a cycle, so ``x''`` is an impulse ``v_k - v_(k-1)`` at the
start of cycle k: ``e' -= v_k - v_(k-1)``, then ``[e, e']`` propagates with ``Phi = expm(A T)``
(:func:`distctrl.sim.physics.resonance_step`, coefficients computed once here). This is exact for
the piecewise-linear motor motion, for any f0; scenarios allow f0 up to 1/(4T). ``actual`` stays
the motor encoder (the loop is closed on the motor); ``nozzle`` is the nozzle position.
``resonance_hz = 0`` (the default) is the rigid drive: ``nozzle`` is ``position``, nothing else changes.
"""
from __future__ import annotations

import math
from collections import deque

from distctrl.errors.config import MAX_DELAY_CYCLES, ConfigError, require_int, require_number
from distctrl.sim.physics import limit_velocity, quantise, resonance_coefficients, resonance_step

__all__ = ["Drive"]


class Drive:
    """One servo axis; ``step(setpoint_mm) -> actual_mm`` once per GEO cycle.

    Public state: ``position`` (true mechanical position, mm), ``actual`` (encoder position fed
    back and returned, mm), ``velocity`` (mm/s, of the last cycle), ``setpoint_history`` (the bus
    delay line, oldest first), ``following_error`` (delayed setpoint - actual, mm), ``at_limit``,
    ``nozzle`` (mm: the motor ``position`` plus the resonance's ``deflection``; ``position`` for a
    rigid drive), ``deflection`` (mm) and ``deflection_rate`` (mm/s).
    """

    __slots__ = ("cycle_time", "kv", "v_max", "a_max", "bus_delay_cycles", "resolution", "min_pos",
                 "max_pos", "velocity_feedforward", "position", "actual", "velocity", "setpoint_history",
                 "following_error", "at_limit", "_dv_max", "_prev_setpoint", "_inv_T", "_inv_res", "_limited",
                 "resonance_hz", "damping", "nozzle", "deflection", "deflection_rate", "resonance_phi")

    def __init__(self, cycle_time: float = 0.001, *, kv: float = 30.0, v_max: float = 500.0,
                 a_max: float = 5000.0, bus_delay_cycles: int = 1, resolution: float = 0.0,
                 min_pos: float | None = None, max_pos: float | None = None,
                 initial_position: float = 0.0, velocity_feedforward: float = 0.0,
                 resonance_hz: float = 0.0, damping: float = 0.05):
        name = "Drive"
        self.cycle_time = require_number(cycle_time, f"{name}.cycle_time", lo=0.0, lo_open=True)
        # kv*T < 1 keeps the discrete loop monotone (see module docstring)
        self.kv = require_number(kv, f"{name}.kv", lo=0.0, hi=1.0 / self.cycle_time,
                                 lo_open=True, hi_open=True)
        self.v_max = require_number(v_max, f"{name}.v_max", lo=0.0, lo_open=True)
        self.a_max = require_number(a_max, f"{name}.a_max", lo=0.0, lo_open=True)
        self.bus_delay_cycles = require_int(bus_delay_cycles, f"{name}.bus_delay_cycles", lo=0,
                                            hi=MAX_DELAY_CYCLES)
        self.resolution = require_number(resolution, f"{name}.resolution", lo=0.0)
        self.velocity_feedforward = require_number(velocity_feedforward, f"{name}.velocity_feedforward",
                                                   lo=0.0, hi=1.0)
        self.min_pos = None if min_pos is None else require_number(min_pos, f"{name}.min_pos")
        self.max_pos = None if max_pos is None else require_number(max_pos, f"{name}.max_pos")
        if self.min_pos is not None and self.max_pos is not None and self.max_pos <= self.min_pos:
            raise ConfigError(f"{name}.max_pos", max_pos, f"greater than min_pos = {self.min_pos:g}")
        #: f0 (Hz) of the mode between motor and nozzle; 0 = rigid. Up to 1/(4T) (1/(2T) is Nyquist)
        self.resonance_hz = require_number(resonance_hz, f"{name}.resonance_hz", lo=0.0,
                                           hi=0.25 / self.cycle_time)
        self.damping = require_number(damping, f"{name}.damping", lo=0.0, hi=1.0, lo_open=True)
        #: (p11, p12, p21, p22) = expm(A T), or None for a rigid drive
        self.resonance_phi = (resonance_coefficients(self.resonance_hz, self.damping, self.cycle_time)
                              if self.resonance_hz else None)
        self.deflection = 0.0
        self.deflection_rate = 0.0
        x0 = require_number(initial_position, f"{name}.initial_position",
                            lo=self.min_pos, hi=self.max_pos)
        self._dv_max = self.a_max * self.cycle_time  # largest velocity change per cycle (mm/s)
        # per-cycle constants (the same numbers as 1.0 / T and 1.0 / resolution each cycle)
        self._inv_T = 1.0 / self.cycle_time
        self._inv_res = 1.0 / self.resolution if self.resolution else 0.0
        self._limited = self.min_pos is not None or self.max_pos is not None
        self.position = x0
        self.nozzle = x0
        self.actual = self._quantise(x0)
        self.velocity = 0.0
        # At rest holding its position: the delay line is full of the initial position.
        self.setpoint_history: deque[float] = deque([x0] * (self.bus_delay_cycles + 1),
                                                    maxlen=self.bus_delay_cycles + 1)
        self._prev_setpoint = x0
        self.following_error = 0.0
        self.at_limit = False

    @property
    def time_constant(self) -> float:
        """Time constant (s) of the unsaturated loop: ``-T / ln(1 - kv*T)``."""
        return -self.cycle_time / math.log1p(-self.kv * self.cycle_time)

    def _quantise(self, x: float) -> float:
        r = self.resolution
        return quantise(x, r, self._inv_res) if r else x

    def step(self, setpoint_mm: float) -> float:
        """Advance one cycle with the new drive setpoint (mm); return the encoder position (mm)."""
        hist = self.setpoint_history
        hist.append(setpoint_mm)
        c = hist[0]
        v = self.kv * (c - self.actual)
        if self.velocity_feedforward:
            v += self.velocity_feedforward * (c - self._prev_setpoint) * self._inv_T
        self._prev_setpoint = c
        v = limit_velocity(v, self.v_max, self.velocity, self._dv_max)
        x = self.position + v * self.cycle_time
        if self._limited:
            self.at_limit = False
            if self.max_pos is not None and x > self.max_pos:
                x, v, self.at_limit = self.max_pos, 0.0, True
            elif self.min_pos is not None and x < self.min_pos:
                x, v, self.at_limit = self.min_pos, 0.0, True
        self.position = x
        phi = self.resonance_phi
        if phi is None:
            self.nozzle = x
        else:
            e, de = resonance_step(self.deflection, self.deflection_rate, v - self.velocity,
                                   phi[0], phi[1], phi[2], phi[3])
            self.deflection = e
            self.deflection_rate = de
            self.nozzle = x + e
        self.velocity = v
        r = self.resolution
        a = quantise(x, r, self._inv_res) if r else x
        self.actual = a
        self.following_error = c - a
        return a
