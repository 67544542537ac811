"""Print docs/parameters.md from the parameter table (``make docs``); a test keeps them equal."""
from __future__ import annotations

from .table import AXIS_PARAMETERS


def _default_text(spec) -> str:
    return str(spec.default)


def render() -> str:
    lines = [
        "# Axis parameters",
        "",
        "Generated from `distctrl/params/table.py` by `make docs` — do not edit by hand.",
        "",
        "The list file uses the kernel's format, one `key value # comment` per line. Values are in the",
        "*list unit*; distctrl converts them once, at loading, to the internal unit (mm, s). Unknown keys,",
        "values of the wrong type and values outside the range are load errors that name the file, the",
        "line, the key, the ID, the value and the range. Aliases are the legacy/German keys used in the",
        "documents' examples. The last three rows are axis data from the ISG axis list that the",
        "controller needs; they are not part of the distance-control documents.",
        "",
        "| ID | key | type | list unit | range | default | internal | description |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for s in AXIS_PARAMETERS:
        desc = s.description
        if s.aliases:
            desc += " (aliases: " + ", ".join(f"`{a}`" for a in s.aliases) + ")"
        if s.note:
            desc += f". *Resolution:* {s.note}"
        lines.append(f"| {s.id} | `{s.key}` | {s.type} | {s.unit} | {s.range_text()} | {_default_text(s)} | "
                     f"`{s.field}` [{s.internal_unit}] | {desc} |")
    lines += ["", "Typo prefix `kenngnr.distsc.` (seeds/003's overview) is accepted as `kenngr.distc.`.", ""]
    return "\n".join(lines)


if __name__ == "__main__":
    print(render(), end="")
