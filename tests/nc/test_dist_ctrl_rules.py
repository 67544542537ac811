"""The DIST_CTRL keyword rules of FCT-M3 §6 and TF5200 Abstandskontrolle §6, and what they turn into."""
from __future__ import annotations

import math

import pytest

from distctrl.control.commands import Action, Command
from distctrl.base.kinds import FilterType, SensorSource
from distctrl.errors import DistCtrlError
from distctrl.nc import NcSyntaxError, dist_ctrl_range_error, parse_program


def word(text: str):
    (block,) = parse_program(text).blocks
    (dist_ctrl,) = block.dist_ctrl
    return dist_ctrl


def command(text: str, lookup=None) -> Command:
    return word(text).to_command(lookup or {}, 1)


def error(text: str, file: str | None = "part.nc") -> NcSyntaxError:
    with pytest.raises(NcSyntaxError) as info:
        parse_program(text, file)
    return info.value


# ---------------------------------------------------------------- accepted commands

@pytest.mark.parametrize("text, action, const_dist, no_move", [
    ("Z[DIST_CTRL ON]", Action.ON, False, False),
    ("Z[DIST_CTRL DRYRUN]", Action.DRYRUN, False, False),
    ("Z[DIST_CTRL ON DRYRUN]", Action.DRYRUN, False, False),
    ("Z[DIST_CTRL DRYRUN ON CONST_DIST]", Action.DRYRUN, True, False),
    ("Z[DIST_CTRL ON CONST_DIST]", Action.ON, True, False),
    ("Z[DIST_CTRL CONST_DIST ON]", Action.ON, True, False),
    ("Z[DIST_CTRL OFF]", Action.OFF, False, False),
    ("Z[DIST_CTRL OFF NO_MOVE]", Action.OFF, False, True),
    ("Z[DIST_CTRL FREEZE]", Action.FREEZE, False, False),
    ("Z[DIST_CTRL CHECK_POS]", Action.CHECK_POS, False, False),
    ("Z[DIST_CTRL REF]", Action.REF, False, False),
    ("Z[DIST_CTRL SET_POS=3]", Action.NONE, False, False),
    ("Z[DIST_CTRL]", Action.NONE, False, False),
])
def test_action_keywords_map_to_command(text, action, const_dist, no_move):
    cmd = command(text)
    assert (cmd.action, cmd.const_dist, cmd.no_move, cmd.line) == (action, const_dist, no_move, 1)


def test_ref_references_sensor_zero():
    assert command("Z[DIST_CTRL REF]").ref_position is None         # "sensor zero" (SPEC §2)
    assert command("Z[DIST_CTRL ON SET_POS=1]").ref_position is None


def test_every_value_keyword_lands_in_its_field():
    cmd = command("A[DIST_CTRL ON SET_POS=30.5 SET_DIST=2 SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR "
                  "VAL1=1 VAL3=-3 VAL5=5e2 KP=0.5 I_TN=0.2 D_TV=0.01 FILTER_TYPE=LOWPASS N_CYCLES=8 "
                  "FG_F0=100 ORDER=2 SMOOTH_FACT=0.25 KALMAN_SIGMA=10]")
    assert cmd == Command(Action.ON, set_pos=30.5, set_dist=2.0, sensor_source=SensorSource.VARIABLE,
                          sensor_var="V.E.SENSOR", vals=(1.0, None, -3.0, None, 500.0), kp=0.5, i_tn=0.2,
                          d_tv=0.01, filter_type=FilterType.LOWPASS, n_cycles=8, fg_f0=100.0, order=2,
                          smooth_fact=0.25, kalman_sigma=10.0, line=1)
    assert isinstance(cmd.order, int) and isinstance(cmd.n_cycles, int)


@pytest.mark.parametrize("name", ["DEFAULT", "MOVING_AVERAGE", "LOWPASS", "KALMAN_MA", "EXPO_MEAN",
                                  "KALMAN_EXPO"])
def test_all_documented_filter_types(name):
    assert command(f"Z[DIST_CTRL FILTER_TYPE={name}]").filter_type == FilterType[name]


@pytest.mark.parametrize("name", ["DEFAULT", "SECOND_ENCODER", "VARIABLE"])
def test_all_sensor_sources(name):
    assert command(f"Z[DIST_CTRL SENSOR_SOURCE={name}]").sensor_source == SensorSource[name]


def test_sensor_var_as_bare_name_is_a_v_e_variable():
    assert command("Z[DIST_CTRL SENSOR_VAR=SENSOR]").sensor_var == "V.E.SENSOR"


def test_lowercase_keywords_are_accepted_and_normalised():
    cmd = command("z[dist_ctrl on const_dist set_dist=1 filter_type=kalman_ma]")
    assert (cmd.action, cmd.const_dist, cmd.set_dist, cmd.filter_type) == (
        Action.ON, True, 1.0, FilterType.KALMAN_MA)
    assert word("z[dist_ctrl on]").axis == "Z"


def test_values_may_be_expressions_evaluated_at_to_command():
    w = word("Z[DIST_CTRL ON SET_POS=V.E.TOP - 0.5 KP=[V.E.K*2] VAL2=(1+2)*3]")
    cmd = w.to_command({"V.E.TOP": 20.0, "V.E.K": 0.25}, line=7)
    assert (cmd.set_pos, cmd.kp, cmd.vals[1], cmd.line) == (19.5, 0.5, 9.0, 7)
    # a callable works as lookup too
    assert w.to_command(lambda name: {"V.E.TOP": 1.0, "V.E.K": 0.5}[name]).kp == 1.0


def test_expression_values_are_range_checked_at_to_command():
    w = word("N10 Z[DIST_CTRL KP=V.E.K]")
    with pytest.raises(NcSyntaxError) as info:
        w.to_command({"V.E.K": 3.0}, 10, file="p.nc")
    assert (info.value.file, info.value.line, info.value.column) == ("p.nc", 1, 17)
    assert "expected 0 < KP <= 2" in info.value.message


def test_unknown_variable_at_to_command_names_variable_and_position():
    with pytest.raises(NcSyntaxError) as info:
        word("\nZ[DIST_CTRL SET_POS=V.E.NOPE]").to_command({})
    assert (info.value.line, info.value.column) == (2, 13)
    assert "V.E.NOPE" in info.value.message


# ---------------------------------------------------------------- rejected commands

@pytest.mark.parametrize("text, line, column, fragment", [
    # DIST_CTRL first
    ("N10 Z[ON DIST_CTRL]", 1, 7, "expected DIST_CTRL as the first keyword"),
    ("N10 Z[KP=1]", 1, 7, "expected DIST_CTRL as the first keyword"),
    ("N10 Z[DIST_CTRL ON DIST_CTRL]", 1, 20, "unknown DIST_CTRL keyword 'DIST_CTRL'"),
    # mutual exclusion
    ("N10 Z[DIST_CTRL ON OFF]", 1, 20, "OFF cannot be combined with ON"),
    ("N10 Z[DIST_CTRL OFF FREEZE]", 1, 21, "FREEZE cannot be combined with OFF"),
    ("N10 Z[DIST_CTRL FREEZE DRYRUN]", 1, 24, "DRYRUN cannot be combined with FREEZE"),
    ("N10 Z[DIST_CTRL CHECK_POS REF]", 1, 27, "REF cannot be combined with CHECK_POS"),
    ("N10 Z[DIST_CTRL REF ON]", 1, 21, "ON cannot be combined with REF"),
    ("N10 Z[DIST_CTRL DRYRUN OFF]", 1, 24, "exclude one another"),
    ("N10 Z[DIST_CTRL ON DRYRUN CHECK_POS]", 1, 27, "CHECK_POS cannot be combined with ON"),
    # CONST_DIST / NO_MOVE partners
    ("N10 Z[DIST_CTRL CONST_DIST SET_DIST=1]", 1, 17, "CONST_DIST without ON or DRYRUN"),
    ("N10 Z[DIST_CTRL OFF CONST_DIST]", 1, 21, "CONST_DIST without ON or DRYRUN"),
    ("N10 Z[DIST_CTRL NO_MOVE]", 1, 17, "NO_MOVE without OFF"),
    ("N10 Z[DIST_CTRL ON NO_MOVE]", 1, 20, "NO_MOVE without OFF"),
    # duplicates
    ("N10 Z[DIST_CTRL ON ON]", 1, 20, "ON given twice"),
    ("N10 Z[DIST_CTRL SET_POS=1 KP=1 SET_POS=2]", 1, 32, "SET_POS given twice"),
    ("N10 Z[DIST_CTRL OFF NO_MOVE NO_MOVE]", 1, 29, "NO_MOVE given twice"),
    ("N10 Z[DIST_CTRL FILTER_TYPE=LOWPASS FILTER_TYPE=LOWPASS]", 1, 37, "FILTER_TYPE given twice"),
    ("N10 Z[DIST_CTRL ON] Z[DIST_CTRL KP=1]", 1, 21, "Z[DIST_CTRL ...] given twice in one block"),
    # missing '=' and values on flags
    ("N10 Z[DIST_CTRL KP]", 1, 19, "expected '=' after KP, got ']'"),
    ("N10 Z[DIST_CTRL KP 0.3]", 1, 20, "expected '=' after KP, got '0.3'"),
    ("N10 Z[DIST_CTRL FILTER_TYPE KALMAN_MA]", 1, 29, "expected '=' after FILTER_TYPE"),
    ("N10 Z[DIST_CTRL SET_POS=]", 1, 25, "expected a value"),
    ("N10 Z[DIST_CTRL ON=1]", 1, 19, "ON takes no value"),
    # unknown names
    ("N10 Z[DIST_CTRL FOO=1]", 1, 17, "unknown DIST_CTRL keyword 'FOO'"),
    ("N10 Z[DIST_CTRL ONN]", 1, 17, "unknown DIST_CTRL keyword 'ONN'"),
    ("N10 Z[DIST_CTRL VAL6=1]", 1, 17, "unknown DIST_CTRL keyword 'VAL6'"),
    ("N10 Z[DIST_CTRL FILTER_TYPE=KALMAN]", 1, 29, "unknown FILTER_TYPE 'KALMAN', expected one of DEFAULT"),
    ("N10 Z[DIST_CTRL FILTER_TYPE=PASS]", 1, 29, "unknown FILTER_TYPE 'PASS'"),
    ("N10 Z[DIST_CTRL FILTER_TYPE=V.E.F]", 1, 29, "unknown FILTER_TYPE"),
    ("N10 Z[DIST_CTRL SENSOR_SOURCE=THIRD_ENCODER]", 1, 31,
     "expected one of DEFAULT, SECOND_ENCODER, VARIABLE"),
    ("N10 Z[DIST_CTRL SENSOR_VAR=V.G.WZ_AKT.L]", 1, 28, "expected the name of a V.E. variable"),
    # unterminated
    ("N10 Z[DIST_CTRL ON\nN20 G1", 1, 19, "expected a DIST_CTRL keyword or ']' after ON, got end of line"),
    ("N10 Z[DIST_CTRL ON", 1, 19, "got end of program"),
])
def test_rule_violations_are_reported_at_the_offending_keyword(text, line, column, fragment):
    exc = error(text)
    assert (exc.file, exc.line, exc.column) == ("part.nc", line, column), str(exc)
    assert fragment in exc.message
    assert str(exc) == f"part.nc:{line}:{column}: {exc.message}"


@pytest.mark.parametrize("keyword, bad, good", [
    ("KP", ["0", "-0.1", "2.0001", "3"], ["0.001", "1", "2"]),
    ("I_TN", ["-0.001", "50.5"], ["0", "50"]),
    ("D_TV", ["-1", "2.1"], ["0", "2"]),
    ("N_CYCLES", ["-1", "100", "3.5"], ["0", "99", "30"]),
    ("ORDER", ["-1", "7", "1.5"], ["0", "6"]),
    ("SMOOTH_FACT", ["0", "1.01"], ["0.01", "1"]),
    ("KALMAN_SIGMA", ["0.5", "10001"], ["1", "10000"]),
    ("FG_F0", ["-1"], ["0", "1e5"]),
])
def test_literal_value_ranges(keyword, bad, good):
    for value in bad:
        exc = error(f"\nN20 Z[DIST_CTRL ON {keyword}={value}]")
        assert (exc.line, exc.column) == (2, 20)
        assert exc.message.startswith(f"{keyword}=") and "out of range, expected" in exc.message
        assert dist_ctrl_range_error(keyword, float(value)) is not None
    for value in good:
        parse_program(f"Z[DIST_CTRL {keyword}={value}]")
        assert dist_ctrl_range_error(keyword, float(value)) is None


def test_constant_expressions_are_range_checked_like_literals():
    assert "KP=3" in error("Z[DIST_CTRL KP=[1+2]]").message
    assert "division by zero" in error("Z[DIST_CTRL SET_POS=1/0]").message
    parse_program("Z[DIST_CTRL KP=V.E.K*10]")   # not constant: checked when evaluated


def test_range_function_rejects_non_finite_values_for_every_keyword():
    for keyword in ("SET_POS", "SET_DIST", "VAL1", "KP", "FG_F0"):
        assert dist_ctrl_range_error(keyword, math.inf) is not None
        assert dist_ctrl_range_error(keyword, math.nan) is not None
    assert dist_ctrl_range_error("SET_POS", -1e6) is None
    assert dist_ctrl_range_error("kp", 1.0) is None


def test_nc_syntax_error_is_a_dist_ctrl_error():
    assert issubclass(NcSyntaxError, DistCtrlError)


@pytest.mark.parametrize("text, action, field, value", [
    ("Z[DIST_CTRL OFF SET_POS=30]", Action.OFF, "set_pos", 30.0),
    ("Z[DIST_CTRL FREEZE SET_DIST=2.5]", Action.FREEZE, "set_dist", 2.5),
    ("Z[DIST_CTRL OFF NO_MOVE SET_DIST=3]", Action.OFF, "set_dist", 3.0),
    ("Z[DIST_CTRL CHECK_POS SET_POS=12]", Action.CHECK_POS, "set_pos", 12.0),
    ("Z[DIST_CTRL REF SET_DIST=1]", Action.REF, "set_dist", 1.0),
    ("Z[DIST_CTRL SET_POS=30 SET_DIST=10]", Action.NONE, "set_dist", 10.0),
])
def test_set_values_combine_with_every_command(text, action, field, value):
    """TF5200 Abstandskontrolle §6: 'Die Schlüsselworte SET_POS, SET_DIST und VAL1-VAL5 können immer in
    Kombination mit programmiert werden' (SET_POS, SET_DIST and VAL1-VAL5 may be programmed with any
    command)."""
    cmd = command(text)
    assert cmd.action == action and getattr(cmd, field) == value
    assert command(text.replace("]", " VAL2=3 VAL5=-1]")).vals == (None, 3.0, None, None, -1.0)
