"""``[[process]]`` tables of a scenario: validation, documented defaults, and the PLC program."""
from __future__ import annotations

from dataclasses import dataclass, field

from ...errors.config import ConfigError, MISSING, require_mapping
from .auto_set_value import AutoSetValue
from .base import ProcessFunction, ProcessTable, require_bool
from .calibrate import Calibrate
from .collision_retract import CollisionRetract
from .corner_lock import CornerLock
from .lift import Lift
from .program import ProcessProgram
from .touch_off import TouchOff
from .void_lock import VoidLock

__all__ = ["ProcessConfig", "PROCESS_COMMON_KEYS", "PROCESS_CLASSES", "PROCESS_FUNCTIONS", "PROCESS_KEYS",
           "process_configs", "make_process_program"]

#: the functions a [[process]] table may name: the registry (a new function: its module and one line here)
PROCESS_CLASSES: dict[str, type[ProcessFunction]] = {cls.name: cls for cls in (
    CornerLock, VoidLock, AutoSetValue,
    Calibrate,              # capacitive calibration run (distctrl calibrate)
    TouchOff,               # docs/process.md "Touch-off"
    CollisionRetract,       # docs/process.md "Collision retract"
    Lift,                   # issue 16, h16-lift
)}
#: each function's own keys (besides function, axis and enabled), as the function declares them
PROCESS_KEYS: dict[str, tuple[str, ...]] = {name: tuple(cls.KEYS) for name, cls in PROCESS_CLASSES.items()}
PROCESS_FUNCTIONS = tuple(PROCESS_KEYS)
#: the keys every function has besides function and axis: ``enabled`` (bool, default true) switches it
#: on or off at start; ``distctrl serve`` switches it at run time (ADS ``Process.<axis>.<function>.enabled``)
PROCESS_COMMON_KEYS = ("enabled",)


@dataclass(frozen=True)
class ProcessConfig:
    """One validated ``[[process]]`` table: ``params`` holds every key of the function, defaults filled in."""

    function: str
    axis: str
    params: dict = field(default_factory=dict)
    index: int = 0
    enabled: bool = True

    def make(self, cycle_time: float):
        return PROCESS_CLASSES[self.function].build(self.axis, cycle_time, self.params)


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
    table = ProcessTable(cfg, f"{key}.", axis, axes[axis], sensor, cycle_time)
    return ProcessConfig(fn, axis, PROCESS_CLASSES[fn].from_config(table), n, enabled)


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
