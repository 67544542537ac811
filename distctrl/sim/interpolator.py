"""Channel path interpolation in the GEO cycle: G1 / G0 straight lines and ``#TIME`` dwell.

A block starts and ends at rest, except inside a chain of G1 blocks the NC prepared ahead
(``start_linear(..., ahead=...)``, see "Look-ahead" below). The path parameter ``s`` (mm along the
straight line) follows an acceleration-limited (trapezoidal) velocity profile that is generated
*online*, one cycle at a time, so the feed override can change at any moment:

    v_k = max(min(V * override, v_{k-1} + A*T, v_brake(r_k)), v_{k-1} - A*T),   s_k = s_{k-1} + v_k*T

* ``V``: the block's path velocity: ``F/60`` for G1 (F in mm/min), the rapid velocity for G0,
  and never more than any axis allows (``V <= v_max_i / |u_i|``, ``u`` = unit direction).
* ``A``: the path acceleration, ``min(a_max_i / |u_i|)`` - so each axis stays within its own
  velocity and acceleration limits (G0 uses the rapid limits; the slowest axis dominates and all
  axes arrive together because they move on one straight line).
* ``v_brake(r)``: the largest velocity from which the *discrete* braking sequence
  ``v, v - A*T, v - 2*A*T, ...`` still stops within the remaining distance ``r``. For
  ``m = floor((sqrt(1 + 8 r / (A T^2)) - 1) / 2)`` it is ``r / (T (m + 1)) + A T m / 2``.
  Braking against it lands exactly on the target, so the path never overshoots and no cycle needs
  more than ``A`` of deceleration. The last cycle snaps to the exact target coordinates.

An override of 0 (feed hold) makes ``V`` zero: the path decelerates at ``A`` and holds; raising the
override again resumes. Override values above 1 are allowed but still capped by the axis limits.
The override also scales G0 (one override input for the channel). Dwell time is not overridden.

The continuous trapezoid takes ``L/V + V/A`` (``L >= V^2/A``) or ``2 sqrt(L/A)``; the discrete
profile needs at most about one cycle more.

**Look-ahead** (tangential transitions): the NC may hand a G1 block the blocks that follow it on the
same straight line in the same direction (``ahead``: their lengths and feeds, prepared before they
run; :class:`distctrl.nc.interpreter.NcInterpreter`). The block then need not stop at its end: its
velocity is bounded by braking so that each following block is entered at no more than its own feed
and the path can still stop at the end of the prepared chain (``v_brake`` of the whole remaining
chain), and the next block starts with the velocity the last one ended with. So a chain of short
blocks (an excitation sampled one block per cycle, ``distctrl excite``) runs at one block per cycle at
the velocities its feeds give, within ``A``; without ``ahead`` nothing changes. Only **short** blocks are
chained: the running block and each prepared one must be covered in at most
:data:`SHORT_BLOCK_CYCLES` cycles at its feed (sampled motion, which stopping at every block end would
play several times slower); longer blocks start and end at rest as before, so runs of programs
without such blocks are unchanged (a real CNC would not stop between long collinear blocks either:
a simplification kept on purpose). A block is at least one
cycle (one block per cycle at most: the part of a cycle after a block's end is not used). If the
next block does not come (the program was stopped), the path runs out along the chain's line,
braking at ``A``, within the distance that was prepared. The following blocks' feeds are taken at
100 % override; the running block's at the current one.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from distctrl.errors.config import ConfigError, require_number

__all__ = ["AxisLimits", "Interpolator", "trapezoid_time"]

#: look-ahead chains only blocks the path covers in at most this many cycles at their feed (module
#: docstring, "Look-ahead")
SHORT_BLOCK_CYCLES = 8


@dataclass(frozen=True)
class AxisLimits:
    """Limits of one axis: ``v_max`` (mm/s) and ``a_max`` (mm/s^2) for G1; ``v_rapid`` and
    ``a_rapid`` for G0 (default: the same as for G1)."""

    v_max: float
    a_max: float
    v_rapid: float | None = None
    a_rapid: float | None = None

    def __post_init__(self) -> None:
        for name in ("v_max", "a_max", "v_rapid", "a_rapid"):
            value = getattr(self, name)
            if value is not None or name in ("v_max", "a_max"):
                require_number(value, f"AxisLimits.{name}", lo=0.0, lo_open=True)

    @property
    def rapid_velocity(self) -> float:
        return self.v_max if self.v_rapid is None else self.v_rapid

    @property
    def rapid_acceleration(self) -> float:
        return self.a_max if self.a_rapid is None else self.a_rapid


def trapezoid_time(length: float, v_max: float, a_max: float) -> float:
    """Closed-form duration (s) of a rest-to-rest trapezoidal move (continuous time)."""
    if length <= 0.0:
        return 0.0
    if length >= v_max * v_max / a_max:
        return length / v_max + v_max / a_max
    return 2.0 * math.sqrt(length / a_max)


def brake_velocity(remaining: float, dv: float, cycle_time: float) -> float:
    """Largest velocity (mm/s) this cycle from which the path can still stop within ``remaining``
    (mm) when the velocity may drop by ``dv`` (mm/s) per cycle. Solves
    ``T * (v + sum_j max(v - j*dv, 0)) = remaining`` exactly (see module docstring)."""
    if remaining <= 0.0:
        return 0.0
    q = remaining / (cycle_time * dv)
    m = math.floor((math.sqrt(1.0 + 8.0 * q) - 1.0) * 0.5)
    return remaining / (cycle_time * (m + 1)) + dv * m * 0.5


class Interpolator:
    """Programmed positions ``p`` of a channel's axes, one :meth:`step` per GEO cycle.

    Public state: ``position`` (dict axis -> mm, programmed), ``path_velocity`` (mm/s),
    ``path_length`` / ``path_position`` (mm, current block), ``feed_override`` (>= 0, settable any
    time), ``block`` ("idle", "linear", "rapid", "dwell").
    """

    def __init__(self, cycle_time: float = 0.001, axes: dict[str, AxisLimits] | None = None,
                 start: dict[str, float] | None = None):
        self.cycle_time = require_number(cycle_time, "Interpolator.cycle_time", lo=0.0, lo_open=True)
        if not axes:
            raise ConfigError("Interpolator.axes", axes, "a non-empty dict axis name -> AxisLimits")
        for name, lim in axes.items():
            if not isinstance(lim, AxisLimits):
                raise ConfigError(f"Interpolator.axes[{name!r}]", lim, "an AxisLimits instance")
        self.axes: dict[str, AxisLimits] = dict(axes)
        self.position: dict[str, float] = {name: 0.0 for name in axes}
        if start:
            self.set_position(start)
        self.feed_override = 1.0
        self.path_velocity = 0.0
        self.path_length = 0.0
        self.path_position = 0.0
        self.block = "idle"
        self._target: dict[str, float] = {}
        # per moving axis: (name, start, delta, lower bound, upper bound) of the segment (mm)
        self._moving: tuple[tuple[str, float, float, float, float], ...] = ()
        self._v_block = 0.0      # path velocity cap of the block at 100 % override (mm/s)
        self._v_axis_cap = 0.0   # path velocity the axes allow (caps override > 1)
        self._dv = 0.0           # path velocity change per cycle, A*T (mm/s)
        self._dwell_left = 0
        #: look-ahead: (length mm, velocity cap mm/s) of the blocks prepared after the running one
        self._ahead: tuple[tuple[float, float], ...] = ()
        self._direction: dict[str, float] = {}      # unit direction of the running G1 block
        #: a G1 block of a prepared chain ended moving: (velocity mm/s, direction, prepared distance mm)
        self._carry: tuple[float, dict[str, float], float] | None = None

    # -- state --------------------------------------------------------------------------------------
    @property
    def done(self) -> bool:
        """True when no block is running (the next block may be started)."""
        return self.block == "idle"

    @property
    def moving_axes(self) -> tuple[str, ...]:
        """The axes the running G0/G1 block moves (empty while no block runs)."""
        if self.block != "linear" and self.block != "rapid":
            return ()
        return tuple(m[0] for m in self._moving)

    def remaining_time(self) -> float:
        """Time (s) the running G0/G1 block still needs at the current override, from its velocity
        profile (continuous trapezoid; the discrete profile needs at most about a cycle more); 0 while
        no G0/G1 runs, ``inf`` while the override holds the path (feed hold)."""
        if self.block != "linear" and self.block != "rapid":
            return 0.0
        r = self.path_length - self.path_position
        if r <= 0.0:
            return 0.0
        ov = self.feed_override
        V = min(self._v_block * ov, self._v_axis_cap) if ov > 0.0 else 0.0
        if V <= 0.0:
            return math.inf
        A = self._dv / self.cycle_time
        v0 = self.path_velocity
        peak = min(V, math.sqrt(A * r + 0.5 * v0 * v0))
        if peak >= v0:                       # accelerate (or cruise), then brake
            cruise = max(0.0, r - (peak * peak - v0 * v0) / (2.0 * A) - peak * peak / (2.0 * A))
            return (peak - v0) / A + cruise / peak + peak / A
        if r < v0 * v0 / (2.0 * A) or V >= v0:   # braking to the end
            return 2.0 * r / v0
        # an override drop: decelerate to V, cruise, brake
        cruise = max(0.0, r - v0 * v0 / (2.0 * A))
        return (v0 - V) / A + cruise / V + V / A

    def set_position(self, positions: dict[str, float]) -> None:
        """Set programmed positions (mm) without motion, e.g. the start of a run; only when idle."""
        if getattr(self, "block", "idle") != "idle":
            raise RuntimeError("set_position while a block is running")
        for name, value in positions.items():
            if name not in self.axes:
                raise ConfigError("set_position", name, "one of the axes " + ", ".join(self.axes),
                                  "unknown axis")
            self.position[name] = require_number(value, f"set_position[{name!r}]")

    # -- blocks -------------------------------------------------------------------------------------
    def start_linear(self, target: dict[str, float], feed_mm_min: float | None = None,
                     ahead: tuple[tuple[float, float], ...] = ()) -> None:
        """Start a straight move to ``target`` (mm; missing axes stay): G1 at path feed
        ``feed_mm_min`` (mm/min), or G0 rapid when ``feed_mm_min`` is None. ``ahead`` (G1 only): the
        (length mm, feed mm/min) of the blocks that follow on the same line in the same direction
        (module docstring, "Look-ahead")."""
        if self.block != "idle":
            raise RuntimeError(f"start_linear while a {self.block} block is running")
        carry, self._carry = self._carry, None
        rapid = feed_mm_min is None
        if not rapid:
            feed = require_number(feed_mm_min, "start_linear.feed_mm_min", lo=0.0, lo_open=True) / 60.0
        delta: dict[str, float] = {}
        tgt: dict[str, float] = {}
        for name, value in target.items():
            if name not in self.axes:
                raise ConfigError("start_linear.target", name, "one of the axes " + ", ".join(self.axes),
                                  "unknown axis")
            value = require_number(value, f"start_linear.target[{name!r}]")
            d = value - self.position[name]
            if d != 0.0:
                delta[name] = d
                tgt[name] = value
        length = math.hypot(*delta.values())  # hypot: no underflow for tiny moves
        if length == 0.0:
            self._carry = carry         # nothing to do: the block is complete at once
            return
        v_axes = a_axes = math.inf
        for name, d in delta.items():
            lim = self.axes[name]
            share = abs(d) / length  # |u_i|
            if share == 0.0:
                continue  # a move below float resolution relative to the others: no limit binds
            v_i = lim.rapid_velocity if rapid else lim.v_max
            a_i = lim.rapid_acceleration if rapid else lim.a_max
            v_axes = min(v_axes, v_i / share)
            a_axes = min(a_axes, a_i / share)
        self._v_axis_cap = v_axes
        self._v_block = v_axes if rapid else min(feed, v_axes)
        self._dv = a_axes * self.cycle_time
        self._target = tgt
        self._moving = tuple((name, self.position[name], d, min(self.position[name], tgt[name]),
                              max(self.position[name], tgt[name])) for name, d in delta.items())
        self.path_length = length
        self.path_position = 0.0
        self.path_velocity = 0.0
        self.block = "rapid" if rapid else "linear"
        self._ahead = ()
        if rapid or not (ahead or carry):
            return
        direction = {name: d / length for name, d in delta.items()}
        if carry is not None and _same_direction(carry[1], direction):
            self.path_velocity = carry[0]        # a tangential transition: the path goes on moving
        reach = SHORT_BLOCK_CYCLES * self.cycle_time
        if ahead and length <= reach * self._v_block:
            chain = []
            for n, f in ahead:                   # short blocks only (module docstring)
                cap = min(float(f) / 60.0, v_axes)
                if not float(n) <= reach * cap:
                    break
                chain.append((float(n), cap))
            if chain:
                self._direction = direction
                self._ahead = tuple(chain)

    def start_dwell(self, seconds: float) -> None:
        """``#TIME``: hold all positions for ``seconds`` (rounded up to whole cycles)."""
        if self.block != "idle":
            raise RuntimeError(f"start_dwell while a {self.block} block is running")
        self._carry = None              # (the NC prepares only G1 blocks as a chain's next block)
        t = require_number(seconds, "start_dwell.seconds", lo=0.0)
        n = math.ceil(t / self.cycle_time - 1e-9)
        if n > 0:
            self._dwell_left = n
            self.block = "dwell"

    def cancel(self) -> None:
        """End the running block where the path stands (a CNC reset followed by a new start): the
        programmed positions stay, the next block starts from them. Only at rest."""
        if self.path_velocity != 0.0 and self.block in ("linear", "rapid"):
            raise RuntimeError("cancel while the path still moves")
        self.block = "idle"
        self._moving = ()
        self._dwell_left = 0
        self.path_velocity = 0.0
        self._ahead = ()
        self._carry = None

    # -- per cycle ----------------------------------------------------------------------------------
    def step(self) -> dict[str, float]:
        """Advance one cycle; return the programmed positions (a new dict, mm)."""
        block = self.block
        if block == "idle" and self._carry is not None:
            self._run_out()             # the prepared next block did not come: brake along the line
            block = self.block
        if block == "linear" or block == "rapid":
            self._step_path()
        elif block == "dwell":
            self._dwell_left -= 1
            if self._dwell_left <= 0:
                self.block = "idle"
        return dict(self.position)

    def _step_path(self) -> None:
        T = self.cycle_time
        L = self.path_length
        s = self.path_position
        r = L - s
        v0 = self.path_velocity
        dv = self._dv
        ov = self.feed_override
        v_cap = self._v_block * ov if ov > 0.0 else 0.0
        if v_cap > self._v_axis_cap:
            v_cap = self._v_axis_cap
        v = v0 + dv
        if v_cap < v:
            v = v_cap
        # Braking only matters near the end: T*(v + v^2/dv) bounds the discrete stopping distance,
        # so the exact (sqrt) solution is needed only below it.
        if self._ahead:
            vl = self._chain_limit(r)
            if vl < v:
                v = vl
        elif r < T * (v + v * v / dv):
            vb = brake_velocity(r, dv, T)
            if vb < v:
                v = vb
        if v < v0 - dv:  # an override drop: decelerate at A, never with a velocity step
            v = v0 - dv
        if v < 0.0:
            v = 0.0
        ds = v * T
        pos = self.position
        if ds >= r - 1e-12 * (L + 1.0):
            # Last cycle: land exactly on the programmed coordinates.
            pos.update(self._target)
            self.path_position = L
            self.path_velocity = r / T
            self.block = "idle"
            if self._ahead:             # the next block of the chain takes this velocity over
                self._carry = (r / T, self._direction, sum(n for n, _ in self._ahead))
                self._ahead = ()
            return
        s += ds
        self.path_position = s
        self.path_velocity = v
        f = s / L
        for name, start, d, lo, hi in self._moving:
            p = start + d * f
            # Rounding must not carry a coordinate past its target.
            pos[name] = lo if p < lo else (hi if p > hi else p)

    # -- look-ahead -------------------------------------------------------------------------------
    def _chain_limit(self, r: float) -> float:
        """The largest velocity this cycle from which every prepared block is entered at no more than
        its cap and the path can stop at the end of the chain (``r``: what is left of this block)."""
        dv, T = self._dv, self.cycle_time
        d = r
        limit = math.inf
        for length, cap in self._ahead:
            # enter the block at <= cap: brake to rest over d plus the distance braking from cap takes
            v = brake_velocity(d + T * (cap + cap * cap / (2.0 * dv)), dv, T)
            if v < limit:
                limit = v
            d += length
        v = brake_velocity(d, dv, T)
        return v if v < limit else limit

    def _run_out(self) -> None:
        """The chain's next block did not come (the program was stopped): brake from the velocity the
        last block ended with along its line, at ``A``, within the prepared distance."""
        v, direction, prepared = self._carry
        self._carry = None
        dv, T = self._dv, self.cycle_time
        n = math.floor(v / dv) if dv > 0.0 else 0
        stop = T * (n * v - dv * n * (n + 1) / 2.0)          # the braking sequence v-dv, v-2dv, ... > 0
        stop = min(max(stop, 0.0), prepared)
        if stop <= 0.0:
            self.path_velocity = 0.0
            return
        pos = self.position
        tgt = {name: pos[name] + u * stop for name, u in direction.items()}
        self._target = tgt
        self._moving = tuple((name, pos[name], tgt[name] - pos[name], min(pos[name], tgt[name]),
                              max(pos[name], tgt[name])) for name in direction)
        self._v_block = 0.0
        self.path_length = stop
        self.path_position = 0.0
        self.path_velocity = v
        self.block = "linear"


def _same_direction(a: dict[str, float], b: dict[str, float]) -> bool:
    if a.keys() != b.keys():
        return False
    return sum(a[k] * b[k] for k in a) >= 1.0 - 1e-9
