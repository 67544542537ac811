"""``[[process]]`` tables of a scenario: validation, documented defaults, and the PLC program."""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from ...sim.config_errors import MISSING, ConfigError, require_int, require_mapping, require_number
from .auto_set_value import AUTO_DEFAULTS, AutoSetValue
from .corner_lock import CORNER_DEFAULTS, CornerLock
from .program import ProcessProgram
from .void_lock import (VOID_DEFAULTS, VOID_THRESHOLD_MM_S, VOID_THRESHOLD_V_S, VOID_WINDOW_DISTANCE_S,
                        VoidLock)

__all__ = ["ProcessConfig", "PROCESS_FUNCTIONS", "PROCESS_NOT_IMPLEMENTED", "PROCESS_KEYS", "process_configs",
           "make_process_program"]

#: the functions a [[process]] table may name, and their own keys (besides function and axis)
PROCESS_KEYS: dict[str, tuple[str, ...]] = {
    "corner_lock": ("share", "hysteresis"),
    "void_lock": ("variable", "threshold", "window", "on_cycles", "off_cycles", "release_band"),
    "auto_set_value": ("delay", "sample_time"),
}
PROCESS_FUNCTIONS = tuple(PROCESS_KEYS)
#: named by issue 16, not implemented yet: refused with a clear message
PROCESS_NOT_IMPLEMENTED = ("touch_off", "lift", "collision_retract", "calibrate")
_VAR_RE = re.compile(r"^(V\.E\.)?[A-Za-z_][A-Za-z0-9_]*$")


@dataclass(frozen=True)
class ProcessConfig:
    """One validated ``[[process]]`` table: ``params`` holds every key of the function, defaults filled in."""

    function: str
    axis: str
    params: dict = field(default_factory=dict)
    index: int = 0

    def make(self, cycle_time: float):
        p = self.params
        if self.function == "corner_lock":
            return CornerLock(self.axis, p["share"], p["hysteresis"])
        if self.function == "void_lock":
            return VoidLock(self.axis, cycle_time, p["threshold"], variable=p["variable"], window=p["window"],
                            on_cycles=p["on_cycles"], off_cycles=p["off_cycles"], release_band=p["release_band"])
        return AutoSetValue(self.axis, cycle_time, p["delay"], p["sample_time"])


def _function(value: object, key: str) -> str:
    allowed = "one of " + ", ".join(repr(f) for f in PROCESS_FUNCTIONS)
    if isinstance(value, str) and value in PROCESS_NOT_IMPLEMENTED:
        raise ConfigError(key, value, allowed + " (issue 16: " + ", ".join(PROCESS_NOT_IMPLEMENTED)
                          + " are not implemented yet)", "not implemented yet:")
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
    require_mapping(cfg, key, ("function", "axis") + PROCESS_KEYS[fn], required=("axis",))
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
            if not isinstance(var, str) or not _VAR_RE.match(var):
                raise ConfigError(k + "variable", var, "a V.E. variable name (e.g. \"ARC_VOLTAGE\" or \"SENSOR\")")
            var = var[4:] if var.startswith("V.E.") else var
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
    else:
        params = {"delay": require_number(cfg.get("delay", AUTO_DEFAULTS["delay"]), k + "delay", lo=0.0, hi=10.0),
                  "sample_time": require_number(cfg.get("sample_time", AUTO_DEFAULTS["sample_time"]),
                                                k + "sample_time", lo=cycle_time, hi=10.0)}
    return ProcessConfig(fn, axis, params, n)


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
    return tuple(out)


def make_process_program(configs, cycle_time: float) -> ProcessProgram | None:
    """One :class:`ProcessProgram` running every configured function in file order; None without any."""
    if not configs:
        return None
    return ProcessProgram([c.make(cycle_time) for c in configs])
