"""Error catalogue of the 3D (channel-specific) distance control (FCT-M3 §12.7, §12.8, SPEC §7).

The 3D variant raises "in principle the same error messages" as the axis variant under its own
IDs (§12.7): :data:`AXIS_TO_3D` maps each axis ID to its 3D partner as §12.7 / SPEC §7 pair them.
:data:`CATALOGUE_3D` lists every 3D ID with severity, the document's text and *when* it is raised
(from the documents and SPEC §7); docs/errors-3d.md is generated from it
(``python -m distctrl.errors.three_d > docs/errors-3d.md``).

Events are the axis variant's :class:`~distctrl.errors.ErrorEvent` values (the cycle path never
raises): :func:`make_event_3d` builds one for a 3D ID, :func:`event_to_3d` translates an event the
shared cycle core produced under an axis ID. The project-range IDs (>= 900000, distctrl.errors)
are the same for both variants; 900020 (tool inclination above kinematic 98's HD4) is referenced
from :mod:`distctrl.errors`, not redefined.

Decisions where the documents are unclear (also in docs/errors-3d.md):

* 70576 (sensor below ``min_pos + tolerance``) has no 3D number; §12.7 has one "Sensor completely
  run out" (310019) for the 3D variant, so both 70330 and 70576 map to 310019 and the detail
  says which limit.
* 900004 (sensor source changed while active, project range for the axis variant) maps to the
  documented 3D ID 310028, which says exactly that.
* 315001 has no documented text (§12.8.2 P-CHAN-00803: "This parameter must be specified. If this is
  not the case, Error ID 315001 is output."); the text here is the project's.
* 310015 "Function is not available" (3D partner of 70336): raised by a ``#DIST CTRL`` command
  when 3D distance control is configured but cannot be used: the "Cutting" licence is missing
  (§12), an option "in preparation" is requested (DIRECTION=X/Y, §12.2) or MODE=ECS is selected
  without an active kinematic 98 (§12.2 note). 20209 is the decoder's answer when
  FCT_3D_DIST_CTRL is not configured at all; 51061 is the run-time answer to any other use of the
  channel's 3D distance control (PLC, CNC objects, an internal select) without it.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..base.states import ERROR_CODE_BY_ID, InternalState
from . import CATALOGUE, ErrorEvent, ErrorId


@dataclass(frozen=True)
class Error3D:
    """One error of the 3D variant."""

    id: int
    severity: str          # "error" (distance control goes to ERROR / the program aborts) or "warning"
    text: str              # the document's error text (verbatim where the document gives one)
    when: str              # the condition that raises it
    source: str            # where it is documented
    axis_id: int | None = None   # the axis variant's ID for the same condition (§12.7)


_S127 = "FCT-M3 §12.7"

CATALOGUE_3D: dict[int, Error3D] = {e.id: e for e in (
    Error3D(310015, "error", "Function is not available",
            "a #DIST CTRL command while 3D distance control is configured but cannot be used: the "
            "\"Cutting\" licence is missing (§12), an option in preparation is requested (DIRECTION=X/Y) or "
            "MODE=ECS is selected without an active kinematic 98 (#KIN ID[98], #TRAFO ON); the state stays "
            "INACTIVE", _S127, 70336),
    Error3D(310017, "error", "Excessive sensing deviation",
            "the offset would exceed max_deviation (P-CHAN-00801); the offset stays limited", _S127, 70331),
    Error3D(310018, "error", "Actual value change of sensor signal greater than limit",
            "sensor change |Δd|/T above max_act_value_change (P-CHAN-00804, µm/s) in a running state",
            _S127, 70329),
    Error3D(310019, "error", "Sensor completely run out",
            "sensor reading outside the window: above max_pos − tolerance (P-CHAN-00806/00808, axis 70330) "
            "or below min_pos + tolerance (P-CHAN-00807/00808, axis 70576), in a running state or at "
            "CHECK_POS", _S127, 70330),
    Error3D(310021, "warning", "Distance control still active at program end",
            "program end (M30/M2) while 3D distance control is active; the current offset is kept as a "
            "static offset and sensor changes no longer act (§12.4.4)", _S127, 70332),
    Error3D(310022, "error", "Distance control active for axis that is to be specified.",
            "an axis the 3D offset acts on is released from the channel (axis exchange) while 3D distance "
            "control is not INACTIVE", _S127, 70333),
    Error3D(310023, "error", "On repeat selection, deselection of distance control not yet complete",
            "a select (ON, DRYRUN, any mode) while the offset is still running out after OFF (TURNING_OFF)",
            _S127, 70334),
    Error3D(310026, "error", "Distance control selected without programmed position",
            "a select without SET_POS / SET_DIST given since the last reset or program end", _S127, 70335),
    Error3D(310027, "error", "Distance control turned on without valid sensor variable",
            "ON / DRYRUN while no SENSOR_VAR is set, the V.E. variable does not exist or its value is not a "
            "finite number", _S127),
    Error3D(310028, "error", "Change of sensor source while distance control is active not allowed",
            "SENSOR_SOURCE or SENSOR_VAR changed while 3D distance control is not INACTIVE", _S127,
            int(ErrorId.SENSOR_SOURCE_CHANGED)),
    Error3D(51061, "error", "3D distance control not configured",
            "3D distance control is used at run time (select, CNC object DIST_CTRL[0], PLC) in a channel "
            "whose P-CHAN-00500 configuration.decoder.function does not contain FCT_3D_DIST_CTRL", _S127),
    Error3D(51062, "error", "Initialization of axis positions during active distance control not allowed.",
            "the channel position is re-initialised (#CS, #TRAFO, #CHANNEL INIT) while 3D distance control is "
            "not INACTIVE; the NC program is aborted (§12.4.5)", _S127 + ", §12.4.5"),
    Error3D(51064, "error", "Mode setting only allowed when 3D distance control is inactive.",
            "MODE= (or DIRECTION=) programmed with a value different from the active one while 3D distance "
            "control is not INACTIVE", _S127),
    Error3D(315001, "error", "Maximum acceleration of distance control not specified (P-CHAN-00803)",
            "3D distance control is selected while dist_ctrl[0].a_max (P-CHAN-00803) is 0 (not specified); "
            "the 3D variant has no \"0 = axis acceleration\" (SPEC §6)",
            "FCT-M3 §12.8.2 P-CHAN-00803 (no text documented)"),
    Error3D(20209, "error", "Unknown Nc-command",
            "#DIST CTRL is programmed in a channel without FCT_3D_DIST_CTRL (P-CHAN-00500): the decoder does "
            "not know the command; the NC program is aborted", "FCT-M3 §12.7 notice"),
    Error3D(int(ErrorId.KIN98_MAX_INCLINATION), CATALOGUE[int(ErrorId.KIN98_MAX_INCLINATION)][0],
            CATALOGUE[int(ErrorId.KIN98_MAX_INCLINATION)][1],
            "the tool inclination θ exceeds kinematic 98's maximum angle HD4 (V.G.KIN_STEP[1].ID[98].PARAM[3]); "
            "the program aborts (distctrl.kinematics.kin98)",
            "FCT-M3 §12.4.2 (unnumbered); project ID from distctrl.errors"),
    Error3D(int(ErrorId.MODE_OFF_SELECTED), *CATALOGUE[int(ErrorId.MODE_OFF_SELECTED)],
            "a select with MODE=OFF (the default): the offset is computed but not superimposed; nothing moves "
            "(SPEC §12)", "FCT-M3 §12.2 MODE (OFF: no superposition); project ID from distctrl.errors"),
    Error3D(int(ErrorId.SET_DIST_NOT_TOOL_LENGTH), *CATALOGUE[int(ErrorId.SET_DIST_NOT_TOOL_LENGTH)],
            "a CONST_DIST select while a kinematic transformation is on (#TRAFO ON) with a SET_DIST other than "
            "the tool length V.G.WZ_AKT.L: the select goes on, but the transformation planned the motion for "
            "the tool length", "FCT-M3 §12.1.2 (Notice); project ID from distctrl.errors"),
)}

#: axis ID -> 3D ID (FCT-M3 §12.7, SPEC §7; 70576 and 900004 are the project's pairing)
AXIS_TO_3D: dict[int, int] = {
    70329: 310018,
    70330: 310019,
    70331: 310017,
    70332: 310021,
    70333: 310022,
    70334: 310023,
    70335: 310026,
    70336: 310015,
    70576: 310019,
    int(ErrorId.SENSOR_SOURCE_CHANGED): 310028,
}

#: 3D ID -> the axis ID of §12.7's pairs (310019 -> 70330, 310028 -> 900004)
THREE_D_TO_AXIS: dict[int, int] = {e.id: e.axis_id for e in CATALOGUE_3D.values() if e.axis_id is not None}

#: 3D error ID -> internal ERROR code of DIST_CTRL[0]::state (6..12), as for the axis partner
#: (docs/states.md); IDs not listed give 12 (ERROR_OTHER). 310019 gives 70330's code (7).
ERROR_CODE_BY_ID_3D: dict[int, InternalState] = {
    three_d: ERROR_CODE_BY_ID[axis] for three_d, axis in THREE_D_TO_AXIS.items() if axis in ERROR_CODE_BY_ID}

PROJECT_RANGE = 900000


def to_3d_id(error_id: int) -> int:
    """The 3D ID for an axis ID (:data:`AXIS_TO_3D`); 3D IDs and shared project-range IDs unchanged.

    Raises KeyError for an ID that is neither.
    """
    error_id = int(error_id)
    if error_id in AXIS_TO_3D:
        return AXIS_TO_3D[error_id]
    if error_id in CATALOGUE_3D or (error_id >= PROJECT_RANGE and error_id in CATALOGUE):
        return error_id
    raise KeyError(f"error ID {error_id} has no 3D counterpart")


def severity_and_text(error_id: int) -> tuple[str, str]:
    """(severity, text) of a 3D ID or a shared project-range ID (distctrl.errors.CATALOGUE)."""
    error_id = int(error_id)
    if error_id in CATALOGUE_3D:
        e = CATALOGUE_3D[error_id]
        return e.severity, e.text
    if error_id >= PROJECT_RANGE and error_id in CATALOGUE:
        return CATALOGUE[error_id]
    hint = f" (the 3D ID is {AXIS_TO_3D[error_id]})" if error_id in AXIS_TO_3D else ""
    raise KeyError(f"error ID {error_id} is not a 3D distance-control error{hint}")


def make_event_3d(error_id: int, cycle: int, line: int | None, detail: str = "",
                  severity: str | None = None) -> ErrorEvent:
    """An :class:`~distctrl.errors.ErrorEvent` for a 3D ID (or a shared project-range ID):
    message = the documented text, ``': ' + detail`` when given; ``severity`` overrides."""
    default_severity, text = severity_and_text(error_id)
    return ErrorEvent(int(error_id), cycle, line, f"{text}{': ' + detail if detail else ''}",
                      severity or default_severity)


def event_to_3d(event: ErrorEvent) -> ErrorEvent:
    """The 3D event for one the shared cycle core produced under an axis ID (cycle, line, the
    detail and an overridden severity are kept); events already in 3D / project IDs are returned
    as they are."""
    new_id = to_3d_id(event.id)
    if new_id == event.id:
        return event
    axis_text = CATALOGUE.get(event.id, ("", ""))[1]
    detail = event.message
    if axis_text and detail.startswith(axis_text):
        detail = detail[len(axis_text):].removeprefix(": ")
    axis_default = CATALOGUE.get(event.id, ("error", ""))[0]
    severity = None if event.severity == axis_default else event.severity
    return make_event_3d(new_id, event.cycle, event.line, detail, severity)


def render() -> str:
    """docs/errors-3d.md."""
    lines = [
        "# Error IDs (3D, channel-specific distance control)",
        "",
        "Generated from `distctrl/errors/three_d.py` by `python -m distctrl.errors.three_d` — do not edit by hand.",
        "",
        "FCT-M3 §12.7: \"In principle, the same error messages occur with channel-specific distance",
        "control and with axis-specific control\", under their own IDs. The axis IDs are in docs/errors.md.",
        "On the cycle path errors are values (`ErrorEvent`, built by `make_event_3d(error_id, cycle, line,",
        "detail)`); an error puts the 3D distance control into ERROR (HLI 5) and holds the offset.",
        "",
        "| ID | severity | text (document) | when | axis ID |",
        "| --- | --- | --- | --- | --- |",
    ]
    for e in CATALOGUE_3D.values():
        axis = str(e.axis_id) if e.axis_id is not None else "—"
        if e.id == 310019:
            axis = "70330, 70576"
        lines.append(f"| {e.id} | {e.severity} | {e.text} | {e.when} | {axis} |")
    lines += [
        "",
        "## Axis ID → 3D ID (`AXIS_TO_3D`)",
        "",
        "| axis | 3D |",
        "| --- | --- |",
    ]
    for a, d in AXIS_TO_3D.items():
        lines.append(f"| {a} | {d} |")
    lines += [
        "",
        "`event_to_3d(event)` translates an event of the shared cycle core (axis ID) to the 3D ID, keeping",
        "cycle, line and detail. The other project-range IDs (900001 non-finite input, 900003 invalid",
        "transition, 900005 value out of range, 900006 read-only object, 900008 sensor not referenced,",
        "900009 OFF NO_MOVE in ERROR, 900010 NC run-time stop, 900020 inclination above HD4) are the same",
        "in both variants (docs/errors.md).",
        "",
        "Where the state code `DIST_CTRL[0]::state` is 6..12, the 3D ID takes its axis partner's code",
        "(`ERROR_CODE_BY_ID_3D`, docs/states.md); the others give 12.",
        "",
        "## Decisions",
        "",
        "- 70576 (below `min_pos + tolerance`) has no 3D number: §12.7 has one \"Sensor completely run out\"",
        "  (310019) for the 3D variant; both 70330 and 70576 map to it, the event's detail names the limit.",
        "- 900004 (sensor source changed while active; project range for the axis variant) maps to 310028,",
        "  which the document defines for exactly that.",
        "- 315001 has no documented text (§12.8.2, P-CHAN-00803 \"must be specified, else error 315001\"); the",
        "  text above is the project's.",
        "- 310015 / 51061 / 20209: 20209 is the decoder's \"Unknown Nc-command\" for `#DIST CTRL` without",
        "  FCT_3D_DIST_CTRL (§12.7 notice); 51061 is any other use of the channel's 3D distance control",
        "  without it; 310015 means configured but not usable (licence \"Cutting\", §12; DIRECTION=X/Y \"in",
        "  preparation\"; MODE=ECS without kinematic 98, §12.2 note).",
        "- 310021 is a warning like 70332; 51062 and 20209 abort the NC program (§12.4.5, §12.7).",
        "- 310022's text is the document's (\"…axis that is to be specified.\"): the condition is the axis",
        "  release of 70333.",
        "",
    ]
    return "\n".join(lines)


__all__ = ["AXIS_TO_3D", "CATALOGUE_3D", "ERROR_CODE_BY_ID_3D", "Error3D", "THREE_D_TO_AXIS", "event_to_3d",
           "make_event_3d", "render", "severity_and_text", "to_3d_id"]


if __name__ == "__main__":
    print(render(), end="")
