"""Parameter table and the kernel list format (FCT-M3 §9)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from distctrl.base.kinds import FilterType
from distctrl.errors import ParameterError
from distctrl.params import AXIS_PARAMETERS, AxisParameters, format_list, load_list, parse_list_text

ROOT = Path(__file__).resolve().parents[2]


def test_example_list_of_9_3_loads_with_its_values():
    pl = load_list(ROOT / "examples" / "axis_z_9_3.lis")
    p = pl.params
    assert p.enabled is True
    assert p.max_deviation == pytest.approx(2000.0)          # max_abweichung 20000000 x 0.1 µm
    assert p.v_max == pytest.approx(50.0)                    # 50000 µm/s
    assert p.a_max == 10000.0
    assert p.max_act_value_change == pytest.approx(100000.0)  # max_istw_sprung, µm/s
    assert p.max_pos == pytest.approx(150.0) and p.min_pos == pytest.approx(-150.0)
    assert p.tolerance == pytest.approx(5.0)                 # toleranz
    assert p.check_sw_limit_switch and p.optimized_scheduling and p.use_both_encoders
    assert p.use_adaptive_acceleration is False              # commented out in the example
    assert p.a_min == 1000.0
    assert p.dist_error_a_min == pytest.approx(0.025) and p.dist_error_a_max == pytest.approx(0.05)
    assert p.filter_type == FilterType.KALMAN_MA and p.n_cycles == 20
    assert p.kalman_sigma == 1000.0                          # legacy key kenngr.distc.sigma
    assert pl.warnings == []                                 # a_max twice, same value: no warning


def test_every_documented_key_is_in_the_table():
    ids = {s.id for s in AXIS_PARAMETERS}
    for pid in ["P-AXIS-00328", "P-AXIS-00413", "P-AXIS-00414", "P-AXIS-00415", "P-AXIS-00416", "P-AXIS-00417",
                "P-AXIS-00418", "P-AXIS-00419", "P-AXIS-00420", "P-AXIS-00421", "P-AXIS-00422", "P-AXIS-00423",
                "P-AXIS-00424", "P-AXIS-00428", "P-AXIS-00500", "P-AXIS-00501", "P-AXIS-00502", "P-AXIS-00504",
                "P-AXIS-00505", "P-AXIS-00507", "P-AXIS-00508", "P-AXIS-00509", "P-AXIS-00533", "P-AXIS-00534",
                "P-AXIS-00230", "P-AXIS-00759", "P-AXIS-00764", "P-AXIS-00765", "P-AXIS-00782", "P-AXIS-00783",
                "P-AXIS-00784", "P-AXIS-00008"]:
        assert pid in ids


def test_defaults_are_the_documented_ones():
    p = AxisParameters()
    assert (p.enabled, p.n_cycles, p.kp, p.i_tn, p.d_tv) == (False, 4, 1.0, 0.0, 0.0)
    assert p.max_deviation == pytest.approx(5.0) and p.v_max == pytest.approx(5.0)
    assert p.max_act_value_change == pytest.approx(5.0)
    assert p.max_pos == pytest.approx(5.0) and p.min_pos == pytest.approx(-5.0)
    assert p.a_min == 500 and p.low_pass_filter_order == 4 and p.low_pass_filter_fg_f0 == 25.0
    assert p.kalman_sigma == 4.0 and p.smoothing_factor == 0.7 and p.filter_type == FilterType.DEFAULT


# ---------------------------------------------------------------- the document's table (FCT-M3 §9.2)
MAX_SGN32, MIN_SGN32, MAX_UNS32 = 2**31 - 1, -(2**31), 2**32 - 1

#: ID -> (key, data type, list unit T, range (lo, lo_open, hi, hi_open) or choices, default), written
#: from FCT-M3 §9.2 as printed ("----" is written -, "0.001 mm/s" µm/s, "1 mm/s²" mm/s²; the
#: documents' lr_hw[i] is the sensor encoder lr_hw[1]). BOOLEAN: "0/1".
DOCUMENTED = {
    "P-AXIS-00328": ("lr_param.distance_control_on", "BOOLEAN", "-", "0/1", 0),
    "P-AXIS-00413": ("kenngr.distc.n_cycles", "SGN32", "-", (0, False, 100, True), 4),
    "P-AXIS-00414": ("kenngr.distc.max_deviation", "SGN32", "0.1 µm", (0, False, MAX_SGN32, True), 50000),
    "P-AXIS-00415": ("kenngr.distc.v_max", "SGN32", "µm/s", (0, False, MAX_SGN32, True), 5000),
    "P-AXIS-00416": ("kenngr.distc.a_max", "SGN32", "mm/s²", (0, False, MAX_SGN32, True), 0),
    "P-AXIS-00417": ("kenngr.distc.max_act_value_change", "SGN32", "µm/s", (0, False, MAX_SGN32, True), 5000),
    "P-AXIS-00418": ("kenngr.distc.ref_offset", "SGN32", "0.1 µm", (MIN_SGN32, False, MAX_SGN32, True), 0),
    "P-AXIS-00419": ("kenngr.distc.max_pos", "SGN32", "0.1 µm", (0, False, MAX_SGN32, True), 50000),
    "P-AXIS-00420": ("kenngr.distc.min_pos", "SGN32", "0.1 µm", (0, False, MAX_SGN32, True), -50000),
    "P-AXIS-00421": ("kenngr.distc.tolerance", "SGN32", "0.1 µm", (0, False, MAX_SGN32, True), 0),
    "P-AXIS-00428": ("kenngr.distc.check_sw_limit_switch", "BOOLEAN", "-", "0/1", 0),
    "P-AXIS-00500": ("kenngr.distc.mode_dist_use_both_encoder", "BOOLEAN", "-", "0/1", 0),
    "P-AXIS-00501": ("kenngr.distc.use_adaptive_acceleration", "BOOLEAN", "-", "0/1", 0),
    "P-AXIS-00502": ("kenngr.distc.a_min", "UNS32", "mm/s²", (1, False, MAX_UNS32, True), 500),
    "P-AXIS-00504": ("kenngr.distc.dist_error_a_min", "UNS32", "0.1 µm", (0, False, MAX_UNS32, True), 1000),
    "P-AXIS-00505": ("kenngr.distc.dist_error_a_max", "UNS32", "0.1 µm", (0, False, MAX_UNS32, True), 5000),
    "P-AXIS-00507": ("kenngr.distc.low_pass_filter_order", "UNS32", "-", (0, False, 6, False), 4),
    "P-AXIS-00508": ("kenngr.distc.low_pass_filter_fg_f0", "REAL64", "Hz", (0, False, None, False), 25),
    "P-AXIS-00509": ("kenngr.distc.optimized_scheduling", "BOOLEAN", "-", "0/1", 0),
    "P-AXIS-00533": ("kenngr.distc.v_weight_down", "UNS32", "0.1 %", (0, False, 2000, True), 0),
    "P-AXIS-00534": ("kenngr.distc.a_weight_down", "UNS32", "0.1 %", (0, False, 2000, True), 0),
    "P-AXIS-00422": ("lr_hw[1].encoder_resolution_num", "UNS32", "increments", (0, True, MAX_UNS32, True), 1),
    "P-AXIS-00423": ("lr_hw[1].encoder_resolution_denom", "UNS32", "0.1 µm", (0, False, MAX_UNS32, True), 1),
    "P-AXIS-00230": ("lr_hw[1].vz_istw", "BOOLEAN", "-", "0/1", 0),
    "P-AXIS-00424": ("lr_hw[1].mode_act_pos", "UNS16", "-", (0, 1, 2), 0),
    "P-AXIS-00759": ("kenngr.distc.kp", "REAL64", "-", (0.0, True, 2.0, False), 1.0),
    "P-AXIS-00764": ("kenngr.distc.i_tn", "REAL64", "s", (0.0, False, 50.0, False), 0.0),
    "P-AXIS-00765": ("kenngr.distc.d_tv", "REAL64", "s", (0.0, False, 2.0, False), 0.0),
    "P-AXIS-00782": ("kenngr.distc.filter_type", "STRING", "-",
                     ("DEFAULT", "MOVING_AVERAGE", "LOWPASS", "KALMAN_MA", "EXPO_MEAN", "KALMAN_EXPO"), "DEFAULT"),
    "P-AXIS-00783": ("kenngr.distc.kalman_sigma", "REAL64", "-", (1.0, False, 10000.0, False), 4),
    "P-AXIS-00784": ("kenngr.distc.smoothing_factor", "REAL64", "-", (0.0, True, 1.0, False), 0.7),
}

#: where the project resolved a contradiction of the documents: ID -> the range it checks instead
#: (the parameter's note says why)
RESOLVED_RANGES = {
    "P-AXIS-00420": (MIN_SGN32, False, MAX_SGN32, True),   # '0 <= min_pos' contradicts the default -50000
    "P-AXIS-00423": (0, True, MAX_UNS32, True),            # a zero denominator is no resolution
}


@pytest.mark.parametrize("pid", sorted(DOCUMENTED))
def test_key_type_unit_range_and_default_are_the_documented_ones(pid):
    """Each distance-control parameter of FCT-M3 §9.2: ID, list key, data type, unit (Dimension T),
    range and default value as printed; the two resolved ranges differ and say so in their note."""
    from distctrl.params.table import BY_ID, BY_KEY

    key, data_type, unit, allowed, default = DOCUMENTED[pid]
    spec = BY_ID[pid]
    assert spec.id == pid and spec.key == key and BY_KEY[key] is spec
    assert spec.type == data_type
    assert spec.unit == unit
    assert spec.default == default
    if allowed == "0/1":
        assert spec.range_text() == "0 or 1" and spec.check(0) and spec.check(1) and not spec.check(2)
    elif isinstance(allowed[0], str) or len(allowed) == 3:
        assert spec.choices == allowed
    elif pid in RESOLVED_RANGES:
        assert (spec.lo, spec.lo_open, spec.hi, spec.hi_open) == RESOLVED_RANGES[pid] != allowed
        assert "documented" in spec.note
    else:
        assert (spec.lo, spec.lo_open, spec.hi, spec.hi_open) == allowed


def test_every_distance_control_parameter_of_9_2_is_in_the_documented_table():
    from distctrl.params.table import BY_ID

    in_9_2 = {pid for pid in BY_ID if pid.startswith("P-AXIS-")} - {"P-AXIS-00018", "P-AXIS-00008",
                                                                   "P-AXIS-00177", "P-AXIS-00178"}
    assert in_9_2 == set(DOCUMENTED)     # the four others are ISG axis-list data (docs/parameters.md)


def test_unknown_key_names_file_line_and_key(tmp_path):
    f = tmp_path / "z.lis"
    f.write_text("kenngr.distc.kp 0.5\nkenngr.distc.kpp 0.3 # typo\n")
    with pytest.raises(ParameterError) as exc:
        load_list(f)
    msg = str(exc.value)
    assert f"{f}:2:" in msg and "kenngr.distc.kpp" in msg
    assert exc.value.line == 2


@pytest.mark.parametrize("line, pid, allowed", [
    ("kenngr.distc.kp 2.5", "P-AXIS-00759", "0 < value <= 2"),
    ("kenngr.distc.kp 0", "P-AXIS-00759", "0 < value <= 2"),
    ("kenngr.distc.n_cycles 100", "P-AXIS-00413", "0 <= value < 100"),
    ("kenngr.distc.i_tn 50.5", "P-AXIS-00764", "0 <= value <= 50"),
    ("kenngr.distc.d_tv -0.1", "P-AXIS-00765", "0 <= value <= 2"),
    ("kenngr.distc.kalman_sigma 0.5", "P-AXIS-00783", "1 <= value <= 10000"),
    ("kenngr.distc.smoothing_factor 0", "P-AXIS-00784", "0 < value <= 1"),
    ("kenngr.distc.low_pass_filter_order 7", "P-AXIS-00507", "0 <= value <= 6"),
    ("kenngr.distc.v_weight_down 2000", "P-AXIS-00533", "0 <= value < 2000"),
    ("lr_hw[1].mode_act_pos 3", "P-AXIS-00424", "one of 0, 1, 2"),
    ("kenngr.distc.filter_type KALMAN", "P-AXIS-00782", "MOVING_AVERAGE"),
    # FCT-M3 §9.2 P-AXIS-00419: 0 <= max_pos < MAX(SGN32); nothing in the documents contradicts it
    ("kenngr.distc.max_pos -1", "P-AXIS-00419", "0 <= value < 2147483647"),
])
def test_out_of_range_values_name_id_value_and_range(line, pid, allowed):
    with pytest.raises(ParameterError) as exc:
        parse_list_text("# header\n" + line + "  # comment\n", "axis.lis")
    msg = str(exc.value)
    assert msg.startswith("axis.lis:2:")
    assert pid in msg and allowed in msg and line.split()[1] in msg


@pytest.mark.parametrize("line", ["kenngr.distc.n_cycles 4.5", "kenngr.distc.v_max fast",
                                  "lr_param.distance_control_on yes", "kenngr.distc.kp"])
def test_bad_types_are_load_errors(line):
    with pytest.raises(ParameterError, match="allowed"):
        parse_list_text(line)


def test_text_after_value_without_hash_is_rejected():
    with pytest.raises(ParameterError, match="comments start with '#'"):
        parse_list_text("lr_param.distance_control_on 1 Enables the distance control function")


def test_duplicate_key_last_value_counts_with_warning():
    pl = parse_list_text("kenngr.distc.kp 0.3\nkenngr.distc.kp 0.6\n", "a.lis")
    assert pl.params.kp == 0.6
    assert len(pl.warnings) == 1 and "a.lis:2" in pl.warnings[0]


def test_aliases_of_the_documents_examples():
    pl = parse_list_text("kenngr.distc.max_abweichung 1000\nkenngr.distc.toleranz 10\n"
                         "kenngr.distc.max_istw_sprung 7000\nkenngr.distc.sigma 300\n"
                         "kenngnr.distsc.kp 0.4\nkenngr.distc.check_switch_limit_switch 1\n")
    p = pl.params
    assert p.max_deviation == pytest.approx(0.1) and p.tolerance == pytest.approx(0.001)
    assert p.max_act_value_change == pytest.approx(7.0) and p.kalman_sigma == 300
    assert p.kp == 0.4 and p.check_sw_limit_switch


# TF5200 Abstandskontrolle §8.2 prints six keys of its parameter descriptions in other spellings
# than the overview (and FCT-M3 §9): they are accepted as aliases, like the overview's
# kenngnr.distsc. prefix.
@pytest.mark.parametrize("line, field, value", [
    ("kenngn.distc.mode_dist_use_both_encoder 1", "use_both_encoders", True),       # P-AXIS-00500
    ("kenngn.distc.use_adaptive_acceleration 1", "use_adaptive_acceleration", True),  # P-AXIS-00501
    ("kenngn.distc.smoothing_factor 0.3", "smoothing_factor", 0.3),                 # P-AXIS-00784
    ("kenng.disc.a_weight_down 300", "a_weight_down", 0.3),                         # P-AXIS-00534, 0.1 %
    ("kenng.disc.filter_type KALMAN_MA", "filter_type", FilterType.KALMAN_MA),      # P-AXIS-00782
    ("kenng.disc.kalman_sigma 1000", "kalman_sigma", 1000.0),                        # P-AXIS-00783
])
def test_tf5200_description_spellings_are_aliases(line, field, value):
    pl = parse_list_text(line + "\n", "tf.lis")
    assert getattr(pl.params, field) == pytest.approx(value) if isinstance(value, float) else \
        getattr(pl.params, field) == value
    assert pl.lines == {"kenngr.distc." + line.split()[0].split(".", 2)[2]: 1}
    # the same range check as under the canonical key, naming the alias as written
    with pytest.raises(ParameterError, match=line.split()[0].replace(".", r"\.")):
        parse_list_text(line.split()[0] + " -5\n", "tf.lis")


def test_tf5200_spellings_are_only_aliases_of_their_own_keys():
    """Only the six printed keys: the prefixes are not general aliases (a typo stays an error)."""
    for line in ("kenngn.distc.kp 0.5", "kenng.disc.v_max 100"):
        with pytest.raises(ParameterError, match="unknown parameter key"):
            parse_list_text(line + "\n", "tf.lis")


def test_cross_parameter_check_names_the_parameters():
    with pytest.raises(ParameterError, match="P-AXIS-00419/00420/00421"):
        parse_list_text("kenngr.distc.max_pos 1000\nkenngr.distc.min_pos 0\nkenngr.distc.tolerance 600\n", "w.lis")


def test_format_list_round_trips():
    p = AxisParameters(enabled=True, kp=0.3, v_max=12.5, max_deviation=3.25, filter_type=FilterType.LOWPASS,
                       low_pass_filter_fg_f0=33.3, v_weight_down=0.5)
    again = parse_list_text(format_list(p)).params
    assert again == p
    assert parse_list_text(format_list(p, only_changed=True)).params == p


def test_constructing_out_of_range_in_python_is_rejected():
    with pytest.raises(ParameterError, match="P-AXIS-00759"):
        AxisParameters(kp=2.1)
    with pytest.raises(ParameterError, match="not finite"):
        AxisParameters(v_max=float("nan"))


def test_docs_parameters_md_is_generated_from_the_table():
    generated = subprocess.run([sys.executable, "-m", "distctrl.params.docgen"], capture_output=True, text=True,
                               check=True).stdout
    assert (ROOT / "docs" / "parameters.md").read_text(encoding="utf-8") == generated


# Was BUG (found by the input fuzzer, tests/reliability): an error across parameters (the sensor
# window, the software limits) named no line when the file did not set the first parameter of
# the check. It now names the last involved line of the file.
@pytest.mark.parametrize("text, line, what", [
    ("kenngr.distc.max_pos 0\nkenngr.distc.toleranz 30000\n", 2, "sensor window"),
    ("kenngr.distc.tolerance 30000\n# a comment\nkenngr.distc.max_pos 0\n", 3, "sensor window"),
    ("kenngr.distc.min_pos 40000\nkenngr.distc.max_pos 30000\n", 2, "sensor window"),
    ("getriebe[0].swe_neg 0\n\ngetriebe[0].swe_pos -100\n", 3, "software limits"),
])
def test_cross_parameter_errors_name_the_last_involved_line(text, line, what):
    with pytest.raises(ParameterError) as info:
        parse_list_text(text, "x.lis")
    assert info.value.line == line and what in str(info.value)
    assert str(info.value).startswith(f"x.lis:{line}: ")


def test_channel_sensor_window_error_names_its_line():
    from distctrl.params.channel import CHANNEL_LIST
    text = "dist_ctrl[0].kp 0.3\ndist_ctrl[0].min_pos 60000\n"
    with pytest.raises(ParameterError) as info:
        parse_list_text(text, "c.lis", fmt=CHANNEL_LIST)
    assert info.value.line == 2 and "sensor window" in str(info.value)


def test_max_pos_follows_the_documented_range_0_and_up():
    """FCT-M3 §9.2 P-AXIS-00419 '0 <= max_pos < MAX(SGN32)' (unlike min_pos, not contradicted)."""
    assert parse_list_text("kenngr.distc.max_pos 0\nkenngr.distc.min_pos -1000\n").params.max_pos == 0.0
    with pytest.raises(ParameterError, match="P-AXIS-00419"):
        AxisParameters(max_pos=-0.001)
    from distctrl.params.table import BY_KEY
    spec = BY_KEY["kenngr.distc.max_pos"]
    assert (spec.lo, spec.lo_open) == (0, False)


def test_the_remaining_defaults_are_the_documented_ones():
    """FCT-M3 §9.2 'Default value' of every parameter the test above does not cover."""
    p = AxisParameters()
    assert p.a_max == 0.0                                              # P-AXIS-00416: 0 = axis acceleration
    assert p.ref_offset == 0.0 and p.tolerance == 0.0                  # P-AXIS-00418, P-AXIS-00421
    assert p.check_sw_limit_switch is False                            # P-AXIS-00428
    assert p.use_both_encoders is False and p.use_adaptive_acceleration is False   # P-AXIS-00500, 00501
    assert p.dist_error_a_min == pytest.approx(0.1) and p.dist_error_a_max == pytest.approx(0.5)  # 1000, 5000 x 0.1 µm
    assert p.optimized_scheduling is False                             # P-AXIS-00509
    assert p.v_weight_down == 0.0 and p.a_weight_down == 0.0           # P-AXIS-00533, 00534 (0 = off)
    assert (p.encoder_resolution_num, p.encoder_resolution_denom) == (1, 1)   # P-AXIS-00422, 00423
    assert p.sensor_sign_reversal is False and p.sensor_mode_act_pos == 0     # P-AXIS-00230, 00424
    assert p.axis_type == "ACHSTYP_TRANSLATOR"                         # P-AXIS-00018 (ISG axis list)
