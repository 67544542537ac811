"""AxisParameters: one axis's distance-control parameters in internal units (mm, s, Hz).

Built from the table in :mod:`distctrl.params.table`; every construction is validated against the
documented ranges, so an ``AxisParameters`` object is always a legal parameter set.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from ..base.kinds import FilterType
from ..errors import ParameterError
from .table import (AXIS_PARAMETERS, AXIS_TYPE_NAMES, AXIS_TYPE_ROTATOR, AXIS_TYPE_TRANSLATOR, BY_FIELD, BY_KEY,
                    ParamSpec)

#: P-AXIS-00018 spellings accepted in a list (the ISG names, the bare names and the numeric codes)
_AXIS_TYPE_ALIASES = {"ACHSTYP_TRANSLATOR": AXIS_TYPE_TRANSLATOR, "TRANSLATOR": AXIS_TYPE_TRANSLATOR,
                      "0X0001": AXIS_TYPE_TRANSLATOR, "1": AXIS_TYPE_TRANSLATOR,
                      "ACHSTYP_ROTATOR": AXIS_TYPE_ROTATOR, "ROTATOR": AXIS_TYPE_ROTATOR,
                      "0X0002": AXIS_TYPE_ROTATOR, "2": AXIS_TYPE_ROTATOR}


def parse_axis_type(text) -> str:
    """P-AXIS-00018 value -> ``ACHSTYP_TRANSLATOR`` / ``ACHSTYP_ROTATOR``; ValueError otherwise (a
    spindle, ACHSTYP_SPINDEL / 0x0004, has no distance control)."""
    name = _AXIS_TYPE_ALIASES.get(str(text).strip().upper())
    if name is None:
        raise ValueError(f"axis type {text!r}")
    return name


def _string_value(spec: ParamSpec, value):
    """Internal value of a STRING parameter: the filter type (P-AXIS-00782) or the axis type (P-AXIS-00018)."""
    if spec.field == "axis_type":
        return parse_axis_type(value)
    return value if isinstance(value, FilterType) else FilterType.parse(str(value))


def _default(spec: ParamSpec):
    if spec.type == "BOOLEAN":
        return bool(spec.default)
    if spec.type == "STRING":
        return _string_value(spec, spec.default)
    if spec.internal_unit in ("-", "increments", "0.1 µm") and spec.type in ("SGN32", "UNS32", "UNS16"):
        return int(spec.default)
    return float(spec.default) * spec.scale


@dataclass(frozen=True)
class AxisParameters:
    """Distance-control parameters of one axis (internal units; see docs/parameters.md)."""

    enabled: bool = _default(BY_FIELD["enabled"])
    n_cycles: int = _default(BY_FIELD["n_cycles"])
    max_deviation: float = _default(BY_FIELD["max_deviation"])              # mm
    v_max: float = _default(BY_FIELD["v_max"])                              # mm/s
    a_max: float = _default(BY_FIELD["a_max"])                              # mm/s², 0 = axis_a_max
    max_act_value_change: float = _default(BY_FIELD["max_act_value_change"])  # mm/s
    ref_offset: float = _default(BY_FIELD["ref_offset"])                    # mm
    max_pos: float = _default(BY_FIELD["max_pos"])                          # mm
    min_pos: float = _default(BY_FIELD["min_pos"])                          # mm
    tolerance: float = _default(BY_FIELD["tolerance"])                      # mm
    check_sw_limit_switch: bool = _default(BY_FIELD["check_sw_limit_switch"])
    use_both_encoders: bool = _default(BY_FIELD["use_both_encoders"])
    use_adaptive_acceleration: bool = _default(BY_FIELD["use_adaptive_acceleration"])
    a_min: float = _default(BY_FIELD["a_min"])                              # mm/s²
    dist_error_a_min: float = _default(BY_FIELD["dist_error_a_min"])        # mm
    dist_error_a_max: float = _default(BY_FIELD["dist_error_a_max"])        # mm
    low_pass_filter_order: int = _default(BY_FIELD["low_pass_filter_order"])
    low_pass_filter_fg_f0: float = _default(BY_FIELD["low_pass_filter_fg_f0"])  # Hz
    optimized_scheduling: bool = _default(BY_FIELD["optimized_scheduling"])
    v_weight_down: float = _default(BY_FIELD["v_weight_down"])              # fraction, 0 = off
    a_weight_down: float = _default(BY_FIELD["a_weight_down"])              # fraction, 0 = off
    encoder_resolution_num: int = _default(BY_FIELD["encoder_resolution_num"])
    encoder_resolution_denom: int = _default(BY_FIELD["encoder_resolution_denom"])
    sensor_sign_reversal: bool = _default(BY_FIELD["sensor_sign_reversal"])
    sensor_mode_act_pos: int = _default(BY_FIELD["sensor_mode_act_pos"])
    kp: float = _default(BY_FIELD["kp"])
    i_tn: float = _default(BY_FIELD["i_tn"])                                # s
    d_tv: float = _default(BY_FIELD["d_tv"])                                # s
    filter_type: FilterType = _default(BY_FIELD["filter_type"])
    kalman_sigma: float = _default(BY_FIELD["kalman_sigma"])
    smoothing_factor: float = _default(BY_FIELD["smoothing_factor"])
    sensor_absolute: bool = _default(BY_FIELD["sensor_absolute"])
    axis_type: str = _default(BY_FIELD["axis_type"])                        # P-AXIS-00018
    axis_a_max: float = _default(BY_FIELD["axis_a_max"])                    # mm/s²
    sw_limit_max: float = _default(BY_FIELD["sw_limit_max"])                # mm
    sw_limit_min: float = _default(BY_FIELD["sw_limit_min"])                # mm

    def __post_init__(self) -> None:
        if isinstance(self.filter_type, str):
            object.__setattr__(self, "filter_type", FilterType.parse(self.filter_type))
        if self.axis_type not in AXIS_TYPE_NAMES:
            try:
                object.__setattr__(self, "axis_type", parse_axis_type(self.axis_type))
            except ValueError:
                spec = BY_FIELD["axis_type"]
                raise ParameterError(f"{spec.id} {spec.key} = {self.axis_type!r} is not allowed; allowed: "
                                     f"{spec.range_text()} (a spindle has no distance control)", key=spec.key,
                                     param_id=spec.id, value=self.axis_type, allowed=spec.range_text()) from None
        for spec in AXIS_PARAMETERS:
            check_internal(spec, getattr(self, spec.field), self.rotary)
        if self.min_pos + self.tolerance >= self.max_pos - self.tolerance:
            raise ParameterError(
                f"P-AXIS-00419/00420/00421 sensor window is empty: min_pos + tolerance "
                f"({self.min_pos + self.tolerance:g} {self.length_unit}) must be below max_pos - tolerance "
                f"({self.max_pos - self.tolerance:g} {self.length_unit})",
                key="kenngr.distc.min_pos/max_pos/tolerance", param_id="P-AXIS-00419/00420/00421")
        if self.sw_limit_min >= self.sw_limit_max:
            raise ParameterError(
                f"P-AXIS-00177/00178 software limits: swe_neg ({self.sw_limit_min:g} {self.length_unit}) must be "
                f"below swe_pos ({self.sw_limit_max:g} {self.length_unit})", param_id="P-AXIS-00177/00178")

    # ------------------------------------------------------------------ derived values
    @property
    def rotary(self) -> bool:
        """A rotary axis (P-AXIS-00018 ACHSTYP_ROTATOR): every length is an angle in degrees."""
        return self.axis_type == AXIS_TYPE_ROTATOR

    @property
    def length_unit(self) -> str:
        """The internal unit of positions, offsets and distances: ``mm`` or ``°`` (rotary)."""
        return "°" if self.rotary else "mm"

    @property
    def sensor_modulo(self) -> bool:
        """The sensor reading wraps into [min_pos, max_pos): P-AXIS-00424 = 2, or = 0 ('depending on
        axis type') on a rotary axis."""
        mode = self.sensor_mode_act_pos
        return mode == 2 or (mode == 0 and self.rotary)

    @property
    def a_max_effective(self) -> float:
        """Acceleration limit of the offset (mm/s²): a_max, or the axis maximum when a_max = 0."""
        return self.a_max if self.a_max > 0 else self.axis_a_max

    @property
    def sensor_mm_per_increment(self) -> float:
        return self.encoder_resolution_denom / self.encoder_resolution_num * 1e-4

    def replace(self, **changes) -> "AxisParameters":
        """A copy with fields changed (internal units), validated."""
        return dataclasses.replace(self, **changes)

    def to_interface(self) -> dict[str, object]:
        """Values in the list file's units, keyed by the list-file key."""
        out: dict[str, object] = {}
        for spec in AXIS_PARAMETERS:
            out[spec.key] = to_interface_value(spec, getattr(self, spec.field), self.rotary)
        return out

    @classmethod
    def from_interface(cls, values: dict[str, object]) -> "AxisParameters":
        """Build from list-file keys and interface-unit values (already type-checked)."""
        rotary = any(BY_KEY[k].field == "axis_type" and parse_axis_type(v) == AXIS_TYPE_ROTATOR
                     for k, v in values.items())
        fields = {}
        for key, value in values.items():
            spec = BY_KEY[key]
            fields[spec.field] = to_internal_value(spec, value, rotary)
        return cls(**fields)


def to_internal_value(spec: ParamSpec, value, rotary: bool = False):
    """List value -> internal value (on a rotary axis lengths are degrees: ``scale_for(rotary)``)."""
    if spec.type == "BOOLEAN":
        return bool(value)
    if spec.type == "STRING":
        return _string_value(spec, value)
    if spec.internal_unit in ("-", "increments", "0.1 µm") and spec.type in ("SGN32", "UNS32", "UNS16"):
        return int(value)
    return float(value) * spec.scale_for(rotary)


def to_interface_value(spec: ParamSpec, value, rotary: bool = False):
    if spec.type == "BOOLEAN":
        return int(bool(value))
    if spec.type == "STRING":
        return value.name if isinstance(value, FilterType) else str(value)
    if spec.type == "REAL64":
        return float(value) / spec.scale_for(rotary)
    return int(round(float(value) / spec.scale_for(rotary)))


def check_internal(spec: ParamSpec, value, rotary: bool = False) -> None:
    """Raise ParameterError unless ``value`` (internal units) is legal for ``spec``."""
    if spec.type == "STRING":
        if spec.field == "axis_type":
            if value not in AXIS_TYPE_NAMES:
                raise ParameterError(f"{spec.id} {spec.key} = {value!r} is not allowed; allowed: {spec.range_text()}",
                                     key=spec.key, param_id=spec.id, value=value, allowed=spec.range_text())
            return
        if not isinstance(value, FilterType) or value == FilterType.PASS:
            raise ParameterError(f"{spec.id} {spec.key} = {value!r} is not allowed; allowed: {spec.range_text()}",
                                 key=spec.key, param_id=spec.id, value=value, allowed=spec.range_text())
        return
    if isinstance(value, bool) and spec.type != "BOOLEAN":
        raise ParameterError(f"{spec.id} {spec.key} = {value!r}: expected a number", key=spec.key,
                             param_id=spec.id, value=value, allowed=spec.range_text())
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{spec.id} {spec.key} = {value!r}: expected a number", key=spec.key,
                             param_id=spec.id, value=value, allowed=spec.range_text()) from None
    if not math.isfinite(x):
        raise ParameterError(f"{spec.id} {spec.key} = {value!r} is not finite; allowed: {spec.range_text()}",
                             key=spec.key, param_id=spec.id, value=value, allowed=spec.range_text())
    iv = x / spec.scale_for(rotary)
    # internal floats carry rounding from the scale: compare with a relative slack
    slack = 1e-9 * max(1.0, abs(iv))
    if spec.type == "BOOLEAN":
        ok = iv in (0.0, 1.0)
    elif spec.choices:
        ok = iv in spec.choices
    else:
        ok = True
        if spec.lo is not None:
            ok = iv > spec.lo if spec.lo_open else iv >= spec.lo - slack
        if spec.hi is not None:
            ok = ok and (iv < spec.hi if spec.hi_open else iv <= spec.hi + slack)
    if not ok:
        raise ParameterError(
            f"{spec.id} {spec.key} = {_show(iv)} {_unit(spec, rotary) if spec.unit != '-' else ''}".rstrip()
            + f" is out of range; allowed: {spec.range_text()}",
            key=spec.key, param_id=spec.id, value=iv, allowed=spec.range_text())


def _unit(spec: ParamSpec, rotary: bool) -> str:
    return spec.unit_rotary if rotary and spec.unit_rotary else spec.unit


def _show(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else f"{x:g}"
