"""The registry of the axis-specific distance-control CNC objects (FCT-M3 §7.5, §7.6, §9.4; SPEC §10).

:data:`AXIS_OBJECTS` is declared once and is also the documentation (``docs/objects.md`` is generated
from it by :mod:`distctrl.objects.docgen`). Every entry names the object as FCT-M3 §9.4 does, its
low index offset ``0x3xxx``, data type, length, unit, access and where its value comes from.

Addressing (SPEC §10): task GEO, ADS port 551, index group ``0x120300``, index offset
``(axis_id << 16) | low_offset`` with ``axis_id`` from 1 (first axis ``DIST_CTRL::kp`` = 0x13106,
third axis 0x33106). Where the older table of §7.6 differs from §9.4, §9.4 wins (SPEC §10); the
entry's ``old_name`` / ``note`` record the difference.

Values are read from an :class:`AxisObjectContext` (the axis's controller and its last
:class:`~distctrl.control.cycle_io.CycleOutput`) and converted from internal mm/s units to the
object's unit here, once (SPEC §1). All encodings are little-endian.
"""
from __future__ import annotations

import math
import numbers
import struct
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Mapping

from ..control.commands import WRITABLE_OBJECTS, ObjectWrite
from ..control.controller import check_object_value as _controller_check   # the single copy of the rule
from ..control.cycle_io import CycleOutput
from ..errors import DistCtrlError, ErrorId
from .units import (INT32_MAX, INT32_MIN, PER_MM_01UM, UINT32_MAX, UM_PER_MM,
                    mm_to_increments, mm_to_nm001, round_saturate)

TASK = "GEO"
ADS_PORT = 551
INDEX_GROUP = 0x120300
#: TF5200 Abstandskontrolle §7.5: DISTCTRL::v_max / a_max at 0x20300, offset
#: 0x10152 / 0x10153 + 0x10000 (axis index - 1) -- served as aliases of DIST_CTRL_PARAM[0]::v_max / a_max
INDEX_GROUP_TF5200 = 0x20300
INDEX_GROUPS = (INDEX_GROUP, INDEX_GROUP_TF5200)
STRING_LENGTH = 30

READ = "read"
READ_WRITE = "read/write"

#: ADS data type codes (pyads.constants.ADST_*) of the object types
ADS_TYPES = {"REAL64": 5, "SGN64": 20, "SGN32": 3, "UNS32": 19, "BOOLEAN": 33, "STRING": 30}
_STRUCT = {"REAL64": "<d", "SGN64": "<q", "SGN32": "<i", "UNS32": "<I"}
_INT_RANGE = {"SGN64": (-(1 << 63), (1 << 63) - 1), "SGN32": (INT32_MIN, INT32_MAX), "UNS32": (0, UINT32_MAX)}
_LENGTH = {"REAL64": 8, "SGN64": 8, "SGN32": 4, "UNS32": 4, "BOOLEAN": 1, "STRING": STRING_LENGTH}


class ObjectAccessError(DistCtrlError, PermissionError):
    """A write to an object that is read-only (project error 900006)."""

    error_id = int(ErrorId.OBJECT_READ_ONLY)


class ObjectValueError(DistCtrlError, ValueError):
    """Raw data of the wrong size, or a value the object's type or range does not allow."""


# ============================================================================ context

class AxisObjectContext:
    """What reading and writing one axis's objects needs.

    ``axis_id`` (from 1) is the ``A_ID`` of the index offset. ``output`` is the axis's last
    :class:`CycleOutput`; the caller may replace it (``ctx.output = out``) or, as usual, pass the one
    it reuses every cycle. ``drive_resolution_mm`` is the drive's mm per increment (drive resolution
    and gear ratio), used by the two ``DIST_CTRL_IFC`` objects in increments.
    """

    def __init__(self, axis_id: int, axis_name: str, controller, output: CycleOutput | None,
                 drive_resolution_mm: float = 1e-4):
        _check_axis_id(axis_id)
        if not (isinstance(drive_resolution_mm, (int, float)) and math.isfinite(drive_resolution_mm)
                and drive_resolution_mm > 0):
            raise ObjectValueError(f"drive_resolution_mm = {drive_resolution_mm!r}; allowed: a finite value > 0")
        self.axis_id = int(axis_id)
        self.axis_name = axis_name
        self.controller = controller
        self.output = output
        self.drive_resolution_mm = float(drive_resolution_mm)

    @property
    def out(self) -> CycleOutput:
        """The last output, or an empty one (all zero, INACTIVE) before the first cycle."""
        return self.output if self.output is not None else CycleOutput()

    def working(self, name: str):
        """A working tuning value (the controller's work data): from the last output once a cycle has
        filled it, else straight from the controller (before the first cycle)."""
        out = self.output
        if out is not None and out.tuning_stamp is not None:
            return getattr(out, _OUT_TUNING[name])
        t = self.controller.tuning
        if name in ("kp", "i_tn", "d_tv", "v_max", "a_max"):
            return getattr(t, name)
        f = t.filter
        return {"smoothing_fact": f.smoothing_factor, "kalman_sigma": f.kalman_sigma,
                "n_cycles": f.effective_n, "filter_type": f.filter_type.name}[name]

    def pending(self, name: str):
        """The value a CNC-object write is waiting with (internal unit), or None."""
        return self.controller.state.pending.get(name)

    def __repr__(self) -> str:
        return f"AxisObjectContext(axis_id={self.axis_id}, axis_name={self.axis_name!r})"


_OUT_TUNING = {"kp": "kp", "i_tn": "i_tn", "d_tv": "d_tv", "v_max": "v_max_param", "a_max": "a_max_param",
               "smoothing_fact": "smoothing_fact", "kalman_sigma": "kalman_sigma", "n_cycles": "n_cycles",
               "filter_type": "filter_type"}


# ============================================================================ the spec type

@dataclass(frozen=True)
class ObjectSpec:
    """One axis-specific CNC object (FCT-M3 §9.4)."""

    name: str                     # as in §9.4, e.g. "DIST_CTRL::kp"
    low_offset: int               # 0x3xxx; the index offset is (axis_id << 16) | low_offset
    type: str                     # REAL64, SGN64, SGN32, UNS32, BOOLEAN, STRING
    length: int                   # bytes
    unit: str                     # the document's unit ("0.01 nm", "Incr.", "-", ...)
    access: str                   # "read" or "read/write"
    description: str
    source: str                   # where the value comes from (internal quantity and unit)
    conversion: str               # how it is converted to the object's unit
    reader: Callable[[AxisObjectContext], Any] = field(repr=False, compare=False)
    write_name: str | None = None  # ObjectWrite.name for read/write objects
    write_scale: float = 1.0      # object unit -> internal unit (µm/s -> mm/s: 1e-3)
    old_name: str | None = None   # name in the older table of §7.6 when it differs
    note: str = ""                # difference to §7.6 / remarks of §9.4
    task: str = TASK
    port: int = ADS_PORT
    index_group: int = INDEX_GROUP

    @property
    def short_name(self) -> str:
        return self.name.split("::", 1)[1]

    @property
    def writable(self) -> bool:
        return self.access == READ_WRITE

    @property
    def ads_type(self) -> int:
        return ADS_TYPES[self.type]

    def index_offset(self, axis_id: int) -> int:
        return index_offset(axis_id, self)


# ============================================================================ declaration helpers

_SGN64_TEXT = "mm × 1e8 (1 count = 0.01 nm = 1e-8 mm), rounded half away from zero, saturated to SGN64"


def _nm(out_field: str) -> dict:
    """SGN64 in 0.01 nm from a CycleOutput length (mm)."""
    return dict(type="SGN64", length=8, unit="0.01 nm", source=f"CycleOutput.{out_field} [mm]",
                conversion=_SGN64_TEXT, reader=lambda ctx: mm_to_nm001(getattr(ctx.out, out_field)))


def _real_scaled(out_field: str, scale: float, unit: str, internal: str) -> dict:
    return dict(type="REAL64", length=8, unit=unit, source=f"CycleOutput.{out_field} [{internal}]",
                conversion=f"{internal} × {scale:g}", reader=lambda ctx: float(getattr(ctx.out, out_field)) * scale)


def _working_real(name: str, unit: str) -> dict:
    return dict(type="REAL64", length=8, unit=unit, source=f"working value CycleOutput.{_OUT_TUNING[name]} "
                f"[{'s' if unit == 's' else '-'}]", conversion="as is",
                reader=lambda ctx: float(ctx.working(name)))


def _incr(kind: str) -> dict:
    if kind == "actual":
        src = "CycleOutput.offset [mm]"
        conv = "mm / drive resolution (mm per increment), rounded half away from zero, saturated to SGN32"

        def reader(ctx):
            return mm_to_increments(ctx.out.offset, ctx.drive_resolution_mm)
    else:
        src = "CycleOutput.offset, CycleOutput.delta_offset [mm]"
        conv = ("increments of this cycle's offset minus increments of last cycle's offset (each rounded as "
                "for actual_offset), so the deltas add up to actual_offset exactly")

        def reader(ctx):
            o, res = ctx.out.offset, ctx.drive_resolution_mm
            return round_saturate(mm_to_increments(o, res) - mm_to_increments(o - ctx.out.delta_offset, res),
                                  INT32_MIN, INT32_MAX)
    return dict(type="SGN32", length=4, unit="Incr.", source=src, conversion=conv, reader=reader)


def _param(name: str) -> dict:
    """DIST_CTRL_PARAM[0]::v_max / a_max: the pending write if one waits, else the working value."""
    if name == "v_max":
        per, unit, internal = UM_PER_MM, "µm/s", "mm/s"
    else:
        per, unit, internal = 1.0, "mm/s²", "mm/s²"

    def reader(ctx):
        value = ctx.pending(name)
        if value is None:
            value = ctx.working(name)
        return round_saturate(float(value) * per, INT32_MIN, INT32_MAX)
    return dict(type="SGN32", length=4, unit=unit, access=READ_WRITE, write_name=name, write_scale=1.0 / per,
                source=f"pending write controller.state.pending['{name}'] if any, else working value "
                       f"CycleOutput.{_OUT_TUNING[name]} [{internal}]",
                conversion=(f"{internal} × {per:g}, " if per != 1.0 else "") + "rounded, saturated to SGN32",
                reader=reader)


def _spec(name: str, low: int, description: str, *, access: str = READ, **kw) -> ObjectSpec:
    return ObjectSpec(name=name, low_offset=low, description=description, access=access, **kw)


def _position_01nm(what: str, source: str, get) -> dict:
    """SGN64 in 0.01 nm of an axis position (mm)."""
    return dict(type="SGN64", length=8, unit="0.01 nm", source=f"{source} [mm]", conversion=_SGN64_TEXT,
                reader=lambda ctx: mm_to_nm001(get(ctx)))


def _position_incr(source: str, get, high_res: bool) -> dict:
    """A position in drive increments (drive resolution incl. gear ratio): SGN64 for the high-resolution
    command position, SGN32 (like DIST_CTRL_IFC::actual_offset) for the actual position."""
    if high_res:
        return dict(type="SGN64", length=8, unit="Incr.", source=f"{source} [mm]",
                    conversion="mm / drive resolution, rounded half away from zero, saturated to SGN64",
                    reader=lambda ctx: round_saturate(get(ctx) / ctx.drive_resolution_mm, -(1 << 63), (1 << 63) - 1))
    return dict(type="SGN32", length=4, unit="Incr.", source=f"{source} [mm]",
                conversion="mm / drive resolution, rounded half away from zero, saturated to SGN32",
                reader=lambda ctx: mm_to_increments(get(ctx), ctx.drive_resolution_mm))


_FIG34 = ("FCT-M3 §7.5 Fig. 34 lists it among the axis-specific objects 'in the position control loop' that "
          "'remain available' beside distance control, without address or type; distctrl serves it at this "
          "project offset so it can be scoped with the distance-control objects")


_ADOPTION = ("The new value becomes effective only on INACTIVE→ACTIVE or FREEZE→ACTIVE (§9.4 remark); "
             "until then it is pending.")

# ============================================================================ the table (FCT-M3 §9.4)

AXIS_OBJECTS: tuple[ObjectSpec, ...] = (
    _spec("DIST_CTRL_IFC::a_max_int", 0x3000, "Maximum acceleration of the linear slope (the limit the "
          "slope limiter applied this cycle).", **_real_scaled("a_max_int", PER_MM_01UM, "0.1 µm/s²", "mm/s²")),
    _spec("DIST_CTRL_IFC::sloped_delta_deviation", 0x3001, "The deviation to be executed in this cycle after "
          "being influenced by the slope (v·T).", **_nm("sloped_delta_deviation"),
          old_name="DIST_CTRL_IFC::slope_delta_abweichung", note="§7.6 uses the German name"),
    _spec("DIST_CTRL::m_actual_offset", 0x3100, "Current offset to the interpolated command position of the "
          "drive as specified by distance control.", **_nm("m_actual_offset"),
          old_name="DIST_CTRL::actual_offset",
          note="§7.6 lists 0x3100 as DIST_CTRL::actual_offset in Incr.; §9.4 (followed) has m_actual_offset in "
               "0.01 nm; the offset in increments is DIST_CTRL_IFC::actual_offset (0x3900)"),
    _spec("DIST_CTRL::v_max_int", 0x3102, "Maximum permissible velocity of the axis (the velocity limit the "
          "slope limiter applied this cycle, override included).",
          **_real_scaled("v_max_int", PER_MM_01UM, "0.1 µm/s", "mm/s")),
    _spec("DIST_CTRL::set_distance", 0x3103, "Set command distance of the tool to the surface. Only effective "
          "in SET_DIST mode.", **_nm("set_distance")),
    _spec("DIST_CTRL::set_pos", 0x3104, "Set command value of the workpiece surface. Only effective in "
          "SET_POS mode.", **_nm("set_pos")),
    _spec("DIST_CTRL::state", 0x3105, "Current internal state of distance control: 0 IDLE, 2 ACTIVE, "
          "3 FREEZE, 4 OFF, 5 OFF_NO_MOVE, 6-12 ERROR, 15 DRYRUN.", type="UNS32", length=4, unit="-",
          source="CycleOutput.state (InternalState)", conversion="as is",
          reader=lambda ctx: int(ctx.out.state)),
    _spec("DIST_CTRL::kp", 0x3106, "Weighting of the distance control output values (0 < KP <= 2), analogous "
          "to P-AXIS-00759. " + _ADOPTION, access=READ_WRITE, write_name="kp", **_working_real("kp", "-")),
    _spec("DIST_CTRL::i_tn", 0x3107, "Integral action time of the PID controller (0 <= I_TN <= 50 s), "
          "analogous to P-AXIS-00764. " + _ADOPTION, access=READ_WRITE, write_name="i_tn",
          **_working_real("i_tn", "s")),
    _spec("DIST_CTRL::d_tv", 0x3108, "Derivative action time of the PID controller (0 <= D_TV <= 2 s), "
          "analogous to P-AXIS-00765. " + _ADOPTION, access=READ_WRITE, write_name="d_tv",
          **_working_real("d_tv", "s"),
          note="§7.6's first table gives index group 0x20300 for d_tv (a typo; 0x120300 like the others)"),
    _spec("DIST_CTRL::smoothing_fact", 0x3109, "Currently set smoothing factor of the exponential averaging "
          "filter (weight of the current measured value), analogous to P-AXIS-00784.",
          **_working_real("smoothing_fact", "-")),
    _spec("DIST_CTRL::kalman_sigma", 0x310A, "Currently set uncertainty of the included measured values, "
          "analogous to P-AXIS-00783.", **_working_real("kalman_sigma", "-")),
    _spec("DIST_CTRL::n_cycles", 0x310B, "Currently set number of measured values used for filtering "
          "(P-AXIS-00413): the n the filter uses, 4 under FILTER_TYPE DEFAULT (P-AXIS-00782).", type="SGN32", length=4, unit="-", source="working value CycleOutput.n_cycles",
          conversion="as is", reader=lambda ctx: int(ctx.working("n_cycles"))),
    _spec("DIST_CTRL::skip_dist_ctrl", 0x310C, "Not in use - in preparation (always False).", type="BOOLEAN",
          length=1, unit="-", source="constant False (not in use)", conversion="as is",
          reader=lambda ctx: False),
    _spec("DIST_CTRL::filter_type", 0x310D, "Active filter type to smooth sensor values (P-AXIS-00782 names).",
          type="STRING", length=STRING_LENGTH, unit="-", source="working value CycleOutput.filter_type",
          conversion="the filter type's name, ASCII, NUL-padded to 30 bytes",
          reader=lambda ctx: str(ctx.working("filter_type"))),
    _spec("DIST_CTRL::max_dist_change", 0x310E, "Maximum change in sensor values per cycle, for the "
          "'Kalman_DYN' filter. Filter not yet available: always 0.", type="REAL64", length=8, unit="0.1 µm",
          source="constant 0.0 (the Kalman_DYN filter is not available, no parameter sets it)",
          conversion="as is", reader=lambda ctx: 0.0),
    _spec("DIST_CTRL::filtered_feedback", 0x310F, "Filtered feedback value.", **_nm("filtered_feedback"),
          old_name="DIST_CTRL::istw_filt", note="§7.6: DIST_CTRL::istw_filt in Incr.; §9.4 (followed): 0.01 nm"),
    _spec("DIST_CTRL::feedback_value", 0x3110, "Calculated feedback value (the filter input). SET_DIST mode: "
          "measured distance d; SET_DIST with use_both_encoder: d + c - a, the distance once the drive has "
          "reached its command (FCT-M3 §7.1, SPEC §3); SET_POS: measured position of the real surface a - d.",
          **_nm("feedback_value"), old_name="DIST_CTRL::sensor_data",
          note="§7.6: DIST_CTRL::sensor_data in Incr.; §9.4 (followed): feedback_value in 0.01 nm"),
    _spec("DIST_CTRL::target_deviation", 0x3111, "SET_DIST mode: filtered distance minus set distance; "
          "SET_POS mode: filtered real surface minus the specified command surface. Filtered sensor values "
          "are included.", **_nm("target_deviation"), old_name="DIST_CTRL::deviation",
          note="§7.6: DIST_CTRL::deviation"),
    _spec("DIST_CTRL::delta_deviation_pre_limiter", 0x3112, "The distance to be executed in this cycle before "
          "the limiter (PID output u).", **_nm("delta_deviation_pre_limiter"),
          old_name="DIST_CTRL::delta_abweichung_pre_slope", note="§7.6 uses the German name"),
    _spec("DIST_CTRL::sensor_value", 0x3113, "Return value of the sensor (encoder reading s, or the "
          "distance variable).", **_nm("sensor_value"), note="not in the §7.6 table"),
    _spec("DIST_CTRL_PARAM[0]::v_max", 0x3500, "The maximum velocity set by P-AXIS-00415 when a position "
          "offset is executed. " + _ADOPTION + " Reads the pending value while a write waits.", **_param("v_max")),
    _spec("DIST_CTRL_PARAM[0]::a_max", 0x3501, "The maximum acceleration set by P-AXIS-00416 when a position "
          "offset is executed (0 = axis acceleration P-AXIS-00008). " + _ADOPTION
          + " Reads the pending value while a write waits.", **_param("a_max")),
    _spec("DIST_CTRL_IFC::actual_offset", 0x3900, "Offset to the interpolated command position of the drive "
          "currently output by distance control to the drive. Drive resolution and gear ratio included.",
          **_incr("actual"), note="not in the §7.6 table"),
    _spec("DIST_CTRL_IFC::delta_offset", 0x3901, "Delta currently output to the drive in this cycle. Drive "
          "resolution and gear ratio included.", **_incr("delta"),
          note="not in the §7.6 table; §9.4 prints its offset as 0x<A_D>3901 (typo for A_ID)"),
)

#: FCT-M3 §7.5 Fig. 34: the general axis objects next to distance control (project offsets)
GENERAL_AXIS_OBJECTS: tuple[ObjectSpec, ...] = (
    _spec("m_sollw_absolut", 0x3A00, "Interpolated command position of the axis (programmed path, before the "
          "distance-control offset): p.", **_position_01nm("p", "controller.state.last_p (programmed position "
          "of the cycle)", lambda ctx: ctx.controller.state.last_p), note=_FIG34),
    _spec("sollw_absolut", 0x3A01, "Command position of the axis including the distance-control offset: "
          "c = p + o.", **_position_01nm("c", "CycleOutput.command_position", lambda ctx: ctx.out.command_position),
          note=_FIG34),
    _spec("dig cmd pos high_res", 0x3A02, "Command position sent to the drive, in drive increments (high "
          "resolution).", **_position_incr("CycleOutput.command_position", lambda ctx: ctx.out.command_position,
                                          True), note=_FIG34),
    _spec("dig act pos", 0x3A03, "Actual position of the drive (motor encoder), in drive increments.",
          **_position_incr("controller.state.last_a (actual position of the cycle)",
                           lambda ctx: ctx.controller.state.last_a, False), note=_FIG34),
)

#: TF5200 Abstandskontrolle §7.5: aliases of DIST_CTRL_PARAM[0]::v_max / a_max
TF5200_OBJECTS: tuple[ObjectSpec, ...] = (
    _spec("DISTCTRL::v_max", 0x0152, "TF5200 Abstandskontrolle §7.5: maximum velocity when a position offset "
          "is executed (P-AXIS-00415). The same value as DIST_CTRL_PARAM[0]::v_max (an alias): "
          + _ADOPTION, index_group=INDEX_GROUP_TF5200, **_param("v_max"),
          note="TF5200 §7.5 address: index group 0x20300, offset 0x10152 + 0x10000 (axis index - 1); "
               "SPEC §10: served as an alias so a client written from the TwinCAT manual works"),
    _spec("DISTCTRL::a_max", 0x0153, "TF5200 Abstandskontrolle §7.5: maximum acceleration when a position "
          "offset is executed (P-AXIS-00416). The same value as DIST_CTRL_PARAM[0]::a_max (an alias): "
          + _ADOPTION, index_group=INDEX_GROUP_TF5200, **_param("a_max"),
          note="TF5200 §7.5 address: index group 0x20300, offset 0x10153 + 0x10000 (axis index - 1)"),
)

#: every object the GEO port serves per axis: the documented §9.4 objects, Fig. 34's general axis
#: objects and the TF5200 aliases
SERVED_OBJECTS: tuple[ObjectSpec, ...] = AXIS_OBJECTS + GENERAL_AXIS_OBJECTS + TF5200_OBJECTS
#: every served object by (index group, low offset)
BY_ADDRESS: dict[tuple[int, int], ObjectSpec] = {(s.index_group, s.low_offset): s for s in SERVED_OBJECTS}
#: the objects of index group 0x120300 by low offset
BY_LOW_OFFSET: dict[int, ObjectSpec] = {s.low_offset: s for s in SERVED_OBJECTS if s.index_group == INDEX_GROUP}
BY_NAME: dict[str, ObjectSpec] = {s.name: s for s in SERVED_OBJECTS}


def _selfcheck() -> None:
    assert len(BY_ADDRESS) == len(SERVED_OBJECTS) and len(BY_NAME) == len(SERVED_OBJECTS)
    assert all(s.index_group in INDEX_GROUPS for s in SERVED_OBJECTS)
    assert all(s.index_group == INDEX_GROUP for s in AXIS_OBJECTS + GENERAL_AXIS_OBJECTS)
    for s in SERVED_OBJECTS:
        assert _LENGTH[s.type] == s.length, s.name
        assert s.access in (READ, READ_WRITE), s.name
        assert (s.write_name is not None) == s.writable, s.name
        assert s.write_name is None or s.write_name in WRITABLE_OBJECTS, s.name
        assert 0 <= s.low_offset <= 0xFFFF, s.name


_selfcheck()


def find_spec(name: str) -> ObjectSpec:
    """The spec by full name (``DIST_CTRL::kp``) or, when unique, by short name (``kp``)."""
    if name in BY_NAME:
        return BY_NAME[name]
    hits = [s for s in SERVED_OBJECTS if "::" in s.name and s.short_name == name]
    if len(hits) == 1:
        return hits[0]
    if hits:
        raise KeyError(f"object name {name!r} is ambiguous: {', '.join(s.name for s in hits)}")
    raise KeyError(f"unknown CNC object {name!r}")


# ============================================================================ addressing

def _check_axis_id(axis_id: int) -> None:
    if isinstance(axis_id, bool) or not isinstance(axis_id, numbers.Integral) or not 1 <= axis_id <= 0xFFFF:
        raise ObjectValueError(f"axis_id = {axis_id!r}; allowed: an integer 1 <= axis_id <= 65535")


def index_offset(axis_id: int, spec: ObjectSpec) -> int:
    """``(axis_id << 16) | low_offset`` (SPEC §10); axis_id from 1."""
    _check_axis_id(axis_id)
    return (int(axis_id) << 16) | spec.low_offset


def find_object(index_group: int, index_offset: int,
                contexts: Mapping[int, AxisObjectContext] | Iterable[AxisObjectContext]
                ) -> tuple[ObjectSpec, AxisObjectContext] | None:
    """The object and axis an ADS (index group, index offset) addresses, or None."""
    spec = BY_ADDRESS.get((index_group, index_offset & 0xFFFF))
    if spec is None:
        return None
    axis_id = index_offset >> 16
    ctx = _context_for(axis_id, contexts)
    if ctx is None:
        return None
    return spec, ctx


def _context_for(axis_id: int, contexts) -> AxisObjectContext | None:
    if isinstance(contexts, Mapping):
        ctx = contexts.get(axis_id)
        if ctx is not None and ctx.axis_id == axis_id:
            return ctx
        contexts = contexts.values()
    for ctx in contexts:
        if ctx.axis_id == axis_id:
            return ctx
    return None


# ============================================================================ values

def read_value(spec: ObjectSpec, ctx: AxisObjectContext):
    """The object's current value in its own unit: int (SGN64/SGN32/UNS32), float (REAL64),
    bool (BOOLEAN) or str (STRING)."""
    return spec.reader(ctx)


def read_bytes(spec: ObjectSpec, ctx: AxisObjectContext) -> bytes:
    """The object's current value encoded as the ADS server returns it."""
    return encode(spec, read_value(spec, ctx))


#: struct packers by type, and the fast path of :func:`encode` for the usual value types (a float for
#: REAL64, an in-range int for the integers): the same bytes without the abstract-type checks, which
#: cost more than the packing on the ADS server's read path
_PACK = {t: struct.Struct(f).pack for t, f in _STRUCT.items()}


def encode(spec: ObjectSpec, value) -> bytes:
    """Little-endian bytes of ``value`` (in the object's unit); exactly ``spec.length`` bytes."""
    t = spec.type
    cls = type(value)
    if cls is float and t == "REAL64":
        return _PACK[t](value)
    if cls is int and t in _INT_RANGE:
        lo, hi = _INT_RANGE[t]
        if lo <= value <= hi:
            return _PACK[t](value)
    if t == "REAL64":
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise ObjectValueError(f"{spec.name}: REAL64 needs a number, got {value!r}")
        return struct.pack("<d", float(value))
    if t in _INT_RANGE:
        n = _as_int(spec, value)
        return struct.pack(_STRUCT[t], n)
    if t == "BOOLEAN":
        if not isinstance(value, (bool, numbers.Integral)) or int(value) not in (0, 1):
            raise ObjectValueError(f"{spec.name}: BOOLEAN needs True/False, got {value!r}")
        return b"\x01" if value else b"\x00"
    if t == "STRING":
        if not isinstance(value, str):
            raise ObjectValueError(f"{spec.name}: STRING needs a str, got {value!r}")
        raw = value.encode("ascii", errors="strict") if value.isascii() else None
        if raw is None or b"\x00" in raw or len(raw) > spec.length - 1:
            raise ObjectValueError(f"{spec.name}: {value!r} is not an ASCII string of at most "
                                   f"{spec.length - 1} characters")
        return raw.ljust(spec.length, b"\x00")
    raise ObjectValueError(f"{spec.name}: unknown type {t}")   # pragma: no cover - table is checked


def decode(spec: ObjectSpec, data: bytes):
    """The value in ``data`` (exactly ``spec.length`` little-endian bytes)."""
    data = bytes(data)
    if len(data) != spec.length:
        raise ObjectValueError(f"{spec.name}: {spec.type} needs {spec.length} bytes, got {len(data)}")
    t = spec.type
    if t in _STRUCT:
        return struct.unpack(_STRUCT[t], data)[0]
    if t == "BOOLEAN":
        return data != b"\x00"
    return data.split(b"\x00", 1)[0].decode("ascii", errors="replace")


def _as_int(spec: ObjectSpec, value) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ObjectValueError(f"{spec.name}: {spec.type} needs an integer, got {value!r}")
    if not isinstance(value, numbers.Integral):
        if not (math.isfinite(value) and float(value).is_integer()):
            raise ObjectValueError(f"{spec.name}: {spec.type} needs an integer, got {value!r}")
    n = int(value)
    lo, hi = _INT_RANGE[spec.type]
    if not lo <= n <= hi:
        raise ObjectValueError(f"{spec.name}: {n} outside the {spec.type} range [{lo}, {hi}]")
    return n


def write_value(spec: ObjectSpec, ctx: AxisObjectContext, value, *, line: int | None = None) -> ObjectWrite:
    """The :class:`ObjectWrite` (internal units) for writing ``value`` (object unit) to ``spec``.

    The caller queues it into the axis's ``CycleInput.commands``; the controller keeps it pending and
    adopts it only on INACTIVE→active or FREEZE→active. Raises :class:`ObjectAccessError` for a
    read-only object and :class:`ObjectValueError` for a value of the wrong type or outside the range
    the controller accepts (kp 0 < kp <= 2, i_tn 0..50 s, d_tv 0..2 s, v_max/a_max >= 0).
    """
    if not spec.writable:
        raise ObjectAccessError(f"{spec.name} (axis {ctx.axis_id}, offset 0x{index_offset(ctx.axis_id, spec):X}) "
                                f"is read-only (error {int(ErrorId.OBJECT_READ_ONLY)})")
    if spec.type == "REAL64":
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise ObjectValueError(f"{spec.name}: REAL64 needs a number, got {value!r}")
        raw = float(value)
    else:
        raw = _as_int(spec, value)
    internal = float(raw) * spec.write_scale
    problem = _range_problem(spec.write_name, internal)
    if problem:
        raise ObjectValueError(f"{spec.name} = {value!r} {spec.unit}: {problem}")
    return ObjectWrite(spec.write_name, internal, line=line,
                       meta={"object": spec.name, "axis_id": ctx.axis_id, "raw": raw,
                             "index_offset": index_offset(ctx.axis_id, spec)})


def write_bytes(spec: ObjectSpec, ctx: AxisObjectContext, data: bytes, *, line: int | None = None) -> ObjectWrite:
    """:func:`write_value` from raw ADS bytes (access is checked before the size)."""
    if not spec.writable:
        raise ObjectAccessError(f"{spec.name} is read-only (error {int(ErrorId.OBJECT_READ_ONLY)})")
    return write_value(spec, ctx, decode(spec, data), line=line)


def _range_problem(name: str, value: float) -> str:
    """The controller's own acceptance check, so the object layer refuses exactly what it would."""
    return _controller_check(name, value)


# ============================================================================ object browser

#: the columns of the ISG object browser (FCT-M3 §7.6), plus the access
COLUMNS = ("Nr", "Gruppe", "Offset", "Bezeichner", "Datentyp", "Länge", "Einheit", "Wert", "Zugriff")


def format_value(spec: ObjectSpec, value) -> str:
    """A value as the object browser shows it (REAL64 with up to 12 significant digits)."""
    if spec.type == "STRING":
        return f'"{value}"'
    if spec.type == "BOOLEAN":
        return "True" if value else "False"
    if spec.type == "REAL64":
        return f"{float(value):.12g}"
    return str(int(value))


def object_table(contexts: Mapping[int, AxisObjectContext] | Iterable[AxisObjectContext]) -> list[dict]:
    """One row per object and axis (axes by axis_id, objects by offset), keyed by :data:`COLUMNS`
    (``Nr`` counts from 1 over all rows; ``Wert`` is formatted by :func:`format_value`) plus ``Achse``,
    the axis name."""
    ctxs = contexts.values() if isinstance(contexts, Mapping) else contexts
    rows = []
    for ctx in sorted(ctxs, key=lambda c: c.axis_id):
        for spec in SERVED_OBJECTS:
            rows.append(object_row(len(rows) + 1, spec.index_group, index_offset(ctx.axis_id, spec), spec,
                                   read_value(spec, ctx), Achse=ctx.axis_name))
    return rows


def object_row(nr: int, index_group: int, index_offset_: int, spec: ObjectSpec, value, **extra) -> dict:
    """One object-browser row (the columns of FCT-M3 §7.6), shared by the axis and 3D tables."""
    row = {"Nr": nr, "Gruppe": f"0x{index_group:X}", "Offset": f"0x{index_offset_:X}", "Bezeichner": spec.name,
           "Datentyp": spec.type, "Länge": spec.length, "Einheit": spec.unit, "Wert": format_value(spec, value),
           "Zugriff": spec.access}
    row.update(extra)
    return row


#: the columns of the object tables whose values are right-aligned (numbers)
RIGHT_ALIGNED = frozenset({"Nr", "Länge", "Wert", "No", "Length", "Raw value", "Value"})


def format_object_table(rows: list[dict], columns: tuple[str, ...] = COLUMNS,
                        right: frozenset[str] = RIGHT_ALIGNED) -> str:
    """A plain fixed-width text table of :func:`object_table` rows (a header line, a rule, the rows);
    the ``right`` columns right-aligned."""
    cells = [[str(c) for c in columns]] + [[str(r.get(c, "")) for c in columns] for r in rows]
    widths = [max(len(row[i]) for row in cells) for i in range(len(columns))]

    def fmt(row):
        return "  ".join(v.rjust(w) if columns[i] in right else v.ljust(w)
                         for i, (v, w) in enumerate(zip(row, widths))).rstrip()
    lines = [fmt(cells[0]), "  ".join("-" * w for w in widths)]
    lines += [fmt(r) for r in cells[1:]]
    return "\n".join(lines) + "\n"
