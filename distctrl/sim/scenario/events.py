"""``[[events]]``: timed actions (PLC commands, overrides, feed hold, reset, CNC start, axis errors,
sensor faults, variables; :class:`Event`; docs/scenarios.md)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from distctrl.errors.config import MISSING, ConfigError, require_mapping, require_number

from .axes import AxisConfig
from .common import _axis_ref, _bool, _file, _transition, _var_name
from .sensor import SensorConfig, _fault

#: event action -> (allowed keys, required keys)
EVENT_KINDS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "plc": (("axis", "transition", "position"), ("axis", "transition")),
    "override": (("axis", "value"), ("value",)),
    "feed_hold": (("axis", "value"), ("axis",)),
    "reset": ((), ()),
    "axis_error": (("axis",), ("axis",)),
    "axis_release": (("axis",), ("axis",)),
    "sensor_fault": (("kind", "value", "duration", "duration_cycles", "rate"), ("kind",)),
    "variable": (("name", "value"), ("name", "value")),
    "plc_cyclic": (("axis", "position", "distance"), ("axis",)),
    "start": (("program", "program_text"), ()),
}
OVERRIDE_AXIS_MAX = 1.0
OVERRIDE_PATH_MAX = 1.27


@dataclass(frozen=True)
class Event:
    """A timed action at ``t`` seconds. ``kind`` is one of :data:`EVENT_KINDS`; ``data`` holds the
    normalised values (see docs/scenarios.md); ``index`` is the event's position in the file."""

    t: float
    kind: str
    data: dict = field(default_factory=dict)
    index: int = 0



def _event(n: int, cfg: object, axes: dict[str, AxisConfig], sensor: SensorConfig | None,
           duration: float | None, base_dir: Path = Path(".")) -> Event:
    key = f"events[{n}]"
    actions = tuple(EVENT_KINDS)
    require_mapping(cfg, key, ("t",) + actions, required=("t",))
    assert isinstance(cfg, dict)
    t_hi = duration
    t = require_number(cfg["t"], f"{key}.t", lo=0.0, hi=t_hi)
    given = [k for k in cfg if k != "t"]
    if not given:
        raise ConfigError(key, MISSING, "exactly one action key: " + ", ".join(actions))
    if len(given) > 1:
        raise ConfigError(key, given, "exactly one action key per event (one of " + ", ".join(actions)
                          + "); use one [[events]] table per action", "more than one action:")
    kind = given[0]
    akey = f"{key}.{kind}"
    keys, required = EVENT_KINDS[kind]
    body = cfg[kind]
    require_mapping(body, akey, keys, required)
    assert isinstance(body, dict)
    data: dict[str, Any]
    if kind == "plc":
        data = {"axis": _axis_ref(body["axis"], f"{akey}.axis", axes),
                "transition": _transition(body["transition"], f"{akey}.transition"),
                "position": require_number(body.get("position", 0.0), f"{akey}.position")}
    elif kind == "override":
        axis = body.get("axis")
        if axis is not None:
            axis = _axis_ref(axis, f"{akey}.axis", axes)
        hi = OVERRIDE_AXIS_MAX if axis is not None else OVERRIDE_PATH_MAX
        value = body["value"]
        try:
            value = require_number(value, f"{akey}.value", lo=0.0, hi=hi)
        except ConfigError as exc:
            what = "axis feed override" if axis is not None else "channel path override (no axis)"
            raise ConfigError(f"{akey}.value", value, f"{what}: a number in [0, {hi:g}]",
                              exc.problem) from None
        data = {"axis": axis, "value": value}
    elif kind == "feed_hold":
        data = {"axis": _axis_ref(body["axis"], f"{akey}.axis", axes),
                "value": _bool(body.get("value", True), f"{akey}.value")}
    elif kind == "reset":
        data = {}
    elif kind == "start":
        # CNC start of a program (docs/scenarios.md): the scenario's own one, or another file / text
        if "program" in body and "program_text" in body:
            raise ConfigError(f"{akey}.program_text", "...", "at most one of 'program' (a file) or "
                              "'program_text'", "both 'program' and")
        if "program" in body:
            data = {"program": str(_file(body["program"], f"{akey}.program", base_dir, "NC program file"))}
        elif "program_text" in body:
            text = body["program_text"]
            if not isinstance(text, str):
                raise ConfigError(f"{akey}.program_text", text, "the NC program as a string", "not a string:")
            data = {"program_text": text}
        else:
            data = {}
    elif kind in ("axis_error", "axis_release"):
        data = {"axis": _axis_ref(body["axis"], f"{akey}.axis", axes)}
    elif kind == "sensor_fault":
        if sensor is None:
            raise ConfigError(akey, body, "a sensor_fault event needs a [sensor] table", "no sensor for")
        fault = _fault(body, akey, start_time=t)  # validates; Fault(**data) rebuilds it (start: t)
        data = {k: (int(getattr(fault, k)) if k == "duration_cycles"
                    else float(getattr(fault, k)) if k in ("value", "duration", "rate")
                    else getattr(fault, k)) for k in keys if k in body}
    elif kind == "variable":
        data = {"name": _var_name(body["name"], f"{akey}.name"),
                "value": require_number(body["value"], f"{akey}.value")}
    else:  # plc_cyclic
        axis = _axis_ref(body["axis"], f"{akey}.axis", axes)
        has = [k for k in ("position", "distance") if k in body]
        if len(has) != 1:
            problem = "neither position nor distance in" if not has else "both position and distance in"
            raise ConfigError(akey, body, "exactly one of 'position' (D_Position, mm) or 'distance' "
                              "(D_Distance, mm) besides 'axis'", problem)
        data = {"axis": axis, has[0]: require_number(body[has[0]], f"{akey}.{has[0]}")}
    return Event(t, kind, data, n)
