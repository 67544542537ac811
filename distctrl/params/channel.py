"""Channel parameters of the 3D (channel-specific) distance control (FCT-M3 §12.8).

:data:`CHANNEL_PARAMETERS` is the declarative table, in the same form as the axis table
(:mod:`distctrl.params.table`): P-CHAN-00500 ``configuration.decoder.function`` and
P-CHAN-00800 … 00827 ``dist_ctrl[0].*`` with the IDs, keys, data types, list units, ranges and
defaults of §12.8.2. docs/parameters-channel.md is generated from it
(``python -m distctrl.params.docgen --channel``).

:class:`ChannelParameters` holds the values in internal units (mm, s, Hz, fractions);
:meth:`ChannelParameters.to_axis_parameters` gives the same law parameters as an
``AxisParameters`` for the shared cycle core. Channel lists are read by the axis list reader
(:mod:`distctrl.params.listfile`) with :data:`CHANNEL_LIST`:
:func:`load_channel_list` / :func:`parse_channel_list_text`.

Decisions where §12.8 is unclear (also in docs/parameters-channel.md):

* Only ``i = 0`` exists ("i can only have the value 0", §12.8.1): ``dist_ctrl[1].kp`` is a load
  error naming the P-CHAN ID.
* P-CHAN-00803 ``a_max`` is documented ``0 < a_max`` with default 0 and "must be specified, else
  error 315001". The loader accepts 0 (= not specified); the runtime raises 315001 when the 3D
  distance control is selected with ``a_max = 0`` (SPEC §6). ``to_axis_parameters`` keeps 0 — the
  axis meaning "0 = axis acceleration" must not be applied to the 3D variant.
* P-CHAN-00804 unit µm/s (the overview's "0.1 µm/cycle" is wrong, SPEC §12).
* P-CHAN-00807 ``min_pos``: documented ``0 <= min_pos`` contradicts its default −50000 and the
  §12.8.3 example −1500000: full SGN32 range, as for the axis table. P-CHAN-00806 ``max_pos``
  keeps its documented ``0 <= max_pos`` (default 50000 and the example 1500000 agree with it).
* P-CHAN-00815 ``low_pass_filter_enable`` (only in §12.8.2, the legacy switch that the axis
  variant replaced by filter type LOWPASS): 1 selects LOWPASS while ``filter_type`` is DEFAULT;
  any other ``filter_type`` wins (:attr:`ChannelParameters.effective_filter_type`).
* P-CHAN-00500: one name per list line. Only FCT_3D_DIST_CTRL matters here
  (``fct_3d_dist_ctrl``); the other documented names (FCT_USE_CACHED_FILES,
  FCT_VOL_COMP_COMPUTATION, ``-``) are accepted and mean "3D distance control off".
"""
from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from pathlib import Path

from ..base.kinds import FILTER_TYPE_NAMES, FilterType
from ..errors import ParameterError
from .axis import AxisParameters, check_internal, to_interface_value, to_internal_value
from .listfile import KeyProblem, ListFormat, ParameterList, format_list, load_list, parse_list_text
from .table import SGN32_MAX, SGN32_MIN, UM, UM_S, UNS32_MAX, ParamSpec, _p

#: the value of P-CHAN-00500 that enables 3D distance control
FCT_3D_DIST_CTRL = "FCT_3D_DIST_CTRL"
#: the names §12.8.2 documents for P-CHAN-00500 ("-": no functionalities defined)
DECODER_FUNCTIONS = ("FCT_USE_CACHED_FILES", "FCT_VOL_COMP_COMPUTATION", FCT_3D_DIST_CTRL, "-")
#: IDs in P-CHAN-00800 … 00827 that the documents do not define
UNDOCUMENTED_IDS = ("P-CHAN-00809", "P-CHAN-00818", "P-CHAN-00824")

_D = "dist_ctrl[0]."
_SINCE = "as of V3.1.3080.12 / V3.1.3107.44"

CHANNEL_PARAMETERS: tuple[ParamSpec, ...] = (
    _p("P-CHAN-00500", "configuration.decoder.function", "fct_3d_dist_ctrl", "STRING", "-", "bool", 1, "",
       choices=DECODER_FUNCTIONS,
       description="Decoder function enable; FCT_3D_DIST_CTRL enables 3D distance control "
                   "(without it #DIST CTRL is error 20209)",
       note="default is a blank string (no function); only FCT_3D_DIST_CTRL is used here, the other "
            "names are accepted and leave 3D distance control off"),
    _p("P-CHAN-00800", _D + "n_cycles", "n_cycles", "SGN32", "-", "-", 1, 4, 0, 100, hi_open=True,
       description="Number of sensor values used by the filter (n <= 1: pass-through)"),
    _p("P-CHAN-00801", _D + "max_deviation", "max_deviation", "SGN32", "0.1 µm", "mm", UM, 50000,
       0, SGN32_MAX, hi_open=True,
       description="Maximum position offset; exceeding it raises 70331/310017 and the offset is limited"),
    _p("P-CHAN-00802", _D + "v_max", "v_max", "SGN32", "µm/s", "mm/s", UM_S, 5000, 0, SGN32_MAX, hi_open=True,
       description="Maximum velocity of the offset"),
    _p("P-CHAN-00803", _D + "a_max", "a_max", "SGN32", "mm/s²", "mm/s²", 1, 0, 0, SGN32_MAX, hi_open=True,
       description="Maximum acceleration of the offset; must be specified (> 0)",
       note="documented '0 < a_max' with default 0: 0 (= not specified) loads, and selecting 3D "
            "distance control with a_max = 0 raises 315001 at run time (SPEC §6)"),
    _p("P-CHAN-00804", _D + "max_act_value_change", "max_act_value_change", "SGN32", "µm/s", "mm/s", UM_S,
       5000, 0, SGN32_MAX, hi_open=True,
       description="Maximum permissible change speed of the sensor reading (70329/310018)",
       note="unit µm/s (the overview's '0.1 µm/cycle' is wrong, SPEC §12)"),
    _p("P-CHAN-00805", _D + "ref_offset", "ref_offset", "SGN32", "0.1 µm", "mm", UM, 0, SGN32_MIN, SGN32_MAX,
       hi_open=True, description="Reference point offset of the sensor measuring system"),
    _p("P-CHAN-00806", _D + "max_pos", "max_pos", "SGN32", "0.1 µm", "mm", UM, 50000, 0, SGN32_MAX,
       hi_open=True, description="Upper limit of the sensor reading (70330/310019)"),
    _p("P-CHAN-00807", _D + "min_pos", "min_pos", "SGN32", "0.1 µm", "mm", UM, -50000, SGN32_MIN, SGN32_MAX,
       hi_open=True, description="Lower limit of the sensor reading (70576)",
       note="documented range '0 <= min_pos' contradicts its own default -50000 and the §12.8.3 "
            "example -1500000: SGN32 range"),
    _p("P-CHAN-00808", _D + "tolerance", "tolerance", "SGN32", "0.1 µm", "mm", UM, 0, 0, SGN32_MAX,
       hi_open=True, description="Tolerance band inside the sensor limits; also the WAIT target window"),
    _p("P-CHAN-00810", _D + "mode_dist_use_both_encoder", "use_both_encoders", "BOOLEAN", "-", "bool", 1, 0,
       description="CONST_DIST: couple distance sensor and motor encoder"),
    _p("P-CHAN-00811", _D + "use_adaptive_acceleration", "use_adaptive_acceleration", "BOOLEAN", "-", "bool",
       1, 0, description="Adaptive weighting of the acceleration by the distance error"),
    _p("P-CHAN-00812", _D + "a_min", "a_min", "UNS32", "mm/s²", "mm/s²", 1, 500, 1, UNS32_MAX,
       description="Minimum acceleration (adaptive weighting)"),
    _p("P-CHAN-00813", _D + "dist_error_a_min", "dist_error_a_min", "UNS32", "0.1 µm", "mm", UM, 1000,
       0, UNS32_MAX, hi_open=True, description="Distance error up to which a_min is used"),
    _p("P-CHAN-00814", _D + "dist_error_a_max", "dist_error_a_max", "UNS32", "0.1 µm", "mm", UM, 5000,
       0, UNS32_MAX, hi_open=True, description="Distance error from which a_max is used"),
    _p("P-CHAN-00815", _D + "low_pass_filter_enable", "low_pass_filter_enable", "BOOLEAN", "-", "bool", 1, 0,
       description="Low-pass filter on (legacy switch; filter_type LOWPASS is the current way)",
       note="not in the §12.8.1 overview; 1 selects LOWPASS while filter_type is DEFAULT, any other "
            "filter_type wins"),
    _p("P-CHAN-00816", _D + "low_pass_filter_order", "low_pass_filter_order", "UNS32", "-", "-", 1, 4, 0, 6,
       description="Order of the Butterworth low-pass (0 = pass-through)"),
    _p("P-CHAN-00817", _D + "low_pass_filter_fg_f0", "low_pass_filter_fg_f0", "REAL64", "Hz", "Hz", 1, 25.0,
       0, None, description="Cut-off frequency of the low-pass; must lie below 1/(2T) when used"),
    _p("P-CHAN-00819", _D + "v_weight_down", "v_weight_down", "UNS32", "0.1 %", "fraction", 1e-3, 0, 0, 2000,
       hi_open=True, description="Velocity weighting of the lowering movement (0 = off)"),
    _p("P-CHAN-00820", _D + "a_weight_down", "a_weight_down", "UNS32", "0.1 %", "fraction", 1e-3, 0, 0, 2000,
       hi_open=True, description="Acceleration weighting of the lowering movement (0 = off)"),
    _p("P-CHAN-00821", _D + "kp", "kp", "REAL64", "-", "-", 1, 1.0, 0.0, 2.0, lo_open=True,
       description="Weighting of the output (P gain); NC KP= is analogous"),
    _p("P-CHAN-00822", _D + "i_tn", "i_tn", "REAL64", "s", "s", 1, 0.0, 0.0, 50.0,
       description="Integral action time (0 = no I component); NC I_TN= is analogous"),
    _p("P-CHAN-00823", _D + "d_tv", "d_tv", "REAL64", "s", "s", 1, 0.0, 0.0, 2.0,
       description="Derivative action time (0 = no D component); NC D_TV= is analogous"),
    _p("P-CHAN-00825", _D + "filter_type", "filter_type", "STRING", "-", "-", 1, "DEFAULT",
       choices=FILTER_TYPE_NAMES, description="Filter for the sensor values; NC FILTER_TYPE="),
    _p("P-CHAN-00826", _D + "kalman_sigma", "kalman_sigma", "REAL64", "-", "-", 1, 4.0, 1.0, 10000.0,
       description="Kalman filter: uncertainty of the measured values; NC KALMAN_SIGMA="),
    _p("P-CHAN-00827", _D + "smoothing_factor", "smoothing_factor", "REAL64", "-", "-", 1, 0.7, 0.0, 1.0,
       lo_open=True, description="Exponential mean: weight of the newest value; NC SMOOTH_FACT="),
)

BY_KEY: dict[str, ParamSpec] = {s.key: s for s in CHANNEL_PARAMETERS}
BY_FIELD: dict[str, ParamSpec] = {s.field: s for s in CHANNEL_PARAMETERS}
BY_ID: dict[str, ParamSpec] = {s.id: s for s in CHANNEL_PARAMETERS}

#: ChannelParameters fields that AxisParameters has under the same name and meaning
AXIS_FIELDS: tuple[str, ...] = tuple(
    s.field for s in CHANNEL_PARAMETERS if s.field not in ("fct_3d_dist_ctrl", "low_pass_filter_enable"))


# ---------------------------------------------------------------- value conversions

def channel_to_internal(spec: ParamSpec, value):
    """Interface (list) value -> ChannelParameters field value."""
    if spec.field == "fct_3d_dist_ctrl":
        return str(value).strip().upper() == FCT_3D_DIST_CTRL
    return to_internal_value(spec, value)


def channel_to_interface(spec: ParamSpec, value):
    """ChannelParameters field value -> interface (list) value."""
    if spec.field == "fct_3d_dist_ctrl":
        return FCT_3D_DIST_CTRL if value else "-"
    return to_interface_value(spec, value)


def _parse_string(spec: ParamSpec, text: str) -> object:
    if spec.field == "fct_3d_dist_ctrl":
        name = text.strip().upper()
        if name not in DECODER_FUNCTIONS:
            raise ValueError(f"unknown decoder function {text!r}")
        return name
    return FilterType.parse(text).name


def _default(spec: ParamSpec):
    if spec.field == "fct_3d_dist_ctrl":
        return False
    return to_internal_value(spec, spec.default)


_INDEXED_KEY = re.compile(r"^dist_ctrl\[([0-9]+)\]\.(.+)$")


def resolve_channel_key(key: str) -> tuple[str, KeyProblem | None]:
    """``dist_ctrl[i].name`` -> ``dist_ctrl[0].name``; any ``i`` other than 0 is a problem."""
    match = _INDEXED_KEY.match(key)
    if match is None:
        return key, None
    canonical = f"dist_ctrl[0].{match.group(2)}"
    index = int(match.group(1))
    if index != 0:
        return canonical, KeyProblem(
            f"index i = {index} does not exist: only i = 0 is allowed (one 3D distance control per "
            "channel, FCT-M3 §12.8.1)", canonical)
    return canonical, None


# ---------------------------------------------------------------- the parameter set

@dataclass(frozen=True)
class ChannelParameters:
    """3D distance-control parameters of one channel (internal units; docs/parameters-channel.md).

    Every construction is validated against the documented ranges (ParameterError naming the
    P-CHAN ID, value and range), so a ``ChannelParameters`` is always a legal parameter set.
    """

    fct_3d_dist_ctrl: bool = _default(BY_FIELD["fct_3d_dist_ctrl"])              # P-CHAN-00500
    n_cycles: int = _default(BY_FIELD["n_cycles"])
    max_deviation: float = _default(BY_FIELD["max_deviation"])                  # mm
    v_max: float = _default(BY_FIELD["v_max"])                                  # mm/s
    a_max: float = _default(BY_FIELD["a_max"])                                  # mm/s², 0 -> 315001 at select
    max_act_value_change: float = _default(BY_FIELD["max_act_value_change"])    # mm/s
    ref_offset: float = _default(BY_FIELD["ref_offset"])                        # mm
    max_pos: float = _default(BY_FIELD["max_pos"])                              # mm
    min_pos: float = _default(BY_FIELD["min_pos"])                              # mm
    tolerance: float = _default(BY_FIELD["tolerance"])                          # mm
    use_both_encoders: bool = _default(BY_FIELD["use_both_encoders"])
    use_adaptive_acceleration: bool = _default(BY_FIELD["use_adaptive_acceleration"])
    a_min: float = _default(BY_FIELD["a_min"])                                  # mm/s²
    dist_error_a_min: float = _default(BY_FIELD["dist_error_a_min"])            # mm
    dist_error_a_max: float = _default(BY_FIELD["dist_error_a_max"])            # mm
    low_pass_filter_enable: bool = _default(BY_FIELD["low_pass_filter_enable"])
    low_pass_filter_order: int = _default(BY_FIELD["low_pass_filter_order"])
    low_pass_filter_fg_f0: float = _default(BY_FIELD["low_pass_filter_fg_f0"])  # Hz
    v_weight_down: float = _default(BY_FIELD["v_weight_down"])                  # fraction, 0 = off
    a_weight_down: float = _default(BY_FIELD["a_weight_down"])                  # fraction, 0 = off
    kp: float = _default(BY_FIELD["kp"])
    i_tn: float = _default(BY_FIELD["i_tn"])                                    # s
    d_tv: float = _default(BY_FIELD["d_tv"])                                    # s
    filter_type: FilterType = _default(BY_FIELD["filter_type"])
    kalman_sigma: float = _default(BY_FIELD["kalman_sigma"])
    smoothing_factor: float = _default(BY_FIELD["smoothing_factor"])

    def __post_init__(self) -> None:
        if isinstance(self.filter_type, str):
            object.__setattr__(self, "filter_type", FilterType.parse(self.filter_type))
        for spec in CHANNEL_PARAMETERS:
            value = getattr(self, spec.field)
            if spec.field == "fct_3d_dist_ctrl":
                if not isinstance(value, bool):
                    raise ParameterError(
                        f"{spec.id} {spec.key}: fct_3d_dist_ctrl must be a bool, got {value!r}",
                        key=spec.key, param_id=spec.id, value=value, allowed=spec.range_text())
                continue
            check_internal(spec, value)
        if self.min_pos + self.tolerance >= self.max_pos - self.tolerance:
            raise ParameterError(
                f"P-CHAN-00806/00807/00808 sensor window is empty: min_pos + tolerance "
                f"({self.min_pos + self.tolerance:g} mm) must be below max_pos - tolerance "
                f"({self.max_pos - self.tolerance:g} mm)",
                key=f"{_D}min_pos/{_D}max_pos/{_D}tolerance", param_id="P-CHAN-00806/00807/00808")

    # ------------------------------------------------------------------ derived values
    @property
    def effective_filter_type(self) -> FilterType:
        """filter_type, or LOWPASS when the legacy switch P-CHAN-00815 is on and filter_type is DEFAULT."""
        if self.low_pass_filter_enable and self.filter_type == FilterType.DEFAULT:
            return FilterType.LOWPASS
        return self.filter_type

    def to_axis_parameters(self) -> AxisParameters:
        """The same law parameters as ``AxisParameters`` for the shared cycle core.

        ``enabled`` = ``fct_3d_dist_ctrl``; every field in :data:`AXIS_FIELDS` is copied 1:1
        (``filter_type`` as :attr:`effective_filter_type`). ``a_max = 0`` stays 0: the 3D runtime
        must raise 315001 at select time instead of using the axis acceleration (SPEC §6). The
        axis-only fields (sensor encoder scaling, software limits, optimized_scheduling,
        check_sw_limit_switch, axis_a_max) keep their defaults.
        """
        fields = {name: getattr(self, name) for name in AXIS_FIELDS}
        fields["filter_type"] = self.effective_filter_type
        return AxisParameters(enabled=self.fct_3d_dist_ctrl, **fields)

    def replace(self, **changes) -> "ChannelParameters":
        """A copy with fields changed (internal units), validated."""
        return dataclasses.replace(self, **changes)

    def to_interface(self) -> dict[str, object]:
        """Values in the list file's units, keyed by the list-file key."""
        return {spec.key: channel_to_interface(spec, getattr(self, spec.field))
                for spec in CHANNEL_PARAMETERS}

    @classmethod
    def from_interface(cls, values: dict[str, object]) -> "ChannelParameters":
        """Build from list-file keys (``dist_ctrl[0].kp`` …) and interface-unit values."""
        fields = {}
        for key, value in values.items():
            spec = BY_KEY[resolve_channel_key(key)[0]]
            fields[spec.field] = channel_to_internal(spec, value)
        return cls(**fields)


#: the channel list kind for :mod:`distctrl.params.listfile`
CHANNEL_LIST = ListFormat("channel", CHANNEL_PARAMETERS, ChannelParameters, channel_to_internal,
                          channel_to_interface, parse_string=_parse_string, resolve_key=resolve_channel_key,
                          docs="docs/parameters-channel.md", by_key=BY_KEY)


def parse_channel_list_text(text: str, source: str = "<string>",
                            base: ChannelParameters | None = None) -> ParameterList:
    """Parse a channel list (``.params`` is a :class:`ChannelParameters`)."""
    return parse_list_text(text, source, base, fmt=CHANNEL_LIST)


def load_channel_list(path: str | Path, base: ChannelParameters | None = None) -> ParameterList:
    """Load a channel list file, e.g. examples/channel_3d_12_8_3.lis."""
    return load_list(path, base, fmt=CHANNEL_LIST)


def format_channel_list(params: ChannelParameters, *, only_changed: bool = False,
                        comments: bool = True) -> str:
    """Write channel parameters in the kernel list format (loadable by :func:`parse_channel_list_text`)."""
    return format_list(params, only_changed=only_changed, comments=comments, fmt=CHANNEL_LIST)


__all__ = ["CHANNEL_PARAMETERS", "CHANNEL_LIST", "ChannelParameters", "FCT_3D_DIST_CTRL", "DECODER_FUNCTIONS",
           "UNDOCUMENTED_IDS", "AXIS_FIELDS", "BY_KEY", "BY_FIELD", "BY_ID", "parse_channel_list_text",
           "load_channel_list", "format_channel_list", "resolve_channel_key", "channel_to_internal",
           "channel_to_interface"]
