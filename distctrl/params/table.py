"""The axis parameter table: declared once, used for loading, validation, defaults and the docs.

Each :class:`ParamSpec` states the parameter as the documents do (ID, list-file key, data type,
interface unit, allowed range, default) plus how it maps onto the internal field of
:class:`~distctrl.params.axis.AxisParameters` (``scale``: internal = interface value * scale).
docs/parameters.md is generated from this table (``make docs``); a test keeps the two in sync.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ..base.kinds import FILTER_TYPE_NAMES

SGN32_MIN, SGN32_MAX = -(2**31), 2**31 - 1
UNS32_MAX = 2**32 - 1


@dataclass(frozen=True)
class ParamSpec:
    id: str                      # P-AXIS-xxxxx
    key: str                     # list-file key as in FCT-M3 §9
    field: str                   # AxisParameters field
    type: str                    # BOOLEAN, SGN32, UNS32, UNS16, REAL64, STRING
    unit: str                    # interface unit (in the list file)
    internal_unit: str           # unit of the AxisParameters field
    scale: float                 # internal = value * scale
    default: object              # in interface units
    lo: float | None = None      # allowed range, interface units
    hi: float | None = None
    lo_open: bool = False        # True: lo itself not allowed
    hi_open: bool = False        # True: hi itself not allowed
    choices: tuple = ()          # for STRING / enumerated integers
    aliases: tuple = ()          # legacy / German keys of the documents' examples, other printed spellings
    description: str = ""
    note: str = ""               # where the project resolved a contradiction of the documents
    unit_rotary: str = ""        # list unit on a rotary axis (P-AXIS-00018 ACHSTYP_ROTATOR), if it differs
    scale_rotary: float | None = None   # internal = value * scale_rotary on a rotary axis (None: scale)
    nc_word: str = ""            # the DIST_CTRL keyword that sets it in a program (FCT-M3 §6), if any
    short_keys: tuple = ()       # names accepted in a filter spec / sweep grid; the first is the canonical one

    @property
    def integer(self) -> bool:
        """True for the integer data types (SGN32, UNS32, UNS16)."""
        return self.type in ("SGN32", "UNS32", "UNS16")

    def scale_for(self, rotary: bool) -> float:
        """internal = list value * this, on a translatory (``rotary`` False) or rotary axis."""
        return self.scale_rotary if rotary and self.scale_rotary is not None else self.scale

    def range_text(self, name: str = "value") -> str:
        """The documented range as text, e.g. ``0 < value <= 1`` (``name`` stands for the value)."""
        if self.choices:
            return "one of " + ", ".join(str(c) for c in self.choices)
        if self.type == "BOOLEAN":
            return "0 or 1"
        lo = "" if self.lo is None else f"{_fmt(self.lo)} {'<' if self.lo_open else '<='} "
        hi = "" if self.hi is None else f" {'<' if self.hi_open else '<='} {_fmt(self.hi)}"
        return f"{lo}{name}{hi}"

    def check(self, value: float) -> bool:
        """True when ``value`` (interface units) lies in the documented range."""
        if self.choices:
            return value in self.choices
        if self.type == "BOOLEAN":
            return value in (0, 1)
        if self.lo is not None and (value < self.lo or (self.lo_open and value == self.lo)):
            return False
        if self.hi is not None and (value > self.hi or (self.hi_open and value == self.hi)):
            return False
        return True


def _fmt(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else repr(x)


def _p(id, key, field, type, unit, internal_unit, scale, default, lo=None, hi=None, **kw) -> ParamSpec:
    return ParamSpec(id, key, field, type, unit, internal_unit, scale, default, lo, hi, **kw)


UM = 1e-4       # 0.1 µm -> mm (0.0001° -> ° on a rotary axis)
UM_S = 1e-3     # µm/s -> mm/s (0.001°/s -> °/s)

#: P-AXIS-00018 axis types distance control is documented for ("Axis types T, R" of every parameter)
AXIS_TYPE_TRANSLATOR = "ACHSTYP_TRANSLATOR"
AXIS_TYPE_ROTATOR = "ACHSTYP_ROTATOR"
AXIS_TYPE_NAMES = (AXIS_TYPE_TRANSLATOR, AXIS_TYPE_ROTATOR)

AXIS_PARAMETERS: tuple[ParamSpec, ...] = (
    _p("P-AXIS-00328", "lr_param.distance_control_on", "enabled", "BOOLEAN", "-", "bool", 1, 0,
       description="Enabling of distance control (spindle with touch probe)"),
    _p("P-AXIS-00413", "kenngr.distc.n_cycles", "n_cycles", "SGN32", "-", "-", 1, 4, 0, 100, hi_open=True,
       nc_word="N_CYCLES", short_keys=("n_cycles",),
       description="Number of sensor values used by the filter (n <= 1: pass-through)"),
    _p("P-AXIS-00414", "kenngr.distc.max_deviation", "max_deviation", "SGN32", "0.1 µm", "mm", UM, 50000,
       0, SGN32_MAX, hi_open=True, aliases=("kenngr.distc.max_abweichung",),
       description="Maximum position offset; exceeding it raises 70331 and the offset is limited"),
    _p("P-AXIS-00415", "kenngr.distc.v_max", "v_max", "SGN32", "µm/s", "mm/s", UM_S, 5000, 0, SGN32_MAX,
       hi_open=True, short_keys=("v_max",), description="Maximum velocity of the offset"),
    _p("P-AXIS-00416", "kenngr.distc.a_max", "a_max", "SGN32", "mm/s²", "mm/s²", 1, 0, 0, SGN32_MAX,
       hi_open=True, short_keys=("a_max",), description="Maximum acceleration of the offset; 0 = axis acceleration P-AXIS-00008"),
    _p("P-AXIS-00417", "kenngr.distc.max_act_value_change", "max_act_value_change", "SGN32", "µm/s", "mm/s",
       UM_S, 5000, 0, SGN32_MAX, hi_open=True, aliases=("kenngr.distc.max_istw_sprung",),
       description="Maximum permissible change speed of the sensor reading (70329)",
       note="unit µm/s (the overview's '0.1 µm/cycle' is wrong, SPEC §12)"),
    _p("P-AXIS-00418", "kenngr.distc.ref_offset", "ref_offset", "SGN32", "0.1 µm", "mm", UM, 0,
       SGN32_MIN, SGN32_MAX, hi_open=True, description="Reference point offset of the sensor measuring system"),
    _p("P-AXIS-00419", "kenngr.distc.max_pos", "max_pos", "SGN32", "0.1 µm", "mm", UM, 50000,
       0, SGN32_MAX, hi_open=True, description="Upper limit of the sensor reading (70330)"),
    _p("P-AXIS-00420", "kenngr.distc.min_pos", "min_pos", "SGN32", "0.1 µm", "mm", UM, -50000,
       SGN32_MIN, SGN32_MAX, hi_open=True, description="Lower limit of the sensor reading (70576)",
       note="documented range '0 <= min_pos' contradicts its own default -50000: SGN32 range"),
    _p("P-AXIS-00421", "kenngr.distc.tolerance", "tolerance", "SGN32", "0.1 µm", "mm", UM, 0, 0, SGN32_MAX,
       hi_open=True, aliases=("kenngr.distc.toleranz",),
       description="Tolerance band inside the sensor limits; also the WAIT target window"),
    _p("P-AXIS-00428", "kenngr.distc.check_sw_limit_switch", "check_sw_limit_switch", "BOOLEAN", "-", "bool",
       1, 0, aliases=("kenngr.distc.check_switch_limit_switch",),
       description="Include the offset in the software limit switch monitoring"),
    _p("P-AXIS-00500", "kenngr.distc.mode_dist_use_both_encoder", "use_both_encoders", "BOOLEAN", "-", "bool",
       1, 0, aliases=("kenngn.distc.mode_dist_use_both_encoder",),
       description="CONST_DIST: couple distance sensor and motor encoder"),
    _p("P-AXIS-00501", "kenngr.distc.use_adaptive_acceleration", "use_adaptive_acceleration", "BOOLEAN", "-",
       "bool", 1, 0, aliases=("kenngn.distc.use_adaptive_acceleration",),
       description="Adaptive weighting of the acceleration by the distance error"),
    _p("P-AXIS-00502", "kenngr.distc.a_min", "a_min", "UNS32", "mm/s²", "mm/s²", 1, 500, 1, UNS32_MAX,
       hi_open=True, description="Minimum acceleration (adaptive weighting)",
       note="FCT-M3 §9.2 prints 'mm/s²' for the axis type R too; on a rotary axis it is read as °/s², the unit "
            "of P-AXIS-00416 a_max it is blended with (an acceleration in mm/s² has no meaning for an angle)"),
    _p("P-AXIS-00504", "kenngr.distc.dist_error_a_min", "dist_error_a_min", "UNS32", "0.1 µm", "mm", UM, 1000,
       0, UNS32_MAX, hi_open=True, description="Distance error up to which a_min is used"),
    _p("P-AXIS-00505", "kenngr.distc.dist_error_a_max", "dist_error_a_max", "UNS32", "0.1 µm", "mm", UM, 5000,
       0, UNS32_MAX, hi_open=True, description="Distance error from which a_max is used"),
    _p("P-AXIS-00507", "kenngr.distc.low_pass_filter_order", "low_pass_filter_order", "UNS32", "-", "-", 1, 4,
       0, 6, nc_word="ORDER", short_keys=("order",), description="Order of the Butterworth low-pass (0 = pass-through)"),
    _p("P-AXIS-00508", "kenngr.distc.low_pass_filter_fg_f0", "low_pass_filter_fg_f0", "REAL64", "Hz", "Hz", 1,
       25.0, 0, None, nc_word="FG_F0", short_keys=("fg_f0",), description="Cut-off frequency of the low-pass; must lie below 1/(2T) when used"),
    _p("P-AXIS-00509", "kenngr.distc.optimized_scheduling", "optimized_scheduling", "BOOLEAN", "-", "bool", 1,
       0, short_keys=("optimized_scheduling",), description="Dead time reduction: 1 = this cycle's sensor value is used, 0 = last cycle's"),
    _p("P-AXIS-00533", "kenngr.distc.v_weight_down", "v_weight_down", "UNS32", "0.1 %", "fraction", 1e-3, 0,
       0, 2000, hi_open=True, description="Velocity weighting of the lowering movement (0 = off)"),
    _p("P-AXIS-00534", "kenngr.distc.a_weight_down", "a_weight_down", "UNS32", "0.1 %", "fraction", 1e-3, 0,
       0, 2000, hi_open=True, aliases=("kenng.disc.a_weight_down",),
       description="Acceleration weighting of the lowering movement (0 = off)"),
    _p("P-AXIS-00422", "lr_hw[1].encoder_resolution_num", "encoder_resolution_num", "UNS32", "increments",
       "increments", 1, 1, 0, UNS32_MAX, lo_open=True, hi_open=True,
       description="Sensor resolution numerator: num increments per denom x 0.1 µm (rotary axis: x 0.0001°)"),
    _p("P-AXIS-00423", "lr_hw[1].encoder_resolution_denom", "encoder_resolution_denom", "UNS32", "0.1 µm",
       "0.1 µm", 1, 1, 0, UNS32_MAX, lo_open=True, hi_open=True,
       description="Sensor resolution denominator (travel in 0.1 µm; rotary axis: in 0.0001°)",
       note="documented '0 <= denom' but 0 would be a zero resolution: 0 < denom"),
    _p("P-AXIS-00230", "lr_hw[1].vz_istw", "sensor_sign_reversal", "BOOLEAN", "-", "bool", 1, 0,
       description="Sign reversal of the sensor reading"),
    _p("P-AXIS-00424", "lr_hw[1].mode_act_pos", "sensor_mode_act_pos", "UNS16", "-", "-", 1, 0,
       choices=(0, 1, 2),
       description="Sensor value range: 0 by axis type P-AXIS-00018 (linear on a translatory axis, modulo on a "
                   "rotary axis), 1 linear, 2 modulo (min_pos..max_pos)"),
    _p("P-AXIS-00759", "kenngr.distc.kp", "kp", "REAL64", "-", "-", 1, 1.0, 0.0, 2.0, lo_open=True,
       nc_word="KP", short_keys=("kp",),
       description="Weighting of the output (P gain)"),
    _p("P-AXIS-00764", "kenngr.distc.i_tn", "i_tn", "REAL64", "s", "s", 1, 0.0, 0.0, 50.0, nc_word="I_TN", short_keys=("i_tn",),
       description="Integral action time (0 = no I component)"),
    _p("P-AXIS-00765", "kenngr.distc.d_tv", "d_tv", "REAL64", "s", "s", 1, 0.0, 0.0, 2.0, nc_word="D_TV", short_keys=("d_tv",),
       description="Derivative action time (0 = no D component)"),
    _p("P-AXIS-00782", "kenngr.distc.filter_type", "filter_type", "STRING", "-", "-", 1, "DEFAULT",
       choices=FILTER_TYPE_NAMES, nc_word="FILTER_TYPE", short_keys=("filter_type",), aliases=("kenng.disc.filter_type",), description="Filter for the sensor values"),
    _p("P-AXIS-00783", "kenngr.distc.kalman_sigma", "kalman_sigma", "REAL64", "-", "-", 1, 4.0, 1.0, 10000.0,
       nc_word="KALMAN_SIGMA", short_keys=("kalman_sigma", "sigma"),
       aliases=("kenngr.distc.sigma", "kenng.disc.kalman_sigma"), description="Kalman filter: uncertainty of the measured values"),
    _p("P-AXIS-00784", "kenngr.distc.smoothing_factor", "smoothing_factor", "REAL64", "-", "-", 1, 0.7, 0.0, 1.0,
       lo_open=True, nc_word="SMOOTH_FACT", short_keys=("smoothing_factor", "smooth_fact"), aliases=("kenngn.distc.smoothing_factor",),
       description="Exponential mean: weight of the newest value"),
    # --- axis type (ISG axis list): translatory (T, mm) or rotary (R, °) distance-controlled axis ---
    _p("P-AXIS-00018", "kenngr.achs_typ", "axis_type", "STRING", "-", "-", 1, AXIS_TYPE_TRANSLATOR,
       choices=AXIS_TYPE_NAMES,
       description="Axis type: ACHSTYP_TRANSLATOR (T: lengths in mm, list units 0.1 µm, µm/s) or ACHSTYP_ROTATOR "
                   "(R: angles in °, list units 0.0001°, 0.001°/s; P-AXIS-00424 = 0 is modulo); also 0x0001 / 0x0002",
       note="ISG axis list; every distance-control parameter is documented for the axis types T and R "
            "(SPEC §12); a spindle (ACHSTYP_SPINDEL) has no distance control"),
    # --- project parameter (the documents name the case, not a parameter) ---
    _p("PRJ-AXIS-0001", "kenngr.distc.sensor_absolute", "sensor_absolute", "BOOLEAN", "-", "bool", 1, 1,
       description="The sensor (encoder 2) delivers absolute values; 0: it must be referenced (REF) before a "
                   "select, else error 900008",
       note="project parameter: HLI DistanceControl transitions 1, 4, 5, 6 require referencing 'if no absolute "
            "encoder is used' but name no parameter for it"),
    # --- axis data the controller needs (ISG axis list, not part of the distance-control documents) ---
    _p("P-AXIS-00008", "getriebe[0].amax", "axis_a_max", "UNS32", "mm/s²", "mm/s²", 1, 1000, 0, UNS32_MAX,
       lo_open=True, hi_open=True, description="Maximum axis acceleration (used when a_max = 0)"),
    _p("P-AXIS-00177", "getriebe[0].swe_pos", "sw_limit_max", "SGN32", "0.1 µm", "mm", UM, SGN32_MAX - 1,
       SGN32_MIN, SGN32_MAX, hi_open=True, description="Positive software limit switch of the axis"),
    _p("P-AXIS-00178", "getriebe[0].swe_neg", "sw_limit_min", "SGN32", "0.1 µm", "mm", UM, SGN32_MIN,
       SGN32_MIN, SGN32_MAX, hi_open=True, description="Negative software limit switch of the axis"),
)

#: the list unit of a rotary axis (FCT-M3 §9.2, column "Dimension R") where it differs from T; P-AXIS-00417's
#: R unit 0.0001°/s has a different scale than its T unit µm/s. P-AXIS-00502 documents "mm/s²" for R too,
#: read as °/s² like a_max.
_ROTARY_UNITS = {"0.1 µm": ("0.0001°", None), "µm/s": ("0.001°/s", None), "mm/s²": ("°/s²", None)}
_ROTARY_SPECIAL = {"P-AXIS-00417": ("0.0001°/s", 1e-4), "P-AXIS-00423": ("0.0001°", None)}


def _with_rotary_units(spec: ParamSpec) -> ParamSpec:
    if spec.id in _ROTARY_SPECIAL:
        unit, scale = _ROTARY_SPECIAL[spec.id]
    elif spec.unit in _ROTARY_UNITS:
        unit, scale = _ROTARY_UNITS[spec.unit]
    else:
        return spec
    return dataclasses.replace(spec, unit_rotary=unit, scale_rotary=scale)


AXIS_PARAMETERS = tuple(_with_rotary_units(s) for s in AXIS_PARAMETERS)

#: Keys the list format knows but the controller does not use (accepted and ignored, with no error).
IGNORED_KEYS: frozenset[str] = frozenset()

BY_KEY: dict[str, ParamSpec] = {}
for _spec in AXIS_PARAMETERS:
    BY_KEY[_spec.key] = _spec
    for _alias in _spec.aliases:
        BY_KEY[_alias] = _spec
BY_FIELD: dict[str, ParamSpec] = {s.field: s for s in AXIS_PARAMETERS}
BY_ID: dict[str, ParamSpec] = {s.id: s for s in AXIS_PARAMETERS}
#: DIST_CTRL keyword -> the parameter it sets (FCT-M3 §6); the NC grammar's number and name keys include them
BY_NC_WORD: dict[str, ParamSpec] = {s.nc_word: s for s in AXIS_PARAMETERS if s.nc_word}


def short_key_fields(specs=AXIS_PARAMETERS) -> dict[str, str]:
    """Every accepted short key (and the field name itself) -> field, for the specs with short keys."""
    return {k: s.field for s in specs if s.short_keys for k in (*s.short_keys, s.field)}
