"""Channel parameters of the 3D distance control (FCT-M3 §12.8) and the channel list format."""
from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import pytest

from distctrl.base.kinds import FilterType
from distctrl.errors import ParameterError
from distctrl.params import AxisParameters, parse_list_text
from distctrl.params.channel import (
    AXIS_FIELDS, CHANNEL_LIST, CHANNEL_PARAMETERS, BY_ID, ChannelParameters, format_channel_list,
    load_channel_list, parse_channel_list_text,
)
from distctrl.params.listfile import load_list

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "channel_3d_12_8_3.lis"
MAX_SGN32, MIN_SGN32, MAX_UNS32 = 2**31 - 1, -(2**31), 2**32 - 1

# ---------------------------------------------------------------- the document's table (§12.8.2)

#: ID -> (key, data type, list unit, range as documented, default as documented).
#: Written from FCT-M3 §12.8.2; "0.1 10^-3 mm" is written 0.1 µm.
DOCUMENTED = {
    "P-CHAN-00500": ("configuration.decoder.function", "STRING", "-",
                     "FCT_USE_CACHED_FILES FCT_VOL_COMP_COMPUTATION FCT_3D_DIST_CTRL -", ""),
    "P-CHAN-00800": ("dist_ctrl[0].n_cycles", "SGN32", "-", "0 <= n_cycles < 100", 4),
    "P-CHAN-00801": ("dist_ctrl[0].max_deviation", "SGN32", "0.1 µm", "0 <= max_deviation < MAX(SGN32)", 50000),
    "P-CHAN-00802": ("dist_ctrl[0].v_max", "SGN32", "µm/s", "0 <= v_max < MAX(SGN32)", 5000),
    "P-CHAN-00803": ("dist_ctrl[0].a_max", "SGN32", "mm/s²", "0 < a_max < MAX(SGN32)", 0),
    "P-CHAN-00804": ("dist_ctrl[0].max_act_value_change", "SGN32", "µm/s",
                     "0 <= max_act_value_change < MAX(SGN32)", 5000),
    "P-CHAN-00805": ("dist_ctrl[0].ref_offset", "SGN32", "0.1 µm", "MIN(SGN32) <= ref_offset < MAX(SGN32)", 0),
    "P-CHAN-00806": ("dist_ctrl[0].max_pos", "SGN32", "0.1 µm", "0 <= max_pos < MAX(SGN32)", 50000),
    "P-CHAN-00807": ("dist_ctrl[0].min_pos", "SGN32", "0.1 µm", "0 <= min_pos < MAX(SGN32)", -50000),
    "P-CHAN-00808": ("dist_ctrl[0].tolerance", "SGN32", "0.1 µm", "0 <= P-CHAN-00808 < MAX(SGN32)", 0),
    "P-CHAN-00810": ("dist_ctrl[0].mode_dist_use_both_encoder", "BOOLEAN", "-", "0 1", 0),
    "P-CHAN-00811": ("dist_ctrl[0].use_adaptive_acceleration", "BOOLEAN", "-", "0 1", 0),
    "P-CHAN-00812": ("dist_ctrl[0].a_min", "UNS32", "mm/s²", "1 ... MAX(UNS32)", 500),
    "P-CHAN-00813": ("dist_ctrl[0].dist_error_a_min", "UNS32", "0.1 µm", "0 <= dist_error_a_min < MAX(UNS32)", 1000),
    "P-CHAN-00814": ("dist_ctrl[0].dist_error_a_max", "UNS32", "0.1 µm", "0 <= dist_error_a_max < MAX(UNS32)", 5000),
    "P-CHAN-00815": ("dist_ctrl[0].low_pass_filter_enable", "BOOLEAN", "-", "0 1", 0),
    "P-CHAN-00816": ("dist_ctrl[0].low_pass_filter_order", "UNS32", "-", "0 ... 6", 4),
    "P-CHAN-00817": ("dist_ctrl[0].low_pass_filter_fg_f0", "REAL64", "Hz",
                     "0 <= low_pass_filter_fg_f0 < MAX(REAL64)", 25),
    "P-CHAN-00819": ("dist_ctrl[0].v_weight_down", "UNS32", "0.1 %", "0 <= v_weight_down < 2000", 0),
    "P-CHAN-00820": ("dist_ctrl[0].a_weight_down", "UNS32", "0.1 %", "0 <= a_weight_down < 2000", 0),
    "P-CHAN-00821": ("dist_ctrl[0].kp", "REAL64", "-", "0.0 < kp <= 2.0", 1.0),
    "P-CHAN-00822": ("dist_ctrl[0].i_tn", "REAL64", "s", "0.0 <= i_tn <= 50.0", 0.0),
    "P-CHAN-00823": ("dist_ctrl[0].d_tv", "REAL64", "s", "0.0 <= d_tv <= 2.0", 0.0),
    "P-CHAN-00825": ("dist_ctrl[0].filter_type", "STRING", "-",
                     "DEFAULT MOVING_AVERAGE LOWPASS KALMAN_MA EXPO_MEAN KALMAN_EXPO", "DEFAULT"),
    "P-CHAN-00826": ("dist_ctrl[0].kalman_sigma", "REAL64", "-", "1.0 <= P-CHAN-00826 <= 10000.0", 4),
    "P-CHAN-00827": ("dist_ctrl[0].smoothing_factor", "REAL64", "-", "0 < P-CHAN-00827 <= 1.0", 0.7),
}

#: the range each numeric parameter is checked against: (lo, lo_open, hi, hi_open). Equal to the
#: documented range except where the project resolved a contradiction of the documents.
CHECKED_RANGES = {
    "P-CHAN-00800": (0, False, 100, True),
    "P-CHAN-00801": (0, False, MAX_SGN32, True),
    "P-CHAN-00802": (0, False, MAX_SGN32, True),
    "P-CHAN-00803": (0, False, MAX_SGN32, True),       # documented 0 < a_max, default 0: 0 loads, 315001 at run time
    "P-CHAN-00804": (0, False, MAX_SGN32, True),
    "P-CHAN-00805": (MIN_SGN32, False, MAX_SGN32, True),
    "P-CHAN-00806": (0, False, MAX_SGN32, True),           # as documented (nothing contradicts 0 <= max_pos)
    "P-CHAN-00807": (MIN_SGN32, False, MAX_SGN32, True),   # documented 0 <= min_pos contradicts default -50000
    "P-CHAN-00808": (0, False, MAX_SGN32, True),
    "P-CHAN-00812": (1, False, MAX_UNS32, False),
    "P-CHAN-00813": (0, False, MAX_UNS32, True),
    "P-CHAN-00814": (0, False, MAX_UNS32, True),
    "P-CHAN-00816": (0, False, 6, False),
    "P-CHAN-00817": (0, False, None, False),
    "P-CHAN-00819": (0, False, 2000, True),
    "P-CHAN-00820": (0, False, 2000, True),
    "P-CHAN-00821": (0.0, True, 2.0, False),
    "P-CHAN-00822": (0.0, False, 50.0, False),
    "P-CHAN-00823": (0.0, False, 2.0, False),
    "P-CHAN-00826": (1.0, False, 10000.0, False),
    "P-CHAN-00827": (0.0, True, 1.0, False),
}


def test_every_documented_id_is_in_the_table_and_nothing_else():
    assert {s.id for s in CHANNEL_PARAMETERS} == set(DOCUMENTED)
    assert len(CHANNEL_PARAMETERS) == len(DOCUMENTED)   # no ID twice
    # 00809, 00818 and 00824 are not defined by the documents
    for missing in ("P-CHAN-00809", "P-CHAN-00818", "P-CHAN-00824"):
        assert missing not in BY_ID


@pytest.mark.parametrize("pid", sorted(DOCUMENTED))
def test_key_type_unit_and_default_are_the_documented_ones(pid):
    key, dtype, unit, _documented_range, default = DOCUMENTED[pid]
    spec = BY_ID[pid]
    assert (spec.key, spec.type, spec.unit) == (key, dtype, unit)
    assert spec.default == default


@pytest.mark.parametrize("pid", sorted(CHECKED_RANGES))
def test_numeric_ranges(pid):
    lo, lo_open, hi, hi_open = CHECKED_RANGES[pid]
    spec = BY_ID[pid]
    assert (spec.lo, spec.lo_open, spec.hi, spec.hi_open) == (lo, lo_open, hi, hi_open)
    if pid in ("P-CHAN-00803", "P-CHAN-00807"):   # deviates from DOCUMENTED[pid][3]
        assert spec.note and "documented" in spec.note


def test_enumerations_and_booleans():
    assert BY_ID["P-CHAN-00500"].choices == tuple(DOCUMENTED["P-CHAN-00500"][3].split())
    assert BY_ID["P-CHAN-00825"].choices == tuple(DOCUMENTED["P-CHAN-00825"][3].split())
    for pid in ("P-CHAN-00810", "P-CHAN-00811", "P-CHAN-00815"):
        assert BY_ID[pid].range_text() == "0 or 1"


def test_unit_of_00804_is_um_per_s_as_the_description_says():
    spec = BY_ID["P-CHAN-00804"]
    assert spec.unit == "µm/s" and "0.1 µm/cycle" in spec.note


def test_defaults_in_internal_units():
    p = ChannelParameters()
    assert p.fct_3d_dist_ctrl is False
    assert (p.n_cycles, p.kp, p.i_tn, p.d_tv, p.a_max) == (4, 1.0, 0.0, 0.0, 0.0)
    assert p.max_deviation == pytest.approx(5.0) and p.v_max == pytest.approx(5.0)      # 50000 x 0.1 µm, 5000 µm/s
    assert p.max_act_value_change == pytest.approx(5.0)
    assert p.max_pos == pytest.approx(5.0) and p.min_pos == pytest.approx(-5.0) and p.tolerance == 0.0
    assert p.a_min == 500 and p.dist_error_a_min == pytest.approx(0.1) and p.dist_error_a_max == pytest.approx(0.5)
    assert p.low_pass_filter_enable is False and p.low_pass_filter_order == 4 and p.low_pass_filter_fg_f0 == 25.0
    assert p.v_weight_down == 0.0 and p.a_weight_down == 0.0
    assert p.filter_type == FilterType.DEFAULT and p.kalman_sigma == 4.0 and p.smoothing_factor == 0.7
    assert p.use_both_encoders is False and p.use_adaptive_acceleration is False


# ---------------------------------------------------------------- the §12.8.3 example list

def test_example_list_of_12_8_3_loads_with_its_values():
    pl = load_channel_list(EXAMPLE)
    p = pl.params
    assert isinstance(p, ChannelParameters)
    assert p.fct_3d_dist_ctrl is True                          # FCT_3D_DIST_CTRL
    assert p.max_deviation == pytest.approx(1000.0)            # 10000000 x 0.1 µm
    assert p.v_max == pytest.approx(10.0)                      # 10000 µm/s
    assert p.a_max == 100.0                                    # mm/s²
    assert p.max_act_value_change == pytest.approx(10000.0)    # 10000000 µm/s
    assert p.v_weight_down == 0.0 and p.a_weight_down == 0.0
    assert p.ref_offset == 0.0
    assert p.max_pos == pytest.approx(150.0) and p.min_pos == pytest.approx(-150.0)   # ±1500000 x 0.1 µm
    assert p.tolerance == 0.0
    assert (p.kp, p.i_tn, p.d_tv) == (0.3, 0.0, 0.01)
    assert p.n_cycles == 20 and p.filter_type == FilterType.MOVING_AVERAGE
    assert p.smoothing_factor == 0.05 and p.kalman_sigma == 2000.0
    assert p.low_pass_filter_order == 3 and p.low_pass_filter_fg_f0 == 50.0
    assert p.use_adaptive_acceleration is False and p.a_min == 1.0
    assert p.dist_error_a_min == pytest.approx(0.04) and p.dist_error_a_max == pytest.approx(0.25)
    assert pl.warnings == []
    assert pl.lines["dist_ctrl[0].kp"] == EXAMPLE.read_text(encoding="utf-8").splitlines().index(
        "dist_ctrl[0].kp                    0.3") + 1


def test_example_list_is_the_printed_listing():
    body = EXAMPLE.read_text(encoding="utf-8").rstrip("\n").splitlines()[5:]   # after the five header lines
    assert body[0] == "# P-CHAN-00500: Activate functionality"
    assert body[-1] == "dist_ctrl[0].dist_error_a_max 2500"
    seeds = ROOT.parent / "shared" / "seeds"
    if seeds.is_dir():   # every line after the header is a line of the document
        document = next(seeds.glob("000_*.txt")).read_text(encoding="utf-8").splitlines()
        assert all(line in document for line in body if line)


def test_load_list_with_the_channel_format_is_the_same():
    assert load_list(EXAMPLE, fmt=CHANNEL_LIST).params == load_channel_list(EXAMPLE).params


# ---------------------------------------------------------------- errors

def error(text: str, tmp_path, name: str = "chan.lis") -> ParameterError:
    f = tmp_path / name
    f.write_text(text, encoding="utf-8")
    with pytest.raises(ParameterError) as exc:
        load_channel_list(f)
    exc.value.path = f
    return exc.value


def test_index_other_than_0_is_rejected_naming_file_line_key_and_id(tmp_path):
    exc = error("dist_ctrl[0].kp 0.5\ndist_ctrl[1].kp 0.3\n", tmp_path)
    msg = str(exc)
    assert f"{exc.path}:2:" in msg and "dist_ctrl[1].kp" in msg and "P-CHAN-00821" in msg
    assert "only i = 0" in msg
    assert (exc.line, exc.key, exc.param_id) == (2, "dist_ctrl[1].kp", "P-CHAN-00821")


def test_index_with_leading_zeros_is_index_0():
    assert parse_channel_list_text("dist_ctrl[00].kp 0.5").params.kp == 0.5


def test_unknown_key_names_file_line_and_key(tmp_path):
    exc = error("dist_ctrl[0].kp 0.5\n\n# comment\ndist_ctrl[0].kpp 0.3\n", tmp_path)
    assert f"{exc.path}:4:" in str(exc) and "dist_ctrl[0].kpp" in str(exc)
    assert exc.line == 4 and exc.allowed == "a key of docs/parameters-channel.md"


def test_axis_keys_are_unknown_in_a_channel_list_and_vice_versa(tmp_path):
    assert "unknown parameter key" in str(error("kenngr.distc.kp 0.5\n", tmp_path))
    with pytest.raises(ParameterError, match="unknown parameter key"):
        parse_list_text("dist_ctrl[0].kp 0.5")   # the axis format stays the default


@pytest.mark.parametrize("line, pid, allowed", [
    ("dist_ctrl[0].kp 2.5", "P-CHAN-00821", "0 < value <= 2"),
    ("dist_ctrl[0].kp 0", "P-CHAN-00821", "0 < value <= 2"),
    ("dist_ctrl[0].n_cycles 100", "P-CHAN-00800", "0 <= value < 100"),
    ("dist_ctrl[0].n_cycles -1", "P-CHAN-00800", "0 <= value < 100"),
    ("dist_ctrl[0].i_tn 50.5", "P-CHAN-00822", "0 <= value <= 50"),
    ("dist_ctrl[0].d_tv -0.1", "P-CHAN-00823", "0 <= value <= 2"),
    ("dist_ctrl[0].kalman_sigma 0.5", "P-CHAN-00826", "1 <= value <= 10000"),
    ("dist_ctrl[0].smoothing_factor 0", "P-CHAN-00827", "0 < value <= 1"),
    ("dist_ctrl[0].low_pass_filter_order 7", "P-CHAN-00816", "0 <= value <= 6"),
    ("dist_ctrl[0].low_pass_filter_fg_f0 -1", "P-CHAN-00817", "0 <= value"),
    ("dist_ctrl[0].v_weight_down 2000", "P-CHAN-00819", "0 <= value < 2000"),
    ("dist_ctrl[0].a_weight_down 2000", "P-CHAN-00820", "0 <= value < 2000"),
    ("dist_ctrl[0].a_min 0", "P-CHAN-00812", "1 <= value <= 4294967295"),
    ("dist_ctrl[0].a_max -1", "P-CHAN-00803", "0 <= value < 2147483647"),
    ("dist_ctrl[0].max_deviation 2147483647", "P-CHAN-00801", "0 <= value < 2147483647"),
    ("dist_ctrl[0].tolerance -1", "P-CHAN-00808", "0 <= value < 2147483647"),
    ("dist_ctrl[0].max_pos -10", "P-CHAN-00806", "0 <= value < 2147483647"),
    ("dist_ctrl[0].mode_dist_use_both_encoder 2", "P-CHAN-00810", "0 or 1"),
    ("dist_ctrl[0].low_pass_filter_enable 2", "P-CHAN-00815", "0 or 1"),
    ("dist_ctrl[0].filter_type KALMAN", "P-CHAN-00825", "MOVING_AVERAGE"),
    ("configuration.decoder.function FCT_4D_DIST_CTRL", "P-CHAN-00500", "FCT_3D_DIST_CTRL"),
])
def test_out_of_range_values_name_file_line_key_id_value_and_range(line, pid, allowed, tmp_path):
    exc = error(f"# header\n{line}  # comment\n", tmp_path)
    msg = str(exc)
    key, value = line.split()
    assert f"{exc.path}:2:" in msg
    assert key in msg and pid in msg and value in msg and allowed in msg
    assert (exc.line, exc.key, exc.param_id) == (2, key, pid)
    assert allowed in exc.allowed


@pytest.mark.parametrize("line, why", [
    ("dist_ctrl[0].n_cycles 4.5", "expected an integer (SGN32)"),
    ("dist_ctrl[0].a_max fast", "expected an integer (SGN32)"),
    ("dist_ctrl[0].kp high", "expected a number (REAL64)"),
    ("dist_ctrl[0].use_adaptive_acceleration TRUE", "expected an integer (BOOLEAN)"),
    ("dist_ctrl[0].kp", "missing value"),
    ("dist_ctrl[0].kp 0.5 0.6", "unexpected text after the value"),
])
def test_bad_types_name_key_and_id(line, why, tmp_path):
    exc = error(line + "\n", tmp_path)
    msg = str(exc)
    assert why in msg and line.split()[0] in msg and exc.param_id and exc.param_id in msg
    assert f"{exc.path}:1:" in msg


def test_empty_sensor_window_names_the_channel_ids_and_line(tmp_path):
    exc = error("dist_ctrl[0].max_pos 1000\ndist_ctrl[0].min_pos 1000\n", tmp_path)
    assert "P-CHAN-00806/00807/00808" in str(exc) and exc.line in (1, 2)


def test_decoder_function_names():
    for name in ("FCT_USE_CACHED_FILES", "FCT_VOL_COMP_COMPUTATION", "-"):
        p = parse_channel_list_text(f"configuration.decoder.function {name}").params
        assert p.fct_3d_dist_ctrl is False
    assert parse_channel_list_text("configuration.decoder.function fct_3d_dist_ctrl").params.fct_3d_dist_ctrl


def test_a_max_0_loads_and_stays_0_for_the_runtime_315001():
    p = parse_channel_list_text("configuration.decoder.function FCT_3D_DIST_CTRL\ndist_ctrl[0].a_max 0").params
    assert p.a_max == 0.0
    assert p.to_axis_parameters().a_max == 0.0


def test_constructing_out_of_range_in_python_is_rejected_with_the_channel_id():
    with pytest.raises(ParameterError, match="P-CHAN-00821"):
        ChannelParameters(kp=2.1)
    with pytest.raises(ParameterError, match="not finite"):
        ChannelParameters(v_max=float("nan"))
    with pytest.raises(ParameterError, match="P-CHAN-00500"):
        ChannelParameters(fct_3d_dist_ctrl=1)   # type: ignore[arg-type]
    assert ChannelParameters(filter_type="LOWPASS").filter_type == FilterType.LOWPASS


# ---------------------------------------------------------------- mapping onto the axis law parameters

def test_to_axis_parameters_maps_every_law_field_1_to_1():
    p = load_channel_list(EXAMPLE).params.replace(use_both_encoders=True, use_adaptive_acceleration=True,
                                                  v_weight_down=0.5, a_weight_down=0.25, i_tn=2.0)
    axis = p.to_axis_parameters()
    assert isinstance(axis, AxisParameters)
    assert axis.enabled is True
    assert set(AXIS_FIELDS) == {s.field for s in CHANNEL_PARAMETERS} - {"fct_3d_dist_ctrl", "low_pass_filter_enable"}
    axis_fields = {f.name for f in dataclasses.fields(AxisParameters)}
    for name in AXIS_FIELDS:
        assert name in axis_fields
        assert getattr(axis, name) == getattr(p, name), name
    # axis-only fields keep their defaults
    default = AxisParameters()
    for name in axis_fields - set(AXIS_FIELDS) - {"enabled"}:
        assert getattr(axis, name) == getattr(default, name), name


def test_to_axis_parameters_of_the_defaults_is_disabled():
    axis = ChannelParameters().to_axis_parameters()
    assert axis.enabled is False and axis.kp == 1.0 and axis.n_cycles == 4


def test_low_pass_filter_enable_selects_lowpass_only_while_filter_type_is_default():
    on = ChannelParameters(low_pass_filter_enable=True)
    assert on.effective_filter_type == FilterType.LOWPASS
    assert on.to_axis_parameters().filter_type == FilterType.LOWPASS
    explicit = ChannelParameters(low_pass_filter_enable=True, filter_type=FilterType.KALMAN_MA)
    assert explicit.to_axis_parameters().filter_type == FilterType.KALMAN_MA
    assert ChannelParameters().to_axis_parameters().filter_type == FilterType.DEFAULT


# ---------------------------------------------------------------- writing lists and the docs

def test_format_and_parse_round_trip():
    p = load_channel_list(EXAMPLE).params.replace(low_pass_filter_enable=True, i_tn=1.5)
    text = format_channel_list(p)
    assert "P-CHAN-00821" in text and "dist_ctrl[0].low_pass_filter_enable" in text
    assert parse_channel_list_text(text).params == p
    assert parse_channel_list_text(format_channel_list(p, only_changed=True)).params == p
    assert format_channel_list(ChannelParameters(), only_changed=True) == "\n"


def test_interface_dict_round_trip():
    p = load_channel_list(EXAMPLE).params
    values = p.to_interface()
    assert values["configuration.decoder.function"] == "FCT_3D_DIST_CTRL"
    assert values["dist_ctrl[0].max_deviation"] == 10000000
    assert ChannelParameters.from_interface(values) == p


def test_docs_parameters_channel_md_is_generated_from_the_table():
    generated = subprocess.run([sys.executable, "-m", "distctrl.params.docgen", "--channel"], capture_output=True,
                               text=True, check=True).stdout
    assert (ROOT / "docs" / "parameters-channel.md").read_text(encoding="utf-8") == generated
    for spec in CHANNEL_PARAMETERS:
        assert spec.id in generated and f"`{spec.key}`" in generated


def test_docgen_rejects_unknown_arguments():
    res = subprocess.run([sys.executable, "-m", "distctrl.params.docgen", "--bogus"], capture_output=True, text=True)
    assert res.returncode == 2 and "usage" in res.stderr
