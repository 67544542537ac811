"""distctrl's law as a LinuxCNC component: the configuration of hal/distctrl_thc.comp and its Python reference.

:class:`ThcConfig` holds the component's settings with the documents' ranges (KP P-AXIS-00759 0 < kp <= 2,
I_TN P-AXIS-00764 and D_TV P-AXIS-00765 >= 0 s, the filter of P-AXIS-00782/00413/00784/00783/00507/00508
through :class:`distctrl.control.filters.FilterConfig`, v_max P-AXIS-00415, a_max P-AXIS-00416,
max_deviation P-AXIS-00414) and gives them as ``setp`` lines (:meth:`ThcConfig.setp_lines`), the filter
coefficients designed by distctrl's own design (:func:`distctrl.control.filters.design_coefficients`).

:class:`ThcReference` is the component's cycle in Python, made of the law's functions
(:mod:`distctrl.control.law`, the only copy of the law, which the cycle core calls): tests/linuxcnc/test_thc.py
streams inputs through the C component in halrun and checks its outputs equal this reference's bit for bit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..control import law
from ..control.filters import FilterConfig, design_coefficients
from ..errors import ParameterError
from .hal_env import LinuxCNCError

__all__ = ["ThcConfig", "ThcReference", "lround"]


def lround(x: float) -> int:
    """C's lround: to the nearest integer, halves away from zero."""
    return int(math.copysign(math.floor(abs(x) + 0.5), x))


def _check(name: str, value: float, lo: float, hi: float, lo_open: bool = False, pid: str = "") -> float:
    value = float(value)
    ok = (lo < value if lo_open else lo <= value) and value <= hi and math.isfinite(value)
    if not ok:
        rng = f"{lo:g} {'<' if lo_open else '<='} value <= {hi:g}"
        raise LinuxCNCError(f"distctrl_thc {name} = {value!r} out of range ({pid}); allowed: {rng}")
    return value


@dataclass(frozen=True)
class ThcConfig:
    """The component's settings (module docstring), in mm, s, V."""
    kp: float = 0.5
    i_tn: float = 0.0
    d_tv: float = 0.0
    use_both_encoders: bool = False
    filter: FilterConfig = field(default_factory=FilterConfig)
    v_max: float = 100.0
    a_max: float = 2000.0
    max_deviation: float = 20.0
    set_dist: float = 1.5
    arc_v0: float = 95.0
    arc_k: float = 6.0
    resolution: float = 0.001
    cornerlock_threshold: float = 90.0
    voidlock_slope: float = 500.0
    voidlock_window: float = 0.02
    voidlock_on_cycles: int = 3
    voidlock_off_cycles: int = 20
    voidlock_release_band: float = 5.0

    def check(self, cycle_time: float) -> None:
        """Raise :class:`LinuxCNCError` naming the parameter and its range unless every value is allowed."""
        _check("kp", self.kp, 0.0, 2.0, lo_open=True, pid="KP, P-AXIS-00759")
        _check("i-tn", self.i_tn, 0.0, 1e4, pid="I_TN, P-AXIS-00764")
        _check("d-tv", self.d_tv, 0.0, 1e4, pid="D_TV, P-AXIS-00765")
        _check("v-max", self.v_max, 0.0, 1e4, lo_open=True, pid="P-AXIS-00415, mm/s")
        _check("a-max", self.a_max, 0.0, 1e7, lo_open=True, pid="P-AXIS-00416")
        _check("max-deviation", self.max_deviation, 0.0, 1e4, lo_open=True, pid="P-AXIS-00414")
        _check("set-dist", self.set_dist, 0.0, 100.0, lo_open=True, pid="SET_DIST")
        _check("arc-k", self.arc_k, 0.5, 50.0, pid="V/mm")
        _check("arc-v0", self.arc_v0, 0.0, 400.0, pid="V")
        _check("resolution", self.resolution, 0.0, 1.0, lo_open=True, pid="mm per count")
        _check("cornerlock-threshold", self.cornerlock_threshold, 0.0, 100.0, pid="%")
        _check("voidlock-slope", self.voidlock_slope, 0.0, 1e6, lo_open=True, pid="V/s")
        _check("voidlock-window", self.voidlock_window, cycle_time, 100 * cycle_time, pid="s, 1..100 periods")
        _check("voidlock-on-cycles", self.voidlock_on_cycles, 0, 1e6, pid="periods")
        _check("voidlock-off-cycles", self.voidlock_off_cycles, 0, 1e6, pid="periods")
        _check("voidlock-release-band", self.voidlock_release_band, 0.0, 1e4, pid="V")
        try:
            self.filter.check(cycle_time)
        except ParameterError as exc:
            raise LinuxCNCError(f"distctrl_thc filter: {exc}") from None

    def coefficients(self, cycle_time: float) -> list[float]:
        self.check(cycle_time)
        return design_coefficients(self.filter, cycle_time)

    @classmethod
    def from_params(cls, p, **kw) -> "ThcConfig":
        """From an axis parameter list (:class:`distctrl.params.AxisParameters`): KP, I_TN, D_TV, both
        encoders, the filter, v_max, a_max (0: the axis's), max_deviation; ``kw`` sets the rest."""
        fields = dict(kp=p.kp, i_tn=p.i_tn, d_tv=p.d_tv, use_both_encoders=bool(p.use_both_encoders),
                      filter=FilterConfig(p.filter_type, p.n_cycles, p.smoothing_factor, p.kalman_sigma,
                                          p.low_pass_filter_order, p.low_pass_filter_fg_f0),
                      v_max=p.v_max, a_max=p.a_max if p.a_max > 0 else p.axis_a_max,
                      max_deviation=p.max_deviation)
        fields.update(kw)
        return cls(**fields)

    def setp_lines(self, cycle_time: float, name: str = "distctrl-thc.0") -> list[str]:
        """halcmd ``setp`` lines for the component instance ``name`` (exact: repr of each double)."""
        fc = self.coefficients(cycle_time)
        pins = {"use-both-encoders": int(self.use_both_encoders), "kp": self.kp, "i-tn": self.i_tn, "d-tv": self.d_tv, "v-max": self.v_max, "a-max": self.a_max,
                "max-deviation": self.max_deviation, "set-dist": self.set_dist, "arc-v0": self.arc_v0,
                "arc-k": self.arc_k, "resolution": self.resolution,
                "cornerlock-threshold": self.cornerlock_threshold, "voidlock-slope": self.voidlock_slope,
                "voidlock-window": self.voidlock_window, "voidlock-on-cycles": int(self.voidlock_on_cycles),
                "voidlock-off-cycles": int(self.voidlock_off_cycles),
                "voidlock-release-band": self.voidlock_release_band}
        lines = [f"setp {name}.{k} {v!r}" for k, v in pins.items()]
        lines += [f"setp {name}.fc-{i:03d} {float(c)!r}" for i, c in enumerate(fc)]
        return lines


class ThcReference:
    """The component's cycle (hal/distctrl_thc.comp) in Python from distctrl's law functions."""

    def __init__(self, config: ThcConfig, period_ns: int = 1_000_000):
        self.T = period_ns * 1e-9                    # as halcompile's fperiod
        self.c = config
        self.fc = config.coefficients(self.T)
        self.fs = [0.0] * law.FS_LEN
        self.buf = [0.0] * law.MAX_N
        self.integral = self.m_prev = self.v_prev = self.o = 0.0
        self.was_active = False
        self.vbuf = [0.0] * 100
        self.vmean = [0.0] * 100
        self.vsum = self.vlevel = 0.0
        self.vi = self.nfill = self.nmfill = self.non = self.noff = 0
        self.cornerlock = self.voidlock = False

    def _counts(self) -> int:
        r = self.c.resolution
        return lround(self.o / r) if r > 0.0 else 0

    def _void_lock(self, x: float, on: bool) -> None:
        """distctrl's void_lock (its ST, distctrl/plc/process/void_lock.py) as the component runs it."""
        c, T = self.c, self.T
        if not on:
            self.nfill = self.nmfill = self.non = self.noff = 0
            self.vsum = 0.0
            self.voidlock = False
            return
        N = min(100, max(1, lround(c.voidlock_window / T)))
        if self.vi >= N:
            self.vi = 0
        vi = self.vi
        old = self.vbuf[vi]
        full = self.nfill >= N
        mean_old = self.vmean[vi]
        mfull = self.nmfill >= N
        self.vbuf[vi] = x
        self.vsum = self.vsum + x - (old if full else 0.0)
        if not full:
            self.nfill += 1
        mean = 0.0
        if self.nfill >= N:
            mean = self.vsum / N
            self.vmean[vi] = mean
            if self.nmfill < N:
                self.nmfill += 1
        self.vi = (vi + 1) % N
        if not full:
            self.voidlock = False
            self.non = self.noff = 0
            return
        rate = (x - old) / (N * T)
        if not self.voidlock:
            self.non = self.non + 1 if abs(rate) > c.voidlock_slope else 0
            if self.non >= c.voidlock_on_cycles:
                self.voidlock = True
                self.vlevel = mean_old if mfull else old
                self.noff = 0
        else:
            if abs(rate) <= c.voidlock_slope and mean - self.vlevel <= c.voidlock_release_band:
                self.noff += 1
            else:
                self.noff = 0
            if self.noff >= c.voidlock_off_cycles:
                self.voidlock = False
                self.non = 0

    def step(self, arc_voltage: float, enable: bool, cornerlock_enable: bool = False, current_velocity: float = 0.0,
             requested_velocity: float = 0.0, voidlock_enable: bool = False, z_command: float = 0.0,
             z_actual: float = 0.0, reset: bool = False) -> dict:
        c, T = self.c, self.T
        d = (arc_voltage - c.arc_v0) * (1.0 / c.arc_k)
        self.cornerlock = bool(cornerlock_enable and current_velocity < requested_velocity * c.cornerlock_threshold * 0.01)
        self._void_lock(arc_voltage, bool(voidlock_enable and enable))
        out = {"distance": d, "cornerlock_is_locked": self.cornerlock, "voidlock_is_locked": self.voidlock}
        if not enable:
            self.was_active = False
            self.v_prev = 0.0
            if reset:
                self.o = 0.0
            return {**out, "state": 0, "offset": self.o, "velocity": 0.0, "counts": self._counts(),
                    "filtered": None}
        fb = law.feedback_value(True, c.use_both_encoders, d, z_actual, z_command)
        if not self.was_active:
            law.filter_seed(self.fc, self.fs, self.buf, fb)
            self.integral = 0.0
            self.m_prev = -fb
            self.was_active = True
        locked = self.cornerlock or self.voidlock
        y = law.filter_step(self.fc, self.fs, self.buf, fb)
        _, e, m = law.mode_error(True, y, c.set_dist, self.o)
        if locked:
            u, e, ic = 0.0, 0.0, self.integral
        else:
            t_over_tn = T / c.i_tn if c.i_tn > 0.0 else 0.0
            dg = law.derivative_gain(c.kp, c.d_tv, T)
            u, ic = law.pid_step(c.kp, t_over_tn, dg, self.integral, self.m_prev, e, m)
            u, ic = law.finite_step(u, ic, self.integral)
        v = law.slope_limit(u, e, self.v_prev, T, c.v_max, c.a_max, c.a_max, 1.0, 1.0)[0]
        v = law.bound_velocity(v, self.o, T, -c.max_deviation, c.max_deviation, c.a_max)
        self.o = law.advance_offset(self.o, v, T, -c.max_deviation, c.max_deviation)
        if not locked:
            self.integral = law.integrator_after_limiter(self.integral, ic, u, v, e, T)
        self.m_prev = m
        self.v_prev = v
        return {**out, "state": 2 if locked else 1, "offset": self.o, "velocity": v,
                "counts": self._counts(), "filtered": y}
