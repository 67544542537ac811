"""distctrl's law as a LinuxCNC component: the configuration of hal/distctrl_thc.comp and its Python reference.

:class:`ThcConfig` holds the component's settings with the documents' ranges (KP P-AXIS-00759 0 < kp <= 2,
I_TN P-AXIS-00764 0..50 s, D_TV P-AXIS-00765 0..2 s, the filter of P-AXIS-00782/00413/00784/00783/00507/00508
through :class:`distctrl.control.filters.FilterConfig`, v_max P-AXIS-00415, a_max P-AXIS-00416,
max_deviation P-AXIS-00414, the monitoring's max_act_value_change P-AXIS-00417 and sensor window
max_pos/min_pos/tolerance P-AXIS-00419/00420/00421, the software limits P-AXIS-00428/00177/00178, the
lowering weights P-AXIS-00533/00534 and the adaptive acceleration P-AXIS-00501..00505 through
:class:`distctrl.params.AxisParameters`' own checks, the locks through distctrl's corner_lock and void_lock
functions' keys) and gives them as ``setp`` lines (:meth:`ThcConfig.setp_lines`), the filter
coefficients designed by distctrl's own design (:func:`distctrl.control.filters.design_coefficients`).

:class:`ThcCore` is the component's period in Python with distctrl's cycle core
(:class:`distctrl.control.controller.AxisDistanceController`, whose numbers are :mod:`distctrl.control.law`'s,
the only copy of the law) as its law: the pins become the core's inputs and the PLC's commands (ON,
ON_CONST_DIST or DRYRUN by ``mode`` and ``dryrun``, FREEZE while a lock holds, OFF). :class:`ThcLocks` is the
corner lock and void lock, the PLC's part:
distctrl's own CornerLock and VoidLock process functions, stepped on the pins.
tests/linuxcnc/test_thc.py streams inputs through the C component in halrun and checks its outputs
(offset, velocity, filtered value, HLI state, error ID, counts, locks, the void lock's rate and mean)
equal ThcCore's bit for bit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import SimpleNamespace

from ..base.kinds import FilterType, SensorSource
from ..base.states import CommandSource, HliState
from ..control.commands import Action, Command
from ..control import law
from ..control.controller import AxisDistanceController
from ..control.cycle_io import CycleInput, CycleOutput
from ..control.filters import FilterConfig, design_coefficients
from ..errors import ParameterError
from ..errors.config import ConfigError
from ..params.axis import AxisParameters
from ..plc.process.corner_lock import CornerLock
from ..plc.process.void_lock import VoidLock
from .hal_env import LinuxCNCError

__all__ = ["ThcConfig", "ThcCore", "ThcLocks", "lround", "CORNERLOCK_MODES", "MODES"]

#: cornerlock-mode: 0 distctrl's corner_lock process function (the default), 1 plasmac 1.235's rule
CORNERLOCK_MODES = {"distctrl": 0, "plasmac": 1}
#: the mode pin: 0 CONST_DIST (the height above the plate, the default), 1 SET_POS (the surface at set-pos)
MODES = {"CONST_DIST": 0, "SET_POS": 1}
#: the void lock's signal, a V.E. variable of the PLC (the arc voltage)
_ARC = "V.E.ARC_VOLTAGE"
#: the parameter list's defaults (software limits, adaptive acceleration, lowering weights)
_AXIS = AxisParameters()


def lround(x: float) -> int:
    """C's lround: to the nearest integer, halves away from zero."""
    return int(math.copysign(math.floor(abs(x) + 0.5), x))


#: thc-setp's comment blocks: (title, [(pin, what it is)]) in the order printed
_PIN_GROUPS = (
    ("the law (FCT-M3 §7.2): PID on the distance", [
        ("kp", "KP, P-AXIS-00759, 1/s"), ("i-tn", "I_TN, P-AXIS-00764, s (0: no I)"),
        ("d-tv", "D_TV, P-AXIS-00765, s (0: no D)"),
        ("use-both-encoders", "P-AXIS-00500: 1 feedback d + c - a (FCT-M3 §7.1)")]),
    ("the offset's limits (keep them within the INI's external-offset limits)", [
        ("v-max", "P-AXIS-00415, mm/s"), ("a-max", "P-AXIS-00416, mm/s²"),
        ("max-deviation", "P-AXIS-00414, mm: the offset's bound"),
        ("check-sw-limit-switch", "P-AXIS-00428: 1 the command kept within the software limits"),
        ("sw-limit-max", "P-AXIS-00177, mm"), ("sw-limit-min", "P-AXIS-00178, mm"),
        ("v-weight-down", "P-AXIS-00533, fraction of v-max when lowering (0 off)"),
        ("a-weight-down", "P-AXIS-00534, fraction of a-max when lowering (0 off)"),
        ("use-adaptive-acceleration", "P-AXIS-00501 (Fig. 31)"), ("a-min", "P-AXIS-00502, mm/s²"),
        ("dist-error-a-min", "P-AXIS-00504, mm"), ("dist-error-a-max", "P-AXIS-00505, mm")]),
    ("monitoring (ERROR and its ID on error-id)", [
        ("max-act-value-change", "P-AXIS-00417, mm/s: a larger jump of the distance is 70329"),
        ("max-pos", "P-AXIS-00419, mm (reading s = -distance above: 70330)"),
        ("min-pos", "P-AXIS-00420, mm (below: 70576)"), ("tolerance", "P-AXIS-00421, mm")]),
    ("the sensor: arc voltage to distance, V = arc-v0 + arc-k * height", [
        ("set-dist", "SET_DIST, mm: the cut height"), ("arc-v0", "V at zero height"),
        ("arc-k", "V per mm"), ("resolution", "mm per z-offset count")]),
    ("the corner lock and the void lock (distctrl's corner_lock and void_lock functions)", [
        ("cornerlock-mode", "0 distctrl's corner lock, 1 plasmac's rule"),
        ("cornerlock-threshold", "% of feed-upm below which the height is held"),
        ("cornerlock-hysteresis", "% above the threshold to arm and open again"),
        ("voidlock-slope", "V/s over the window that closes the void lock"),
        ("voidlock-window", "s"), ("voidlock-on-cycles", "periods above the slope to close"),
        ("voidlock-off-cycles", "steady periods to open"),
        ("voidlock-release-band", "V above the level before the void")]),
    ("the mode (read when thc-enable selects)", [
        ("dryrun", "1: DRYRUN, the offset stands"), ("mode", "0 CONST_DIST, 1 SET_POS"),
        ("set-pos", "SET_POS, mm (mode 1)")]),
)


def _fc_name(i: int) -> str:
    """The name of coefficient i of the law's buffer (distctrl.control.law's FC_* layout)."""
    fixed = {law.FC_KIND: "filter type code", law.FC_N: "n (window, periods)",
             law.FC_ALPHA: "smoothing alpha",
             law.FC_SIGMA: "Kalman sigma", law.FC_DECAY_N: "rho^n (rho = 1 - alpha)",
             law.FC_WSUM: "sum of the weights", law.FC_NSEC: "low-pass: number of sections",
             law.FC_INV_N: "1/n", law.FC_GAIN: "Kalman gain K", law.FC_P_PRIOR: "Kalman prior variance P-",
             law.FC_EXPO_OLDER: "EXPO_MEAN: beta = alpha / (1 - rho^(n-1))"}
    if i in fixed:
        return fixed[i]
    if law.FC_SOS <= i < law.FC_ZI:
        sec, k = divmod(i - law.FC_SOS, 6)
        return f"low-pass section {sec + 1}: {('b0', 'b1', 'b2', 'a0', 'a1', 'a2')[k]}"
    if law.FC_ZI <= i < law.FC_GAIN:
        sec, k = divmod(i - law.FC_ZI, 2)
        return f"low-pass section {sec + 1}: initial state zi[{k}] (unit input)"
    return f"Kalman prediction coefficient {i - law.FC_PRED} (oldest measurement first)"


def _coefficient_names(kind: FilterType, n: int, sections: int) -> dict[int, str]:
    """The coefficients a filter of this kind reads (always printed), by index."""
    idx = [law.FC_KIND, law.FC_N, law.FC_ALPHA, law.FC_SIGMA, law.FC_DECAY_N, law.FC_WSUM, law.FC_NSEC,
           law.FC_INV_N]
    if kind == FilterType.LOWPASS:
        idx += [law.FC_SOS + 6 * s + k for s in range(sections) for k in range(6)]
        idx += [law.FC_ZI + 2 * s + k for s in range(sections) for k in range(2)]
    elif kind == FilterType.EXPO_MEAN:
        idx.append(law.FC_EXPO_OLDER)
    elif kind in (FilterType.KALMAN_MA, FilterType.KALMAN_EXPO):
        idx += [law.FC_GAIN, law.FC_P_PRIOR] + [law.FC_PRED + k for k in range(n)]
    return {i: _fc_name(i) for i in idx}


def _ranges(idx: list[int]) -> str:
    """fc-010..fc-020, fc-030 for a sorted list of indices."""
    parts, start = [], idx[0]
    for a, b in zip(idx, idx[1:] + [None]):
        if b != a + 1:
            parts.append(f"fc-{start:03d}" + (f"..fc-{a:03d}" if a != start else ""))
            start = b
    return ", ".join(parts)


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
    cornerlock_mode: str = "distctrl"          # CORNERLOCK_MODES
    cornerlock_threshold: float = 90.0         # % of feed-upm: corner_lock.share * 100 (plasmac's threshold)
    cornerlock_hysteresis: float = 5.0         # %: corner_lock.hysteresis * 100 (mode distctrl)
    voidlock_slope: float = 500.0
    voidlock_window: float = 0.02
    voidlock_on_cycles: int = 3
    voidlock_off_cycles: int = 20
    voidlock_release_band: float = 5.0
    max_act_value_change: float = 5000.0   # P-AXIS-00417, mm/s: the sensor jump limit (70329)
    max_pos: float = 50000.0               # P-AXIS-00419, mm: the window of the reading s = -distance (70330)
    min_pos: float = -50000.0              # P-AXIS-00420, mm (70576)
    tolerance: float = 0.0                 # P-AXIS-00421, mm
    check_sw_limit_switch: bool = False    # P-AXIS-00428: the offset bounded by the software limits
    sw_limit_max: float = _AXIS.sw_limit_max   # P-AXIS-00177 swe_pos, mm (of axis-z-command's coordinates)
    sw_limit_min: float = _AXIS.sw_limit_min   # P-AXIS-00178 swe_neg, mm
    v_weight_down: float = 0.0             # P-AXIS-00533, fraction (0 = off): v_max of a lowering move
    a_weight_down: float = 0.0             # P-AXIS-00534, fraction (0 = off): a_max of a lowering move
    use_adaptive_acceleration: bool = False    # P-AXIS-00501 (Fig. 31)
    a_min: float = _AXIS.a_min             # P-AXIS-00502, mm/s²
    dist_error_a_min: float = _AXIS.dist_error_a_min   # P-AXIS-00504, mm
    dist_error_a_max: float = _AXIS.dist_error_a_max   # P-AXIS-00505, mm
    dryrun: bool = False                   # the dryrun pin's setting: thc-enable selects DRYRUN
    mode: str = "CONST_DIST"               # the mode pin's setting (MODES), read at the select
    set_pos: float = 0.0                   # SET_POS (mm, axis-z-command's coordinates): the surface position

    def check(self, cycle_time: float) -> None:
        """Raise :class:`LinuxCNCError` naming the parameter and its range unless every value is allowed."""
        _check("kp", self.kp, 0.0, 2.0, lo_open=True, pid="KP, P-AXIS-00759")
        _check("i-tn", self.i_tn, 0.0, 50.0, pid="I_TN, P-AXIS-00764, s")
        _check("d-tv", self.d_tv, 0.0, 2.0, pid="D_TV, P-AXIS-00765, s")
        _check("max-act-value-change", self.max_act_value_change, 0.0, 2147483647.0, pid="P-AXIS-00417, mm/s")
        _check("max-pos", self.max_pos, 0.0, 2147483647.0, pid="P-AXIS-00419, mm")
        _check("min-pos", self.min_pos, -2147483648.0, 2147483647.0, pid="P-AXIS-00420, mm")
        _check("tolerance", self.tolerance, 0.0, 2147483647.0, pid="P-AXIS-00421, mm")
        if not self.min_pos + self.tolerance < self.max_pos - self.tolerance:
            raise LinuxCNCError(f"distctrl_thc sensor window is empty (P-AXIS-00419/00420/00421): min-pos + "
                                f"tolerance ({self.min_pos + self.tolerance:g} mm) must be below max-pos - "
                                f"tolerance ({self.max_pos - self.tolerance:g} mm)")
        _check("v-max", self.v_max, 0.0, 1e4, lo_open=True, pid="P-AXIS-00415, mm/s")
        _check("a-max", self.a_max, 0.0, 1e7, lo_open=True, pid="P-AXIS-00416")
        _check("max-deviation", self.max_deviation, 0.0, 1e4, lo_open=True, pid="P-AXIS-00414")
        _check("set-dist", self.set_dist, 0.0, 100.0, lo_open=True, pid="SET_DIST")
        if self.mode not in MODES:
            raise LinuxCNCError(f"distctrl_thc mode = {self.mode!r} unknown; allowed: "
                                + ", ".join(f"{k} ({v})" for k, v in MODES.items()))
        _check("set-pos", self.set_pos, -1e6, 1e6, pid="SET_POS, mm")
        _check("arc-k", self.arc_k, 0.5, 50.0, pid="V/mm")
        _check("arc-v0", self.arc_v0, 0.0, 400.0, pid="V")
        _check("resolution", self.resolution, 0.0, 1.0, lo_open=True, pid="mm per count")
        if self.cornerlock_mode not in CORNERLOCK_MODES:
            raise LinuxCNCError(f"distctrl_thc cornerlock-mode = {self.cornerlock_mode!r} unknown; allowed: "
                                + ", ".join(f"{k} ({v})" for k, v in CORNERLOCK_MODES.items()))
        if self.cornerlock_mode == "plasmac":
            _check("cornerlock-threshold", self.cornerlock_threshold, 0.0, 100.0, pid="% of feed-upm, plasmac")
        _check("cornerlock-hysteresis", self.cornerlock_hysteresis, 0.0, 50.0, pid="%, corner_lock.hysteresis * 100")
        _check("voidlock-window", self.voidlock_window, cycle_time, 100 * cycle_time, pid="s, 1..100 periods")
        # distctrl's own functions check their keys (docs/process.md): corner_lock.share 0 < s <= 1,
        # hysteresis 0..0.5 with share + hysteresis <= 1; void_lock's threshold, window, cycles, band
        pins = {"corner_lock.share": "cornerlock-threshold / 100",
                "corner_lock.hysteresis": "cornerlock-hysteresis / 100",
                "void_lock.threshold": "voidlock-slope", "void_lock.window": "voidlock-window",
                "void_lock.on_cycles": "voidlock-on-cycles", "void_lock.off_cycles": "voidlock-off-cycles",
                "void_lock.release_band": "voidlock-release-band"}
        try:
            if self.cornerlock_mode == "distctrl":
                CornerLock("Z", share=self.cornerlock_share, hysteresis=self.cornerlock_hysteresis_share)
            VoidLock("Z", cycle_time, self.voidlock_slope, window=self.voidlock_window,
                     on_cycles=self.voidlock_on_cycles, off_cycles=self.voidlock_off_cycles,
                     release_band=self.voidlock_release_band)
        except ConfigError as exc:
            raise LinuxCNCError(f"distctrl_thc {pins.get(exc.key, exc.key)}: {exc}") from None
        try:
            self.filter.check(cycle_time)
        except ParameterError as exc:
            raise LinuxCNCError(f"distctrl_thc filter: {exc}") from None
        try:                                         # the parameter list's own checks (ranges, swe_neg < swe_pos)
            self.axis_parameters()
        except ParameterError as exc:
            raise LinuxCNCError(f"distctrl_thc: {exc}") from None

    @property
    def cornerlock_share(self) -> float:
        """corner_lock.share: ``cornerlock-threshold`` % as a share (the component computes the same)."""
        return self.cornerlock_threshold * 0.01

    @property
    def cornerlock_hysteresis_share(self) -> float:
        """corner_lock.hysteresis: ``cornerlock-hysteresis`` % as a share."""
        return self.cornerlock_hysteresis * 0.01

    def coefficients(self, cycle_time: float) -> list[float]:
        self.check(cycle_time)
        return design_coefficients(self.filter, cycle_time)

    @classmethod
    def from_params(cls, p, **kw) -> "ThcConfig":
        """From an axis parameter list (:class:`distctrl.params.AxisParameters`): KP, I_TN, D_TV, both
        encoders, the filter, v_max, a_max (0: the axis's), max_deviation, the monitoring's
        max_act_value_change, max_pos, min_pos, tolerance, the software limits, the lowering weights and
        the adaptive acceleration; ``kw`` sets the rest."""
        fields = dict(kp=p.kp, i_tn=p.i_tn, d_tv=p.d_tv, use_both_encoders=bool(p.use_both_encoders),
                      filter=FilterConfig(p.filter_type, p.n_cycles, p.smoothing_factor, p.kalman_sigma,
                                          p.low_pass_filter_order, p.low_pass_filter_fg_f0),
                      v_max=p.v_max, a_max=p.a_max if p.a_max > 0 else p.axis_a_max,
                      max_deviation=p.max_deviation, max_act_value_change=p.max_act_value_change,
                      max_pos=p.max_pos, min_pos=p.min_pos, tolerance=p.tolerance,
                      check_sw_limit_switch=bool(p.check_sw_limit_switch), sw_limit_max=p.sw_limit_max,
                      sw_limit_min=p.sw_limit_min, v_weight_down=p.v_weight_down, a_weight_down=p.a_weight_down,
                      use_adaptive_acceleration=bool(p.use_adaptive_acceleration), a_min=p.a_min,
                      dist_error_a_min=p.dist_error_a_min, dist_error_a_max=p.dist_error_a_max)
        fields.update(kw)
        return cls(**fields)

    def axis_parameters(self) -> AxisParameters:
        """The axis parameter list the cycle core runs the component's law with (:class:`ThcCore`): these
        settings, the sensor absolute (no REF), optimized scheduling (the reading of this period)."""
        f = self.filter
        return AxisParameters(enabled=True, kp=self.kp, i_tn=self.i_tn, d_tv=self.d_tv,
                              use_both_encoders=self.use_both_encoders, filter_type=f.filter_type,
                              n_cycles=f.n_cycles, smoothing_factor=f.smoothing_factor, kalman_sigma=f.kalman_sigma,
                              low_pass_filter_order=f.order, low_pass_filter_fg_f0=f.fg_f0, v_max=self.v_max,
                              a_max=self.a_max, max_deviation=self.max_deviation,
                              max_act_value_change=self.max_act_value_change, max_pos=self.max_pos,
                              min_pos=self.min_pos, tolerance=self.tolerance, sensor_absolute=True,
                              optimized_scheduling=True, use_adaptive_acceleration=self.use_adaptive_acceleration,
                              a_min=self.a_min, dist_error_a_min=self.dist_error_a_min,
                              dist_error_a_max=self.dist_error_a_max, v_weight_down=self.v_weight_down,
                              a_weight_down=self.a_weight_down, check_sw_limit_switch=self.check_sw_limit_switch,
                              sw_limit_max=self.sw_limit_max, sw_limit_min=self.sw_limit_min)

    def setp_lines(self, cycle_time: float, name: str = "distctrl-thc.0") -> list[str]:
        """halcmd ``setp`` lines for the component instance ``name`` (exact: repr of each double)."""
        fc = self.coefficients(cycle_time)
        pins = {"use-both-encoders": int(self.use_both_encoders), "kp": self.kp, "i-tn": self.i_tn, "d-tv": self.d_tv,
                "v-max": self.v_max, "a-max": self.a_max,
                "max-deviation": self.max_deviation, "set-dist": self.set_dist, "arc-v0": self.arc_v0,
                "arc-k": self.arc_k, "resolution": self.resolution,
                "cornerlock-mode": CORNERLOCK_MODES.get(self.cornerlock_mode, -1),
                "cornerlock-threshold": self.cornerlock_threshold,
                "cornerlock-hysteresis": self.cornerlock_hysteresis, "voidlock-slope": self.voidlock_slope,
                "voidlock-window": self.voidlock_window, "voidlock-on-cycles": int(self.voidlock_on_cycles),
                "voidlock-off-cycles": int(self.voidlock_off_cycles),
                "voidlock-release-band": self.voidlock_release_band,
                "max-act-value-change": self.max_act_value_change, "max-pos": self.max_pos,
                "min-pos": self.min_pos, "tolerance": self.tolerance,
                "check-sw-limit-switch": int(self.check_sw_limit_switch), "sw-limit-max": self.sw_limit_max,
                "sw-limit-min": self.sw_limit_min, "v-weight-down": self.v_weight_down,
                "a-weight-down": self.a_weight_down,
                "use-adaptive-acceleration": int(self.use_adaptive_acceleration), "a-min": self.a_min,
                "dist-error-a-min": self.dist_error_a_min, "dist-error-a-max": self.dist_error_a_max,
                "dryrun": int(self.dryrun), "mode": MODES.get(self.mode, -1), "set-pos": self.set_pos}
        lines = [f"setp {name}.{k} {v!r}" for k, v in pins.items()]
        lines += [f"setp {name}.fc-{i:03d} {float(c)!r}" for i, c in enumerate(fc)]
        return lines

    def setp_document(self, cycle_time: float, source: str, name: str = "distctrl-thc.0",
                      notes: tuple[str, ...] = ()) -> list[str]:
        """The same ``setp`` lines as :meth:`setp_lines` (the same values), grouped under comment blocks
        that say what each group is, each pin with a comment naming its parameter and unit, the filter
        coefficients named by what they are in the filter they implement; coefficients the filter does
        not use and that are 0 are left at the component's default 0 (one comment says which)."""
        values = dict(ln.split(" ", 2)[1:] for ln in self.setp_lines(cycle_time, name))
        f = self.filter
        kind = FilterType(f.effective_kind)
        out = ["# distctrl_thc's parameters: GENERATED by `distctrl linuxcnc thc-setp` from " + source,
               "# Do not edit by hand: change the list (or the options) and generate this file again;",
               "# every value was checked against the documents' ranges when it was written.",
               f"# Servo period {cycle_time * 1000:g} ms (the filter coefficients are designed for it).",
               *[f"# {n}" for n in notes],
               "loadrt distctrl_thc"]
        for title, group in _PIN_GROUPS:
            out += ["", f"# --- {title} ---"]
            for pin, what in group:
                out.append(f"setp {name}.{pin} {values[f'{name}.{pin}']}    # {what}")
        fc = [float(v) for v in self.coefficients(cycle_time)]
        used = _coefficient_names(kind, f.effective_n, int(fc[law.FC_NSEC]))
        out += ["", f"# --- the distance filter: {kind.name} (P-AXIS-00782 = {int(kind)}), "
                f"n = {f.effective_n}, smoothing {f.smoothing_factor:g}, Kalman sigma {f.kalman_sigma:g}, "
                f"low-pass order {f.order} at fg/f0 {f.fg_f0:g} ---",
                "# fc-000..fc-134: the law's coefficient buffer, designed by distctrl's own filter design",
                "# (distctrl.control.filters.design_coefficients), read by the component as they are."]
        left = []
        for i, c in enumerate(fc):
            if i in used or c != 0.0 or math.copysign(1.0, c) < 0:
                out.append(f"setp {name}.fc-{i:03d} {c!r}    # {used.get(i) or _fc_name(i)}")
            else:
                left.append(i)
        if left:
            out.append(f"# not used by {kind.name} and 0: {_ranges(left)} "
                       "(left at the component's default 0)")
        return out


class _Hold:
    """The component's FREEZE hold as the process functions see it (:class:`distctrl.plc.process.hold.
    FreezeHold`'s face to them): ``held_by_us`` while the component is in a FREEZE its locks commanded,
    the requests of this period. The sequence itself is :class:`ThcCore`'s commands (FREEZE while a lock
    requests it, ON_CONST_DIST when none does), as in the component."""

    def __init__(self) -> None:
        self.held_by_us = False
        self.requests: set[str] = set()

    def request(self, who: str) -> None:
        self.requests.add(who)


class ThcLocks:
    """The component's corner lock and void lock: distctrl's own process functions, stepped once a period.

    These are the PLC's part, not the cycle core's. :meth:`step` runs distctrl's
    :class:`~distctrl.plc.process.corner_lock.CornerLock` and :class:`~distctrl.plc.process.void_lock.VoidLock`
    (their ``step``, not a copy) on the component's pins, as distctrl's PLC program runs them on an axis:
    ``state_r.actual_state`` is the HLI state of the previous period, the hold is ours while the component
    is in a FREEZE its locks commanded, the path is ``current-velocity`` · 60 against ``feed-upm`` (F times
    the override, units/min, plasmac's pins; the override is in ``feed-upm``, so the function's own override
    is 1), the void lock's V.E. variable is ``arc-voltage-in``, and switching ``cornerlock-enable`` or
    ``voidlock-enable`` resets the function as distctrl's program switch does. A closed lock is a FREEZE
    request to the core (:class:`ThcCore`). hal/distctrl_thc.comp runs the same in C; tests/linuxcnc/test_thc.py
    checks it period for period (the locks and the void lock's rate and mean bit for bit).

    ``cornerlock-mode`` 1 (plasmac) selects plasmac 1.235's rule instead of the function: locked while
    ``current-velocity`` · 60 is below ``cornerlock-threshold`` % of ``feed-upm``, open again above 99 %
    (plasmac.comp, CUT_MODE_01), while ``thc-enable`` is on, without arming."""

    def __init__(self, config: ThcConfig, period_ns: int = 1_000_000):
        self.T = period_ns * 1e-9                    # as halcompile's fperiod
        self.c = config
        self.plasmac = config.cornerlock_mode == "plasmac"
        self.hold = _Hold()
        self.corner = CornerLock("Z", share=config.cornerlock_share, hysteresis=config.cornerlock_hysteresis_share)
        self.void = VoidLock("Z", self.T, config.voidlock_slope, variable=_ARC, window=config.voidlock_window,
                             on_cycles=config.voidlock_on_cycles, off_cycles=config.voidlock_off_cycles,
                             release_band=config.voidlock_release_band)
        self.corner.bind(self.hold)
        self.void.bind(self.hold)
        self._state_r = SimpleNamespace(actual_state=STATE_INACTIVE)
        self._path = SimpleNamespace(D_CommandFeed=0.0, D_ActiveFeed=0.0, override=1.0)
        self.machine = SimpleNamespace(hli={"Z": SimpleNamespace(state_r=self._state_r)}, variables={},
                                       channel_path=self._path)
        self._cl_on = self._vl_on = False
        self.cycle = 0
        self.cornerlock = self.voidlock = False

    @staticmethod
    def _switch(fn, on: bool, was: bool) -> bool:
        if on != was:
            fn.reset()                               # distctrl's program switch: a change resets the function
        return on

    def step(self, arc_voltage: float, state: int, held: bool, enable: bool, cornerlock_enable: bool,
             current_velocity: float, feed_upm: float, voidlock_enable: bool) -> bool:
        """One period of both locks; ``state`` the HLI state of the previous period, ``held`` it is a FREEZE
        the locks commanded. True if either lock requests the hold."""
        self.cycle += 1
        self._state_r.actual_state = state
        self.hold.held_by_us = held
        self.hold.requests.clear()
        m = self.machine
        if self.plasmac:
            thr = self.c.cornerlock_threshold
            v = current_velocity * 60.0
            if not (cornerlock_enable and enable):
                self.cornerlock = False
            elif v < feed_upm * thr * 0.01:
                self.cornerlock = True
            elif self.cornerlock and v > feed_upm * 0.99:
                self.cornerlock = False
        else:
            self._cl_on = self._switch(self.corner, bool(cornerlock_enable), self._cl_on)
            if self._cl_on:
                self._path.D_CommandFeed = feed_upm
                self._path.D_ActiveFeed = current_velocity * 60.0
                self.corner.step(m, self.cycle)
            self.cornerlock = self._cl_on and self.corner.armed and self.corner.locked
        self._vl_on = self._switch(self.void, bool(voidlock_enable), self._vl_on)
        if self._vl_on:
            m.variables[_ARC] = arc_voltage
            self.void.step(m, self.cycle)
        self.voidlock = self._vl_on and self.void.locked
        return self.cornerlock or self.voidlock


#: HLI_DIST_CTRL_STATE_* the component reaches (its state pin; HLI DistanceControl)
STATE_INACTIVE, STATE_FREEZE, STATE_TURNING_OFF, STATE_ACTIVE_CONST_DIST, STATE_ERROR = (
    int(HliState.INACTIVE), int(HliState.FREEZE), int(HliState.TURNING_OFF), int(HliState.ACTIVE_CONST_DIST),
    int(HliState.ERROR))
STATE_ACTIVE, STATE_DRYRUN_CONST_DIST, STATE_DRYRUN_SETPOS = (
    int(HliState.ACTIVE), int(HliState.DRYRUN_CONST_DIST), int(HliState.DRYRUN_SETPOS))
_TRACKING = (STATE_ACTIVE, STATE_ACTIVE_CONST_DIST)
_OFF_FROM = (STATE_ACTIVE, STATE_ACTIVE_CONST_DIST, STATE_FREEZE, STATE_ERROR, STATE_DRYRUN_CONST_DIST,
             STATE_DRYRUN_SETPOS)


class ThcCore:
    """The component's period with distctrl's cycle core (:class:`AxisDistanceController`) as the law.

    The pins become what a PLC gives the core (HLI DistanceControl, PLC-commanded): the distance
    ``(arc-voltage-in - arc-v0) * (1 / arc-k)`` as the sensor variable (the reading ``s = -distance``,
    SPEC §1), ``axis-z-command`` as the programmed position p (the core adds its own offset: c = p + o),
    ``axis-z-position`` as a, ``set-dist`` and ``set-pos`` as the cyclic D_Distance and D_Position; and from the
    state of the previous period and this period's locks (:class:`ThcLocks`: distctrl's corner_lock and
    void_lock functions, which see that state as ``state_r.actual_state``) the commands:

    * thc-enable on and INACTIVE: the select, by ``mode`` read now: ON_CONST_DIST with SET_DIST (mode 0) or
      ON with SET_POS (mode 1), and FREEZE at once if a lock holds; with ``dryrun`` on, DRYRUN with the
      mode's set value (HLI CONST_DIST / DRYRUN: the cycle runs, the offset stands; a DRYRUN selected while
      the offset still moves is a FREEZE until it stands, the core's rule), which no lock freezes;
    * thc-enable on, ACTIVE or ACTIVE_CONST_DIST and a lock holds: FREEZE; the FREEZE the locks commanded
      and no lock: ON into the mode of the select;
    * thc-enable off in ACTIVE(_CONST_DIST), DRYRUN, FREEZE or ERROR: OFF (TURNING_OFF runs the offset out
      to 0, then INACTIVE). ERROR is left only this way (FCT-M3 §8.1): thc-enable off, then on.

    hal/distctrl_thc.comp is this class in C; tests/linuxcnc/test_thc.py checks it bit for bit."""

    def __init__(self, config: ThcConfig, period_ns: int = 1_000_000):
        self.T = period_ns * 1e-9                    # as halcompile's fperiod
        self.c = config
        config.check(self.T)
        self.ctrl = AxisDistanceController(config.axis_parameters(), self.T)
        self.locks = ThcLocks(config, period_ns)
        self.state = STATE_INACTIVE
        self._held = False
        self._const_dist = True
        self._first = True

    def step(self, arc_voltage: float, enable: bool, cornerlock_enable: bool = False, current_velocity: float = 0.0,
             feed_upm: float = 0.0, voidlock_enable: bool = False, z_command: float = 0.0,
             z_actual: float = 0.0, set_dist: float | None = None, dryrun: bool | None = None,
             mode: int | None = None, set_pos: float | None = None) -> dict:
        c = self.c
        set_dist = c.set_dist if set_dist is None else set_dist
        dryrun = c.dryrun if dryrun is None else dryrun
        mode = MODES[c.mode] if mode is None else mode
        set_pos = c.set_pos if set_pos is None else set_pos
        d = (arc_voltage - c.arc_v0) * (1.0 / c.arc_k)
        locked = self.locks.step(arc_voltage, self.state, self._held, enable, cornerlock_enable, current_velocity,
                                 feed_upm, voidlock_enable)
        inp = CycleInput(programmed_position=z_command, actual_position=z_actual, sensor_variable=d,
                         cyclic_set_dist=set_dist, cyclic_set_pos=set_pos)
        cmds = inp.commands
        if self._first:                              # the distance comes from the PLC (a V.E. variable)
            cmds.append(Command(Action.NONE, sensor_source=SensorSource.VARIABLE, source=CommandSource.PLC))
            self._first = False
        st = self.state
        freeze = False
        if st == STATE_INACTIVE and enable:          # the select: mode and dryrun are read here
            self._const_dist = mode != MODES["SET_POS"]

        def select(action: Action) -> Command:
            if self._const_dist:
                return Command(action, const_dist=True, set_dist=set_dist, source=CommandSource.PLC)
            return Command(action, const_dist=False, set_pos=set_pos, source=CommandSource.PLC)

        if not enable:
            if st in _OFF_FROM:
                cmds.append(Command(Action.OFF, source=CommandSource.PLC))
        elif st == STATE_INACTIVE and dryrun:        # DRYRUN (HLI CONST_DIST / DRYRUN); no lock freezes it
            cmds.append(select(Action.DRYRUN))
        elif st == STATE_INACTIVE:
            cmds.append(select(Action.ON))
            if locked:
                cmds.append(Command(Action.FREEZE, source=CommandSource.PLC))
                freeze = True
        elif st in _TRACKING and locked:
            cmds.append(Command(Action.FREEZE, source=CommandSource.PLC))
            freeze = True
        elif st == STATE_FREEZE and self._held and not locked:   # the hold releases only its own FREEZE,
            cmds.append(select(Action.ON))                      # into the mode it froze

        out = CycleOutput()
        self.ctrl.update(inp, out)
        self.state = out.hli_state
        # the hold is ours while the component stays in the FREEZE its locks commanded
        self._held = self.state == STATE_FREEZE and (freeze or self._held)
        err = self.ctrl.state.error
        o = out.offset
        r = c.resolution
        return {"distance": d, "state": out.hli_state, "error_id": err.id if err is not None else 0,
                "offset": o, "velocity": out.offset_velocity, "filtered": out.filtered_feedback,
                "counts": lround(o / r) if r > 0.0 else 0, "cornerlock_is_locked": self.locks.cornerlock,
                "voidlock_is_locked": self.locks.voidlock, "voidlock_rate": self.locks.void.rate,
                "voidlock_mean": self.locks.void.mean, "target_deviation": out.target_deviation,
                "wanted_step": out.delta_deviation_pre_limiter,
                "events": [ev.id for ev in out.events]}
