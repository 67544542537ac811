"""The object browser's table and the state names of the live page, from the hub's last snapshot."""
from __future__ import annotations

from ..objects.browser import value_text
from ..objects.channel3d import INDEX_GROUP_3D_BASE
from ..objects.registry import SERVED_OBJECTS, index_offset
from ..base.states import HLI_STATE_NAMES

#: the "axis id" of channel 1's 3D objects in the hub's tables
CHANNEL = 0


def state_name(code: int) -> str:
    return HLI_STATE_NAMES.get(int(code), str(code))


def value_cell(spec, raw, resolution_mm: float) -> str:
    """The Value column: in mm / mm/s / mm/s² or the state's name where the object has one, else the
    value itself (unitless objects such as kp, flags, strings), never blank."""
    text = value_text(spec, raw, resolution_mm)
    if text:
        return text
    if isinstance(raw, str):
        return raw
    if spec.type == "BOOLEAN" or isinstance(raw, bool):
        return "TRUE" if raw else "FALSE"
    number = f"{raw:.10g}" if isinstance(raw, float) else str(raw)
    return number if spec.unit in ("", "-") else f"{number} {spec.unit}"


def object_table(hub) -> dict[str, list]:
    """The object browser's columns from the hub's last snapshot."""
    snap = hub.snapshot
    cols: dict[str, list] = {k: [] for k in ("axis", "group", "offset", "name", "type", "unit", "raw", "value",
                                             "access", "pending", "axis_id")}
    for axis_id, ctx in hub.contexts.items():
        for spec in SERVED_OBJECTS:
            raw, pending = snap["objects"][(axis_id, spec.name)]
            cols["axis"].append(f"{axis_id} {ctx.axis_name}")
            cols["axis_id"].append(axis_id)
            cols["group"].append(f"0x{spec.index_group:X}")
            cols["offset"].append(f"0x{index_offset(axis_id, spec):X}")
            cols["name"].append(spec.name)
            cols["type"].append(spec.type)
            cols["unit"].append(spec.unit)
            cols["raw"].append(raw if isinstance(raw, str) else f"{raw:.10g}" if isinstance(raw, float) else str(raw))
            cols["value"].append(value_cell(spec, raw, ctx.drive_resolution_mm))
            cols["access"].append(spec.access)
            if not spec.writable:
                cols["pending"].append("")
            elif pending is None:
                cols["pending"].append("adopted")
            else:
                cols["pending"].append(f"pending {pending / spec.write_scale:.10g}")
    for spec in hub.channel_objects:
        raw, pending = snap["objects"][(CHANNEL, spec.name)]
        cols["axis"].append("0 channel 1")
        cols["axis_id"].append(CHANNEL)
        cols["group"].append(f"0x{INDEX_GROUP_3D_BASE | 1:X}")
        cols["offset"].append(f"0x{spec.low_offset:X}")
        for key, v in (("name", spec.name), ("type", spec.type), ("unit", spec.unit), ("access", spec.access)):
            cols[key].append(v)
        cols["raw"].append(raw if isinstance(raw, str) else f"{raw:.10g}" if isinstance(raw, float) else str(raw))
        cols["value"].append(value_cell(spec, raw, 1e-4))
        cols["pending"].append("" if not spec.writable else "adopted" if pending is None
                               else f"pending {pending / spec.write_scale:.10g}")
    return cols
