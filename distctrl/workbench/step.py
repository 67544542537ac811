"""Step-response workbench: the documents' controller-tuning method on the virtual machine.

FCT-M3 ch. 3 tunes distance control step by step: first a P controller (I and D off) starting at
``K_p = 0.2``; observe the response of the control loop to a *defined change in distance* and raise
``K_p`` until there is a recognisable but rapidly decaying oscillation; then the I part (start
``T_n = 5`` s, reduce it) only against a permanent control deviation; then the D part (start
``T_v = 0.01`` s) to damp oscillations. This module makes that experiment repeatable:

* :func:`parse_settings` turns ``--kp 0.2,0.5,1 --i-tn 0 --d-tv 0,0.01`` into the cartesian product
  of :class:`StepSetting`;
* :func:`step_scenario` builds the run: a Z axis with a probe (or the Z axis, parameter list and
  sensor of a given scenario) holding the set distance, and at ``t_step`` the sensor sees the
  surface rise by ``step_mm`` (a sensor ``jump`` fault, see below);
* :func:`measure` reads rise time, overshoot, settling time, steady-state error and the number of
  oscillation swings from the offset response ``<axis>.dc.offset``;
* :func:`run_steps`, :func:`format_table`, :func:`hints` and :func:`plot_steps` run a sweep and
  present it (``distctrl step``, docs/workbench-step.md).

Why a sensor ``jump`` and not a step in the surface: the jump happens exactly at ``t_step`` (a step
feature needs an X motion and is crossed when the interpolator gets there), and the controller
cannot tell the two apart -- it sees the same change of its measurement -- so the *offset* response
is the same. The difference is the true distance: a real surface step also changes the true
distance (it drops by the step and recovers as the offset lifts the axis), the fault does not (the
true distance *grows* by the step while the offset follows the fake reading). The metrics therefore
use the offset, never ``true.distance``.

Errors are :class:`StepError` (a ``DistCtrlError``) whose messages say what is allowed.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, NamedTuple, Sequence

import numpy as np

from ..control.controller import AxisDistanceController
from ..errors import DistCtrlError
from ..params.listfile import parse_list_text
from ..sim.runner import run
from ..sim.scenario import Scenario, load_scenario, scenario_from_dict
from ..trace.plot import MAX_POINTS, envelope
from .plotfiles import PLOT_SUFFIXES, check_plot_suffix  # noqa: F401  (PLOT_SUFFIXES: part of the API)
from .tables import render_table

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ..sim.scenario import Scenario
    from ..trace import Trace

__all__ = [
    "StepError", "StepSettingError", "StepSetting", "StepMetrics", "StepResult",
    "KP_RANGE", "I_TN_RANGE", "D_TV_RANGE", "MODES", "BAND", "RECOGNISABLE_PCT", "RAPID_CROSSINGS",
    "LARGE_PCT", "DEFAULT_AXIS_LIST", "DEFAULT_AXIS", "DEFAULT_SENSOR", "parse_settings", "step_scenario",
    "measure", "run_steps", "format_table", "hints", "plot_steps", "check_plot_path", "auto_step",
    "suggested_kp", "LIMITED_SHARE", "NOISE_SIGMAS", "results_json",
]

# ------------------------------------------------------------------------------------------------------
# constants
# ------------------------------------------------------------------------------------------------------
#: the documented ranges (P-AXIS-00759/00764/00765, NC KP / I_TN / D_TV): (lo, hi, lo_open)
KP_RANGE = (0.0, 2.0, True)
I_TN_RANGE = (0.0, 50.0, False)
D_TV_RANGE = (0.0, 2.0, False)
#: distance-control modes the step can be run in
MODES = ("CONST_DIST", "SET_POS")
#: settling band: +-2 % of the step
BAND = 0.02
#: an overshoot from this size (% of the step) on is "recognisable"
RECOGNISABLE_PCT = 2.0
#: "rapidly decaying": settled, with at most this many zero crossings after the first peak (2 periods)
RAPID_CROSSINGS = 4
#: above this overshoot (% of the step) it is called large, however fast it decays
LARGE_PCT = 40.0
#: a response is "limiter-bound" when the slope limiter (P-AXIS-00415 v_max, P-AXIS-00416 a_max and the
#: braking it implies) changed the PID's offset step in at least this share of the cycles from the step
#: until it settled (the whole run after the step when it did not settle)
LIMITED_SHARE = 0.1
#: the settling band is widened to this many standard deviations of the offset's noise before the step
#: (a probe with noise never stays inside +-2 % of a small step)
NOISE_SIGMAS = 5.0
#: the automatic step (``--step auto``) keeps the first cycle's demand of every setting within this share
#: of the limiter's reach, and is not smaller than this many probe noise standard deviations
AUTO_MARGIN = 0.5
AUTO_NOISE_FLOOR = 20.0
#: the automatic step is never larger than this (mm)
AUTO_MAX_MM = 1.0
#: longest run one setting may ask for (s of machine time)
MAX_DURATION = 60.0
#: the step may use at most this share of the sensor's measuring range
_RANGE_SHARE = 0.8

#: The default virtual machine's Z axis (kernel list format, docs/workbench-step.md): a high-dynamic
#: laser-head Z axis. Plain CONST_DIST (P-AXIS-00500 = 0): the measured distance answers the offset
#: only through the drive, so this is the loop that can oscillate (SPEC §3). v_max / a_max of
#: distance control are high enough that a 1 mm step is not only a slope-limiter ramp.
DEFAULT_AXIS_LIST = """\
# distctrl step: default Z axis with a probe on encoder 2
lr_param.distance_control_on        1
kenngr.distc.max_deviation          100000    # [0.1 um] 10 mm
kenngr.distc.v_max                  500000    # [um/s] 500 mm/s
kenngr.distc.a_max                  50000     # [mm/s^2]
kenngr.distc.max_act_value_change   100000000 # [um/s] 100 m/s: the step itself is a jump of the reading
kenngr.distc.max_pos                100000    # [0.1 um] +10 mm
kenngr.distc.min_pos                -100000   # [0.1 um] -10 mm
kenngr.distc.optimized_scheduling   1
kenngr.distc.mode_dist_use_both_encoder 0
kenngr.distc.filter_type            MOVING_AVERAGE
kenngr.distc.n_cycles               1
kenngr.distc.kp                     0.2
kenngr.distc.i_tn                   0
kenngr.distc.d_tv                   0
"""
#: drive data of the default Z axis (scenario keys, mm, s): a stiff direct drive (kv 500 1/s, time
#: constant 2 ms) with 50 % velocity feed-forward and one cycle of fieldbus delay
DEFAULT_AXIS: dict[str, Any] = {"kv": 500.0, "v_max": 1000.0, "a_max": 100000.0, "bus_delay_cycles": 1,
                                "feedforward": 0.5, "resolution": 1e-4}
#: the default probe (scenario ``[sensor]`` keys)
DEFAULT_SENSOR: dict[str, Any] = {"kind": "encoder", "range_min": -10.0, "range_max": 10.0,
                                  "noise_std": 0.0, "delay_cycles": 0}


# ------------------------------------------------------------------------------------------------------
# errors
# ------------------------------------------------------------------------------------------------------
class StepError(DistCtrlError, ValueError):
    """Bad input to the step workbench (setting, scenario, step, mode, times, plot path)."""


class StepSettingError(StepError):
    """A KP / I_TN / D_TV value or list that cannot be parsed or is out of its documented range."""

# ------------------------------------------------------------------------------------------------------
# settings
# ------------------------------------------------------------------------------------------------------
def _range_text(name: str, rng: tuple[float, float, bool], unit: str) -> str:
    lo, hi, lo_open = rng
    return f"{lo:g} {'<' if lo_open else '<='} {name} <= {hi:g}{unit}"


def _check(name: str, value: object, rng: tuple[float, float, bool], unit: str = "") -> float:
    allowed = _range_text(name, rng, unit)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise StepSettingError(f"{name} = {value!r} is not a number; allowed: {allowed}")
    v = float(value)
    lo, hi, lo_open = rng
    if not math.isfinite(v) or (v <= lo if lo_open else v < lo) or v > hi:
        raise StepSettingError(f"{name} = {value!r} is out of range; allowed: {allowed}")
    return v


@dataclass(frozen=True)
class StepSetting:
    """One controller setting: ``kp`` (P-AXIS-00759), ``i_tn`` (s, 0 = no I part), ``d_tv`` (s, 0 = no D)."""

    kp: float
    i_tn: float = 0.0
    d_tv: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "kp", _check("KP", self.kp, KP_RANGE))
        object.__setattr__(self, "i_tn", _check("I_TN", self.i_tn, I_TN_RANGE, " s"))
        object.__setattr__(self, "d_tv", _check("D_TV", self.d_tv, D_TV_RANGE, " s"))

    @property
    def label(self) -> str:
        """``KP=0.5 I_TN=0 D_TV=0.01``"""
        return f"KP={self.kp:g} I_TN={self.i_tn:g} D_TV={self.d_tv:g}"

    @property
    def kind(self) -> str:
        """``P``, ``PI``, ``PD`` or ``PID``."""
        return "P" + ("I" if self.i_tn > 0 else "") + ("D" if self.d_tv > 0 else "")

    def nc_words(self) -> str:
        """The DIST_CTRL words: ``KP=0.5 I_TN=0 D_TV=0.01``."""
        return f"KP={_nc(self.kp)} I_TN={_nc(self.i_tn)} D_TV={_nc(self.d_tv)}"

    def __str__(self) -> str:
        return self.label


def _nc(x: float) -> str:
    """A number as an NC value: 12 significant digits, no exponent (``1``, ``0.5``, ``0.0001``)."""
    text = f"{x:.12g}"
    if "e" in text:
        text = f"{x:.15f}".rstrip("0").rstrip(".")
    return text


def _values(name: str, spec: object, rng: tuple[float, float, bool], unit: str) -> list[float]:
    allowed = _range_text(name, rng, unit)
    if isinstance(spec, str):
        parts = [p.strip() for p in spec.replace(";", ",").split(",")]
        if not spec.strip() or any(p == "" for p in parts):
            raise StepSettingError(f"{name} list {spec!r}: empty value; allowed: comma-separated numbers, "
                                   f"each {allowed} (e.g. '0.2,0.5,1')")
        values: list[object] = []
        for p in parts:
            try:
                values.append(float(p))
            except ValueError:
                raise StepSettingError(f"{name} list {spec!r}: {p!r} is not a number; allowed: "
                                       f"comma-separated numbers, each {allowed}") from None
    elif isinstance(spec, (int, float)) and not isinstance(spec, bool):
        values = [spec]
    else:
        try:
            values = list(spec)  # type: ignore[arg-type]
        except TypeError:
            raise StepSettingError(f"{name} = {spec!r}: expected a number, a list of numbers or a "
                                   f"comma-separated string; allowed: each {allowed}") from None
        if not values:
            raise StepSettingError(f"{name}: empty list; allowed: at least one value, each {allowed}")
    out: list[float] = []
    for v in values:
        x = _check(name, v, rng, unit)
        if x not in out:
            out.append(x)
    return out


def parse_settings(kp: object = "0.2,0.5,1", i_tn: object = "0", d_tv: object = "0") -> list[StepSetting]:
    """The cartesian product of the KP, I_TN and D_TV lists (KP outermost, D_TV innermost).

    Each argument is a comma-separated string (``"0.2,0.5,1"``), a number or a sequence of numbers;
    repeated values are dropped. Ranges (the documented ones): ``0 < KP <= 2``, ``0 <= I_TN <= 50`` s,
    ``0 <= D_TV <= 2`` s; anything else raises :class:`StepSettingError`.
    """
    kps = _values("KP", kp, KP_RANGE, "")
    tns = _values("I_TN", i_tn, I_TN_RANGE, " s")
    tvs = _values("D_TV", d_tv, D_TV_RANGE, " s")
    return [StepSetting(a, b, c) for a, b, c in itertools.product(kps, tns, tvs)]


# ------------------------------------------------------------------------------------------------------
# the scenario
# ------------------------------------------------------------------------------------------------------
def _number(name: str, value: object, *, lo: float | None = None, hi: float | None = None,
            lo_open: bool = False, nonzero: bool = False, allowed: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
        raise StepError(f"{name} = {value!r} is not a finite number; allowed: {allowed}")
    v = float(value)
    bad = (lo is not None and (v <= lo if lo_open else v < lo)) or (hi is not None and v > hi) \
        or (nonzero and v == 0.0)
    if bad:
        raise StepError(f"{name} = {value!r} is out of range; allowed: {allowed}")
    return v


def _step_axis(base: "Scenario") -> str:
    sensor = base.sensor
    if sensor is not None and sensor.axis is not None and sensor.axis in base.axes:
        return sensor.axis
    if "Z" in base.axes:
        return "Z"
    raise StepError(f"scenario {base.name!r}: no Z axis and no sensor axis; allowed: a scenario with an "
                    f"[axes.Z] table (or a [sensor] axis) whose parameter list enables distance control")


def _sensor_dict(base: "Scenario", axis: str) -> dict[str, Any]:
    sc = base.sensor
    if sc is None:
        return dict(DEFAULT_SENSOR, axis=axis)
    out: dict[str, Any] = {"axis": axis, "kind": sc.kind, "noise_std": sc.noise_std,
                           "delay_cycles": sc.delay_cycles, "seed": sc.seed, "range_max": sc.range_max}
    if sc.kind == "encoder":
        out["range_min"] = sc.range_min
    else:
        out["variable"] = sc.variable
        out["resolution"] = sc.resolution
        if sc.characteristic is not None:
            out["characteristic"] = [list(p) for p in sc.characteristic]
    return out


def _check_travel(sensor: dict, params, set_dist: float, step_mm: float, ramp_mm: float) -> None:
    """The reading ``s`` (= -d) starts at ``-set_dist`` and ends ``step_mm + ramp_mm`` higher: both must lie
    inside the sensor's range and the monitoring window (P-AXIS-00419/00420/00421), with 20 % to
    spare for the transient; the offset's end value inside 80 % of max_deviation (P-AXIS-00414)."""
    if sensor["kind"] == "encoder":
        lo, hi = float(sensor.get("range_min", -10.0)), float(sensor.get("range_max", 10.0))
    else:
        lo, hi = -float(sensor.get("range_max", 10.0)), 0.0
    lo, hi = max(lo, params.min_pos + params.tolerance), min(hi, params.max_pos - params.tolerance)
    s0 = -set_dist
    if not lo < s0 < hi:
        raise StepError(f"set_dist = {set_dist:g} mm: the reading s = -{set_dist:g} mm is outside the sensor "
                        f"window ({-hi:g} mm < distance < {-lo:g} mm by its range and P-AXIS-00419..00421); "
                        f"allowed: a set distance inside it")
    room_up, room_down = _RANGE_SHARE * (hi - s0), _RANGE_SHARE * (s0 - lo)
    room_up = min(room_up, _RANGE_SHARE * params.max_deviation)
    room_down = min(room_down, _RANGE_SHARE * params.max_deviation)
    allowed = (f"-{room_down:.3g} mm <= step <= {room_up:.3g} mm (80 % of the sensor window around "
               f"SET_DIST = {set_dist:g} mm and of max_deviation = {params.max_deviation:g} mm)")
    if not -room_down <= step_mm <= room_up:
        raise StepError(f"step = {step_mm:g} mm is out of range; allowed: {allowed}")
    end = step_mm + ramp_mm
    if not -room_down <= end <= room_up:
        raise StepError(f"step + ramp reach {end:.3g} mm by the end of the run; allowed: {allowed} "
                        f"(lower the ramp or the duration)")


def step_scenario(base: "Scenario | str | os.PathLike | None", setting: StepSetting, step_mm: float = 1.0,
                  mode: str = "CONST_DIST", t_step: float = 0.5, duration: float = 2.0, *,
                  set_dist: float = 1.0, ramp_mm_s: float = 0.0) -> "Scenario":
    """The scenario of one step-response run.

    The axis (Z, or ``base``'s sensor axis) starts ``set_dist`` mm above a flat surface at 0 and
    distance control is selected at once with the setting's parameters::

        Z[DIST_CTRL ON CONST_DIST SET_DIST=1 KP=0.5 I_TN=0 D_TV=0.01]     (mode CONST_DIST)
        Z[DIST_CTRL ON SET_POS=0 KP=0.5 I_TN=0 D_TV=0.01]                 (mode SET_POS)

    then the program dwells until ``duration``. At ``t_step`` a sensor ``jump`` fault of ``step_mm``
    (signed so that the sensor reports the surface ``step_mm`` higher) starts and stays: the offset
    has to rise by ``step_mm``. With ``ramp_mm_s`` a ``drift`` fault starting at the same time makes
    the reported surface keep rising at that rate (a ramp: a P controller keeps a constant control
    deviation, the I part removes it).

    Without ``base`` the axis is the default virtual machine (:data:`DEFAULT_AXIS_LIST`,
    :data:`DEFAULT_AXIS`, :data:`DEFAULT_SENSOR`). With ``base`` (a :class:`Scenario` or a TOML path)
    the axis keeps its parameter list, drive data and sensor (kind, noise, dead time, range), the
    cycle time and seed; its program, surface, other axes and events are not used. The list must
    enable distance control (P-AXIS-00328); KP / I_TN / D_TV come from ``setting``.
    """

    if not isinstance(setting, StepSetting):
        raise StepError(f"setting = {setting!r}; allowed: a StepSetting (see parse_settings)")
    mode_u = mode.upper() if isinstance(mode, str) else mode
    if mode_u not in MODES:
        raise StepError(f"mode = {mode!r}; allowed: one of {', '.join(MODES)}")
    duration = _number("duration", duration, lo=0.0, lo_open=True, hi=MAX_DURATION,
                       allowed=f"0 < duration <= {MAX_DURATION:g} s")
    t_step = _number("t_step", t_step, lo=0.0, lo_open=True, hi=duration,
                     allowed=f"0 < t_step < duration ({duration:g} s)")
    if t_step >= duration:
        raise StepError(f"t_step = {t_step!r} is out of range; allowed: 0 < t_step < duration "
                        f"({duration:g} s)")
    set_dist = _number("set_dist", set_dist, lo=0.0, lo_open=True, allowed="a distance > 0 mm")
    ramp_mm_s = _number("ramp_mm_s", ramp_mm_s, allowed="a finite rate in mm/s (0: no ramp)")

    if base is not None and not isinstance(base, Scenario):
        base = load_scenario(base)
    if base is None:
        axis = "Z"
        params = parse_list_text(DEFAULT_AXIS_LIST, "<distctrl step default Z axis>").params
        params_file = None
        axis_cfg: dict[str, Any] = dict(DEFAULT_AXIS)
        sensor: dict[str, Any] = dict(DEFAULT_SENSOR, axis=axis)
        cycle_time, seed, variables = 0.001, 0, {}
        source = "<distctrl step>"
    else:
        axis = _step_axis(base)
        ax = base.axes[axis]
        if not ax.params.enabled:
            raise StepError(f"scenario {base.name!r}: axis {axis} has no distance control "
                            f"(lr_param.distance_control_on = 0 in its parameter list); allowed: an axis "
                            f"whose list enables distance control (P-AXIS-00328 = 1)")
        params, params_file = ax.params, ax.params_file
        axis_cfg = {"kv": ax.kv, "v_max": ax.v_max, "a_max": ax.a_max, "v_rapid": ax.v_rapid,
                    "a_rapid": ax.a_rapid, "bus_delay_cycles": ax.bus_delay_cycles,
                    "resolution": ax.resolution, "feedforward": ax.feedforward,
                    "resonance_hz": ax.resonance_hz, "damping": ax.damping}
        sensor = _sensor_dict(base, axis)
        cycle_time, seed, variables = base.cycle_time, base.seed, dict(base.variables)
        source = f"step on {base.path or base.name}"

    step_mm = _number("step", step_mm, nonzero=True, allowed="a step != 0 in mm (> 0: the surface rises)")
    _check_travel(sensor, params, set_dist, step_mm, ramp_mm_s * (duration - t_step))
    jump_rate = abs(step_mm) / cycle_time
    if jump_rate > params.max_act_value_change:
        raise StepError(f"step = {step_mm:g} mm: the reading jumps by it in one cycle ({jump_rate:g} mm/s), "
                        f"more than the axis list's max_act_value_change (P-AXIS-00417) "
                        f"{params.max_act_value_change:g} mm/s allows (the run would stop with error 70329); "
                        f"allowed: |step| <= {params.max_act_value_change * cycle_time:.4g} mm, or raise "
                        f"P-AXIS-00417 in the list")

    # the probe reports s = surface - z (a rising surface raises it), a distance sensor d = z - surface
    sign = 1.0 if sensor["kind"] == "encoder" else -1.0
    words = f"SET_DIST={_nc(set_dist)}" if mode_u == "CONST_DIST" else "SET_POS=0"
    source_words = ""
    if sensor["kind"] == "distance":
        source_words = f" SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.{sensor['variable']}"
    select = "ON CONST_DIST" if mode_u == "CONST_DIST" else "ON"
    program = (f"%STEP\n"
               f"; distctrl step: {setting.label}, step {step_mm:g} mm at {t_step:g} s ({mode_u})\n"
               f"N10 {axis}[DIST_CTRL {select} {words} {setting.nc_words()}{source_words}]\n"
               f"N20 #TIME {_nc(duration)}\n"
               f"N30 M30\n")
    events: list[dict] = [{"t": t_step, "sensor_fault": {"kind": "jump", "value": sign * step_mm}}]
    if ramp_mm_s:
        events.append({"t": t_step, "sensor_fault": {"kind": "drift", "rate": sign * ramp_mm_s}})
    data = {"name": f"step {setting.label}", "cycle_time": cycle_time, "program_text": program,
            "duration": duration, "settle_time": 0.0, "seed": seed, "variables": variables,
            "axes": {axis: dict(axis_cfg, start=set_dist)}, "surface": {"base": 0.0},
            "sensor": sensor, "events": events}
    sc = scenario_from_dict(data, base_dir=".", source=source)
    ax_cfg = dataclasses.replace(sc.axes[axis], params=params, params_file=params_file)
    return dataclasses.replace(sc, axes={axis: ax_cfg})


# ------------------------------------------------------------------------------------------------------
# metrics
# ------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StepMetrics:
    """Step-response metrics of the offset response ``y(t) = o(t) - o(t_step-)`` (mm, s).

    * ``rise_time_s``: from 10 % to 90 % of the step (linear interpolation between cycles); ``None``
      when 90 % is never reached;
    * ``overshoot_mm`` / ``overshoot_pct``: the largest excursion beyond the reference (the step, plus
      the ramp if any), >= 0;
    * ``settling_time_s``: from the step until the response enters +-2 % of the reference and stays
      there to the end of the run; ``None`` (not settled) unless it stays inside for at least the
      last 10 % of the run after the step (so a limit cycle is not "settled" by chance);
    * ``steady_state_error_mm``: the permanent control deviation, averaged over the last 10 % of the
      run after the step, positive when the offset is short of the reference (in the direction of
      the step). From a distance-control trace it is the controller's own remaining error ``e``
      (SPEC §3: ``SET_DIST - filtered distance`` in CONST_DIST, ``filtered surface - SET_POS -
      offset`` in SET_POS), which is what the I part integrates; it equals ``reference - response``
      once the axis has settled on a step, but not on a ramp, where the offset runs ahead of the
      axis by the drive's following error. Without those columns: ``reference - response``;
    * ``oscillation``: zero crossings of the error (response - reference) after the first peak, a
      crossing counted once the error reaches beyond +-1 % of the step on the other side (2 crossings
      = 1 period); 0 without overshoot;
    * ``peak_time_s``: time of the largest excursion beyond the reference (``None`` without one);
    * ``band_mm``: the half-width of the settling band actually used: +-2 % of the step, or
      :data:`NOISE_SIGMAS` standard deviations of the offset's noise before the step where that is
      larger (``None`` from an old caller that built the metrics by hand);
    * ``limited_share``: the share (0..1) of the cycles from the step until it settled (the whole run
      after the step if it did not) in which the slope limiter changed the PID's offset step
      (``|u - v·T|``: P-AXIS-00415 v_max, P-AXIS-00416 a_max and its braking, the offset bounds);
      ``None`` when the trace lacks ``<axis>.dc.pre_limiter`` / ``<axis>.dc.sloped_delta``.
      :attr:`limiter_bound` (at least :data:`LIMITED_SHARE`): the limiter, not KP, shaped the response.
    """

    step_mm: float
    rise_time_s: float | None
    overshoot_mm: float
    overshoot_pct: float
    settling_time_s: float | None
    steady_state_error_mm: float
    oscillation: int
    peak_time_s: float | None = None
    band_mm: float | None = None
    limited_share: float | None = None

    @property
    def settled(self) -> bool:
        return self.settling_time_s is not None

    @property
    def limiter_bound(self) -> bool:
        """The slope limiter changed the PID's step in at least :data:`LIMITED_SHARE` of the transient."""
        return self.limited_share is not None and self.limited_share >= LIMITED_SHARE

    @property
    def band(self) -> float:
        """The settling band in mm (+-)."""
        return self.band_mm if self.band_mm is not None else BAND * abs(self.step_mm)

    @property
    def periods(self) -> int:
        """Oscillation periods after the first peak (two zero crossings each, rounded up)."""
        return (self.oscillation + 1) // 2

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["settled"] = self.settled
        d["band_mm"] = self.band
        d["limiter_bound"] = self.limiter_bound
        return d


def _first_crossing(tt: np.ndarray, y: np.ndarray, level: float) -> float | None:
    """The first time ``y`` reaches ``level`` from below (linear interpolation), None if never."""
    idx = np.flatnonzero(y >= level)
    if idx.size == 0:
        return None
    k = int(idx[0])
    if k == 0:
        return float(tt[0])
    y0, y1 = float(y[k - 1]), float(y[k])
    frac = (level - y0) / (y1 - y0) if y1 != y0 else 1.0
    return float(tt[k - 1] + frac * (tt[k] - tt[k - 1]))


def _trace_of(result: Any) -> "Trace":
    trace = getattr(result, "trace", result)
    if trace is None or not hasattr(trace, "columns"):
        raise StepError("measure: no trace; allowed: a RunResult with its trace kept, or a Trace")
    return trace


def _offset_column(trace: "Trace", column: str | None) -> str:
    if column is not None:
        if column not in trace:
            raise StepError(f"measure: no column {column!r} in the trace; allowed: one of "
                            f"{', '.join(c for c in trace.columns if c.endswith('offset')) or 'its columns'}")
        return column
    for c in trace.columns:
        if c.endswith(".dc.offset"):
            return c
    raise StepError("measure: the trace has no '<axis>.dc.offset' column; allowed: a trace of a run with "
                    "distance control, or name the column")


def _control_error(trace: "Trace", col: str) -> np.ndarray | None:
    """The controller's remaining error ``e`` per cycle (SPEC §3), NaN where it is not tracking:
    ``-target_deviation`` in ACTIVE_CONST_DIST (4), ``target_deviation - offset`` in ACTIVE (1,
    SET_POS; the offset before the cycle's update, i.e. the previous row's). None when the trace
    lacks the columns (e.g. a synthetic trace)."""
    if not col.endswith(".dc.offset"):
        return None
    ax = col[:-len(".dc.offset")]
    state_col, td_col = f"{ax}.dc.state", f"{ax}.dc.target_deviation"
    if state_col not in trace or td_col not in trace:
        return None
    state = np.asarray(trace[state_col])
    td = np.asarray(trace[td_col], dtype=np.float64)
    o = np.asarray(trace[col], dtype=np.float64)
    o_prev = np.concatenate((o[:1], o[:-1]))   # the row holds the offset after this cycle's update
    return np.where(state == 4, -td, np.where(state == 1, td - o_prev, np.nan))


def measure(result: Any, t_step: float, step_mm: float, *, ramp_mm_s: float = 0.0, column: str | None = None,
            band: float = BAND) -> StepMetrics:
    """Step-response metrics (:class:`StepMetrics`) of a run (``RunResult``) or a :class:`Trace`.

    The response is the offset column (default: the first ``<axis>.dc.offset``) relative to its value
    just before ``t_step`` (the mean of up to 10 samples before it); the reference is ``step_mm``
    (plus ``ramp_mm_s`` times the time since the step). ``band`` is the settling band as a fraction of
    the step (0.02 = +-2 %).
    """
    trace = _trace_of(result)
    col = _offset_column(trace, column)
    step_mm = _number("step", step_mm, nonzero=True, allowed="a step != 0 in mm")
    t_step = _number("t_step", t_step, allowed="the time of the step in s")
    band = _number("band", band, lo=0.0, lo_open=True, hi=1.0, allowed="0 < band <= 1 (fraction of the step)")
    t = np.asarray(trace.t, dtype=np.float64)
    y_all = np.asarray(trace[col], dtype=np.float64)
    if t.size < 3:
        raise StepError(f"measure: the trace has {t.size} samples; allowed: a trace covering the step")
    T = float(np.median(np.diff(t)))
    pre = t < t_step - 0.5 * T
    n_pre = int(np.count_nonzero(pre))
    if n_pre == 0 or t.size - n_pre < 2:
        raise StepError(f"measure: t_step = {t_step:g} s is outside the trace ({t[0]:g} .. {t[-1]:g} s); "
                        f"allowed: a time with samples before and after it")
    # the quiet time before the step: its second half, at most 0.5 s
    k_quiet = max(n_pre // 2, n_pre - int(round(0.5 / T))) if T > 0 else n_pre // 2
    quiet = y_all[k_quiet:n_pre]
    quiet = quiet[np.isfinite(quiet)]
    noise_mm = float(np.std(quiet)) if quiet.size >= 10 else 0.0
    if noise_mm > 1e-4 * abs(step_mm) and quiet.size >= 10:
        # a noisy offset: the mean of the quiet time (the last samples alone carry the noise)
        baseline = float(np.mean(quiet[-min(quiet.size, int(round(0.1 / T)) if T > 0 else 100):]))
    else:
        baseline = float(np.mean(y_all[max(0, n_pre - 10):n_pre]))
    # the band widens to the offset's noise, unless the limiter already acted before the step (a loop
    # that oscillates on its own is not noise: its swing must not count as settled)
    pre_limited = _limited_share(trace, col, k_quiet, None, T, stop=n_pre)
    if pre_limited is not None and pre_limited > 0.01:
        noise_mm = 0.0
    band_mm = max(band * abs(step_mm), NOISE_SIGMAS * noise_mm)
    # a swing counts beyond half the band on the other side, or beyond the noise band (noise alone
    # does not get there)
    hysteresis = max(band * abs(step_mm) / 2.0, NOISE_SIGMAS * noise_mm) / abs(step_mm)
    band = band_mm / abs(step_mm)
    tt = t[n_pre:] - t_step
    yn = (y_all[n_pre:] - baseline) / step_mm
    rn = 1.0 + ramp_mm_s * tt / step_mm
    err = yn - rn
    finite = np.isfinite(err)
    if not finite.all():  # a run that failed (NaN offsets are never written, but be safe)
        err = np.where(finite, err, np.inf)
        yn = np.where(finite, yn, 0.0)

    t10, t90 = _first_crossing(tt, yn, 0.1), _first_crossing(tt, yn, 0.9)
    rise = t90 - t10 if t10 is not None and t90 is not None else None

    peak = float(np.max(err))
    overshoot = peak if peak > 0 and math.isfinite(peak) else 0.0
    peak_time = float(tt[int(np.argmax(err))]) if overshoot > 0 else None

    n_final = max(1, err.size // 10)
    outside = np.flatnonzero(~(np.abs(err) <= band))
    if outside.size == 0:
        settling: float | None = 0.0
    elif outside[-1] >= err.size - n_final:   # must stay inside for (at least) the final 10 %
        settling = None
    else:
        k = int(outside[-1])
        e0, e1 = abs(float(err[k])), abs(float(err[k + 1]))
        frac = (e0 - band) / (e0 - e1) if math.isfinite(e0) and e0 != e1 else 1.0
        settling = float(tt[k] + min(max(frac, 0.0), 1.0) * (tt[k + 1] - tt[k]))

    sse = -float(np.mean(err[-n_final:])) * abs(step_mm)
    e_ctrl = _control_error(trace, col)
    if e_ctrl is not None:
        tail = e_ctrl[-n_final:]
        if np.isfinite(tail).all():
            sse = float(np.mean(tail)) * (1.0 if step_mm > 0 else -1.0)

    signs = np.sign(err[np.abs(err) > hysteresis])
    above = np.flatnonzero(signs > 0)
    oscillation = int(np.count_nonzero(signs[above[0] + 1:] != signs[above[0]:-1])) if above.size else 0

    limited = _limited_share(trace, col, n_pre, settling, T)
    return StepMetrics(step_mm=step_mm, rise_time_s=rise, overshoot_mm=overshoot * abs(step_mm),
                       overshoot_pct=overshoot * 100.0, settling_time_s=settling, steady_state_error_mm=sse,
                       oscillation=oscillation, peak_time_s=peak_time, band_mm=band_mm, limited_share=limited)


def _limited_share(trace: "Trace", col: str, n_pre: int, settling: float | None, T: float,
                   stop: int | None = None) -> float | None:
    """Share of the transient's cycles (from the step to the settling time, or to the end of the run)
    in which the limiter changed the PID's step: ``|u - v·T| > max(1 nm, 0.1 % of |u|)`` with ``u`` =
    ``<axis>.dc.pre_limiter`` (DIST_CTRL::delta_deviation_pre_limiter) and ``v·T`` =
    ``<axis>.dc.sloped_delta`` (DIST_CTRL_IFC::sloped_delta_deviation). None without those columns."""
    if not col.endswith(".dc.offset"):
        return None
    ax = col[:-len(".dc.offset")]
    u_col, v_col = f"{ax}.dc.pre_limiter", f"{ax}.dc.sloped_delta"
    if u_col not in trace or v_col not in trace:
        return None
    u = np.asarray(trace[u_col], dtype=np.float64)[n_pre:stop]
    vt = np.asarray(trace[v_col], dtype=np.float64)[n_pre:stop]
    if settling is not None:
        n = max(1, int(math.ceil(settling / T - 1e-9)) + 1) if T > 0 else u.size
        u, vt = u[:n], vt[:n]
    if u.size == 0:
        return None
    with np.errstate(invalid="ignore"):
        clipped = np.abs(u - vt) > np.maximum(1e-6, 1e-3 * np.abs(u))
    return float(np.count_nonzero(clipped)) / u.size


# ------------------------------------------------------------------------------------------------------
# running a sweep
# ------------------------------------------------------------------------------------------------------
class StepResult(NamedTuple):
    """One setting's run: unpacks as ``(setting, metrics, trace)``. ``trace.meta`` holds ``step``
    (t_step, step_mm, ramp_mm_s, mode, column), ``errors`` and ``warnings`` of the run."""

    setting: StepSetting
    metrics: StepMetrics
    trace: "Trace"

    def to_dict(self) -> dict:
        """This setting's row of ``distctrl step --json``: its words, metrics (s, mm, %), class,
        limiter reach, errors and warnings."""
        info = self.trace.meta.get("step", {})
        s = self.setting
        return {"setting": {"kp": s.kp, "i_tn_s": s.i_tn, "d_tv_s": s.d_tv, "label": s.label, "kind": s.kind},
                "metrics": self.metrics.to_dict(), "class": _classify(self.metrics),
                "limiter": {"v_max_mm_s": info.get("v_max"), "a_max_mm_s2": info.get("a_max"),
                            "linear_step_mm": info.get("linear_step_mm")},
                "errors": list(_errors_of(self)),
                "warnings": list(self.trace.meta.get("warnings") or []) if hasattr(self.trace, "meta") else []}

    def plot(self, path: str | os.PathLike | None = None, title: str | None = None) -> "Figure":
        """The offset response (:func:`plot_steps` of this one result); saved too with ``path``."""
        return plot_steps([self], path, title)

    def to_csv(self, path: str | os.PathLike) -> None:
        """The run's trace as CSV with its ``.meta.json`` sidecar (units, meta) (:meth:`distctrl.trace.Trace.to_csv`)."""
        self.trace.to_csv(path)


class _Bar:
    """A rich progress bar over the settings, on a terminal only."""

    def __init__(self, total: int, enabled: bool | None):
        self.bar = None
        if enabled is None:
            enabled = sys.stderr.isatty()
        if enabled and total > 0:
            from rich.console import Console
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

            self.bar = Progress(TextColumn("step responses"), BarColumn(), MofNCompleteColumn(),
                                TextColumn("{task.fields[label]}"), TimeElapsedColumn(), transient=True,
                                console=Console(stderr=True))
            self.bar.start()
            self.task = self.bar.add_task("step", total=total, label="")

    def update(self, done: int, label: str) -> None:
        if self.bar is not None:
            self.bar.update(self.task, completed=done, label=label)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.stop()


def _limits(params, setting: StepSetting, cycle_time: float) -> dict[str, float]:
    """The limiter's reach for ``setting`` on an axis with ``params`` (mm, s): ``v_max`` (P-AXIS-00415),
    ``a_max`` (P-AXIS-00416, or the axis acceleration when 0; a_min with adaptive acceleration, the
    lowering weights applied when smaller) and ``linear_step_mm``: the largest step whose first cycle
    the PID answers inside them (the wanted step ``k·step`` with ``k = KP (1 + T/T_n) + g_D`` within
    ``v_max·T``, ``a_max·T²`` and the braking bound ``sqrt(2 a_max e)``)."""
    ctrl = AxisDistanceController(params.replace(kp=setting.kp, i_tn=setting.i_tn, d_tv=setting.d_tv),
                                  cycle_time)
    c = ctrl.law_constants()
    T = float(c["T"])
    v = float(c["v_max"]) * min(1.0, float(c["w_v"]))
    a = float(c["a_base"]) * min(1.0, float(c["w_a"]))
    if params.use_adaptive_acceleration:
        a = min(a, float(params.a_min)) if params.a_min > 0 else a
    k = setting.kp * (1.0 + float(c["i_gain"])) + float(c["d_gain"])
    linear = min(v * T / k, a * T * T / k, 2.0 * a * T * T / (k * k)) if k > 0 and a > 0 and v > 0 else math.inf
    return {"v_max": v, "a_max": a, "linear_step_mm": linear}


def _axis_data(base: "Scenario | None") -> tuple[Any, float, dict[str, Any]]:
    """(parameter list, cycle time, sensor dict) of the axis a step runs on."""
    if base is None:
        return (parse_list_text(DEFAULT_AXIS_LIST, "<distctrl step default Z axis>").params, 0.001,
                dict(DEFAULT_SENSOR, axis="Z"))
    axis = _step_axis(base)
    return base.axes[axis].params, base.cycle_time, _sensor_dict(base, axis)


def auto_step(settings: Iterable[StepSetting], base: "Scenario | str | os.PathLike | None" = None
              ) -> tuple[float, str]:
    """The default step of ``distctrl step`` (``--step auto``): ``(step_mm, reason)``.

    The largest step that keeps the first cycle of every setting within :data:`AUTO_MARGIN` of the
    limiter's reach (:func:`_limits`: P-AXIS-00415 v_max, P-AXIS-00416 a_max), at most
    :data:`AUTO_MAX_MM`, rounded down to 2 significant digits; but not smaller than
    :data:`AUTO_NOISE_FLOOR` times the sensor's noise (a step drowned in noise measures the noise).
    When the noise floor wins, the limiter may still decide the largest KPs; :func:`measure` says so.
    """

    settings = list(settings)
    if not settings:
        raise StepSettingError("no settings; allowed: at least one StepSetting (see parse_settings)")
    if base is not None and not isinstance(base, Scenario):
        base = load_scenario(base)
    params, T, sensor = _axis_data(base)
    linear = min(_limits(params, s, T)["linear_step_mm"] for s in settings)
    want = min(AUTO_MAX_MM, AUTO_MARGIN * linear)
    want = _round_down(want)
    floor = _round_up(AUTO_NOISE_FLOOR * float(sensor.get("noise_std") or 0.0))
    if floor > want:
        return floor, (f"auto: {AUTO_NOISE_FLOOR:g} x the sensor noise ({sensor.get('noise_std'):g} mm); "
                       f"{want:g} mm would keep every setting inside P-AXIS-00415/00416")
    if want >= AUTO_MAX_MM:
        return want, "auto: every setting stays inside P-AXIS-00415/00416"
    return want, "auto: the largest KP's first cycle stays inside P-AXIS-00415/00416"


def _round_down(x: float) -> float:
    """Down to 2 significant digits (0.0266 -> 0.026)."""
    if not (x > 0 and math.isfinite(x)):
        return x
    e = math.floor(math.log10(x)) - 1
    return math.floor(x / 10 ** e + 1e-9) * 10 ** e if e < 0 else float(math.floor(x / 10 ** e) * 10 ** e)


def _round_up(x: float) -> float:
    if not (x > 0 and math.isfinite(x)):
        return 0.0
    e = math.floor(math.log10(x)) - 1
    return round(math.ceil(x / 10 ** e - 1e-9) * 10 ** e, 12)


def run_steps(settings: Iterable[StepSetting], base: "Scenario | str | os.PathLike | None" = None, *,
              step_mm: "float | str" = 1.0, mode: str = "CONST_DIST", t_step: float = 0.5, duration: float = 2.0,
              set_dist: float = 1.0, ramp_mm_s: float = 0.0,
              progress: bool | None = None) -> list[StepResult]:
    """Run the step response of every setting (same machine, same step) and measure it.

    ``step_mm="auto"``: the step of :func:`auto_step`. All scenarios are built (and validated) before
    the first run, so bad input fails at once. ``progress``: a rich progress bar on stderr; ``None``
    (default) shows it when stderr is a terminal. ``trace.meta["step"]`` also holds the limiter's
    reach for the setting (``v_max``, ``a_max``, ``linear_step_mm``, see :func:`_limits`) and, with
    ``auto``, the reason for the step (``auto``).
    """

    settings = list(settings)
    if not settings:
        raise StepSettingError("no settings; allowed: at least one StepSetting (see parse_settings)")
    if base is not None and not isinstance(base, Scenario):
        base = load_scenario(base)
    auto = None
    if isinstance(step_mm, str):
        if step_mm.strip().lower() != "auto":
            raise StepError(f"step = {step_mm!r}; allowed: a step != 0 in mm, or 'auto'")
        step_mm, auto = auto_step(settings, base)
    scenarios = [step_scenario(base, s, step_mm, mode, t_step, duration, set_dist=set_dist,
                               ramp_mm_s=ramp_mm_s) for s in settings]
    params, T, _ = _axis_data(base)
    out: list[StepResult] = []
    bar = _Bar(len(settings), progress)
    try:
        for n, (setting, sc) in enumerate(zip(settings, scenarios)):
            bar.update(n, setting.label)
            res = run(sc)
            trace = res.trace
            col = _offset_column(trace, None)
            info = {"t_step": float(t_step), "step_mm": float(step_mm), "ramp_mm_s": float(ramp_mm_s),
                    "mode": mode.upper(), "column": col, "setting": setting.label, **_limits(params, setting, T)}
            if auto is not None:
                info["auto"] = auto
            trace.meta.update({"step": info, "errors": list(res.errors), "warnings": list(res.warnings)})
            out.append(StepResult(setting, measure(trace, t_step, step_mm, ramp_mm_s=ramp_mm_s, column=col),
                                  trace))
        bar.update(len(settings), "")
    finally:
        bar.close()
    return out


# ------------------------------------------------------------------------------------------------------
# presentation
# ------------------------------------------------------------------------------------------------------
TABLE_COLUMNS = ("setting", "rise 10-90 % [ms]", "overshoot [%]", "overshoot [mm]", "settling [ms]",
                 "band ± [mm]", "steady-state error [mm]", "oscillation", "at limiter [%]")
#: the limiter's parameters, as the hints name them
LIMITER_IDS = "P-AXIS-00415/00416"


def _ms(v: float | None, missing: str = "-") -> str:
    return missing if v is None or not math.isfinite(v) else f"{v * 1e3:.1f}"


def _errors_of(r: StepResult) -> list:
    return (r.trace.meta.get("errors") if hasattr(r.trace, "meta") else None) or []


def _row(r: StepResult) -> tuple[str, ...]:
    m = r.metrics
    errors = _errors_of(r)
    label = r.setting.label + (" (error " + ", ".join(str(e["id"]) for e in errors) + ")" if errors else "")
    share = "-" if m.limited_share is None else f"{m.limited_share * 100:.0f}" + (" !" if m.limiter_bound else "")
    return (label, _ms(m.rise_time_s), f"{m.overshoot_pct:.1f}", f"{m.overshoot_mm:.4f}",
            _ms(m.settling_time_s, "not settled"), f"{m.band:.4f}", _signed(m.steady_state_error_mm),
            str(m.oscillation), share)


def _signed(v: float) -> str:
    """``+0.0250``; values that round to zero print as ``+0.0000`` (no ``-0.0000``)."""
    return f"{0.0 if abs(v) < 5e-5 else v:+.4f}"


def format_table(results: Sequence[StepResult], title: str | None = None, plain: bool = False) -> str:
    """The metrics of every setting as a text table (rich, no colour; ``plain=True``: fixed-width ASCII).
    ``at limiter [%]``: :attr:`StepMetrics.limited_share`, marked ``!`` when the response is limiter-bound."""
    rows = [_row(r) for r in results]
    return render_table(TABLE_COLUMNS, rows, title, plain)


def _decay_text(m: StepMetrics) -> str:
    if m.oscillation == 0:
        return "decaying without a further swing"
    return f"decaying in {m.periods} period{'s' if m.periods != 1 else ''}"


def _classify(m: StepMetrics) -> str:
    """``oscillating`` (more than 2 periods after the first peak, settled or not), ``deviation`` (a
    steady-state error beyond the band), ``slow`` (not settled, without those), ``damped`` (no
    recognisable overshoot), ``large`` (overshoot above 40 %) or ``good`` (a recognisable overshoot
    up to 40 %, rapidly decaying)."""
    if m.oscillation > RAPID_CROSSINGS:
        return "oscillating"
    if abs(m.steady_state_error_mm) > m.band:
        return "deviation"
    if not m.settled:
        return "slow"
    if m.overshoot_pct < RECOGNISABLE_PCT:
        return "damped"
    if m.overshoot_pct > LARGE_PCT:
        return "large"
    return "good"


def _overshoot_text(m: StepMetrics) -> str:
    if m.overshoot_pct < RECOGNISABLE_PCT:
        return f"no recognisable overshoot ({m.overshoot_pct:.1f} %), rise time {_ms(m.rise_time_s)} ms"
    return f"overshoot {m.overshoot_pct:.0f} % {_decay_text(m)}"


def _linear_step(r: StepResult) -> float | None:
    v = r.trace.meta.get("step", {}).get("linear_step_mm") if hasattr(r.trace, "meta") else None
    return float(v) if v is not None and math.isfinite(float(v)) else None


def _step_advice(results: Sequence[StepResult]) -> str:
    """``--step 0.013`` (half the smallest linear step of the given results) or a generic advice."""
    lin = [x for x in (_linear_step(r) for r in results) if x is not None]
    if not lin:
        return "a smaller --step"
    return f"a smaller --step (at most about {_round_down(AUTO_MARGIN * min(lin)):g} mm)"


def suggested_kp(results: Sequence[StepResult]) -> StepResult | None:
    """The setting the summary suggests: the largest P-only KP whose response is "recognisable but
    rapidly decaying", settled, ran without an error and was not limiter-bound; None if there is none."""
    good = [r for r in results if r.setting.kind == "P" and not _errors_of(r) and not r.metrics.limiter_bound
            and r.metrics.settled and _classify(r.metrics) == "good"]
    return max(good, key=lambda r: r.setting.kp) if good else None


#: from this KP on the D part has no room and no effect (docs/control-law.md, "The D part":
#: kp + g < 1 with g_max = 0.3·(1 − kp); :func:`distctrl.control.law.derivative_gain` is 0 there)
D_NO_EFFECT_KP = 1.0
_NO_D = "D_TV has no effect at KP >= 1 (KP already takes the whole error in one cycle)"


def _remedy(s: StepSetting) -> str:
    """What to change for too much overshoot / oscillation: KP, and the D part only where it acts."""
    if s.kp >= D_NO_EFFECT_KP:
        return "lower KP" + (f"; {_NO_D}" if s.d_tv > 0 else "")
    return "lower KP or D_TV" if s.d_tv > 0 else "lower KP or add D (method step 4)"


def hints(results: Sequence[StepResult]) -> list[str]:
    """Short factual hints along the documents' method (FCT-M3 ch. 3), one per setting plus a summary.

    Step 1 (P only): a setting without a recognisable overshoot (< 2 %) is slow but safe (raise KP);
    one with a recognisable overshoot (2 ... 40 %) that decays within 2 periods is what the method
    looks for; a larger overshoot, more swings or no settling: lower KP or add D. Step 2 (I): only
    for a permanent control deviation. Step 4 (D): the overshoot with and without D_TV at the same
    KP / I_TN is compared (below KP 1 only: from KP 1 on the D part has no effect, and no hint offers
    D_TV there). A response the slope limiter decided (:attr:`StepMetrics.limiter_bound`)
    says so and is never called good nor suggested: it shows the limiter, not KP.
    """
    out: list[str] = []
    for r in results:
        s, m = r.setting, r.metrics
        errors = _errors_of(r)
        head = f"{s.label}: "
        if errors:
            ids = ", ".join(str(e["id"]) for e in errors)
            out.append(head + f"the run stopped with error {ids} — the loop is unstable or a limit was hit: "
                              f"lower KP")
            continue
        kind = _classify(m)
        limited = ""
        if m.limiter_bound:
            limited = (f"response limited by {LIMITER_IDS} (the limiter changed the PID's step in "
                       f"{m.limited_share * 100:.0f} % of the cycles")
            limited += " until it settled)" if m.settled else " after the step)"
        if m.limiter_bound and kind in ("good", "damped", "large", "slow"):
            # the shape is the limiter's: KP cannot be judged from it
            lin = _linear_step(r)
            if lin is not None and abs(m.step_mm) <= lin:
                # the step's first cycle was inside the limiter: something else drove the offset there
                out.append(head + f"{_overshoot_text(m)} — {limited}, although the step's first cycle was inside "
                                  f"it: the ramp, the I part or the loop's own swing drove the offset to the limit; "
                                  f"not a setting to judge by this response")
            else:
                out.append(head + f"{_overshoot_text(m)} — {limited} — use {_step_advice([r])} to see KP's own "
                                  f"response")
            continue
        if kind == "oscillating":
            remedy = _remedy(s)
            state = (f"not settled within ±{m.band:.4g} mm by the end of the run" if not m.settled
                     else f"settled after {_ms(m.settling_time_s)} ms")
            text = (f"overshoot {m.overshoot_pct:.0f} %, {m.oscillation} zero crossings after the first "
                    f"peak, {state} — more oscillation than 'rapidly decaying': {remedy}")
            if m.limiter_bound:
                text += f"; {limited}: its amplitude is the limiter's"
        elif kind == "deviation":
            text = (f"{_overshoot_text(m)}; steady-state error {m.steady_state_error_mm:+.4f} mm — a "
                    f"permanent control deviation: " + ("add I (T_n from 5 s, then reduce it; method step 2)"
                                              if s.i_tn == 0 else "reduce I_TN"))
            if m.limiter_bound:
                text += f"; {limited}"
        elif kind == "slow":
            text = (f"{_overshoot_text(m)}; not settled within ±{m.band:.4g} mm by the end of the run "
                    f"without oscillating: a slow approach (a longer run shows more)")
        elif kind == "large":
            remedy = _remedy(s)
            text = f"{_overshoot_text(m)} — a large overshoot (above {LARGE_PCT:.0f} %): {remedy}"
        elif kind == "damped":
            text = (f"{_overshoot_text(m)} — well damped"
                    + (": KP may be raised (method step 1)" if s.kind == "P" else ""))
        else:
            text = (f"{_overshoot_text(m)} — recognisable but rapidly decaying"
                    + (": a good P setting" if s.kind == "P" else ""))
        out.append(head + text)
    # D: the same KP and I_TN with and without D_TV
    by_pi: dict[tuple[float, float], list[StepResult]] = {}
    for r in results:
        by_pi.setdefault((r.setting.kp, r.setting.i_tn), []).append(r)
    for (kp, tn), group in by_pi.items():
        without = [r for r in group if r.setting.d_tv == 0]
        if not without:
            continue
        m0 = without[0].metrics
        for r in group:
            if r.setting.d_tv == 0:
                continue
            if kp >= D_NO_EFFECT_KP:
                out.append(f"KP={kp:g} I_TN={tn:g}: D_TV={r.setting.d_tv:g}: {_NO_D}; the response is that "
                           f"of D_TV=0")
                continue
            if m0.overshoot_pct < RECOGNISABLE_PCT:
                continue
            m1 = r.metrics
            if m0.limiter_bound and m1.limiter_bound:
                out.append(f"KP={kp:g} I_TN={tn:g}: D_TV={r.setting.d_tv:g} cannot be judged: the limiter "
                           f"({LIMITER_IDS}) decided both responses")
                continue
            verb = "reduces" if m1.overshoot_pct < m0.overshoot_pct else "does not reduce"
            settle = "" if m1.settled or not m0.settled else "; and it no longer settles: lower D_TV"
            out.append(f"KP={kp:g} I_TN={tn:g}: D_TV={r.setting.d_tv:g} {verb} the overshoot "
                       f"({m0.overshoot_pct:.0f} % -> {m1.overshoot_pct:.0f} %, oscillation "
                       f"{m0.oscillation} -> {m1.oscillation} zero crossings){settle}")
    # summary for the P part: the largest KP with a recognisable but rapidly decaying overshoot, never one
    # the limiter decided or one that did not settle
    p_only = [r for r in results if r.setting.kind == "P" and not _errors_of(r)]
    # limiter-bound and not oscillating: the limiter shaped the response, KP cannot be judged from it (an
    # oscillating one is judged: it oscillates, whatever bounds its swing)
    undecided = [r for r in p_only if r.metrics.limiter_bound and _classify(r.metrics) != "oscillating"]
    free = [r for r in p_only if r not in undecided]
    best = suggested_kp(results)
    if best is not None:
        out.append(f"suggested P setting: KP={best.setting.kp:g} (the largest tested KP whose overshoot is "
                   f"recognisable but rapidly decaying, not decided by the limiter)")
    elif p_only and not free:
        out.append(f"the limiter ({LIMITER_IDS}) decided every P response: no KP can be judged from this step; "
                   f"use {_step_advice(undecided)}")
    elif free and not undecided and all(_classify(r.metrics) == "damped" for r in free):
        top = max(r.setting.kp for r in free)
        out.append(f"no tested KP overshoots recognisably: try KP above {top:g}")
    elif free and not undecided and all(_classify(r.metrics) == "oscillating" for r in free):
        out.append(f"every tested KP oscillates too much: try KP below {min(r.setting.kp for r in free):g}")
    if undecided and free:
        names = ", ".join(f"KP={r.setting.kp:g}" for r in undecided)
        out.append(f"not judged (the limiter, {LIMITER_IDS}, decided the response): {names}; use "
                   f"{_step_advice(undecided)} for them")
    return out


def results_json(results: Sequence[StepResult]) -> dict:
    """The results as one JSON-able object (``distctrl step --json``): the step, per setting its
    words, metrics (s, mm, %), class, limiter share and errors, the hints and the suggested KP."""
    info0 = results[0].trace.meta.get("step", {}) if results else {}
    best = suggested_kp(results)
    rows = [r.to_dict() for r in results]
    return {"step_mm": info0.get("step_mm"), "step_auto": info0.get("auto"), "mode": info0.get("mode"),
            "t_step_s": info0.get("t_step"), "ramp_mm_s": info0.get("ramp_mm_s"),
            "limited_share_threshold": LIMITED_SHARE, "results": rows, "hints": hints(results),
            "suggested_kp": best.setting.kp if best is not None else None}




#: the step plot's time axis: this many times the slowest settling time of the responses that settle ...
SETTLE_VIEW = 4.0
#: ... but at least this long (s)
MIN_VIEW_S = 0.02


def check_plot_path(path: str | os.PathLike) -> Path:
    return check_plot_suffix(path, StepError)


def plot_steps(results: Sequence[StepResult], path: str | os.PathLike | None = None,
               title: str | None = None) -> "Figure":
    """The offset responses overlaid: x ``t − t_step [s]``, y ``offset response [mm]``, one line per
    setting (labelled ``KP=.. I_TN=.. D_TV=..``), the step level (plus ramp) and the ±2 % band dashed.

    Returns the Figure (Agg canvas, no pyplot); with ``path`` it is saved too, the format by suffix
    (.png, .svg, .pdf).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure


    if not results:
        raise StepError("plot_steps: no results; allowed: the list run_steps returns")
    if path is not None:
        path = check_plot_path(path)
    info0 = results[0].trace.meta.get("step", {})
    step_mm = float(info0.get("step_mm", results[0].metrics.step_mm))
    ramp = float(info0.get("ramp_mm_s", 0.0))
    curves, t_end = [], 0.0
    for n, r in enumerate(results):
        info = r.trace.meta.get("step", {})
        t_step = float(info.get("t_step", 0.0))
        col = info.get("column") or _offset_column(r.trace, None)
        t = np.asarray(r.trace.t, dtype=np.float64)
        y = np.asarray(r.trace[col], dtype=np.float64)
        T = float(np.median(np.diff(t))) if t.size > 1 else 0.001
        pre = int(np.count_nonzero(t < t_step - 0.5 * T))
        baseline = float(np.mean(y[max(0, pre - 10):pre])) if pre else float(y[0])
        x = t - t_step
        keep = x >= -min(0.05, t_step)
        settles = r.metrics.settled
        label = r.setting.label + ("" if settles else " (does not settle)")
        curves.append((n, x[keep], y[keep] - baseline, label, settles, r.metrics.settling_time_s))
        t_end = max(t_end, float(x[-1]))
    # the time axis from the responses that settle (audit R1: a limit cycle drawn over the whole run hid
    # responses that settle in milliseconds): SETTLE_VIEW x the slowest settling time; a response that
    # does not settle says so in the legend, and a second panel shows the whole run
    settling = [c[5] for c in curves if c[4] and c[5] is not None]
    zoom = bool(settling) and len(settling) < len(curves)
    t_view = min(t_end, max(SETTLE_VIEW * max(settling), MIN_VIEW_S)) if settling else t_end
    if zoom and t_view < 0.5 * t_end:
        fig = Figure(figsize=(10.0, 7.6), layout="constrained")
        FigureCanvasAgg(fig)
        ax, whole = fig.subplots(2, 1, height_ratios=(3, 1.3))
    else:
        fig = Figure(figsize=(10.0, 5.6), layout="constrained")
        FigureCanvasAgg(fig)
        ax, whole = fig.subplots(1, 1), None
        t_view = t_end if not settling else t_view
    for panel, t_hi in ((ax, t_view), (whole, t_end)):
        if panel is None:
            continue
        for n, x, y, label, settles, _ in curves:
            sel = x <= t_hi + 1e-12
            xs, ys = envelope(x[sel], y[sel], MAX_POINTS)
            panel.plot(xs, ys, color=f"C{n % 10}", linewidth=1.2 if settles else 0.8,
                       linestyle="-" if settles else ":", label=label if panel is ax else "_nolegend_")
        xr = np.array([0.0, t_hi])
        ref = step_mm + ramp * xr
        band = BAND * abs(step_mm)
        main = panel is ax
        panel.plot([-0.05, 0.0, 0.0], [0.0, 0.0, step_mm], color="0.25", linestyle="--", linewidth=0.9,
                   label="_nolegend_")
        panel.plot(xr, ref, color="0.25", linestyle="--", linewidth=0.9,
                   label=(f"step {step_mm:g} mm" + (f" + ramp {ramp:g} mm/s" if ramp else "")) if main
                   else "_nolegend_")
        panel.plot(xr, ref + band, color="0.55", linestyle="--", linewidth=0.7,
                   label=f"±{BAND * 100:.0f} % band" if main else "_nolegend_")
        panel.plot(xr, ref - band, color="0.55", linestyle="--", linewidth=0.7, label="_nolegend_")
        panel.set_xlim(-min(0.05, 0.25 * t_hi), t_hi)
        panel.grid(True, alpha=0.4)
        panel.set_ylabel("offset response [mm]")
    ax.set_xlabel("t − t_step [s]")
    ax.legend(loc="best", fontsize="small")
    if whole is not None:
        ax.set_title(f"the first {t_view * 1e3:.0f} ms ({SETTLE_VIEW:g} x the slowest settling time)",
                     fontsize="medium")
        whole.set_title("the whole run: dotted = does not settle", fontsize="medium")
        whole.set_xlabel("t − t_step [s]")
    mode = info0.get("mode")
    fig.suptitle(title if title is not None else
                 f"Distance-control step response ({mode + ', ' if mode else ''}step {step_mm:g} mm)")
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
    return fig
