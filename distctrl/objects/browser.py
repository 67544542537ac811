"""The object browser of ``distctrl objects``: the CNC objects of distance control with English
headers, the axis, the raw value in the object's unit beside the value in mm, mm/s or mm/s², and the
state names beside the state numbers.

Rows come from a local machine (:func:`local_rows`, contexts of a scenario) or from a served one over
ADS (:func:`remote_rows`, pyads against ``distctrl serve``: what ``--watch`` refreshes). FCT-M3 §7.6
shows the browser with German headers; :data:`GERMAN` maps ours to them.
"""
from __future__ import annotations

import ctypes
from typing import Iterable, Mapping

from ..base.states import InternalState
from .registry import (SERVED_OBJECTS, AxisObjectContext, ObjectSpec, decode, format_object_table, format_value,
                       index_offset, read_value)

#: the browser's columns
COLUMNS = ("No", "Axis", "Group", "Offset", "Name", "Type", "Length", "Unit", "Raw value", "Value", "Access")
#: our header -> the header of FCT-M3 §7.6's object browser
GERMAN = {"No": "Nr", "Group": "Gruppe", "Offset": "Offset", "Name": "Bezeichner", "Type": "Datentyp",
          "Length": "Länge", "Unit": "Einheit", "Raw value": "Wert", "Access": "Zugriff", "Axis": "Achse"}
#: an object's unit -> (factor to the SI-like unit, that unit)
TO_MM = {"0.01 nm": (1e-8, "mm"), "0.1 µm": (1e-4, "mm"), "0.1 µm/s": (1e-4, "mm/s"),
         "0.1 µm/s²": (1e-4, "mm/s²"), "µm/s": (1e-3, "mm/s"), "mm/s²": (1.0, "mm/s²")}


def value_text(spec: ObjectSpec, value, resolution_mm: float) -> str:
    """The value in mm / mm/s / mm/s² (increments with the drive's resolution), or the state's name."""
    if spec.name.endswith("::state"):
        try:
            return InternalState(int(value)).name
        except ValueError:
            return f"unknown state {int(value)}"
    if spec.unit == "Incr.":
        return f"{int(value) * resolution_mm:.6f} mm"
    if spec.unit == "s" and spec.type == "REAL64":
        return f"{float(value):.6g} s"
    conv = TO_MM.get(spec.unit)
    if conv is None or spec.type in ("STRING", "BOOLEAN"):
        return ""
    factor, unit = conv
    return f"{float(value) * factor:.6g} {unit}"


def row(no: int, axis_id: int, axis_name: str, spec: ObjectSpec, value, resolution_mm: float) -> dict:
    return {"No": no, "Axis": f"{axis_id} {axis_name}", "Group": f"0x{spec.index_group:X}",
            "Offset": f"0x{index_offset(axis_id, spec):X}", "Name": spec.name, "Type": spec.type,
            "Length": spec.length, "Unit": spec.unit, "Raw value": format_value(spec, value),
            "Value": value_text(spec, value, resolution_mm), "Access": spec.access,
            "raw": value}


def local_rows(contexts: Mapping[int, AxisObjectContext] | Iterable[AxisObjectContext]) -> list[dict]:
    """The browser rows of local axis contexts (axes by axis_id, objects by offset)."""
    ctxs = contexts.values() if isinstance(contexts, Mapping) else contexts
    rows: list[dict] = []
    for ctx in sorted(ctxs, key=lambda c: c.axis_id):
        for spec in SERVED_OBJECTS:
            rows.append(row(len(rows) + 1, ctx.axis_id, ctx.axis_name, spec, read_value(spec, ctx),
                            ctx.drive_resolution_mm))
    return rows


def remote_rows(conn, axes: Mapping[int, str], resolution_mm: float = 1e-4) -> list[dict]:
    """The browser rows read over ADS from a served machine (``conn``: an open pyads Connection to AMS
    port 551); ``axes``: axis_id -> name. Each object is read with its exact length."""
    rows: list[dict] = []
    for axis_id, name in sorted(axes.items()):
        for spec in SERVED_OBJECTS:
            raw = conn.read(spec.index_group, index_offset(axis_id, spec), ctypes.c_uint8 * spec.length)
            rows.append(row(len(rows) + 1, axis_id, name, spec, decode(spec, bytes(raw)), resolution_mm))
    return rows


def format_rows(rows: list[dict], columns: tuple[str, ...] = COLUMNS) -> str:
    """A plain fixed-width text table (a header line, a rule, the rows), as the registry's."""
    return format_object_table(rows, columns)


def json_rows(rows: list[dict]) -> list[dict]:
    """The rows for ``--json``: English keys, the raw value as a number (or string/bool)."""
    return [{"no": r["No"], "axis": r["Axis"], "group": r["Group"], "offset": r["Offset"], "name": r["Name"],
             "type": r["Type"], "length": r["Length"], "unit": r["Unit"], "raw_value": r["raw"],
             "value": r["Value"] or None, "access": r["Access"]} for r in rows]
