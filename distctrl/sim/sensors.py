"""Height sensors of the virtual machine, read once per GEO cycle.

Two sensors share one pipeline (:class:`SensorBase`); per call of ``read(cycle, axis_z, surface_z)``:

1. physical value in mm: :class:`EncoderProbe` ``s = surface_z - axis_z`` (= -d, SPEC §1),
   :class:`DistanceSensor` ``d = axis_z - surface_z``;
2. ``+`` Gaussian noise (``noise_std`` mm) ``+`` the additive faults (``jump``, ``drift``,
   ``noise_burst``) - these disturb the measurement itself;
3. saturation to the measuring range (the probe's mechanical stroke, the sensor's range), then
   characteristic and quantisation into the output unit (raw increments, resp. mm);
4. the replacing faults (``freeze``, ``dropout``, ``nan``) - a sensor that sticks or fails;
5. dead time: the value leaves a ring buffer ``delay_cycles`` reads later (the buffer starts filled
   with the first value, so there is no start-up transient).

Faults happen in the sensor, before the dead time: a fault starting at cycle ``k`` reaches the
control at cycle ``k + delay_cycles``.

``read`` must be called exactly once per cycle with increasing ``cycle`` numbers; ``cycle`` only
times the faults (the dead time counts calls). Noise is drawn from ``numpy.random.default_rng``
seeded with ``seed`` in blocks of :data:`NOISE_BLOCK` samples, so runs are reproducible and the
per-cycle cost stays at a list index.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from distctrl.sim.config_errors import MISSING, ConfigError, require_choice, require_int, require_number
from distctrl.sim.physics import probe_increments

__all__ = ["Fault", "FAULT_KINDS", "SensorBase", "EncoderProbe", "DistanceSensor", "NOISE_BLOCK"]

NOISE_BLOCK = 4096
FAULT_KINDS = ("jump", "drift", "freeze", "dropout", "nan", "noise_burst")


@dataclass(frozen=True)
class Fault:
    """A sensor fault, active from its start for ``duration`` (``None``: until the end of the run).

    Start: ``start_cycle`` or ``start_time`` (s, rounded to the nearest cycle), or given later to
    :meth:`SensorBase.inject`. Duration: ``duration`` (s) or ``duration_cycles``.

    =============  ===============================================================================
    kind           effect while active
    =============  ===============================================================================
    jump           adds ``value`` mm to the measurement
    drift          adds ``rate`` mm/s times the time since the start
    noise_burst    adds Gaussian noise of std ``value`` mm (on top of the normal noise)
    freeze         repeats the last value delivered before the start
    dropout        delivers a reading of ``value`` mm (default 0; the probe reports it in increments)
    nan            delivers ``value``: NaN (default), ``inf`` or ``-inf``
    =============  ===============================================================================

    Several faults may overlap: the additive ones add up; of the replacing ones the later in the
    table wins (``nan`` over ``dropout`` over ``freeze``).
    """

    kind: str
    start_cycle: int | None = None
    start_time: float | None = None
    duration: float | None = None
    duration_cycles: int | None = None
    value: float | None = None
    rate: float = 0.0

    def __post_init__(self) -> None:
        require_choice(self.kind, "Fault.kind", FAULT_KINDS)
        if self.start_cycle is not None and self.start_time is not None:
            raise ConfigError("Fault.start_time", self.start_time,
                              "either start_cycle or start_time, not both")
        if self.start_cycle is not None:
            require_int(self.start_cycle, "Fault.start_cycle", lo=0)
        if self.start_time is not None:
            require_number(self.start_time, "Fault.start_time", lo=0.0)
        if self.duration is not None and self.duration_cycles is not None:
            raise ConfigError("Fault.duration_cycles", self.duration_cycles,
                              "either duration (s) or duration_cycles, not both")
        if self.duration is not None:
            require_number(self.duration, "Fault.duration", lo=0.0)
        if self.duration_cycles is not None:
            require_int(self.duration_cycles, "Fault.duration_cycles", lo=0)
        require_number(self.rate, "Fault.rate")
        if self.kind == "noise_burst" and self.value is None:
            raise ConfigError("Fault.value", MISSING,
                              "the extra noise std in mm (>= 0) for kind 'noise_burst'")
        if self.kind == "jump":
            if self.value is None:
                raise ConfigError("Fault.value", MISSING,
                                  "the jump height in mm (finite number) for kind 'jump'")
            require_number(self.value, "Fault.value")
        elif self.kind == "noise_burst":
            require_number(self.value, "Fault.value", lo=0.0)
        elif self.kind == "dropout" and self.value is not None:
            require_number(self.value, "Fault.value")
        elif self.kind == "nan" and self.value is not None:
            v = self.value
            if isinstance(v, bool) or not isinstance(v, (int, float)) or math.isfinite(v):
                raise ConfigError("Fault.value", v, "nan, inf or -inf")


class _ScheduledFault:
    """A :class:`Fault` resolved to cycles for one sensor, with its run-time state."""

    __slots__ = ("fault", "kind", "start", "end", "held")

    def __init__(self, fault: Fault, start: int, end: float):
        self.fault = fault
        self.kind = fault.kind
        self.start = start
        self.end = end          # first cycle no longer affected (inf: never ends)
        self.held: float | None = None  # freeze: the held value


def _cycles(seconds: float, cycle_time: float) -> int:
    return int(round(seconds / cycle_time))


class SensorBase:
    """Shared noise / fault / dead-time pipeline; see the module docstring for the order."""

    #: +1: the physical value is axis_z - surface_z (distance d); -1: surface_z - axis_z (probe s = -d)
    _sense_sign = 1.0

    def __init__(self, cycle_time: float, noise_std: float, delay_cycles: int, seed: int | None,
                 faults: Iterable[Fault], name: str):
        self.cycle_time = require_number(cycle_time, f"{name}.cycle_time", lo=0.0, lo_open=True)
        self.noise_std = require_number(noise_std, f"{name}.noise_std", lo=0.0)
        self.delay_cycles = require_int(delay_cycles, f"{name}.delay_cycles", lo=0)
        self.seed = seed
        # Two independent streams: a noise burst must not shift the normal noise sequence.
        noise_seq, burst_seq = np.random.SeedSequence(seed).spawn(2)
        self.rng = np.random.default_rng(noise_seq)
        self._burst_rng = np.random.default_rng(burst_seq)
        self._noise: list[float] = []
        self._noise_i = 0
        self._burst: list[float] = []
        self._burst_i = 0
        self.faults: list[_ScheduledFault] = []
        for f in faults:
            self.inject(f)
        self._delay_line: list[float] = []
        self._delay_i = 0
        self.last_measured: float | None = None  # value entering the dead time (after faults)
        self.last_value: float | None = None     # value the control saw at the last read

    # -- faults -------------------------------------------------------------------------------------
    def inject(self, fault: Fault, at_cycle: int | None = None) -> None:
        """Schedule ``fault``; ``at_cycle`` overrides the fault's own start."""
        if at_cycle is not None:
            start = require_int(at_cycle, "inject.at_cycle", lo=0)
        elif fault.start_cycle is not None:
            start = int(fault.start_cycle)
        elif fault.start_time is not None:
            start = _cycles(fault.start_time, self.cycle_time)
        else:
            raise ConfigError("Fault.start_cycle", MISSING,
                              "start_cycle, start_time or inject(fault, at_cycle)")
        if fault.duration_cycles is not None:
            end: float = start + int(fault.duration_cycles)
        elif fault.duration is not None:
            end = start + _cycles(fault.duration, self.cycle_time)
        else:
            end = math.inf
        self.faults.append(_ScheduledFault(fault, start, end))

    def clear_faults(self) -> None:
        self.faults.clear()

    # -- noise --------------------------------------------------------------------------------------
    def _normal(self) -> float:
        i = self._noise_i
        if i >= len(self._noise):
            self._noise = self.rng.standard_normal(NOISE_BLOCK).tolist()
            i = 0
        self._noise_i = i + 1
        return self._noise[i]

    def _burst_normal(self) -> float:
        i = self._burst_i
        if i >= len(self._burst):
            self._burst = self._burst_rng.standard_normal(NOISE_BLOCK).tolist()
            i = 0
        self._burst_i = i + 1
        return self._burst[i]

    # -- conversion hooks (subclasses) --------------------------------------------------------------
    def _convert(self, x_mm: float) -> float:
        """Saturate, apply the characteristic and quantise: mm -> output unit."""
        raise NotImplementedError

    def _encode(self, x_mm: float) -> float:
        """Unit conversion and quantisation only (used for a dropout reading)."""
        raise NotImplementedError

    def ideal(self, axis_z: float, surface_z: float) -> float:
        """The noise-, fault- and delay-free output for this geometry (output unit)."""
        return self._convert(self._sense_sign * (axis_z - surface_z))

    # -- per cycle ----------------------------------------------------------------------------------
    def read(self, cycle: int, axis_z: float, surface_z: float) -> float:
        """The value the control sees this cycle (output unit), after noise, faults and dead time.

        ``axis_z``: true (mechanical) axis position in mm; ``surface_z``: surface height under the
        sensor in mm.
        """
        x = self._sense_sign * (axis_z - surface_z)
        if self.noise_std:
            x += self.noise_std * self._normal()
        faults = self.faults
        if faults:
            replace = None
            for f in faults:
                if cycle < f.start or cycle >= f.end:
                    continue
                kind = f.kind
                if kind == "jump":
                    x += f.fault.value
                elif kind == "drift":
                    x += f.fault.rate * (cycle - f.start) * self.cycle_time
                elif kind == "noise_burst":
                    x += f.fault.value * self._burst_normal()
                else:
                    replace = f if replace is None or _PRIORITY[kind] >= _PRIORITY[replace.kind] else replace
                    if kind == "freeze" and f.held is None:
                        f.held = self.last_measured  # None at the very first cycle: set below
            y = self._convert(x)
            if replace is not None:
                kind = replace.kind
                if kind == "freeze":
                    if replace.held is None:
                        replace.held = y
                    y = replace.held
                elif kind == "dropout":
                    v = replace.fault.value
                    y = self._encode(0.0 if v is None else v)
                else:  # nan
                    v = replace.fault.value
                    y = math.nan if v is None else float(v)
        else:
            y = self._convert(x)
        self.last_measured = y

        n = self.delay_cycles
        if n:
            line = self._delay_line
            if not line:
                line.extend([y] * n)  # start filled with the first value: no start-up jump
            i = self._delay_i
            out = line[i]
            line[i] = y
            self._delay_i = i + 1 if i + 1 < n else 0
            y = out
        self.last_value = y
        return y


_PRIORITY = {"freeze": 0, "dropout": 1, "nan": 2}


class EncoderProbe(SensorBase):
    """Tactile probe on encoder 2: delivers raw increments the core converts back to ``s`` (mm).

    The true reading ``s = surface_z - axis_z`` (= -d) is limited to the mechanical stroke
    ``[range_min, range_max]`` mm and quantised to increments, exactly inverting the core's
    conversion ``s = sign * increments * denom / num * 1e-4 + ref_offset``
    (``num`` = P-AXIS-00422 increments per ``denom`` = P-AXIS-00423 x 0.1 um, ``sign = -1`` when
    P-AXIS-00230 ``sign_reversal`` is set, ``ref_offset`` = P-AXIS-00418). Hence::

        increments = round(sign * (s - ref_offset) * num / denom * 1e4)

    returned as a float holding an integer value.
    """

    _sense_sign = -1.0

    def __init__(self, cycle_time: float = 0.001, *, range_min: float = -10.0, range_max: float = 10.0,
                 resolution_num: int = 1, resolution_denom: int = 1, sign_reversal: bool = False,
                 ref_offset: float = 0.0, noise_std: float = 0.0, delay_cycles: int = 0,
                 seed: int | None = 0, faults: Iterable[Fault] = ()):
        name = "EncoderProbe"
        self.range_min = require_number(range_min, f"{name}.range_min")
        self.range_max = require_number(range_max, f"{name}.range_max", lo=self.range_min, lo_open=True)
        self.resolution_num = require_int(resolution_num, f"{name}.resolution_num", lo=1)
        self.resolution_denom = require_int(resolution_denom, f"{name}.resolution_denom", lo=1)
        if not isinstance(sign_reversal, (bool, int)) or sign_reversal not in (0, 1):
            raise ConfigError(f"{name}.sign_reversal", sign_reversal, "false/true (or 0/1)")
        self.sign_reversal = bool(sign_reversal)
        self.ref_offset = require_number(ref_offset, f"{name}.ref_offset")
        #: increments per mm including the sign (the inverse of the core's scaling)
        sign = -1.0 if self.sign_reversal else 1.0
        self.increments_per_mm = sign * self.resolution_num / self.resolution_denom * 1e4
        super().__init__(cycle_time, noise_std, delay_cycles, seed, faults, name)

    def _encode(self, x_mm: float) -> float:
        return float(math.floor((x_mm - self.ref_offset) * self.increments_per_mm + 0.5))

    def _convert(self, x_mm: float) -> float:
        if x_mm != x_mm:  # NaN geometry in, NaN out (math.floor would raise)
            return x_mm
        return probe_increments(x_mm, self.range_min, self.range_max, self.ref_offset, self.increments_per_mm)

    def to_mm(self, increments: float) -> float:
        """The core's conversion (for tests and plots): raw increments -> reading ``s`` in mm."""
        s = increments * self.resolution_denom / self.resolution_num * 1e-4
        return (-s if self.sign_reversal else s) + self.ref_offset


class DistanceSensor(SensorBase):
    """Distance sensor (e.g. capacitive) delivering ``d`` in mm as a variable (SENSOR_SOURCE VARIABLE).

    ``d = axis_z - surface_z`` saturated to ``[0, range_max]``, mapped through ``characteristic``
    (piecewise-linear table of ``(true_mm, reported_mm)`` pairs, true values strictly increasing;
    beyond the table the end values hold; default identity) and quantised to ``resolution`` mm
    (0 = not quantised).
    """

    def __init__(self, cycle_time: float = 0.001, *, range_max: float = 10.0,
                 characteristic: Sequence[tuple[float, float]] | None = None, resolution: float = 0.0,
                 noise_std: float = 0.0, delay_cycles: int = 0, seed: int | None = 0,
                 faults: Iterable[Fault] = ()):
        name = "DistanceSensor"
        self.range_max = require_number(range_max, f"{name}.range_max", lo=0.0, lo_open=True)
        self.resolution = require_number(resolution, f"{name}.resolution", lo=0.0)
        self.characteristic: tuple[tuple[float, float], ...] | None = None
        if characteristic is not None:
            pts = []
            for n, pair in enumerate(characteristic):
                key = f"{name}.characteristic[{n}]"
                if not isinstance(pair, (tuple, list)) or len(pair) != 2:
                    raise ConfigError(key, pair, "a pair (true_mm, reported_mm)")
                pts.append((require_number(pair[0], key + "[0]"), require_number(pair[1], key + "[1]")))
            if len(pts) < 2 or any(b[0] <= a[0] for a, b in zip(pts, pts[1:])):
                raise ConfigError(f"{name}.characteristic", characteristic,
                                  "at least 2 pairs with strictly increasing true_mm")
            self.characteristic = tuple(pts)
            self._char_x = [p[0] for p in pts]
            self._char_y = [p[1] for p in pts]
        super().__init__(cycle_time, noise_std, delay_cycles, seed, faults, name)

    def _encode(self, x_mm: float) -> float:
        r = self.resolution
        return math.floor(x_mm / r + 0.5) * r if r else x_mm

    def _apply_characteristic(self, d: float) -> float:
        xs, ys = self._char_x, self._char_y
        if d <= xs[0]:
            return ys[0]
        if d >= xs[-1]:
            return ys[-1]
        i = 1
        while xs[i] < d:  # tables are short (a handful of points): a linear scan beats bisect
            i += 1
        x0, x1 = xs[i - 1], xs[i]
        return ys[i - 1] + (ys[i] - ys[i - 1]) * (d - x0) / (x1 - x0)

    def _convert(self, x_mm: float) -> float:
        if x_mm != x_mm:  # NaN geometry in, NaN out (math.floor would raise)
            return x_mm
        if x_mm < 0.0:
            x_mm = 0.0
        elif x_mm > self.range_max:
            x_mm = self.range_max
        if self.characteristic is not None:
            x_mm = self._apply_characteristic(x_mm)
        r = self.resolution
        return math.floor(x_mm / r + 0.5) * r if r else x_mm
