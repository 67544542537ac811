"""distctrl's law as a LinuxCNC component: the configuration of hal/distctrl_thc.comp and its Python reference.

:class:`ThcConfig` holds the component's settings with the documents' ranges (KP P-AXIS-00759 0 < kp <= 2,
I_TN P-AXIS-00764 0..50 s, D_TV P-AXIS-00765 0..2 s, the filter of P-AXIS-00782/00413/00784/00783/00507/00508
through :class:`distctrl.control.filters.FilterConfig`, v_max P-AXIS-00415, a_max P-AXIS-00416,
max_deviation P-AXIS-00414, the monitoring's max_act_value_change P-AXIS-00417 and sensor window
max_pos/min_pos/tolerance P-AXIS-00419/00420/00421) and gives them as ``setp`` lines (:meth:`ThcConfig.setp_lines`), the filter
coefficients designed by distctrl's own design (:func:`distctrl.control.filters.design_coefficients`).

:class:`ThcCore` is the component's period in Python with distctrl's cycle core
(:class:`distctrl.control.controller.AxisDistanceController`, whose numbers are :mod:`distctrl.control.law`'s,
the only copy of the law) as its law: the pins become the core's inputs and the PLC's commands (ON,
FREEZE while a lock holds, OFF). :class:`ThcLocks` is the corner lock and void lock, the PLC's part.
tests/linuxcnc/test_thc.py streams inputs through the C component in halrun and checks its outputs
(offset, velocity, filtered value, HLI state, error ID, counts, locks) equal ThcCore's bit for bit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..base.kinds import SensorSource
from ..base.states import CommandSource, HliState
from ..control.commands import Action, Command
from ..control.controller import AxisDistanceController
from ..control.cycle_io import CycleInput, CycleOutput
from ..control.filters import FilterConfig, design_coefficients
from ..errors import ParameterError
from ..params.axis import AxisParameters
from .hal_env import LinuxCNCError

__all__ = ["ThcConfig", "ThcCore", "ThcLocks", "lround"]


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
    max_act_value_change: float = 5000.0   # P-AXIS-00417, mm/s: the sensor jump limit (70329)
    max_pos: float = 50000.0               # P-AXIS-00419, mm: the window of the reading s = -distance (70330)
    min_pos: float = -50000.0              # P-AXIS-00420, mm (70576)
    tolerance: float = 0.0                 # P-AXIS-00421, mm

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
        encoders, the filter, v_max, a_max (0: the axis's), max_deviation, the monitoring's
        max_act_value_change, max_pos, min_pos, tolerance; ``kw`` sets the rest."""
        fields = dict(kp=p.kp, i_tn=p.i_tn, d_tv=p.d_tv, use_both_encoders=bool(p.use_both_encoders),
                      filter=FilterConfig(p.filter_type, p.n_cycles, p.smoothing_factor, p.kalman_sigma,
                                          p.low_pass_filter_order, p.low_pass_filter_fg_f0),
                      v_max=p.v_max, a_max=p.a_max if p.a_max > 0 else p.axis_a_max,
                      max_deviation=p.max_deviation, max_act_value_change=p.max_act_value_change,
                      max_pos=p.max_pos, min_pos=p.min_pos, tolerance=p.tolerance)
        fields.update(kw)
        return cls(**fields)

    def axis_parameters(self) -> AxisParameters:
        """The axis parameter list the cycle core runs the component's law with (:class:`ThcCore`): these
        settings, the sensor absolute (no REF), optimized scheduling (the reading of this period), no
        adaptive acceleration, no lowering weights, no software limits (LinuxCNC's motion keeps them)."""
        f = self.filter
        return AxisParameters(enabled=True, kp=self.kp, i_tn=self.i_tn, d_tv=self.d_tv,
                              use_both_encoders=self.use_both_encoders, filter_type=f.filter_type,
                              n_cycles=f.n_cycles, smoothing_factor=f.smoothing_factor, kalman_sigma=f.kalman_sigma,
                              low_pass_filter_order=f.order, low_pass_filter_fg_f0=f.fg_f0, v_max=self.v_max,
                              a_max=self.a_max, max_deviation=self.max_deviation,
                              max_act_value_change=self.max_act_value_change, max_pos=self.max_pos,
                              min_pos=self.min_pos, tolerance=self.tolerance, sensor_absolute=True,
                              optimized_scheduling=True, use_adaptive_acceleration=False, v_weight_down=0.0,
                              a_weight_down=0.0, check_sw_limit_switch=False)

    def setp_lines(self, cycle_time: float, name: str = "distctrl-thc.0") -> list[str]:
        """halcmd ``setp`` lines for the component instance ``name`` (exact: repr of each double)."""
        fc = self.coefficients(cycle_time)
        pins = {"use-both-encoders": int(self.use_both_encoders), "kp": self.kp, "i-tn": self.i_tn, "d-tv": self.d_tv, "v-max": self.v_max, "a-max": self.a_max,
                "max-deviation": self.max_deviation, "set-dist": self.set_dist, "arc-v0": self.arc_v0,
                "arc-k": self.arc_k, "resolution": self.resolution,
                "cornerlock-threshold": self.cornerlock_threshold, "voidlock-slope": self.voidlock_slope,
                "voidlock-window": self.voidlock_window, "voidlock-on-cycles": int(self.voidlock_on_cycles),
                "voidlock-off-cycles": int(self.voidlock_off_cycles),
                "voidlock-release-band": self.voidlock_release_band,
                "max-act-value-change": self.max_act_value_change, "max-pos": self.max_pos,
                "min-pos": self.min_pos, "tolerance": self.tolerance}
        lines = [f"setp {name}.{k} {v!r}" for k, v in pins.items()]
        lines += [f"setp {name}.fc-{i:03d} {float(c)!r}" for i, c in enumerate(fc)]
        return lines


class ThcLocks:
    """The component's corner lock and void lock in Python (hal/distctrl_thc.comp runs the same).

    These are the PLC's part, not the cycle core's: the corner lock is plasmac's (current-velocity below
    cornerlock-threshold % of requested-velocity, no arming or hysteresis, so that the pin means what
    plasmac's does), the void lock is distctrl's void_lock function (distctrl/plc/process/void_lock.py,
    its ST) on the arc voltage. A closed lock is a FREEZE command to the core (:class:`ThcCore`)."""

    def __init__(self, config: ThcConfig, period_ns: int = 1_000_000):
        self.T = period_ns * 1e-9                    # as halcompile's fperiod
        self.c = config
        self.vbuf = [0.0] * 100
        self.vmean = [0.0] * 100
        self.vsum = self.vlevel = 0.0
        self.vi = self.nfill = self.nmfill = self.non = self.noff = 0
        self.cornerlock = self.voidlock = False

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

    def step(self, arc_voltage: float, enable: bool, cornerlock_enable: bool, current_velocity: float,
             requested_velocity: float, voidlock_enable: bool) -> bool:
        """One period of both locks; True if either holds."""
        c = self.c
        self.cornerlock = bool(cornerlock_enable and current_velocity < requested_velocity * c.cornerlock_threshold * 0.01)
        self._void_lock(arc_voltage, bool(voidlock_enable and enable))
        return self.cornerlock or self.voidlock


#: HLI_DIST_CTRL_STATE_* the component reaches (its state pin; HLI DistanceControl)
STATE_INACTIVE, STATE_FREEZE, STATE_TURNING_OFF, STATE_ACTIVE_CONST_DIST, STATE_ERROR = (
    int(HliState.INACTIVE), int(HliState.FREEZE), int(HliState.TURNING_OFF), int(HliState.ACTIVE_CONST_DIST),
    int(HliState.ERROR))


class ThcCore:
    """The component's period with distctrl's cycle core (:class:`AxisDistanceController`) as the law.

    The pins become what a PLC gives the core (HLI DistanceControl, PLC-commanded): the distance
    ``(arc-voltage-in - arc-v0) * (1 / arc-k)`` as the sensor variable (the reading ``s = -distance``,
    SPEC §1), ``axis-z-command`` as the programmed position p (the core adds its own offset: c = p + o),
    ``axis-z-position`` as a, ``set-dist`` as the cyclic D_Distance; and from the state of the previous
    period and this period's locks (:class:`ThcLocks`) the commands:

    * thc-enable on and INACTIVE: ON_CONST_DIST with SET_DIST (and FREEZE at once if a lock holds);
    * thc-enable on, ACTIVE_CONST_DIST and a lock holds: FREEZE; FREEZE and no lock: ON_CONST_DIST;
    * thc-enable off in ACTIVE_CONST_DIST, FREEZE or ERROR: OFF (TURNING_OFF runs the offset out to 0,
      then INACTIVE). ERROR is left only this way (FCT-M3 §8.1): thc-enable off, then on again.

    hal/distctrl_thc.comp is this class in C; tests/linuxcnc/test_thc.py checks it bit for bit."""

    def __init__(self, config: ThcConfig, period_ns: int = 1_000_000):
        self.T = period_ns * 1e-9                    # as halcompile's fperiod
        self.c = config
        config.check(self.T)
        self.ctrl = AxisDistanceController(config.axis_parameters(), self.T)
        self.locks = ThcLocks(config, period_ns)
        self.state = STATE_INACTIVE
        self._first = True

    def step(self, arc_voltage: float, enable: bool, cornerlock_enable: bool = False, current_velocity: float = 0.0,
             requested_velocity: float = 0.0, voidlock_enable: bool = False, z_command: float = 0.0,
             z_actual: float = 0.0, set_dist: float | None = None) -> dict:
        c = self.c
        set_dist = c.set_dist if set_dist is None else set_dist
        d = (arc_voltage - c.arc_v0) * (1.0 / c.arc_k)
        locked = self.locks.step(arc_voltage, enable, cornerlock_enable, current_velocity, requested_velocity,
                                 voidlock_enable)
        inp = CycleInput(programmed_position=z_command, actual_position=z_actual, sensor_variable=d,
                         cyclic_set_dist=set_dist)
        cmds = inp.commands
        if self._first:                              # the distance comes from the PLC (a V.E. variable)
            cmds.append(Command(Action.NONE, sensor_source=SensorSource.VARIABLE, source=CommandSource.PLC))
            self._first = False
        st = self.state
        on = Command(Action.ON, const_dist=True, set_dist=set_dist, source=CommandSource.PLC)
        if not enable:
            if st in (STATE_ACTIVE_CONST_DIST, STATE_FREEZE, STATE_ERROR):
                cmds.append(Command(Action.OFF, source=CommandSource.PLC))
        elif st == STATE_INACTIVE:
            cmds.append(on)
            if locked:
                cmds.append(Command(Action.FREEZE, source=CommandSource.PLC))
        elif st == STATE_ACTIVE_CONST_DIST and locked:
            cmds.append(Command(Action.FREEZE, source=CommandSource.PLC))
        elif st == STATE_FREEZE and not locked:
            cmds.append(on)
        out = CycleOutput()
        self.ctrl.update(inp, out)
        self.state = out.hli_state
        err = self.ctrl.state.error
        o = out.offset
        r = c.resolution
        return {"distance": d, "state": out.hli_state, "error_id": err.id if err is not None else 0,
                "offset": o, "velocity": out.offset_velocity, "filtered": out.filtered_feedback,
                "counts": lround(o / r) if r > 0.0 else 0, "cornerlock_is_locked": self.locks.cornerlock,
                "voidlock_is_locked": self.locks.voidlock,
                "events": [ev.id for ev in out.events]}
