"""CNC objects of the 3D (channel-specific) distance control (FCT-M3 §12.6, SPEC §10).

:data:`CHANNEL3D_OBJECTS` is declared once, in the style of the axis table
(:data:`distctrl.objects.registry.AXIS_OBJECTS`), and is also the documentation: ``docs/objects-3d.md``
is generated from it (``python -m distctrl.objects.channel3d > docs/objects-3d.md``).

Addressing (SPEC §10): task GEO, ADS port 551, index group ``0x121300 | channel_id`` with
``channel_id`` from 1 (channel 1: ``0x121301``), index offset = the low offset ``0x3xxx`` of §12.6
*without* an axis part (there is only ``DIST_CTRL[0]``, one 3D distance control per channel).

Values come from a :class:`Channel3DObjectContext` ``(channel_id, source)``: ``source`` is any
object that has the attributes of :data:`OBJECT_ATTRIBUTES` in internal units (mm, mm/s, mm/s², s;
SPEC §1) — the 3D controller's :class:`Channel3DValues`, or simply the shared cycle core's
:class:`~distctrl.control.cycle_io.CycleOutput` (the names are the same). They are converted to the
object's unit here, once, with the registry's conversions; encoding and decoding are the registry's
:func:`~distctrl.objects.registry.encode` / :func:`~distctrl.objects.registry.decode`
(little-endian).

Where §12.6 is unclear (also in docs/objects-3d.md):

* ``DIST_CTRL[0]::state`` is printed at index offset ``0x<3105`` (typo): 0x3105.
* ``DIST_CTRL_PARAM[0]:a_max`` and ``DIST_CTRL_IFC[0]:actual_offset`` / ``:delta_offset`` are printed
  with a single colon (typo): ``::`` like every other object.
* The index group is printed ``0x12130<C_ID>`` (one hex digit, channels 1-15). ``channel_id`` is
  OR-ed into the low byte, so 1..255 are accepted (SPEC §10: ``0x121300 | channel_id``).
* ``DIST_CTRL_PARAM[0]::a_max`` writes of 0 are refused: for the 3D variant a_max must be > 0
  (P-CHAN-00803, error 315001); the axis meaning "0 = axis acceleration" does not exist here.
* ``DIST_CTRL_IFC[0]::actual_offset`` / ``delta_offset`` are in increments: the 3D offset (a length
  along the compensation direction) divided by the context's ``drive_resolution_mm`` (default
  1e-4 mm, i.e. 0.1 µm per increment).
"""
from __future__ import annotations

import math
import numbers
import re
from dataclasses import dataclass, field, fields
from typing import Any, Iterable, Mapping, Protocol, runtime_checkable

from ..control.commands import ObjectWrite
from ..control.controller import check_object_value
from ..errors import ErrorEvent, ErrorId
from .registry import (ADS_PORT, COLUMNS, READ, READ_WRITE, STRING_LENGTH, TASK, ObjectAccessError, ObjectSpec,
                       ObjectValueError, decode, encode, format_object_table, object_row, read_value)
from .units import (INT32_MAX, INT32_MIN, PER_MM_01UM, UM_PER_MM, mm_to_increments, mm_to_nm001,
                    round_saturate)

#: base of the 3D index group; the group of channel ``c`` is ``INDEX_GROUP_3D_BASE | c``
INDEX_GROUP_3D_BASE = 0x121300
MAX_CHANNEL_ID = 0xFF

__all__ = ["CHANNEL3D_OBJECTS", "COLUMNS_3D", "BY_LOW_OFFSET_3D", "BY_NAME_3D", "OBJECT_ATTRIBUTES",
           "INDEX_GROUP_3D_BASE",
           "Channel3DSource", "Channel3DValues", "Channel3DObjectContext", "ObjectSpec3D", "index_group_3d",
           "find_spec_3d", "find_object_3d", "read_value_3d", "read_bytes", "write_value", "write_bytes",
           "object_table_3d", "format_object_table", "render"]


# ============================================================================ the values

@runtime_checkable
class Channel3DSource(Protocol):
    """What the 3D objects read (internal units). :class:`Channel3DValues` and
    :class:`~distctrl.control.cycle_io.CycleOutput` both satisfy it; ``pending`` is optional
    (a mapping of CNC-object writes waiting for adoption, internal units)."""

    offset: float                       # mm   DIST_CTRL_IFC[0]::actual_offset (output to the path)
    delta_offset: float                 # mm   DIST_CTRL_IFC[0]::delta_offset (this cycle's change of offset)
    m_actual_offset: float              # mm   DIST_CTRL[0]::m_actual_offset
    sloped_delta_deviation: float       # mm   DIST_CTRL_IFC[0]::sloped_delta_deviation
    set_pos: float                      # mm   DIST_CTRL[0]::set_pos
    set_distance: float                 # mm   DIST_CTRL[0]::set_distance
    state: int                          # -    DIST_CTRL[0]::state (internal code)
    kp: float                           # -    DIST_CTRL[0]::kp (working value)
    i_tn: float                         # s    DIST_CTRL[0]::i_tn
    d_tv: float                         # s    DIST_CTRL[0]::d_tv
    smoothing_fact: float               # -    DIST_CTRL[0]::smoothing_fact
    kalman_sigma: float                 # -    DIST_CTRL[0]::kalman_sigma
    n_cycles: int                       # -    DIST_CTRL[0]::n_cycles
    filter_type: str                    # -    DIST_CTRL[0]::filter_type (name)
    filtered_feedback: float            # mm   DIST_CTRL[0]::filtered_feedback
    feedback_value: float               # mm   DIST_CTRL[0]::feedback_value
    target_deviation: float             # mm   DIST_CTRL[0]::target_deviation
    delta_deviation_pre_limiter: float  # mm   DIST_CTRL[0]::delta_deviation_pre_limiter
    sensor_value: float                 # mm   DIST_CTRL[0]::sensor_value
    v_max_int: float                    # mm/s  DIST_CTRL[0]::v_max_int (limit applied this cycle)
    a_max_int: float                    # mm/s² DIST_CTRL_IFC[0]::a_max_int (limit applied this cycle)
    v_max_param: float                  # mm/s  DIST_CTRL_PARAM[0]::v_max (working value)
    a_max_param: float                  # mm/s² DIST_CTRL_PARAM[0]::a_max (working value)


#: the attributes the objects read from a source (names of :class:`Channel3DSource`)
OBJECT_ATTRIBUTES: tuple[str, ...] = tuple(Channel3DSource.__annotations__)


@dataclass
class Channel3DValues:
    """Everything the 3D objects and the 3D diagnosis dump show, in internal units (SPEC §1).

    The 3D controller fills one per channel and cycle. The first block has the names of the shared
    cycle core's :class:`~distctrl.control.cycle_io.CycleOutput` (copy them with
    :meth:`from_cycle_output`); the second block is 3D only. Every value has a neutral default, so
    a partly filled instance is valid. Any other object with the same attribute names may be used
    as a context source instead (the objects read only :data:`OBJECT_ATTRIBUTES`).
    """

    # --- as CycleOutput (the shared core) ------------------------------------------------------
    offset: float = 0.0                  # mm: offset output to the path (after the FILTER_TIME blend)
    delta_offset: float = 0.0            # mm: change of ``offset`` this cycle
    m_actual_offset: float = 0.0         # mm: offset as specified by distance control (before the blend)
    sloped_delta_deviation: float = 0.0  # mm: v·T of the slope limiter
    delta_deviation_pre_limiter: float = 0.0  # mm: PID output u
    set_pos: float = 0.0                 # mm: working SET_POS (surface)
    set_distance: float = 0.0            # mm: working SET_DIST (distance along the tool)
    target_deviation: float = 0.0        # mm
    sensor_value: float = 0.0            # mm: the sensor variable's value (V.E., orthogonal distance)
    feedback_value: float = 0.0          # mm: distance (CONST_DIST) or surface (SET_POS / both encoders)
    filtered_feedback: float = 0.0       # mm: the filtered feedback (filtered distance in CONST_DIST)
    measured_distance: float = 0.0       # mm: distance d after the sensor pipeline
    state: int = 0                       # DIST_CTRL[0]::state internal code (InternalState)
    hli_state: int = 0                   # HliState (0 INACTIVE, 1 ACTIVE, ... 7 DRYRUN_SETPOS)
    kp: float = 1.0                      # -
    i_tn: float = 0.0                    # s
    d_tv: float = 0.0                    # s
    smoothing_fact: float = 0.7          # -
    kalman_sigma: float = 4.0            # -
    n_cycles: int = 4                    # -
    filter_type: str = "DEFAULT"         # FilterType name
    v_max_int: float = 0.0               # mm/s: velocity limit applied this cycle
    a_max_int: float = 0.0               # mm/s²: acceleration limit applied this cycle
    v_max_param: float = 0.0             # mm/s: DIST_CTRL_PARAM[0]::v_max working value
    a_max_param: float = 0.0             # mm/s²: DIST_CTRL_PARAM[0]::a_max working value
    offset_velocity: float = 0.0         # mm/s: offset velocity applied this cycle
    target_reached: bool = True
    command_source: int = 0              # 0 NC, 1 PLC
    cycle: int = 0
    events: list = field(default_factory=list)   # ErrorEvents of this cycle
    # --- 3D only ------------------------------------------------------------------------------
    pending: dict = field(default_factory=dict)  # CNC-object writes awaiting adoption (name -> internal)
    control_mode: int = 0                # Mode: 0 SET_POS (surface), 1 CONST_DIST
    programmed_set_pos: float | None = None    # mm: SET_POS given since the last reset (None: none)
    programmed_set_dist: float | None = None   # mm: SET_DIST given since the last reset (None: none)
    orthogonal_set_distance: float = 0.0  # mm: SET_DIST·cos θ (virtual length with kinematic 98)
    compensation_mode: int = 0           # CompensationMode active (0 OFF, 1 PCS, 2 MCS, 3 ECS, 4 ACS)
    new_compensation_mode: int = 0       # CompensationMode programmed for the next select
    direction: str | None = None         # DIRECTION=X/Y/Z (ACS)
    active_axis_index: int = 0           # channel axis index the offset acts on (ACS), 0-based
    new_axis_index: int = 0              # axis index programmed for the next select
    compensation_x: float = 0.0          # mm: offset vector superimposed in machine coordinates
    compensation_y: float = 0.0          # mm
    compensation_z: float = 0.0          # mm
    delta_tool_length: float = 0.0       # mm: change of the tool length by the compensation (ECS)
    cmd_offset: float = 0.0              # mm: offset commanded to the interface (before the blend)
    cmd_offset_frozen: float = 0.0       # mm: offset held while FREEZE (0 when not frozen)
    freeze: bool = False                 # FREEZE active
    wait_for_finished: bool = False      # a #DIST CTRL WAIT block is waiting
    blend_active: bool = False           # the FILTER_TIME sin² blend of (de)activation is running
    filter_time: int = 0                 # FILTER_TIME, interpolator cycles
    fg_f0: float | None = None           # Hz: low-pass cut-off in use (None: the channel parameter)
    order: int | None = None             # low-pass order in use (None: the channel parameter)
    inclination_rad: float = 0.0         # rad: tool inclination θ
    tool_length: float = 0.0             # mm: real tool length L
    virtual_tool_length: float = 0.0     # mm: Lv (kinematic 98), = L without it
    sensor_source: str = "VARIABLE"      # SENSOR_SOURCE
    sensor_var: str | None = None        # "V.E.NAME"
    sensor_valid: bool = True            # False: no valid sensor variable
    ref_shift: float = 0.0               # mm: REF referencing offset
    error: ErrorEvent | None = None      # the error that put the distance control into ERROR

    @classmethod
    def from_cycle_output(cls, out, **extra) -> "Channel3DValues":
        """A :class:`Channel3DValues` with every field ``out`` (a CycleOutput) has, plus ``extra``."""
        names = {f.name for f in fields(cls)}
        kw = {n: getattr(out, n) for n in names if hasattr(out, n)}
        if "events" in kw:
            kw["events"] = list(kw["events"])
        kw.update(extra)
        return cls(**kw)

    @property
    def inclination_deg(self) -> float:
        return math.degrees(self.inclination_rad)


# ============================================================================ the context

def _check_channel_id(channel_id: int) -> None:
    if isinstance(channel_id, bool) or not isinstance(channel_id, numbers.Integral) \
            or not 1 <= channel_id <= MAX_CHANNEL_ID:
        raise ObjectValueError(f"channel_id = {channel_id!r}; allowed: an integer "
                               f"1 <= channel_id <= {MAX_CHANNEL_ID}")


def index_group_3d(channel_id: int) -> int:
    """``0x121300 | channel_id`` (SPEC §10); channel_id from 1."""
    _check_channel_id(channel_id)
    return INDEX_GROUP_3D_BASE | int(channel_id)


class Channel3DObjectContext:
    """What reading and writing one channel's 3D objects needs.

    ``source`` has the :data:`OBJECT_ATTRIBUTES` (a :class:`Channel3DValues`, a CycleOutput, ...);
    the caller may replace it every cycle (``ctx.source = values``). ``drive_resolution_mm`` is the
    mm per increment of the two ``DIST_CTRL_IFC[0]`` objects in increments.
    """

    def __init__(self, channel_id: int, source: Any, drive_resolution_mm: float = 1e-4, channel_name: str = ""):
        _check_channel_id(channel_id)
        if not (isinstance(drive_resolution_mm, (int, float)) and not isinstance(drive_resolution_mm, bool)
                and math.isfinite(drive_resolution_mm) and drive_resolution_mm > 0):
            raise ObjectValueError(f"drive_resolution_mm = {drive_resolution_mm!r}; allowed: a finite value > 0")
        self.channel_id = int(channel_id)
        self.channel_name = channel_name or f"Kanal {self.channel_id}"
        self.source = source
        self.drive_resolution_mm = float(drive_resolution_mm)

    @property
    def index_group(self) -> int:
        return INDEX_GROUP_3D_BASE | self.channel_id

    @property
    def src(self):
        """The source, or an empty :class:`Channel3DValues` (all zero, IDLE) when there is none."""
        return self.source if self.source is not None else Channel3DValues()

    def value(self, name: str):
        return getattr(self.src, name)

    def pending(self, name: str):
        """The value a CNC-object write is waiting with (internal unit), or None."""
        pend = getattr(self.src, "pending", None)
        return pend.get(name) if isinstance(pend, Mapping) else None

    def __repr__(self) -> str:
        return f"Channel3DObjectContext(channel_id={self.channel_id})"


# ============================================================================ the spec type

@dataclass(frozen=True)
class ObjectSpec3D(ObjectSpec):
    """A 3D object: the registry's :class:`ObjectSpec` with the channel addressing of SPEC §10.

    ``index_group`` is the base 0x121300 (the channel is OR-ed in); the index offset is the low
    offset itself.
    """

    def index_offset(self, channel_id: int | None = None) -> int:   # type: ignore[override]
        if channel_id is not None:
            _check_channel_id(channel_id)
        return self.low_offset

    def index_group_for(self, channel_id: int) -> int:
        return index_group_3d(channel_id)


# ============================================================================ declaration helpers

_SGN64_TEXT = "mm × 1e8 (1 count = 0.01 nm = 1e-8 mm), rounded half away from zero, saturated to SGN64"


def _nm(attr: str) -> dict:
    return dict(type="SGN64", length=8, unit="0.01 nm", source=f"{attr} [mm]", conversion=_SGN64_TEXT,
                reader=lambda ctx: mm_to_nm001(ctx.value(attr)))


def _real_scaled(attr: str, scale: float, unit: str, internal: str) -> dict:
    return dict(type="REAL64", length=8, unit=unit, source=f"{attr} [{internal}]",
                conversion=f"{internal} × {scale:g}", reader=lambda ctx: float(ctx.value(attr)) * scale)


def _real(attr: str, unit: str) -> dict:
    return dict(type="REAL64", length=8, unit=unit, source=f"working value {attr} [{unit}]", conversion="as is",
                reader=lambda ctx: float(ctx.value(attr)))


def _incr(kind: str) -> dict:
    if kind == "actual":
        def reader(ctx):
            return mm_to_increments(ctx.value("offset"), ctx.drive_resolution_mm)
        return dict(type="SGN32", length=4, unit="Incr.", source="offset [mm]",
                    conversion="mm / drive resolution (mm per increment), rounded half away from zero, "
                               "saturated to SGN32", reader=reader)

    def reader(ctx):
        o, res = ctx.value("offset"), ctx.drive_resolution_mm
        return round_saturate(mm_to_increments(o, res) - mm_to_increments(o - ctx.value("delta_offset"), res),
                              INT32_MIN, INT32_MAX)
    return dict(type="SGN32", length=4, unit="Incr.", source="offset, delta_offset [mm]",
                conversion="increments of this cycle's offset minus increments of last cycle's offset (each "
                           "rounded as for actual_offset), so the deltas add up to actual_offset exactly",
                reader=reader)


def _param(name: str) -> dict:
    """DIST_CTRL_PARAM[0]::v_max / a_max: the pending write if one waits, else the working value."""
    if name == "v_max":
        per, unit, internal = UM_PER_MM, "µm/s", "mm/s"
    else:
        per, unit, internal = 1.0, "mm/s²", "mm/s²"
    attr = f"{name}_param"

    def reader(ctx):
        value = ctx.pending(name)
        if value is None:
            value = ctx.value(attr)
        return round_saturate(float(value) * per, INT32_MIN, INT32_MAX)
    return dict(type="SGN32", length=4, unit=unit, access=READ_WRITE, write_name=name, write_scale=1.0 / per,
                source=f"pending['{name}'] if a write waits, else working value {attr} [{internal}]",
                conversion=(f"{internal} × {per:g}, " if per != 1.0 else "") + "rounded, saturated to SGN32",
                reader=reader)


def _spec(name: str, low: int, description: str, *, access: str = READ, **kw) -> ObjectSpec3D:
    return ObjectSpec3D(name=name, low_offset=low, description=description, access=access,
                        index_group=INDEX_GROUP_3D_BASE, **kw)


_ADOPTION = ("The new value becomes effective only on INACTIVE→ACTIVE or FREEZE→ACTIVE (§12.6 remark); "
             "until then it is pending.")

# ============================================================================ the table (FCT-M3 §12.6)

CHANNEL3D_OBJECTS: tuple[ObjectSpec3D, ...] = (
    _spec("DIST_CTRL_IFC[0]::a_max_int", 0x3000, "Maximum acceleration of the linear slope (the limit the slope "
          "limiter applied this cycle).", **_real_scaled("a_max_int", PER_MM_01UM, "0.1 µm/s²", "mm/s²")),
    _spec("DIST_CTRL_IFC[0]::sloped_delta_deviation", 0x3001, "The deviation to be executed in this cycle after "
          "being influenced by the slope (v·T).", **_nm("sloped_delta_deviation")),
    _spec("DIST_CTRL[0]::m_actual_offset", 0x3100, "Current offset to the interpolated command position of the "
          "drive as specified by distance control.", **_nm("m_actual_offset")),
    _spec("DIST_CTRL[0]::v_max_int", 0x3102, "Maximum permissible velocity (the velocity limit the slope limiter "
          "applied this cycle).", **_real_scaled("v_max_int", PER_MM_01UM, "0.1 µm/s", "mm/s")),
    _spec("DIST_CTRL[0]::set_distance", 0x3103, "Set command distance of the tool to the surface. Only effective "
          "in SET_DIST mode.", **_nm("set_distance")),
    _spec("DIST_CTRL[0]::set_pos", 0x3104, "Set command value of the workpiece surface. Only effective in "
          "SET_POS mode.", **_nm("set_pos")),
    _spec("DIST_CTRL[0]::state", 0x3105, "Current internal state of 3D distance control: 0 IDLE, 2 ACTIVE, "
          "3 FREEZE, 4 OFF, 5 OFF_NO_MOVE, 6-12 ERROR, 15 DRYRUN.", type="UNS32", length=4, unit="-",
          source="state (InternalState code)", conversion="as is", reader=lambda ctx: int(ctx.value("state")),
          note="§12.6 prints the index offset as 0x<3105 (typo)"),
    _spec("DIST_CTRL[0]::kp", 0x3106, "Weighting of the distance control output values (0 < KP <= 2), "
          "analogous to P-CHAN-00821. " + _ADOPTION, access=READ_WRITE, write_name="kp", **_real("kp", "-")),
    _spec("DIST_CTRL[0]::i_tn", 0x3107, "Integral action time of the PID controller (0 <= I_TN <= 50 s), "
          "analogous to P-CHAN-00822. " + _ADOPTION, access=READ_WRITE, write_name="i_tn", **_real("i_tn", "s")),
    _spec("DIST_CTRL[0]::d_tv", 0x3108, "Derivative action time of the PID controller (0 <= D_TV <= 2 s), "
          "analogous to P-CHAN-00823. " + _ADOPTION, access=READ_WRITE, write_name="d_tv", **_real("d_tv", "s")),
    _spec("DIST_CTRL[0]::smoothing_fact", 0x3109, "Currently set smoothing factor of the exponential averaging "
          "filter (weight of the current measured value), analogous to P-CHAN-00827.",
          **_real("smoothing_fact", "-")),
    _spec("DIST_CTRL[0]::kalman_sigma", 0x310A, "Currently set uncertainty of the included measured values, "
          "analogous to P-CHAN-00826.", **_real("kalman_sigma", "-")),
    _spec("DIST_CTRL[0]::n_cycles", 0x310B, "Currently set number of measured values used for filtering, "
          "analogous to P-CHAN-00800.", type="SGN32", length=4, unit="-", source="working value n_cycles",
          conversion="as is", reader=lambda ctx: int(ctx.value("n_cycles"))),
    _spec("DIST_CTRL[0]::skip_dist_ctrl", 0x310C, "Not in use - in preparation (always False).", type="BOOLEAN",
          length=1, unit="-", source="constant False (not in use)", conversion="as is", reader=lambda ctx: False),
    _spec("DIST_CTRL[0]::filter_type", 0x310D, "Active filter type to smooth sensor values (P-CHAN-00825 names).",
          type="STRING", length=STRING_LENGTH, unit="-", source="working value filter_type",
          conversion="the filter type's name, ASCII, NUL-padded to 30 bytes",
          reader=lambda ctx: str(ctx.value("filter_type"))),
    _spec("DIST_CTRL[0]::max_dist_change", 0x310E, "Maximum change in sensor values per cycle, for the "
          "'Kalman_DYN' filter. Filter not yet available: always 0.", type="REAL64", length=8, unit="0.1 µm",
          source="constant 0.0 (the Kalman_DYN filter is not available)", conversion="as is",
          reader=lambda ctx: 0.0),
    _spec("DIST_CTRL[0]::filtered_feedback", 0x310F, "Filtered feedback value.", **_nm("filtered_feedback")),
    _spec("DIST_CTRL[0]::feedback_value", 0x3110, "Calculated feedback value. SET_DIST mode: measured distance "
          "between the interpolated command position and the surface; SET_DIST (use_both_encoder) and SET_POS: "
          "measured position of the real surface in the selected coordinate system.", **_nm("feedback_value")),
    _spec("DIST_CTRL[0]::target_deviation", 0x3111, "SET_DIST mode: filtered distance minus set distance; SET_POS "
          "mode: filtered real surface minus the specified command surface. Filtered sensor values are included.",
          **_nm("target_deviation")),
    _spec("DIST_CTRL[0]::delta_deviation_pre_limiter", 0x3112, "The distance to be executed in this cycle before "
          "the limiter (PID output u).", **_nm("delta_deviation_pre_limiter")),
    _spec("DIST_CTRL[0]::sensor_value", 0x3113, "Return value of the sensor (the sensor variable).",
          **_nm("sensor_value")),
    _spec("DIST_CTRL_PARAM[0]::v_max", 0x3500, "The maximum velocity set by P-CHAN-00802 when a position offset "
          "is executed. " + _ADOPTION + " Reads the pending value while a write waits.", **_param("v_max")),
    _spec("DIST_CTRL_PARAM[0]::a_max", 0x3501, "The maximum acceleration set by P-CHAN-00803 when a position "
          "offset is executed (must be > 0, error 315001). " + _ADOPTION
          + " Reads the pending value while a write waits.", **_param("a_max"),
          old_name="DIST_CTRL_PARAM[0]:a_max", note="§12.6 prints a single colon (typo)"),
    _spec("DIST_CTRL_IFC[0]::actual_offset", 0x3900, "Offset to the interpolated command position of the drive "
          "currently output by distance control (in increments of the context's drive resolution).",
          **_incr("actual"), old_name="DIST_CTRL_IFC[0]:actual_offset",
          note="§12.6 prints a single colon (typo)"),
    _spec("DIST_CTRL_IFC[0]::delta_offset", 0x3901, "Delta currently output in this cycle (in increments of the "
          "context's drive resolution).", **_incr("delta"),
          old_name="DIST_CTRL_IFC[0]:delta_offset", note="§12.6 prints a single colon (typo)"),
)

BY_LOW_OFFSET_3D: dict[int, ObjectSpec3D] = {s.low_offset: s for s in CHANNEL3D_OBJECTS}
BY_NAME_3D: dict[str, ObjectSpec3D] = {s.name: s for s in CHANNEL3D_OBJECTS}

_LENGTH = {"REAL64": 8, "SGN64": 8, "SGN32": 4, "UNS32": 4, "BOOLEAN": 1, "STRING": STRING_LENGTH}


def _selfcheck() -> None:
    assert len(BY_LOW_OFFSET_3D) == len(CHANNEL3D_OBJECTS) and len(BY_NAME_3D) == len(CHANNEL3D_OBJECTS)
    for s in CHANNEL3D_OBJECTS:
        assert _LENGTH[s.type] == s.length, s.name
        assert (s.write_name is not None) == s.writable, s.name
        assert 0x3000 <= s.low_offset <= 0xFFFF, s.name


_selfcheck()


def find_spec_3d(name: str) -> ObjectSpec3D:
    """The spec by full name (``DIST_CTRL[0]::kp``), the document's single-colon spelling, or, when
    unique, by short name (``kp``)."""
    if name in BY_NAME_3D:
        return BY_NAME_3D[name]
    for s in CHANNEL3D_OBJECTS:
        if s.old_name == name:
            return s
    hits = [s for s in CHANNEL3D_OBJECTS if s.short_name == name]
    if len(hits) == 1:
        return hits[0]
    if hits:
        raise KeyError(f"object name {name!r} is ambiguous: {', '.join(s.name for s in hits)}")
    raise KeyError(f"unknown 3D CNC object {name!r}")


# ============================================================================ addressing

def find_object_3d(index_group: int, index_offset: int,
                   contexts: Mapping[int, Channel3DObjectContext] | Iterable[Channel3DObjectContext]
                   ) -> tuple[ObjectSpec3D, Channel3DObjectContext] | None:
    """The object and channel an ADS (index group, index offset) addresses, or None."""
    if not isinstance(index_group, numbers.Integral) or not isinstance(index_offset, numbers.Integral):
        return None
    if index_group & ~MAX_CHANNEL_ID != INDEX_GROUP_3D_BASE:
        return None
    channel_id = index_group & MAX_CHANNEL_ID
    spec = BY_LOW_OFFSET_3D.get(int(index_offset))
    if spec is None or channel_id == 0:
        return None
    if isinstance(contexts, Mapping):
        ctx = contexts.get(channel_id)
        if ctx is not None and ctx.channel_id == channel_id:
            return spec, ctx
        contexts = contexts.values()
    for ctx in contexts:
        if ctx.channel_id == channel_id:
            return spec, ctx
    return None


# ============================================================================ values

def read_value_3d(spec: ObjectSpec3D, ctx: Channel3DObjectContext):
    """The object's current value in its own unit (int, float, bool or str)."""
    return read_value(spec, ctx)


def read_bytes(spec: ObjectSpec3D, ctx: Channel3DObjectContext) -> bytes:
    """The object's current value encoded as the ADS server returns it (``spec.length`` bytes)."""
    return encode(spec, read_value(spec, ctx))


def write_value(spec: ObjectSpec3D, ctx: Channel3DObjectContext, value, *, line: int | None = None) -> ObjectWrite:
    """The :class:`ObjectWrite` (internal units) for writing ``value`` (object unit) to ``spec``.

    The 3D controller keeps it pending and adopts it only on INACTIVE→active or FREEZE→active.
    Raises :class:`ObjectAccessError` for a read-only object and :class:`ObjectValueError` for a value
    of the wrong type, outside the type's range or outside what the controller accepts
    (kp 0 < kp <= 2, i_tn 0..50 s, d_tv 0..2 s, v_max >= 0, a_max > 0 for the 3D variant).
    """
    if not spec.writable:
        raise ObjectAccessError(f"{spec.name} (channel {ctx.channel_id}, group 0x{ctx.index_group:X}, offset "
                                f"0x{spec.low_offset:X}) is read-only (error {int(ErrorId.OBJECT_READ_ONLY)})")
    raw = decode(spec, encode(spec, value))      # type and range check of the object's data type
    internal = float(raw) * spec.write_scale
    problem = check_object_value(spec.write_name, internal)
    if not problem and spec.write_name == "a_max" and internal <= 0:
        problem = "allowed: value > 0 (P-CHAN-00803; a_max = 0 is error 315001 for the 3D variant)"
    if problem:
        raise ObjectValueError(f"{spec.name} = {value!r} {spec.unit}: {problem}")
    return ObjectWrite(spec.write_name, internal, line=line,
                       meta={"object": spec.name, "channel_id": ctx.channel_id, "raw": raw,
                             "index_group": ctx.index_group, "index_offset": spec.low_offset})


def write_bytes(spec: ObjectSpec3D, ctx: Channel3DObjectContext, data: bytes, *,
                line: int | None = None) -> ObjectWrite:
    """:func:`write_value` from raw ADS bytes (access is checked before the size)."""
    if not spec.writable:
        raise ObjectAccessError(f"{spec.name} is read-only (error {int(ErrorId.OBJECT_READ_ONLY)})")
    return write_value(spec, ctx, decode(spec, data), line=line)


# ============================================================================ object browser

def object_table_3d(contexts: Mapping[int, Channel3DObjectContext] | Iterable[Channel3DObjectContext]
                    ) -> list[dict]:
    """One row per object and channel (channels by id, objects by offset), keyed by the registry's
    :data:`~distctrl.objects.registry.COLUMNS` plus ``Kanal`` (the channel id); format with
    :func:`~distctrl.objects.registry.format_object_table`."""
    ctxs = contexts.values() if isinstance(contexts, Mapping) else contexts
    rows = []
    for ctx in sorted(ctxs, key=lambda c: c.channel_id):
        for spec in CHANNEL3D_OBJECTS:
            rows.append(object_row(len(rows) + 1, ctx.index_group, spec.low_offset, spec, read_value(spec, ctx),
                                   Kanal=ctx.channel_id))
    return rows


# ============================================================================ docs

def render() -> str:
    """docs/objects-3d.md."""
    lines = [
        "# CNC objects (3D, channel-specific distance control)",
        "",
        "Generated from `distctrl/objects/channel3d.py` by `python -m distctrl.objects.channel3d` — do not",
        "edit by hand.",
        "",
        "The objects of FCT-M3 §12.6. They exist only when the channel has",
        "`configuration.decoder.function FCT_3D_DIST_CTRL` (P-CHAN-00500). All of them are in task",
        f"{TASK} (ADS port {ADS_PORT}), index group `0x{INDEX_GROUP_3D_BASE:X} | channel_id` with `channel_id`",
        "from 1 (channel 1: `0x121301`), index offset = the low offset below, without an axis part",
        "(SPEC §10; there is one 3D distance control per channel, `DIST_CTRL[0]`). Raw values are",
        "little-endian; the length is in bytes. The axis objects are in docs/objects.md.",
        "",
        "| index offset | name | type | length | unit | access | value (internal source → object unit) |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for s in CHANNEL3D_OBJECTS:
        lines.append(f"| 0x{s.low_offset:04X} | `{s.name}` | {s.type} | {s.length} | {s.unit} | {s.access} | "
                     f"{s.source} → {s.conversion} |")
    lines += ["", "## Descriptions", ""]
    for s in CHANNEL3D_OBJECTS:
        lines.append(f"- `{s.name}` (0x{s.low_offset:04X}): {s.description}")
    lines += [
        "",
        "## Values: `Channel3DValues`",
        "",
        "`Channel3DObjectContext(channel_id, source, drive_resolution_mm=1e-4)` reads the objects from",
        "`source`, any object with these attributes in internal units (the `Channel3DSource` protocol;",
        "the shared cycle core's `CycleOutput` has all of them, `Channel3DValues.from_cycle_output(out,",
        "**extra)` copies them). An optional `pending` mapping holds object writes waiting for adoption.",
        "",
        "| attribute | unit | object |",
        "| --- | --- | --- |",
    ]
    for attr in OBJECT_ATTRIBUTES:
        users = [s.name for s in CHANNEL3D_OBJECTS if re.search(rf"\b{attr}\b", s.source)]
        lines.append(f"| `{attr}` | {_ATTR_UNITS.get(attr, '-')} | {', '.join('`' + u + '`' for u in users)} |")
    lines += [
        "",
        "`Channel3DValues` (a dataclass with neutral defaults) also carries what the 3D diagnosis dump",
        "shows (docs/diag.md): `measured_distance`, `hli_state`, `control_mode`, `programmed_set_pos`,",
        "`programmed_set_dist`, `orthogonal_set_distance`, `compensation_mode`, `new_compensation_mode`,",
        "`direction`, `active_axis_index`, `new_axis_index`, `compensation_x/y/z`, `delta_tool_length`,",
        "`cmd_offset`, `cmd_offset_frozen`, `freeze`, `wait_for_finished`, `blend_active`, `filter_time`,",
        "`fg_f0`, `order`, `inclination_rad`, `tool_length`, `virtual_tool_length`, `sensor_source`,",
        "`sensor_var`, `sensor_valid`, `ref_shift`, `error`, `events`, `cycle`.",
        "",
        "## Unit conversions",
        "",
        "As for the axis objects (docs/objects.md), with the same functions:",
        "",
        "- SGN64 `0.01 nm`: mm × 1e8, rounded half away from zero, saturated to SGN64.",
        "- REAL64 `0.1 µm/s²` (`a_max_int`), `0.1 µm/s` (`v_max_int`): × 1e4. `kp`, `i_tn`, `d_tv` (s),",
        "  `smoothing_fact`, `kalman_sigma`: as they are.",
        "- SGN32 `µm/s` (`DIST_CTRL_PARAM[0]::v_max`): mm/s × 1000, rounded, saturated; SGN32 `mm/s²`",
        "  (`DIST_CTRL_PARAM[0]::a_max`): rounded to whole mm/s².",
        "- SGN32 `Incr.` (`DIST_CTRL_IFC[0]::actual_offset`, `delta_offset`): the offset along the",
        "  compensation direction / `drive_resolution_mm` (default 1e-4 mm), rounded, saturated;",
        "  `delta_offset` is the difference of the rounded offsets of this and the last cycle.",
        "- UNS32 `DIST_CTRL[0]::state`: the internal state code (0 IDLE, 2 ACTIVE, 3 FREEZE, 4 OFF,",
        "  5 OFF_NO_MOVE, 6-12 ERROR, 15 DRYRUN). STRING: 30 bytes, ASCII, NUL-padded. BOOLEAN: 1 byte.",
        "",
        "## Writing",
        "",
        "Only `DIST_CTRL[0]::kp`, `i_tn`, `d_tv`, `DIST_CTRL_PARAM[0]::v_max` and `a_max` accept writes;",
        "any other raises `ObjectAccessError` (project error 900006). `write_value(spec, ctx, value)` /",
        "`write_bytes(spec, ctx, data)` return an `ObjectWrite` in internal units for the 3D controller,",
        "which adopts it only on INACTIVE → active or FREEZE → active (§12.6 remark). Refused with",
        "`ObjectValueError`: raw data of the wrong size, values the type cannot hold, kp outside",
        "0 < kp <= 2, i_tn outside 0..50 s, d_tv outside 0..2 s, negative v_max, and a_max <= 0 (the 3D",
        "variant has no \"0 = axis acceleration\"; P-CHAN-00803 must be > 0, else error 315001).",
        "",
        "## Where §12.6 was unclear",
        "",
        "- `DIST_CTRL[0]::state` is printed at offset `0x<3105`: read as 0x3105.",
    ]
    for s in CHANNEL3D_OBJECTS:
        if s.old_name:
            lines.append(f"- `{s.old_name}` is printed with a single colon: `{s.name}`.")
    lines += [
        "- The index group is printed `0x12130<C_ID>` (one hex digit). SPEC §10 writes",
        "  `0x121300 | channel_id`; distctrl accepts channel ids 1..255 (the low byte).",
        "- Fig. 53 also shows `m_sollw_absolut`, `sollw_absolut`, `dig cmd pos high_res` and `dig act pos`:",
        "  axis objects of the kernel, not 3D distance-control objects; they are not in this table.",
        "- The HLI values of §12.5 (`bahn_state.virt_tool_length_r`, `inclination_r`) are PLC symbols",
        "  (docs/plc.md), not CNC objects.",
        "",
        "## API",
        "",
        "```python",
        "from distctrl.objects.channel3d import (COLUMNS_3D, Channel3DObjectContext, Channel3DValues,",
        "                                        find_object_3d, object_table_3d, read_bytes, write_bytes)",
        "from distctrl.objects.registry import format_object_table",
        "ctx = Channel3DObjectContext(1, Channel3DValues.from_cycle_output(out, inclination_rad=0.2))",
        "spec, ctx = find_object_3d(0x121301, 0x3106, {1: ctx})     # DIST_CTRL[0]::kp of channel 1",
        "raw = read_bytes(spec, ctx)                                 # 8 bytes, little-endian REAL64",
        "write = write_bytes(spec, ctx, raw)                         # ObjectWrite('kp', ...) for the controller",
        "print(format_object_table(object_table_3d({1: ctx}), COLUMNS_3D))    # the object browser as text",
        "```",
        "",
    ]
    return "\n".join(lines)


_ATTR_UNITS = {"state": "-", "kp": "-", "i_tn": "s", "d_tv": "s", "smoothing_fact": "-", "kalman_sigma": "-",
               "n_cycles": "-", "filter_type": "name", "v_max_int": "mm/s", "a_max_int": "mm/s²",
               "v_max_param": "mm/s", "a_max_param": "mm/s²"}
for _a in OBJECT_ATTRIBUTES:
    _ATTR_UNITS.setdefault(_a, "mm")
del _a

#: the object-browser columns for 3D rows (the registry's plus the channel)
COLUMNS_3D = COLUMNS + ("Kanal",)


if __name__ == "__main__":
    print(render(), end="")
