"""Print docs/parameters.md (axis) or, with ``--channel``, docs/parameters-channel.md from the tables.

``python -m distctrl.params.docgen > docs/parameters.md`` (``make docs``) and
``python -m distctrl.params.docgen --channel > docs/parameters-channel.md``; tests keep them equal.
"""
from __future__ import annotations

import sys

from .channel import AXIS_FIELDS, CHANNEL_PARAMETERS, UNDOCUMENTED_IDS
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
        "documents' examples and the other spellings the documents print (see the end of this page).",
        "P-AXIS-00018 and the last three rows are axis data from the ISG axis list that the controller",
        "needs; they are not part of the distance-control documents.",
        "",
        "**Rotary axes.** Every distance-control parameter is documented for the axis types T and R (FCT-M3",
        "§9.2, column \"Dimension\"). With `kenngr.achs_typ ACHSTYP_ROTATOR` (P-AXIS-00018) the list units are",
        "the R column's (0.0001° for 0.1 µm, 0.001°/s for µm/s, °/s² for mm/s², 0.0001°/s for P-AXIS-00417)",
        "and every internal length is an angle in degrees, so the `internal` column's mm, mm/s, mm/s² read °,",
        "°/s, °/s² (the law is unit-agnostic; `AxisParameters.length_unit`). P-AXIS-00502 is printed in mm/s²",
        "for R too and is read as °/s² (its row). P-AXIS-00424 = 0 (\"depending on axis type\") is then modulo:",
        "the reading wraps into [min_pos, max_pos).",
        "",
        "| ID | key | type | list unit T | list unit R | range | default | internal | description |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for s in AXIS_PARAMETERS:
        desc = s.description
        if s.aliases:
            desc += " (aliases: " + ", ".join(f"`{a}`" for a in s.aliases) + ")"
        if s.note:
            desc += f". *Resolution:* {s.note}"
        lines.append(f"| {s.id} | `{s.key}` | {s.type} | {s.unit} | {s.unit_rotary or s.unit} | {s.range_text()} | "
                     f"{_default_text(s)} | `{s.field}` [{s.internal_unit}] | {desc} |")
    lines += ["", "Typo prefix `kenngnr.distsc.` (TF5200 Abstandskontrolle's overview) is accepted as `kenngr.distc.`.",
              "",
              "The six keys `kenngn.distc.mode_dist_use_both_encoder`, `kenngn.distc.use_adaptive_acceleration`,",
              "`kenngn.distc.smoothing_factor`, `kenng.disc.a_weight_down`, `kenng.disc.filter_type` and",
              "`kenng.disc.kalman_sigma` are the spellings TF5200 Abstandskontrolle §8.2 prints in its parameter",
              "descriptions (P-AXIS-00500, 00501, 00784, 00534, 00782, 00783); they are accepted as aliases of",
              "those six keys only (the prefixes `kenngn.distc.` and `kenng.disc.` are not aliases of other keys).",
              ""]
    return "\n".join(lines)


def render_channel() -> str:
    """docs/parameters-channel.md: the 3D distance control's channel parameters (FCT-M3 §12.8)."""
    lines = [
        "# Channel parameters (3D distance control)",
        "",
        "Generated from `distctrl/params/channel.py` by `python -m distctrl.params.docgen --channel`",
        "— do not edit by hand.",
        "",
        "The 3D (channel-specific) distance control is configured in the channel list (FCT-M3 §12.8).",
        "The format is the axis list's (docs/parameters.md): one `key value # comment` per line, values in",
        "the *list unit*, converted once at loading to the internal unit (mm, s) of",
        "`distctrl.params.channel.ChannelParameters`. Unknown keys, values of the wrong type and values",
        "outside the range are load errors that name the file, the line, the key, the P-CHAN ID, the",
        "value and the range.",
        "",
        "```python",
        "from distctrl.params.channel import load_channel_list",
        "",
        "channel = load_channel_list(\"examples/channel_3d_12_8_3.lis\").params   # ChannelParameters",
        "law = channel.to_axis_parameters()   # AxisParameters for the shared cycle core",
        "```",
        "",
        "- Only `dist_ctrl[0]` exists: one 3D distance control per channel (§12.8.1, \"i can only have",
        "  the value 0\"). `dist_ctrl[1].kp` is a load error that says so.",
        "- `configuration.decoder.function FCT_3D_DIST_CTRL` enables the function (`fct_3d_dist_ctrl`);",
        "  without it `#DIST CTRL` is error 20209 at run time.",
        "- `to_axis_parameters()` copies the fields marked *axis* below 1:1 into `AxisParameters`",
        "  (`enabled` = `fct_3d_dist_ctrl`); the axis-only fields (sensor encoder scaling, software limits,",
        "  `optimized_scheduling`, `check_sw_limit_switch`, `axis_a_max`) keep their defaults.",
        "- `a_max = 0` is loadable (it is the documented default) but means \"not specified\": selecting",
        "  3D distance control then raises 315001 (SPEC §6). It is *not* replaced by the axis",
        "  acceleration as for P-AXIS-00416, and `to_axis_parameters()` keeps the 0.",
        f"- {', '.join(UNDOCUMENTED_IDS)} are not defined by the documents and not accepted.",
        "",
        "| ID | key | type | list unit | range | default | internal | axis | description |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for s in CHANNEL_PARAMETERS:
        desc = s.description
        if s.note:
            desc += f". *Resolution:* {s.note}"
        default = "(blank)" if s.default == "" else str(s.default)
        if s.field in AXIS_FIELDS:
            axis = f"`{s.field}`"
        else:
            axis = "`enabled`" if s.field == "fct_3d_dist_ctrl" else "—"
        lines.append(f"| {s.id} | `{s.key}` | {s.type} | {s.unit} | {s.range_text()} | {default} | "
                     f"`{s.field}` [{s.internal_unit}] | {axis} | {desc} |")
    lines += ["",
              "The §12.8.3 parameterisation example is `examples/channel_3d_12_8_3.lis`; it loads as printed.",
              ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if args not in ([], ["--channel"]):
        print("usage: python -m distctrl.params.docgen [--channel]", file=sys.stderr)
        return 2
    print(render_channel() if args else render(), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
