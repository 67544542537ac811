"""Height sensors of the virtual machine, read once per GEO cycle.

Three sensors share one pipeline (:class:`SensorBase`); per call of
``read(cycle, axis_z, surface_z, x=0.0, y=0.0)``:

1. physical value in mm: :class:`EncoderProbe` ``s = surface_z - axis_z`` (= -d, SPEC §1),
   :class:`DistanceSensor` ``d = axis_z - surface_z``; with a footprint (``footprint_radius > 0``)
   the distance the sensor sees over its footprint around ``(x, y)`` instead (the edge effect of a
   capacitive sensor: :meth:`DistanceSensor.footprint_distance`); :class:`ArcVoltageSensor` the arc
   length over the part of its footprint that has sheet under it;
2. ``+`` Gaussian noise (``noise_std`` mm) ``+`` plume/spark bursts (:class:`Bursts`) ``+`` the
   additive faults (``jump``, ``drift``, ``noise_burst``) - these disturb the measurement itself;
3. saturation to the measuring range (the probe's mechanical stroke, the sensor's range), then
   characteristic and quantisation into the output unit (raw increments, mm, resp. the arc voltage
   in V plus its mains ripple and white noise);
4. the replacing faults (``freeze``, ``dropout``, ``nan``) - a sensor that sticks or fails;
5. dead time: the value leaves a ring buffer ``delay_cycles`` reads later (the buffer starts filled
   with the first value, so there is no start-up transient).

Faults happen in the sensor, before the dead time: a fault starting at cycle ``k`` reaches the
control at cycle ``k + delay_cycles``.

``read`` must be called exactly once per cycle with increasing ``cycle`` numbers; ``cycle`` only
times the faults and the bursts (the dead time counts calls). Noise is drawn from
``numpy.random.default_rng`` seeded with ``seed`` in blocks of :data:`NOISE_BLOCK` samples, so runs
are reproducible and the per-cycle cost stays at a list index. Independent streams (children of
``SeedSequence(seed)``): 0 the normal noise, 1 the ``noise_burst`` faults, 2 the plume bursts, 3 the
arc voltage's white noise - a model switched on or off does not shift the others' sequences.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from distctrl.errors.config import (MAX_DELAY_CYCLES, MISSING, ConfigError, require_choice, require_int,
                                    require_number)
from distctrl.sim.physics import characteristic_value, distance_reading, probe_increments, round_to
from distctrl.sim.surface import Flat, Holes, Ramp, Sine, Step, TiltedPlane

__all__ = ["Fault", "FAULT_KINDS", "Bursts", "SensorBase", "EncoderProbe", "DistanceSensor", "ArcVoltageSensor",
           "NOISE_BLOCK", "footprint_offsets", "FootprintHeights", "FOOTPRINT_RINGS", "FOOTPRINT_PER_RING", "FOOTPRINT_POINTS", "D_MIN"]

NOISE_BLOCK = 4096
FAULT_KINDS = ("jump", "drift", "freeze", "dropout", "nan", "noise_burst")
#: the footprint is sampled on FOOTPRINT_RINGS rings of FOOTPRINT_PER_RING points (equal areas) by
#: default; ``footprint_points`` (a multiple of FOOTPRINT_PER_RING) trades accuracy for speed
FOOTPRINT_RINGS = 2
FOOTPRINT_PER_RING = 8
FOOTPRINT_POINTS = (8, 16, 24, 32)
#: mm: a footprint point closer than this (or in the sheet) counts as this close (1/d stays finite)
D_MIN = 1e-3
_TWO_PI = 2.0 * math.pi


def footprint_offsets(radius: float, rings: int = FOOTPRINT_RINGS,
                      per_ring: int = FOOTPRINT_PER_RING) -> tuple[tuple[float, float], ...]:
    """Sample points ``(dx, dy)`` (mm) of a disc of ``radius`` mm, each standing for an equal area.

    Ring ``k`` (0-based) of ``rings`` lies at ``radius * sqrt((k + 0.5) / rings)`` (the middle of
    its equal-area annulus) and carries ``per_ring`` (even) points at angles
    ``(k + 0.5) / rings * 360° / per_ring + j * 360° / per_ring``: the set is symmetric about the
    centre and no point lies on the X or Y line through it, so a straight edge through the centre
    along X or Y (or any line through it that misses the points) covers exactly half of them.
    """
    if per_ring % 2:
        raise ValueError("per_ring must be even (point symmetry)")
    pts = []
    step = _TWO_PI / per_ring
    for k in range(rings):
        r = radius * math.sqrt((k + 0.5) / rings)
        phi0 = (k + 0.5) / rings * step
        for j in range(per_ring):
            a = phi0 + j * step
            pts.append((r * math.cos(a), r * math.sin(a)))
    return tuple(pts)


class FootprintHeights:
    """The surface heights at a footprint's points around ``(x, y)``, cheaper than one look-up per
    point and feature, and the same values (to rounding):

    * a :class:`~distctrl.sim.surface.Step` or :class:`~distctrl.sim.surface.Ramp` with none of its
      edges within the footprint's extent along its axis is constant there: one look-up at the centre;
    * a :class:`~distctrl.sim.surface.Sine` uses ``sin(a + b) = sin a cos b + cos a sin b`` with the
      points' ``cos b``, ``sin b`` computed once: one ``sin`` and one ``cos`` per read;
    * :class:`~distctrl.sim.surface.Holes` with no hole within the footprint's reach add 0: one
      grid look-up per read (:meth:`~distctrl.sim.surface.Holes.near`);
    * a :class:`~distctrl.sim.surface.TiltedPlane` is its centre value plus a fixed offset per point;
      :class:`~distctrl.sim.surface.Flat` is 0;
    * any other feature (a height map) is looked up at every point.
    """

    def __init__(self, surface, offsets: Sequence[tuple[float, float]]):
        self.base = float(surface.base)
        self.dx = [float(p[0]) for p in offsets]
        self.dy = [float(p[1]) for p in offsets]
        n = len(self.dx)
        reach_x = max(map(abs, self.dx), default=0.0)
        reach_y = max(map(abs, self.dy), default=0.0)
        plane = [0.0] * n
        self.centre: list = []            # features constant over the footprint: looked up at the centre
        self.sines: list = []             # (amplitude, k, phase, on_y, cos list, sin list)
        self.edged: list = []             # (z, on_y, reach, ((a, b), ...)): constant unless an edge is near
        self.points: list = []            # looked up at every point
        self.holes: list = []             # (z, near): 0 over the footprint unless a hole is near
        self._reach = math.hypot(reach_x, reach_y)
        for f in surface.features:
            kind = type(f)
            if kind is Flat:
                continue
            if kind is TiltedPlane:
                self.centre.append(f.z)
                plane = [o + f.sx * dx + f.sy * dy for o, dx, dy in zip(plane, self.dx, self.dy)]
            elif kind is Sine:
                on_y = f.axis == "Y"
                k = _TWO_PI / f.wavelength                                   # = Sine._k
                du = self.dy if on_y else self.dx
                self.sines.append((f.amplitude, k, f.phase, on_y, [math.cos(k * d) for d in du],
                                   [math.sin(k * d) for d in du]))
            elif kind is Step:
                L = f.ramp_length
                edges = [(f.at, f.at + L)]
                if f.width is not None:
                    edges.append((f.at + f.width - L, f.at + f.width))
                on_y = f.axis == "Y"
                self.edged.append((f.z, on_y, reach_y if on_y else reach_x, tuple(edges)))
            elif kind is Ramp:
                on_y = f.axis == "Y"
                self.edged.append((f.z, on_y, reach_y if on_y else reach_x, ((f.start, f.end),)))
            elif kind is Holes:
                self.holes.append((f.z, f.near))
            else:
                self.points.append(f.z)
        self.plane = plane
        self._level = not any(plane)      # no tilt: the points share one height unless a feature varies

    def heights(self, x: float, y: float) -> list[float]:
        """Heights (mm) at the points ``(x + dx_j, y + dy_j)``."""
        c, hs = self.sample(x, y)
        return [c] * len(self.dx) if hs is None else hs

    def sample(self, x: float, y: float) -> tuple[float, list[float] | None]:
        """``(c, None)`` when every point has the height ``c`` (mm): no sine, tilt or height map, and
        no edge within reach - the common case, one look-up per feature; else ``(c, heights)``."""
        c = self.base
        for z in self.centre:
            c += z(x, y)
        varying = None
        for z, on_y, reach, edges in self.edged:
            u = y if on_y else x
            lo, hi = u - reach, u + reach
            for a, b in edges:    # constant for u < a and for u >= b; the points span [lo, hi]
                if hi >= a and lo < b:
                    if varying is None:
                        varying = []
                    varying.append(z)
                    break
            else:
                c += z(x, y)
        for z, near in self.holes:
            if near(x, y, self._reach):
                if varying is None:
                    varying = []
                varying.append(z)
        if varying is None and self._level and not self.sines and not self.points:
            return c, None
        hs = None if self._level else [c + o for o in self.plane]
        for amp, k, phase, on_y, cs, sn in self.sines:
            arg = k * (y if on_y else x) + phase
            s0 = amp * math.sin(arg)
            c0 = amp * math.cos(arg)
            if hs is None:
                hs = [c + s0 * cj + c0 * sj for cj, sj in zip(cs, sn)]
            else:
                hs = [h + s0 * cj + c0 * sj for h, cj, sj in zip(hs, cs, sn)]
        if hs is None:
            hs = [c] * len(self.dx)
        for group in (varying, self.points):
            if group:
                for z in group:
                    hs = [h + z(x + dx, y + dy) for h, dx, dy in zip(hs, self.dx, self.dy)]
        return c, hs


@dataclass(frozen=True)
class Bursts:
    """Plume/spark noise bursts of a distance or arc-voltage sensor (added in mm, like the noise).

    Burst starts form a Poisson process of ``rate`` starts per second (exponential gaps, drawn from
    the sensor's seed); each burst lasts ``duration`` s (rounded to whole cycles, at least one;
    overlapping bursts merge) and adds ``offset + amplitude * N(0, 1)`` mm every cycle it lasts
    (``amplitude``: std in mm; ``offset``: mean shift in mm - a conductive plume between nozzle and
    sheet raises the capacitance, so the sensor reports a smaller distance: ``offset < 0``).
    """

    rate: float
    duration: float
    amplitude: float
    offset: float = 0.0

    def __post_init__(self) -> None:
        require_number(self.rate, "Bursts.rate", lo=0.0)
        require_number(self.duration, "Bursts.duration", lo=0.0, lo_open=True)
        require_number(self.amplitude, "Bursts.amplitude", lo=0.0)
        require_number(self.offset, "Bursts.offset")


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
        self.delay_cycles = require_int(delay_cycles, f"{name}.delay_cycles", lo=0, hi=MAX_DELAY_CYCLES)
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
        #: the geometry over the footprint (subclasses): None = the point under (x, y)
        self._footprint = None
        #: fraction of the footprint with sheet under it at the last read (1 without a footprint)
        self.covered = 1.0
        #: added to the converted value every read (subclasses: the arc voltage's ripple and noise)
        self._output_noise = None
        self.bursts: Bursts | None = None
        self.burst_count = 0                     # bursts started so far
        self._b_next = math.inf                  # cycle (float) of the next burst start
        self._b_end = 0                          # first cycle after the running burst(s)

    def _set_bursts(self, bursts: Bursts | None, name: str) -> None:
        """Switch the plume/spark bursts on (stream 2 of the seed)."""
        if bursts is None:
            return
        if not isinstance(bursts, Bursts):
            raise ConfigError(f"{name}.bursts", bursts, "a Bursts(rate, duration, amplitude, offset)")
        self.bursts = bursts
        self._plume_rng = np.random.default_rng(np.random.SeedSequence(self.seed).spawn(3)[2])
        self._plume: list[float] = []
        self._plume_i = 0
        self._b_cycles = max(1, _cycles(bursts.duration, self.cycle_time))
        # mean gap between starts in cycles (inf: rate 0, never)
        self._b_gap = math.inf if bursts.rate == 0.0 else 1.0 / (bursts.rate * self.cycle_time)
        self._b_next = self._gap()

    def _gap(self) -> float:
        g = self._b_gap
        return g if g == math.inf else float(self._plume_rng.exponential(g))

    def _plume_value(self, cycle: int) -> float:
        """The bursts' contribution this cycle (mm); called every read while bursts are on."""
        while cycle >= self._b_next:             # a burst starts (several only at absurd rates)
            end = cycle + self._b_cycles
            if end > self._b_end:
                self._b_end = end
            self.burst_count += 1
            self._b_next += self._gap()
        if cycle >= self._b_end:
            return 0.0
        i = self._plume_i
        if i >= len(self._plume):
            self._plume = self._plume_rng.standard_normal(NOISE_BLOCK).tolist()
            i = 0
        self._plume_i = i + 1
        b = self.bursts
        return b.offset + b.amplitude * self._plume[i]

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

    def ideal(self, axis_z: float, surface_z: float, x: float = 0.0, y: float = 0.0) -> float:
        """The noise-, burst-, fault- and delay-free output for this geometry (output unit)."""
        fp = self._footprint
        v = self._sense_sign * (axis_z - surface_z) if fp is None else fp(axis_z, surface_z, x, y)
        return self._convert(v)

    # -- per cycle ----------------------------------------------------------------------------------
    def read(self, cycle: int, axis_z: float, surface_z: float, x: float = 0.0, y: float = 0.0) -> float:
        """The value the control sees this cycle (output unit), after noise, faults and dead time.

        ``axis_z``: true (mechanical) axis position in mm; ``surface_z``: surface height under the
        sensor in mm; ``x``, ``y``: where the sensor is (mm; only a sensor with a footprint uses them).
        """
        fp = self._footprint
        v = self._sense_sign * (axis_z - surface_z) if fp is None else fp(axis_z, surface_z, x, y)
        noise_std = self.noise_std
        if noise_std:
            i = self._noise_i                      # _normal() without the call while the block lasts
            if i < len(self._noise):
                self._noise_i = i + 1
                v += noise_std * self._noise[i]
            else:
                v += noise_std * self._normal()
        if self.bursts is not None:
            v += self._plume_value(cycle)
        faults = self.faults
        if faults:
            replace = None
            for f in faults:
                if cycle < f.start or cycle >= f.end:
                    continue
                kind = f.kind
                if kind == "jump":
                    v += f.fault.value
                elif kind == "drift":
                    v += f.fault.rate * (cycle - f.start) * self.cycle_time
                elif kind == "noise_burst":
                    v += f.fault.value * self._burst_normal()
                else:
                    replace = f if replace is None or _PRIORITY[kind] >= _PRIORITY[replace.kind] else replace
                    if kind == "freeze" and f.held is None:
                        f.held = self.last_measured  # None at the very first cycle: set below
            out = self._convert(v)
            if self._output_noise is not None:
                out += self._output_noise(cycle)
            if replace is not None:
                kind = replace.kind
                if kind == "freeze":
                    if replace.held is None:
                        replace.held = out
                    out = replace.held
                elif kind == "dropout":
                    val = replace.fault.value
                    out = self._encode(0.0 if val is None else val)
                else:  # nan
                    val = replace.fault.value
                    out = math.nan if val is None else float(val)
        else:
            out = self._convert(v)
            if self._output_noise is not None:
                out += self._output_noise(cycle)
        self.last_measured = out

        n = self.delay_cycles
        if n:
            line = self._delay_line
            if not line:
                line.extend([out] * n)  # start filled with the first value: no start-up jump
            i = self._delay_i
            delayed = line[i]
            line[i] = out
            self._delay_i = i + 1 if i + 1 < n else 0
            out = delayed
        self.last_value = out
        return out


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

    **Edge effect** (``footprint_radius > 0``, needs ``surface``): a capacitive sensor measures the
    capacitance between its electrode, a disc of ``footprint_radius`` mm under the nozzle, and the
    grounded sheet. Each part of the disc at distance ``d_i`` from the sheet contributes
    ``∝ 1 / d_i`` (parallel plates); a part with no sheet within ``field_range`` mm (default
    ``range_max``: over a hole, beyond the sheet edge, over a deep kerf) contributes nothing. The
    sensor reports the distance of a whole flat sheet with the same capacitance::

        d_seen = N / Σ_i c_i,   c_i = 1 / max(d_i, D_MIN) if d_i <= field_range else 0

    over the N = ``footprint_points`` (default 16) points of :func:`footprint_offsets` (the surface's
    heights there each read, :class:`FootprintHeights`: the model's cost).
    Over a flat sheet ``d_seen = d``; with a fraction ``covered`` of the disc over the sheet and the
    rest over nothing ``d_seen = d / covered`` - half over a straight edge reads twice the distance,
    so the control lowers the head: it dives. No sheet at all: ``d_seen`` = inf, saturated to
    ``range_max``. ``covered`` (the fraction of points with sheet in reach) is kept per read. The
    characteristic applies to ``d_seen`` (after noise and bursts), as on the machine, where the
    amplifier's static non-linearity acts on what the electrode sees.

    **Bursts** (:class:`Bursts`): plume/spark noise bursts added to the distance.
    """

    def __init__(self, cycle_time: float = 0.001, *, range_max: float = 10.0,
                 characteristic: Sequence[tuple[float, float]] | None = None, resolution: float = 0.0,
                 noise_std: float = 0.0, delay_cycles: int = 0, seed: int | None = 0,
                 faults: Iterable[Fault] = (), footprint_radius: float = 0.0, field_range: float | None = None,
                 surface=None, bursts: Bursts | None = None, footprint_points: int = 16,
                 name: str = "DistanceSensor"):
        self.range_max = require_number(range_max, f"{name}.range_max", lo=0.0, lo_open=True)
        self.resolution = require_number(resolution, f"{name}.resolution", lo=0.0)
        self.characteristic: tuple[tuple[float, float], ...] | None = None
        self._char_x: list[float] = []      # the table's columns (empty: no characteristic)
        self._char_y: list[float] = []
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
        self.footprint_radius = require_number(footprint_radius, f"{name}.footprint_radius", lo=0.0)
        self.field_range = self.range_max if field_range is None else \
            require_number(field_range, f"{name}.field_range", lo=0.0, lo_open=True)
        if isinstance(footprint_points, bool) or footprint_points not in FOOTPRINT_POINTS:
            raise ConfigError(f"{name}.footprint_points", footprint_points,
                              "one of " + ", ".join(map(str, FOOTPRINT_POINTS)) + " (sample points of the footprint)")
        self.footprint_points = int(footprint_points)
        self.surface = surface
        super().__init__(cycle_time, noise_std, delay_cycles, seed, faults, name)
        self.offsets: tuple[tuple[float, float], ...] = ()
        if self.footprint_radius > 0.0:
            if surface is None or not hasattr(surface, "features") or not hasattr(surface, "base"):
                raise ConfigError(f"{name}.surface", surface,
                                  "the Surface under the sensor (footprint_radius > 0 samples it)")
            self.offsets = footprint_offsets(self.footprint_radius, self.footprint_points // FOOTPRINT_PER_RING)
            self.footprint_heights = FootprintHeights(surface, self.offsets)
            self._sample = self.footprint_heights.sample
            self._footprint = self.footprint_distance
        self._set_bursts(bursts, name)

    def footprint_distance(self, axis_z: float, surface_z: float, x: float, y: float) -> float:
        """The distance the electrode sees over its footprint at ``(x, y)`` (mm; class docstring);
        sets :attr:`covered`."""
        if axis_z != axis_z:
            return axis_z
        far = self.field_range
        level, hs = self._sample(x, y)
        if hs is None:                    # one height under the whole footprint
            d = axis_z - level
            if d <= far:
                self.covered = 1.0
                return d if d > D_MIN else D_MIN
            self.covered = 0.0
            return math.inf
        npts = len(hs)
        lo = axis_z - max(hs)
        if lo > D_MIN and axis_z - min(hs) <= far:      # all in reach, none too close: the usual case
            self.covered = 1.0
            return npts / sum([1.0 / (axis_z - h) for h in hs])
        n = 0
        c = 0.0
        for h in hs:
            d = axis_z - h
            if d <= far:
                n += 1
                c += 1.0 / d if d > D_MIN else 1.0 / D_MIN
        self.covered = n / npts
        return npts / c if n else math.inf

    # The arithmetic (saturation, characteristic, quantisation) is distctrl.sim.physics's, which the
    # batch kernels compile too (docs/batch.md): one copy, the same numbers bit for bit.
    def _encode(self, x_mm: float) -> float:
        r = self.resolution
        return round_to(x_mm, r) if r else x_mm

    def _apply_characteristic(self, d: float) -> float:
        return characteristic_value(d, self._char_x, self._char_y)

    def _convert(self, x_mm: float) -> float:
        if x_mm != x_mm:  # NaN geometry in, NaN out (math.floor would raise)
            return x_mm
        return distance_reading(x_mm, self.range_max, self._char_x, self._char_y, self.resolution)


class ArcVoltageSensor(DistanceSensor):
    """The arc voltage of a plasma torch (V), which the PLC linearises into the distance variable.

    The arc length is the torch height over the sheet; over a kerf or a hole the arc has to reach
    further, to the sheet beside it, and the voltage jumps. Per read, with ``footprint_radius`` mm
    the radius the arc root wanders over (0: the point under the torch only) and ``field_range`` mm
    the reach beyond which a point counts as "no sheet" (default ``range_max``)::

        covered = (points with d_i <= field_range) / N   (N = footprint_points; 1 point for radius 0)
        d_arc   = mean of those d_i   (no point covered: d at the centre)
        V       = v0 + k · clamp(d_arc + noise + bursts + faults, 0, range_max)
                  + kerf_jump · (1 − covered) + speed_volts · slowdown
                  + ripple · sin(2π ripple_hz · t) + voltage_noise_std · N(0, 1)

    ``v0`` (V) the voltage extrapolated to zero height (cathode and anode falls), ``k`` (V/mm) the
    arc column's gradient (about 4-10 V/mm), ``kerf_jump`` (V) the extra voltage with no sheet
    under the whole footprint, ``ripple`` (V amplitude, at ``ripple_hz``: the power source's
    50/60 Hz, or 100/120 Hz after a bridge) and ``voltage_noise_std`` (V) the arc noise. ``noise_std``
    (mm), the bursts and the faults act on the distance before the conversion (a dropout reports the
    voltage of a ``value`` mm arc). No characteristic, no quantisation: the reading is in volts.

    **Slow-down** (``speed_volts > 0``; 0, the default, leaves the model as without it): the arc
    voltage rises when the torch slows below the speed it cuts at (at a corner the kerf widens and
    the arc burns into its walls, the arc column gets longer)::

        v_f      = first-order lag (time constant speed_tau s) of the nozzle's X/Y speed (mm/s)
        slowdown = clamp(1 − v_f / cut_speed, 0, 1)       (0 at the cut speed, 1 at rest)

    from the nozzle positions the machine hands :meth:`read` every cycle. The term is counted *in a
    cut* only: from the cycle ``v_f`` first reaches 90 % of ``cut_speed`` until the arc breaks (the
    arc length beyond ``range_max``, the torch lifted away); before that the torch pierces or
    accelerates out of the pierce, a regime the steady cut's slow-down law does not describe, and
    the term adds nothing (a plasma control keeps height control off there, QtPlasmaC's THC delay).
    """

    def __init__(self, cycle_time: float = 0.001, *, v0: float = 100.0, k: float = 6.0, ripple: float = 0.0,
                 ripple_hz: float = 50.0, voltage_noise_std: float = 0.0, kerf_jump: float = 0.0,
                 range_max: float = 10.0, noise_std: float = 0.0, delay_cycles: int = 0, seed: int | None = 0,
                 faults: Iterable[Fault] = (), footprint_radius: float = 0.0, field_range: float | None = None,
                 surface=None, bursts: Bursts | None = None, footprint_points: int = 16,
                 speed_volts: float = 0.0, cut_speed: float | None = None, speed_tau: float = 0.02):
        name = "ArcVoltageSensor"
        self.v0 = require_number(v0, f"{name}.v0", lo=0.0)
        self.k = require_number(k, f"{name}.k", lo=0.0, lo_open=True)
        self.ripple = require_number(ripple, f"{name}.ripple", lo=0.0)
        nyquist = 0.5 / require_number(cycle_time, f"{name}.cycle_time", lo=0.0, lo_open=True)
        self.ripple_hz = require_number(ripple_hz, f"{name}.ripple_hz", lo=0.0, hi=nyquist, lo_open=True,
                                        hi_open=True)
        self.voltage_noise_std = require_number(voltage_noise_std, f"{name}.voltage_noise_std", lo=0.0)
        self.kerf_jump = require_number(kerf_jump, f"{name}.kerf_jump", lo=0.0)
        super().__init__(cycle_time, range_max=range_max, noise_std=noise_std, delay_cycles=delay_cycles,
                         seed=seed, faults=faults, footprint_radius=footprint_radius, field_range=field_range,
                         surface=surface, bursts=bursts, footprint_points=footprint_points, name=name)
        self._footprint = self.arc_length
        self._omega_t = _TWO_PI * self.ripple_hz * self.cycle_time      # ripple phase per cycle (rad)
        if self.voltage_noise_std:
            self._vrng = np.random.default_rng(np.random.SeedSequence(self.seed).spawn(4)[3])
            self._vnoise: list[float] = []
            self._vnoise_i = 0
        if self.ripple or self.voltage_noise_std:
            self._output_noise = self.arc_noise
        self.speed_volts = require_number(speed_volts, f"{name}.speed_volts", lo=0.0)
        self.speed_tau = require_number(speed_tau, f"{name}.speed_tau", lo=0.0)
        self.cut_speed = None if cut_speed is None else \
            require_number(cut_speed, f"{name}.cut_speed", lo=0.0, lo_open=True)
        if self.speed_volts and self.cut_speed is None:
            raise ConfigError(f"{name}.cut_speed", MISSING, "the cut speed in mm/s (> 0) with speed_volts > 0")
        #: the slow-down model's state: the lagged speed (mm/s), in a cut, the rise in force (V)
        self.speed = 0.0
        self.in_cut = False
        self.speed_rise = 0.0
        self._last_xy: tuple[float, float] | None = None
        self._speed_alpha = self.cycle_time / (self.speed_tau + self.cycle_time)
        if self.speed_volts:
            self.read = self._read_with_speed          # the plain read() stays as fast as without it

    def _read_with_speed(self, cycle: int, axis_z: float, surface_z: float, x: float = 0.0,
                         y: float = 0.0) -> float:
        """:meth:`read` with the slow-down term updated from this cycle's nozzle position."""
        last = self._last_xy
        v = 0.0 if last is None else math.hypot(x - last[0], y - last[1]) / self.cycle_time
        self._last_xy = (x, y)
        vf = self.speed = self.speed + self._speed_alpha * (v - self.speed)
        ref = self.cut_speed
        if axis_z - surface_z > self.range_max:        # the arc broke (torch lifted): the cut ended
            self.in_cut = False
        elif not self.in_cut and vf >= 0.9 * ref:
            self.in_cut = True
        if self.in_cut and vf < ref:
            self.speed_rise = self.speed_volts * (1.0 - vf / ref)
        else:
            self.speed_rise = 0.0
        return SensorBase.read(self, cycle, axis_z, surface_z, x, y)

    def arc_length(self, axis_z: float, surface_z: float, x: float, y: float) -> float:
        """The arc length (mm) over the covered part of the footprint; sets :attr:`covered`."""
        d0 = axis_z - surface_z
        if not self.offsets:
            self.covered = 1.0 if d0 <= self.field_range else 0.0
            return d0
        if axis_z != axis_z:
            return axis_z
        far = self.field_range
        level, hs = self._sample(x, y)
        if hs is None:                    # one height under the whole footprint
            d = axis_z - level
            self.covered = 1.0 if d <= far else 0.0
            return d if d <= far else d0
        n = 0
        s = 0.0
        for h in hs:
            d = axis_z - h
            if d <= far:
                n += 1
                s += d
        self.covered = n / len(self.offsets)
        return s / n if n else d0

    def arc_noise(self, cycle: int) -> float:
        """Ripple plus white noise (V) at ``cycle``."""
        e = self.ripple * math.sin(self._omega_t * cycle) if self.ripple else 0.0
        if self.voltage_noise_std:
            i = self._vnoise_i
            if i >= len(self._vnoise):
                self._vnoise = self._vrng.standard_normal(NOISE_BLOCK).tolist()
                i = 0
            self._vnoise_i = i + 1
            e += self.voltage_noise_std * self._vnoise[i]
        return e

    def voltage(self, d_mm: float, covered: float = 1.0) -> float:
        """The noise-free arc voltage (V) of an arc ``d_mm`` long with ``covered`` of the footprint
        over sheet, plus the slow-down rise in force (:attr:`speed_rise`, 0 without the model)."""
        if d_mm < 0.0:
            d_mm = 0.0
        elif d_mm > self.range_max:
            d_mm = self.range_max
        return self.v0 + self.k * d_mm + self.kerf_jump * (1.0 - covered) + self.speed_rise

    def _encode(self, x_mm: float) -> float:
        return self.v0 + self.k * x_mm

    def _convert(self, x_mm: float) -> float:
        if x_mm != x_mm:
            return x_mm
        return self.voltage(x_mm, self.covered)
