"""The step experiment's inputs: the documented ranges, the errors, the controller settings
(:class:`StepSetting`, :func:`parse_settings`) and the scenario of one run (:func:`step_scenario`).

Part of :mod:`distctrl.workbench.step` (docs/workbench-step.md); the package face re-exports every name.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
import os
from dataclasses import dataclass
from typing import Any

from ...errors import DistCtrlError
from ...params.listfile import parse_list_text
from ...sim.scenario import Scenario, load_scenario, scenario_from_dict

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


def _step_axis_setup(base: "Scenario | None") -> tuple:
    """``(axis, params, params_file, axis_cfg, sensor, cycle_time, seed, variables, source)`` of the axis a
    step runs on: the default Z axis without ``base``, else ``base``'s sensor axis (or Z) with its list,
    drive data and sensor."""
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
    return axis, params, params_file, axis_cfg, sensor, cycle_time, seed, variables, source


def _program(axis: str, setting: StepSetting, sensor: dict, mode_u: str, step_mm: float, t_step: float,
             duration: float, set_dist: float, ramp_mm_s: float) -> tuple[str, list[dict]]:
    """The NC program (select with the setting's words, dwell, end) and the sensor faults of the step."""
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
    return program, events


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

    base = load_scenario(base) if base is not None and not isinstance(base, Scenario) else base
    axis, params, params_file, axis_cfg, sensor, cycle_time, seed, variables, source = _step_axis_setup(base)

    step_mm = _number("step", step_mm, nonzero=True, allowed="a step != 0 in mm (> 0: the surface rises)")
    _check_travel(sensor, params, set_dist, step_mm, ramp_mm_s * (duration - t_step))
    jump_rate = abs(step_mm) / cycle_time
    if jump_rate > params.max_act_value_change:
        raise StepError(f"step = {step_mm:g} mm: the reading jumps by it in one cycle ({jump_rate:g} mm/s), "
                        f"more than the axis list's max_act_value_change (P-AXIS-00417) "
                        f"{params.max_act_value_change:g} mm/s allows (the run would stop with error 70329); "
                        f"allowed: |step| <= {params.max_act_value_change * cycle_time:.4g} mm, or raise "
                        f"P-AXIS-00417 in the list")

    program, events = _program(axis, setting, sensor, mode_u, step_mm, t_step, duration, set_dist, ramp_mm_s)
    data = {"name": f"step {setting.label}", "cycle_time": cycle_time, "program_text": program,
            "duration": duration, "settle_time": 0.0, "seed": seed, "variables": variables,
            "axes": {axis: dict(axis_cfg, start=set_dist)}, "surface": {"base": 0.0},
            "sensor": sensor, "events": events}
    sc = scenario_from_dict(data, base_dir=".", source=source)
    ax_cfg = dataclasses.replace(sc.axes[axis], params=params, params_file=params_file)
    return dataclasses.replace(sc, axes={axis: ax_cfg})


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
