"""Print docs/objects.md from the object registry (``python -m distctrl.objects.docgen > docs/objects.md``);
a test keeps them equal."""
from __future__ import annotations

from .registry import ADS_PORT, AXIS_OBJECTS, GENERAL_AXIS_OBJECTS, INDEX_GROUP, INDEX_GROUP_TF5200, TASK, TF5200_OBJECTS


def render() -> str:
    lines = [
        "# CNC objects (axis-specific distance control)",
        "",
        "Generated from `distctrl/objects/registry.py` by `python -m distctrl.objects.docgen` — do not edit",
        "by hand.",
        "",
        "The objects of FCT-M3 §9.4 (shown in the ISG object browser, §7.5/§7.6). All of them are in task",
        f"{TASK} (ADS port {ADS_PORT}), index group `0x{INDEX_GROUP:X}`, index offset",
        "`(axis_id << 16) | low offset` with `axis_id` from 1 (SPEC §10): the first axis's `DIST_CTRL::kp` is",
        "`0x13106`, the third axis's `0x33106`. Raw values are little-endian; the length is in bytes.",
        "",
        "| low offset | axis 1 | name | type | length | unit | access | value (internal source → object unit) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for s in AXIS_OBJECTS:
        lines.append(f"| 0x{s.low_offset:04X} | 0x{(1 << 16) | s.low_offset:X} | `{s.name}` | {s.type} | {s.length} | "
                     f"{s.unit} | {s.access} | {s.source} → {s.conversion} |")
    lines += [
        "",
        "## General axis objects (FCT-M3 §7.5, Fig. 34)",
        "",
        "Fig. 34 shows, next to the distance-control objects, four general axis objects of the position control",
        "loop that \"remain available\" (`m_sollw_absolut`, `sollw_absolut`, `dig cmd pos high_res`, `dig act pos`).",
        "The documents give no address or type for them; distctrl serves them in the same index group at the",
        "project offsets below, so they can be scoped together with the distance-control objects:",
        "",
        "| low offset | axis 1 | name | type | length | unit | access | value (internal source → object unit) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for s in GENERAL_AXIS_OBJECTS:
        lines.append(f"| 0x{s.low_offset:04X} | 0x{(1 << 16) | s.low_offset:X} | `{s.name}` | {s.type} | {s.length} | "
                     f"{s.unit} | {s.access} | {s.source} → {s.conversion} |")
    lines += [
        "",
        "## The TwinCAT manual's addresses (TF5200 Abstandskontrolle §7.5)",
        "",
        f"TF5200 §7.5 documents `DISTCTRL::v_max` / `a_max` at index group `0x{INDEX_GROUP_TF5200:X}`, offsets",
        "`0x10152` / `0x10153` + 0x10000·(axis index − 1) (third axis: `0x30152`, the example FCT-M3 §7.6's",
        "footnote still carries; the axis index counts from 1 like `axis_id`, SPEC §10).",
        "distctrl serves them there as aliases of `DIST_CTRL_PARAM[0]::v_max` / `a_max` (SPEC §10): the same",
        "value, the same range check, the same adoption rule, so a client written from the TwinCAT manual works.",
        "",
        "| index group | axis 1 | name | type | length | unit | access |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for s in TF5200_OBJECTS:
        lines.append(f"| 0x{s.index_group:X} | 0x{(1 << 16) | s.low_offset:X} | `{s.name}` | {s.type} | {s.length} | "
                     f"{s.unit} | {s.access} |")
    lines += [
        "",
        "## Descriptions",
        "",
    ]
    for s in AXIS_OBJECTS + GENERAL_AXIS_OBJECTS + TF5200_OBJECTS:
        lines.append(f"- `{s.name}` (0x{s.low_offset:04X}): {s.description}")
    lines += [
        "",
        "## Unit conversions",
        "",
        "Internal values are float64 mm, mm/s, mm/s², s (SPEC §1); the registry converts them once, when an",
        "object is read or written:",
        "",
        "- SGN64 `0.01 nm`: mm × 1e8 (one count is 1e-8 mm), rounded to the nearest count (halves away from",
        "  zero), saturated to the SGN64 range.",
        "- REAL64 `0.1 µm/s²` (`a_max_int`), `0.1 µm/s` (`v_max_int`): mm/s² resp. mm/s × 1e4. `kp`, `i_tn`,",
        "  `d_tv` (s), `smoothing_fact`, `kalman_sigma`: as they are.",
        "- SGN32 `µm/s` (`DIST_CTRL_PARAM[0]::v_max`): mm/s × 1000, rounded, saturated; a write divides by",
        "  1000. SGN32 `mm/s²` (`DIST_CTRL_PARAM[0]::a_max`): rounded to whole mm/s²; 0 means the axis",
        "  acceleration P-AXIS-00008.",
        "- SGN32 `Incr.` (`DIST_CTRL_IFC::actual_offset`, `delta_offset`): mm / drive resolution (mm per",
        "  increment, gear ratio included; `AxisObjectContext(drive_resolution_mm=...)`, default 1e-4 mm),",
        "  rounded, saturated. `delta_offset` is the difference of the rounded offsets of this and the last",
        "  cycle, so the deltas sent to the drive add up to `actual_offset` without drift.",
        "- UNS32 `DIST_CTRL::state`: the internal state code (0 IDLE, 2 ACTIVE, 3 FREEZE, 4 OFF,",
        "  5 OFF_NO_MOVE, 6-12 ERROR by cause, 15 DRYRUN; docs/states.md).",
        "- Rotary axes (P-AXIS-00018 `ACHSTYP_ROTATOR`): the axis's lengths are degrees, so `0.01 nm` reads",
        "  as 1e-8° (also `m_sollw_absolut`, `sollw_absolut`), `0.1 µm` as 0.0001°, `µm/s` as 0.001°/s (also",
        "  `DISTCTRL::v_max`) and `mm/s²` as °/s² (the same integer scales); `Incr.` divides by the drive",
        "  resolution in ° per increment (`drive_resolution_mm` then holds degrees).",
        "- STRING (30 bytes): the filter type's name (P-AXIS-00782), ASCII, NUL-padded; at most 29 characters",
        "  so a terminating NUL always remains. BOOLEAN: one byte, 0 or 1 (any non-zero byte decodes as TRUE).",
        "",
        "## Writing (read/write objects)",
        "",
        "Only `DIST_CTRL::kp`, `DIST_CTRL::i_tn`, `DIST_CTRL::d_tv`, `DIST_CTRL_PARAM[0]::v_max` and",
        "`DIST_CTRL_PARAM[0]::a_max` accept writes; any other raises `ObjectAccessError` (project error",
        "900006). `write_value(spec, ctx, value)` converts the value to internal units and returns an",
        "`ObjectWrite`, which the caller queues into the axis's `CycleInput.commands`. Values the controller",
        "would refuse (kp outside 0 < kp <= 2, i_tn outside 0..50 s, d_tv outside 0..2 s, negative v_max or",
        "a_max, non-finite, non-integer for the SGN32 objects) raise `ObjectValueError` at once (the same",
        "check as the controller's). The controller keeps the write pending and adopts it only on",
        "INACTIVE → ACTIVE(_CONST_DIST) or FREEZE → ACTIVE(_CONST_DIST), exactly the transitions of the §7.6",
        "notice (SPEC §8; not when a DRYRUN state is entered or left). A `KP=` / `I_TN=` / `D_TV=` programmed",
        "in a DIST_CTRL block takes effect with the",
        "block and discards a pending object write of the same parameter.",
        "",
        "What a read returns:",
        "",
        "- `DIST_CTRL::kp`, `i_tn`, `d_tv`: the *working* value (the distance-control work data), i.e. an",
        "  object write is not visible here until it is adopted.",
        "- `DIST_CTRL_PARAM[0]::v_max`, `a_max`: the parameter — the value last written while that write is",
        "  pending (`controller.state.pending`), otherwise the working value. A write becomes pending in the",
        "  cycle that consumes the `ObjectWrite`; before that cycle the read still shows the old value.",
        "- `DIST_CTRL::v_max_int`, `DIST_CTRL_IFC::a_max_int`: the limits the slope limiter actually applied",
        "  this cycle (override, lowering weights and adaptive acceleration included).",
        "- `DIST_CTRL::skip_dist_ctrl` (\"not in use\") is always FALSE; `DIST_CTRL::max_dist_change` (for the",
        "  not yet available Kalman_DYN filter) is always 0.",
        "",
        "## Differences between FCT-M3 §7.6 and §9.4",
        "",
        "SPEC §10: §9.4 is followed. The older object-browser table of §7.6 differs in:",
        "",
        "| low offset | §7.6 | §9.4 (used) |",
        "| --- | --- | --- |",
    ]
    for s in AXIS_OBJECTS:
        if s.old_name or s.note:
            lines.append(f"| 0x{s.low_offset:04X} | {('`' + s.old_name + '`') if s.old_name else '—'} | "
                         f"`{s.name}`{': ' + s.note if s.note else ''} |")
    lines += [
        "",
        "Further:",
        "",
        "- Index-offset scheme: §7.6's footnote says \"+ 0x10000 * axis_index (e.g. 0x30152 for the 3rd axis)\"",
        "  and TF5200 §7.5 lists `DISTCTRL::v_max` / `a_max` at 0x10152 / 0x10153 in index group 0x20300: the",
        "  §9.4 scheme `(axis_id << 16) | 0x3xxx` in 0x120300 is the main one (SPEC §10), the two TF5200",
        "  addresses are served as aliases (above).",
        "- The values in §7.6's browser table (kp 0,3, v_max 500000, ...) are one machine's example values,",
        "  not defaults.",
        "- Fig. 34 writes `DIST_CTRL>::filtered_feedback` (typo) and §9.4 gives `target_deviation` the unit",
        "  \"[0.01 nm] l\" (typo): read as `DIST_CTRL::filtered_feedback` and 0.01 nm.",
        "- Fig. 34 also shows `m_sollw_absolut`, `sollw_absolut`, `dig cmd pos high_res` and `dig act pos`:",
        "  general axis objects of the kernel, served at project offsets (above).",
        "- The 3D distance-control objects (index group `0x121300 | channel_id`, FCT-M3 §12.6) are not part",
        "  of this registry.",
        "",
        "## API",
        "",
        "```python",
        "from distctrl.objects import AxisObjectContext, AXIS_OBJECTS, find_object, read_value, encode, write_value",
        "ctx = AxisObjectContext(1, \"Z\", controller, out, drive_resolution_mm=1e-4)   # out: the axis's CycleOutput",
        "spec, ctx = find_object(0x120300, 0x13106, {1: ctx})      # DIST_CTRL::kp of axis 1",
        "raw = encode(spec, read_value(spec, ctx))                 # 8 bytes, little-endian REAL64",
        "inp.commands.append(write_value(spec, ctx, 0.5))          # adopted on the next FREEZE/INACTIVE -> ON",
        "print(format_object_table(object_table({1: ctx})))       # the object browser as text",
        "```",
        "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    print(render(), end="")
