"""The distance-control objects of the target's axes and 3D channels, in the parameter lists' units.

An axis is addressed by its ``axis_id`` (from 1; index group 0x120300, index offset
``(axis_id << 16) | 0x3xxx``, FCT-M3 §9.4, TF5200 §7.5, SPEC §10), a 3D channel by its channel
number (index group ``0x121300 | channel``, index offset 0x3xxx, FCT-M3 §12.6). The parameters a list
holds are read from the objects that carry them; for these the objects' units are the lists' units
(kp -, i_tn s, d_tv s, v_max µm/s, a_max mm/s², n_cycles -, ...), so a value read here is what
``distctrl params`` prints for the same key.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..base.states import InternalState
from ..objects.channel3d import BY_NAME_3D, INDEX_GROUP_3D_BASE
from ..objects.registry import BY_NAME, INDEX_GROUP, ObjectSpec, ObjectValueError, decode, encode
from ..params.channel import CHANNEL_LIST
from ..params.listfile import AXIS_LIST
from .target import MachineError, Target

#: parameter (list field) -> object short name; the first five are read/write (FCT-M3 §9.4, §12.6)
PARAMETERS = {"kp": "kp", "i_tn": "i_tn", "d_tv": "d_tv", "v_max": "v_max", "a_max": "a_max",
              "n_cycles": "n_cycles", "filter_type": "filter_type", "kalman_sigma": "kalman_sigma",
              "smoothing_factor": "smoothing_fact"}
WRITABLE = ("kp", "i_tn", "d_tv", "v_max", "a_max")
#: states in which distance control is active: a write waits for the next activation (§9.4 remark)
ACTIVE_STATES = frozenset({int(InternalState.ACTIVE), int(InternalState.FREEZE), int(InternalState.DRYRUN)})


def state_name(code: int) -> str:
    try:
        return InternalState(int(code)).name
    except ValueError:
        return f"UNKNOWN_{int(code)}"


@dataclass(frozen=True)
class Unit:
    """An axis or a 3D channel of the target: how its objects are addressed and listed."""

    kind: str            # "axis" or "channel"
    number: int          # axis_id or channel number, from 1
    name: str            # the axis name the user gave (or its number)

    @property
    def list_format(self):
        return AXIS_LIST if self.kind == "axis" else CHANNEL_LIST

    @property
    def label(self) -> str:
        return f"axis {self.name} (axis_id {self.number})" if self.kind == "axis" else f"channel {self.number}"

    def spec(self, short: str) -> ObjectSpec:
        if self.kind == "axis":
            full = {"v_max": "DIST_CTRL_PARAM[0]::v_max", "a_max": "DIST_CTRL_PARAM[0]::a_max"}.get(
                short, f"DIST_CTRL::{short}")
            return BY_NAME[full]
        full = {"v_max": "DIST_CTRL_PARAM[0]::v_max", "a_max": "DIST_CTRL_PARAM[0]::a_max"}.get(
            short, f"DIST_CTRL[0]::{short}")
        return BY_NAME_3D[full]

    def address(self, spec: ObjectSpec) -> tuple[int, int]:
        if self.kind == "axis":
            return INDEX_GROUP, (self.number << 16) | spec.low_offset
        return INDEX_GROUP_3D_BASE | self.number, spec.low_offset

    def list_spec(self, field: str):
        return next(s for s in self.list_format.specs if s.field == field)

    def key(self, field: str) -> str:
        return self.list_spec(field).key


def read_object(target: Target, unit: Unit, spec: ObjectSpec):
    ig, io = unit.address(spec)
    what = f"reading {spec.name} of {unit.label} (0x{ig:X}:0x{io:X})"
    data = target.read(ig, io, spec.length, what)
    try:
        return decode(spec, data)
    except ObjectValueError as exc:
        raise MachineError(f"{what}: the target answered data that is not a {spec.type}: {exc}") from None


def write_object(target: Target, unit: Unit, spec: ObjectSpec, value) -> None:
    ig, io = unit.address(spec)
    what = f"writing {spec.name} = {value} {spec.unit} to {unit.label} (0x{ig:X}:0x{io:X})"
    try:
        data = encode(spec, value)
    except ObjectValueError as exc:
        raise MachineError(f"{what}: {exc}") from None
    target.write(ig, io, data, what)


def read_state(target: Target, unit: Unit) -> int:
    return int(read_object(target, unit, unit.spec("state")))


def read_parameters(target: Target, unit: Unit) -> dict:
    """{field: value} in the list's units (filter_type: its name)."""
    return {field: read_object(target, unit, unit.spec(short)) for field, short in PARAMETERS.items()}


def describe_unit(target: Target, unit: Unit) -> dict:
    """What ``machine show`` prints for one axis or channel: state and parameters with unit and range."""
    state = read_state(target, unit)
    values = read_parameters(target, unit)
    params, details = {}, {}
    for field, value in values.items():
        ls = unit.list_spec(field)
        spec = unit.spec(PARAMETERS[field])
        params[field] = value
        details[field] = {"key": ls.key, "id": ls.id, "unit": ls.unit, "range": ls.range_text(),
                          "object": spec.name, "writable": field in WRITABLE}
    return {"name": unit.name, "index": unit.number, "kind": unit.kind, "state": state_name(state),
            "state_code": state, "active": state in ACTIVE_STATES, "parameters": params, "details": details}


def _probe(target: Target, kind: str, count: int) -> list[Unit]:
    """The units of ``kind`` whose state object answers, 1, 2, ... until the first that does not (0x702
    / 0x703 / 0x70C: no such unit) or ``count``."""
    found = []
    for index in range(1, count + 1):
        unit = Unit(kind, index, str(index))
        try:
            read_state(target, unit)
        except MachineError as exc:
            if exc.code in (0x702, 0x703, 0x70C):
                break
            raise
        found.append(unit)
    return found


def probe_axes(target: Target, names: dict[int, str] | None = None, max_axes: int = 32) -> list[Unit]:
    """The axes whose DIST_CTRL::state answers, axis_id 1, 2, ... until the first that does not
    (0x703 invalid index offset: no such axis) or ``max_axes``; ``names``: axis_id -> name."""
    if names:
        return [Unit("axis", i, n) for i, n in sorted(names.items())]
    return _probe(target, "axis", max_axes)


def probe_channels(target: Target, max_channels: int = 4) -> list[Unit]:
    """The channels with 3D distance control objects (0x121300 | channel answers DIST_CTRL[0]::state)."""
    return _probe(target, "channel", max_channels)


def format_list_text(unit: Unit, values: dict, header: str = "") -> str:
    """The parameters as a parameter list in the kernel's format (loadable by ``distctrl params``)."""
    lines = [f"# {line}" for line in header.splitlines()] if header else []
    for field, value in values.items():
        ls = unit.list_spec(field)
        text = f"{value:.12g}" if isinstance(value, float) else str(value)
        note = "" if field in WRITABLE else " (read-only over ADS)"
        lines.append(f"{ls.key:<34} {text:<14} # {ls.id} [{ls.unit}] {ls.description}{note}")
    return "\n".join(lines) + "\n"
