"""``[[process]]`` tables of a scenario: validation, documented defaults, and the PLC program."""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from ...sim.config_errors import MISSING, ConfigError, require_int, require_mapping, require_number
from .auto_set_value import AUTO_DEFAULTS, AutoSetValue
from .base import require_bool
from .calibrate import CALIBRATE_DEFAULTS, Calibrate
from .collision_retract import COLLISION_DEFAULTS, MAX_RETRACT_ACCEL, MAX_RETRACT_SPEED, CollisionRetract
from .corner_lock import CORNER_DEFAULTS, CornerLock
from .lift import LIFT_DEFAULTS, Lift
from .program import ProcessProgram
from .touch_off import TOUCH_DEFAULTS, TouchOff
from .void_lock import (VOID_DEFAULTS, VOID_THRESHOLD_MM_S, VOID_THRESHOLD_V_S, VOID_WINDOW_DISTANCE_S,
                        VoidLock)

__all__ = ["ProcessConfig", "PROCESS_COMMON_KEYS", "PROCESS_FUNCTIONS", "PROCESS_KEYS", "process_configs",
           "make_process_program"]

#: the functions a [[process]] table may name, and their own keys (besides function and axis)
PROCESS_KEYS: dict[str, tuple[str, ...]] = {
    "corner_lock": ("share", "hysteresis"),
    "void_lock": ("variable", "threshold", "window", "on_cycles", "off_cycles", "release_band"),
    "auto_set_value": ("delay", "sample_time"),
    # capacitive calibration run (distctrl calibrate)
    "calibrate": ("speed", "bottom", "settle", "runs", "variable"),
    # --- touch-off (docs/process.md "Touch-off")
    "touch_off": ("variable", "request", "probe_speed", "detect", "pierce_height", "stroke", "retries",
                  "verify_time", "verify_band", "tolerance"),
    # --- collision retract (docs/process.md "Collision retract")
    "collision_retract": ("variable", "threshold", "short_circuit", "confirm_cycles", "retract", "retract_speed",
                          "retract_accel"),
    # --- lift (issue 16, h16-lift) ---
    "lift": ("height", "min_distance", "v_max", "a_max", "settle_time"),
}
PROCESS_FUNCTIONS = tuple(PROCESS_KEYS)
#: the keys every function has besides function and axis: ``enabled`` (bool, default true) switches it
#: on or off at start; ``distctrl serve`` switches it at run time (ADS ``Process.<axis>.<function>.enabled``)
PROCESS_COMMON_KEYS = ("enabled",)
_VAR_RE = re.compile(r"^(V\.E\.)?[A-Za-z_][A-Za-z0-9_]*$")


def _ve_key(value: object, key: str, allowed: str) -> str:
    """A V.E. variable name given in a [[process]] table, stored without the ``V.E.`` prefix; else
    :class:`ConfigError` naming ``key``."""
    if not isinstance(value, str) or not _VAR_RE.match(value):
        raise ConfigError(key, value, allowed)
    return value[4:] if value.startswith("V.E.") else value


@dataclass(frozen=True)
class ProcessConfig:
    """One validated ``[[process]]`` table: ``params`` holds every key of the function, defaults filled in."""

    function: str
    axis: str
    params: dict = field(default_factory=dict)
    index: int = 0
    enabled: bool = True

    def make(self, cycle_time: float):
        p = self.params
        if self.function == "corner_lock":
            return CornerLock(self.axis, p["share"], p["hysteresis"])
        if self.function == "void_lock":
            return VoidLock(self.axis, cycle_time, p["threshold"], variable=p["variable"], window=p["window"],
                            on_cycles=p["on_cycles"], off_cycles=p["off_cycles"], release_band=p["release_band"])
        if self.function == "calibrate":
            return Calibrate(self.axis, cycle_time, p["variable"], speed=p["speed"], bottom=p["bottom"],
                             settle=p["settle"], runs=p["runs"])
        if self.function == "touch_off":
            return TouchOff(self.axis, cycle_time, **p)
        if self.function == "collision_retract":
            return CollisionRetract(self.axis, cycle_time, **p)
        # --- lift (issue 16, h16-lift) ---
        if self.function == "lift":
            return Lift(self.axis, cycle_time, p["v_max"], p["a_max"], height=p["height"],
                        min_distance=p["min_distance"], settle_time=p["settle_time"])
        return AutoSetValue(self.axis, cycle_time, p["delay"], p["sample_time"])


def _function(value: object, key: str) -> str:
    allowed = "one of " + ", ".join(repr(f) for f in PROCESS_FUNCTIONS)
    if not isinstance(value, str) or value not in PROCESS_FUNCTIONS:
        raise ConfigError(key, value, allowed)
    return value


def _process(n: int, cfg: object, axes: dict, sensor, cycle_time: float, has_3d: bool) -> ProcessConfig:
    key = f"process[{n}]"
    if not isinstance(cfg, dict):
        raise ConfigError(key, cfg, "a table [[process]] with function, axis and the function's keys",
                          "not a table:")
    if "function" not in cfg:
        raise ConfigError(f"{key}.function", MISSING, "one of " + ", ".join(repr(f) for f in PROCESS_FUNCTIONS))
    fn = _function(cfg["function"], f"{key}.function")
    require_mapping(cfg, key, ("function", "axis") + PROCESS_COMMON_KEYS + PROCESS_KEYS[fn], required=("axis",))
    enabled = require_bool(cfg.get("enabled", True), f"{key}.enabled")
    if has_3d:
        raise ConfigError(f"{key}.axis", cfg["axis"], "an axis of the axis variant: the process functions do "
                          "not drive the channel's 3D distance control yet", "3D distance control:")
    axis = cfg["axis"]
    dc_axes = [a for a, ax in axes.items() if ax.params.enabled]
    if not isinstance(axis, str) or axis not in axes:
        raise ConfigError(f"{key}.axis", axis, "a configured axis with distance control: "
                          + (", ".join(dc_axes) or "none"))
    if axis not in dc_axes:
        raise ConfigError(f"{key}.axis", axis, "an axis whose parameter list switches distance control on "
                          "(P-AXIS-00328 lr_param.distance_control_on 1): " + (", ".join(dc_axes) or "none"),
                          "distance control is off on")
    k = f"{key}."
    if fn == "corner_lock":
        share = require_number(cfg.get("share", CORNER_DEFAULTS["share"]), k + "share", lo=0.0, hi=1.0,
                               lo_open=True)
        hyst = require_number(cfg.get("hysteresis", CORNER_DEFAULTS["hysteresis"]), k + "hysteresis", lo=0.0,
                              hi=min(0.5, 1.0 - share))
        params = {"share": share, "hysteresis": hyst}
    elif fn == "void_lock":
        voltage = sensor.voltage_variable if sensor is not None and sensor.kind == "arc_voltage" else None
        default_var = voltage or (sensor.variable if sensor is not None and sensor.kind == "distance" else None)
        var = cfg.get("variable", default_var)
        if var is not None:
            var = _ve_key(var, k + "variable", "a V.E. variable name (e.g. \"ARC_VOLTAGE\" or \"SENSOR\")")
        is_voltage = var is not None and var == voltage
        threshold = require_number(cfg.get("threshold", VOID_THRESHOLD_V_S if is_voltage else VOID_THRESHOLD_MM_S),
                                   k + "threshold", lo=0.0, lo_open=True)
        # a mains period on an arc voltage; on a distance (no ripple) a short window (issue 16's laser sheet)
        window = require_number(cfg.get("window", VOID_DEFAULTS["window"] if is_voltage
                                        else max(VOID_WINDOW_DISTANCE_S, cycle_time)),
                                k + "window", lo=cycle_time, hi=1.0)
        band = require_number(cfg.get("release_band", 0.5 * threshold * window), k + "release_band", lo=0.0,
                              lo_open=True)
        params = {"variable": var, "threshold": threshold, "window": window,
                  "on_cycles": require_int(cfg.get("on_cycles", VOID_DEFAULTS["on_cycles"]), k + "on_cycles",
                                           lo=1, hi=10000),
                  "off_cycles": require_int(cfg.get("off_cycles", VOID_DEFAULTS["off_cycles"]), k + "off_cycles",
                                            lo=1, hi=100000),
                  "release_band": band}
    elif fn == "calibrate":
        params = _calibrate_params(cfg, k, axis, sensor, cycle_time)
    elif fn == "touch_off":
        params = _touch_off(cfg, k, axes[axis], sensor, cycle_time)
    elif fn == "collision_retract":
        params = _collision_retract(cfg, k, axes[axis], sensor)
    # --- lift (issue 16, h16-lift) ---
    elif fn == "lift":
        ax = axes[axis]
        params = {"height": require_number(cfg.get("height", LIFT_DEFAULTS["height"]), k + "height", lo=0.0,
                                           hi=1000.0, lo_open=True),
                  "min_distance": require_number(cfg.get("min_distance", LIFT_DEFAULTS["min_distance"]),
                                                 k + "min_distance", lo=0.0, hi=1.0e6),
                  "v_max": require_number(cfg.get("v_max", ax.v_max), k + "v_max", lo=0.0, hi=ax.v_max,
                                          lo_open=True),
                  "a_max": require_number(cfg.get("a_max", ax.a_max), k + "a_max", lo=0.0, hi=ax.a_max,
                                          lo_open=True),
                  "settle_time": require_number(cfg.get("settle_time", LIFT_DEFAULTS["settle_time"]),
                                                k + "settle_time", lo=0.0, hi=1.0)}
    else:
        params = {"delay": require_number(cfg.get("delay", AUTO_DEFAULTS["delay"]), k + "delay", lo=0.0, hi=10.0),
                  "sample_time": require_number(cfg.get("sample_time", AUTO_DEFAULTS["sample_time"]),
                                                k + "sample_time", lo=cycle_time, hi=10.0)}
    return ProcessConfig(fn, axis, params, n, enabled)


def _calibrate_params(cfg: dict, k: str, axis: str, sensor, cycle_time: float) -> dict:
    """The calibration run's keys: it records a distance sensor's reading on the axis it measures."""
    if sensor is None or sensor.kind != "distance" or sensor.axis != axis:
        what = "no [sensor]" if sensor is None else f"a {sensor.kind!r} sensor on {sensor.axis}"
        raise ConfigError(k + "axis", axis, "the axis of a [sensor] with kind = 'distance' (the calibration run "
                          f"records a distance sensor's reading; the scenario has {what})", "no distance sensor on")
    default_var = sensor.output_variable          # the raw reading when a linearisation is in force
    var = _ve_key(cfg.get("variable", default_var), k + "variable",
                  "a V.E. variable name (default: the one the sensor writes)")
    d = CALIBRATE_DEFAULTS
    speed = require_number(cfg.get("speed", d["speed"]), k + "speed", lo=0.0, hi=20.0, lo_open=True)
    bottom = require_number(cfg.get("bottom", d["bottom"]), k + "bottom", lo=0.0, hi=sensor.range_max,
                            lo_open=True, hi_open=True)
    return {"speed": speed, "bottom": bottom,
            "settle": require_number(cfg.get("settle", d["settle"]), k + "settle", lo=cycle_time, hi=10.0),
            "runs": require_int(cfg.get("runs", d["runs"]), k + "runs", lo=1, hi=10), "variable": var}


def _signal_variable(cfg: dict, k: str, sensor) -> str | None:
    """The ``variable`` key of the motion functions: a V.E. distance in mm; default the sensor's
    distance variable (a distance sensor's, or the linearised one of an arc-voltage sensor); none for
    the probe on encoder 2 (``state_r.actual_distance``)."""
    default = sensor.variable if sensor is not None and sensor.kind in ("distance", "arc_voltage") else None
    var = cfg.get("variable", default)
    if var is None:
        return None
    return _ve_key(var, k + "variable", "a V.E. variable name holding the distance in mm (e.g. \"SENSOR\")")


def _touch_off(cfg: dict, k: str, axis_cfg, sensor, cycle_time: float) -> dict:
    d = TOUCH_DEFAULTS
    request = _ve_key(cfg.get("request", d["request"]), k + "request",
                      "a V.E. variable name (the NC handshake, e.g. \"TOUCH_OFF\")")
    max_dev = axis_cfg.params.max_deviation
    stroke = require_number(cfg.get("stroke", min(d["stroke"], 0.9 * max_dev)), k + "stroke", lo=0.0,
                            hi=max_dev, lo_open=True, hi_open=True)
    return {"variable": _signal_variable(cfg, k, sensor), "request": request,
            "probe_speed": require_number(cfg.get("probe_speed", d["probe_speed"]), k + "probe_speed", lo=0.001,
                                          hi=min(1000.0, axis_cfg.v_max)),
            "detect": require_number(cfg.get("detect", d["detect"]), k + "detect", lo=0.0, hi=100.0),
            "pierce_height": require_number(cfg.get("pierce_height", d["pierce_height"]), k + "pierce_height",
                                            lo=0.0, hi=100.0, lo_open=True),
            "stroke": stroke,
            "retries": require_int(cfg.get("retries", d["retries"]), k + "retries", lo=0, hi=10),
            "verify_time": require_number(cfg.get("verify_time", d["verify_time"]), k + "verify_time", lo=0.0,
                                          hi=1.0),
            "verify_band": require_number(cfg.get("verify_band", d["verify_band"]), k + "verify_band", lo=0.0,
                                          hi=100.0),
            "tolerance": require_number(cfg.get("tolerance", d["tolerance"]), k + "tolerance", lo=0.0, hi=10.0,
                                        lo_open=True)}


def _collision_retract(cfg: dict, k: str, axis_cfg, sensor) -> dict:
    d = COLLISION_DEFAULTS
    sc = cfg.get("short_circuit", d["short_circuit"])
    return {"variable": _signal_variable(cfg, k, sensor),
            "threshold": require_number(cfg.get("threshold", d["threshold"]), k + "threshold", lo=0.0, hi=100.0),
            "short_circuit": None if sc is None else require_number(sc, k + "short_circuit"),
            "confirm_cycles": require_int(cfg.get("confirm_cycles", d["confirm_cycles"]), k + "confirm_cycles",
                                          lo=1, hi=1000),
            "retract": require_number(cfg.get("retract", d["retract"]), k + "retract", lo=0.0, hi=1000.0,
                                      lo_open=True),
            # the retract runs at the axis's limits unless slower ones are given (and never beyond the
            # function's own bounds: an axis may be configured faster than any retract)
            "retract_speed": require_number(cfg.get("retract_speed", min(axis_cfg.v_max, MAX_RETRACT_SPEED)),
                                            k + "retract_speed", lo=0.001, hi=min(axis_cfg.v_max, MAX_RETRACT_SPEED)),
            "retract_accel": require_number(cfg.get("retract_accel", min(axis_cfg.a_max, MAX_RETRACT_ACCEL)),
                                            k + "retract_accel", lo=1.0, hi=min(axis_cfg.a_max, MAX_RETRACT_ACCEL))}


def process_configs(raw: object, axes: dict, sensor, cycle_time: float, has_3d: bool = False
                    ) -> tuple[ProcessConfig, ...]:
    """The validated ``[[process]]`` tables (``raw``: the parsed list); raises :class:`ConfigError`."""
    if not isinstance(raw, list):
        raise ConfigError("process", raw, "a list of tables ([[process]])", "not a list:")
    out = [_process(n, cfg, axes, sensor, cycle_time, has_3d) for n, cfg in enumerate(raw)]
    seen = {}
    for pc in out:
        other = seen.get((pc.function, pc.axis))
        if other is not None:
            raise ConfigError(f"process[{pc.index}].function", pc.function,
                              f"each function once per axis (process[{other}] has {pc.function} on {pc.axis})",
                              "given twice:")
        seen[(pc.function, pc.axis)] = pc.index
    for pc in out:
        # built once here, so that a value the function itself refuses is the scenario's error (with
        # its file and process[i] key) at load, not an error at the run's start (issue 30)
        try:
            pc.make(cycle_time)
        except ConfigError as exc:
            param = exc.key.split(".", 1)[-1]
            raise ConfigError(f"process[{pc.index}].{param}", exc.value, exc.allowed, exc.problem) from None
    return tuple(out)


def make_process_program(configs, cycle_time: float) -> ProcessProgram | None:
    """One :class:`ProcessProgram` running every configured function in file order; None without any."""
    if not configs:
        return None
    functions = []
    for c in configs:
        f = c.make(cycle_time)
        f.enabled = c.enabled                    # [[process]] key enabled (switchable at run time)
        functions.append(f)
    return ProcessProgram(functions)
