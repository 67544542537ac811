"""What every process function shares: the axis, its FREEZE hold, the HLI state it reads, and the
switch that turns it on and off while the machine runs."""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, ClassVar

from ...base.states import HliState
from ...errors.config import ConfigError, require_int, require_number
from .hold import RUNNING_TRACKING, FreezeHold

__all__ = ["ProcessFunction", "Key", "ProcessTable", "tracking_or_held", "require_bool", "ve_key"]

_VAR_RE = re.compile(r"^(V\.E\.)?[A-Za-z_][A-Za-z0-9_]*$")

_FREEZE = int(HliState.FREEZE)


def tracking_or_held(state: int, hold: FreezeHold) -> bool:
    """Distance control tracks (ACTIVE, ACTIVE_CONST_DIST), or is in a FREEZE this hold commanded."""
    return state in RUNNING_TRACKING or (state == _FREEZE and hold.held_by_us)


def require_bool(value: object, key: str) -> bool:
    """``value`` if it is a boolean; else :class:`ConfigError` naming ``key``."""
    if not isinstance(value, bool):
        raise ConfigError(key, value, "true or false", "not a boolean:")
    return value


def ve_key(value: object, key: str, allowed: str) -> str:
    """A V.E. variable name given in a [[process]] table, stored without the ``V.E.`` prefix; else
    :class:`ConfigError` naming ``key``."""
    if not isinstance(value, str) or not _VAR_RE.match(value):
        raise ConfigError(key, value, allowed)
    return value[4:] if value.startswith("V.E.") else value


@dataclass(frozen=True)
class Key:
    """One key of a process function's ``[[process]]`` table, declared once by the function (``KEYS``):
    its default (None: none, or one that depends on the scenario, see ``doc``), its documented range
    (``kind`` "number" or "int" with ``lo``/``hi``; "name" a V.E. variable; "any" checked by the function)
    and what it does. The constructor and the scenario loader both check against this range; the
    loader may narrow it by the scenario (an axis's v_max, the cycle time)."""

    default: Any = None
    doc: str = ""
    kind: str = "number"
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False

    def check(self, value: object, key: str, **narrow) -> Any:
        """``value`` checked against the declared range (``narrow`` overrides lo/hi/lo_open/hi_open),
        else :class:`ConfigError` naming ``key``."""
        b = {"lo": self.lo, "hi": self.hi, "lo_open": self.lo_open, "hi_open": self.hi_open, **narrow}
        if self.kind == "int":
            return require_int(value, key, lo=b["lo"], hi=b["hi"])
        if self.kind == "number":
            return require_number(value, key, **b)
        return value


class ProcessTable:
    """One ``[[process]]`` table as its function reads it (Klipper's config section): the raw table,
    the key prefix for messages (``process[2].``), the axis, its scenario config, the sensor and the
    cycle time."""

    def __init__(self, raw: dict, prefix: str, axis: str, axis_cfg, sensor, cycle_time: float):
        self.raw, self.prefix, self.axis, self.axis_cfg = raw, prefix, axis, axis_cfg
        self.sensor, self.cycle_time = sensor, cycle_time

    def get(self, name: str, default: object = None) -> object:
        return self.raw.get(name, default)

    def read(self, cls: "type[ProcessFunction]", name: str, default: object = None, **narrow) -> Any:
        """Key ``name`` of ``cls.KEYS``: the given value, else ``default`` (else the declared default),
        checked against the declared range narrowed by ``narrow``."""
        key = cls.KEYS[name]
        if default is None:
            default = key.default
        return key.check(self.raw.get(name, default), self.prefix + name, **narrow)


def signal_variable(table: "ProcessTable") -> str | None:
    """The ``variable`` key of the motion functions: a V.E. distance in mm; default the sensor's
    distance variable (a distance sensor's, or the linearised one of an arc-voltage sensor); none for
    the probe on encoder 2 (``state_r.actual_distance``)."""
    sensor = table.sensor
    default = sensor.variable if sensor is not None and sensor.kind in ("distance", "arc_voltage") else None
    var = table.get("variable", default)
    if var is None:
        return None
    return ve_key(var, table.prefix + "variable", "a V.E. variable name holding the distance in mm (e.g. \"SENSOR\")")


class ProcessFunction:
    """One process function on one distance-controlled axis. :meth:`step` runs once per PLC cycle
    (the GEO cycle) while :attr:`enabled` and may call ``self.hold.request(self.name)``; the
    :class:`~distctrl.plc.process.program.ProcessProgram` binds the hold, runs the enabled functions
    and then the holds after every cycle, and switches functions on and off
    (:meth:`~distctrl.plc.process.program.ProcessProgram.set_enabled`).

    Every function implements :meth:`reset` (back to the state it was built in; the program calls it
    whenever the function is switched on or off, so a function switched on again starts afresh).
    """

    name = "process"
    #: the keys of its ``[[process]]`` table besides function, axis and enabled, in documentation order
    KEYS: ClassVar[dict[str, Key]] = {}
    #: the V.E. variables the machine creates (0) at the start (a handshake); an instance may set its own
    declares: tuple[str, ...] = ()

    @classmethod
    def from_config(cls, table: ProcessTable) -> dict:
        """The function's validated keys, defaults filled in, from its ``[[process]]`` table. This
        default reads every declared key with its declared default and range; a function whose
        defaults or ranges depend on the scenario overrides it."""
        return {name: table.read(cls, name) for name in cls.KEYS}

    @classmethod
    def build(cls, axis: str, cycle_time: float, params: dict) -> "ProcessFunction":
        """The function for ``axis`` from the keys :meth:`from_config` returned."""
        return cls(axis, cycle_time, **params)

    def __init__(self, axis: str, enabled: bool = True):
        self.axis = axis
        self.hold: FreezeHold | None = None
        #: what the switch says (``[[process]]`` key ``enabled``, ADS ``Process.<axis>.<name>.enabled``,
        #: :meth:`~distctrl.plc.process.program.ProcessProgram.set_enabled`)
        self.switched_on = require_bool(enabled, f"{self.name}.enabled")

    @property
    def finishing(self) -> bool:
        """Switched off, the function still runs while this is true: a motion of its own under way
        that must end first (a lift landing, a touch-off ending safely, a retract). None here."""
        return False

    @property
    def enabled(self) -> bool:
        """The function runs: switched on, or switched off while it is :attr:`finishing`."""
        return self.switched_on or self.finishing

    @enabled.setter
    def enabled(self, on: bool) -> None:
        self.switched_on = bool(on)

    def bind(self, hold: FreezeHold) -> None:
        self.hold = hold

    def step(self, machine, cycle: int) -> None:  # pragma: no cover - every function overrides it
        raise NotImplementedError

    def reset(self) -> None:  # pragma: no cover - every function overrides it
        raise NotImplementedError

    @property
    def requesting_hold(self) -> bool:
        """The function requested the FREEZE hold in the last cycle it ran (it still wants it)."""
        return self.hold is not None and self.hold.requested_by(self.name)

    def status(self) -> dict:
        """What a UI shows of the function: ``name``, ``axis``, ``enabled``, ``requesting_hold``."""
        return {"name": self.name, "axis": self.axis, "enabled": self.enabled,
                "requesting_hold": self.requesting_hold}
