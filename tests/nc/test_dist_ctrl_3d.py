"""#DIST CTRL (3D distance control) and the kinematics commands: FCT-M3 §12.2/§12.4, PROG #DIST CTRL."""
from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from distctrl.control.commands import Action, Command
from distctrl.control.commands3d import Command3D, CompensationMode
from distctrl.base.kinds import FilterType, SensorSource
from distctrl.nc import (
    Assignment, BinOp, DistCtrl3DWord, KinematicsWord, NcSyntaxError, Num, Program, Var, kin_param_var, parse_file,
    parse_program,
)
from tests.nc.test_fuzz import FUZZ, NC_ALPHABET, check

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
EXAMPLES_3D = [EXAMPLES / "dist3d_1.nc", EXAMPLES / "dist3d_2.nc"]


def word(text: str) -> DistCtrl3DWord:
    (block,) = parse_program(text).blocks
    assert not (block.dist_ctrl or block.axes or block.kinematics or block.assignments)
    (dist_ctrl,) = block.dist_ctrl_3d
    return dist_ctrl


def command(text: str, lookup=None) -> Command3D:
    return word(text).to_command3d(lookup or {}, 1)


def kinematics(text: str) -> KinematicsWord:
    (block,) = parse_program(text).blocks
    assert not (block.dist_ctrl_3d or block.axes or block.assignments)
    (kin,) = block.kinematics
    return kin


def error(text: str, file: str | None = "part.nc") -> NcSyntaxError:
    with pytest.raises(NcSyntaxError) as info:
        parse_program(text, file)
    return info.value


def commands(program: Program) -> list[tuple[int | None, Command3D]]:
    return [(block.number, w.to_command3d({}, block.line)) for block in program.blocks for w in block.dist_ctrl_3d]


# ---------------------------------------------------------------- the two example programs of PROG #DIST CTRL

def test_example_1_behaviour_as_for_axis_specific_distance_control():
    program = parse_file(EXAMPLES_3D[0])
    assert program.name is None
    assert [b.number for b in program.blocks] == [10, 20, 30, 900, 910, 999]
    assert program.blocks[0].g_codes == [0] and program.blocks[0].axes["Z"] == Num(10.0)
    assert program.blocks[-1].ends_program
    cmds = commands(program)
    assert cmds == [
        (20, Command3D(sensor_source=SensorSource.VARIABLE, sensor_var="V.E.SENSOR", line=5)),
        (30, Command3D(Action.ON, const_dist=True, set_dist=1.0, mode=CompensationMode.ACS, direction="Z",
                       line=7)),
        (900, Command3D(Action.OFF, line=10)),
    ]
    assert not cmds[2][1].wait   # "Deactivate distance control with no wait"
    assert not any(b.kinematics for b in program.blocks)


def test_example_2_inclined_tool_with_kinematic_98():
    program = parse_file(EXAMPLES_3D[1])
    blocks = {b.number: b for b in program.blocks}
    assert sorted(blocks) == [10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 110, 120, 130, 140]
    # kinematic 98 parameters in 1e-4 mm / 1e-4 ° as PROG #DIST CTRL prints them (SPEC §12)
    hd = {kin_param_var(1, 98, i): value for i, value in enumerate([1000000, 300000, 600000, 910000])}
    assigned = {a.var: a.value for n in (10, 20, 30, 40) for a in blocks[n].assignments}
    assert assigned == {name: Num(float(value)) for name, value in hd.items()}
    assert list(assigned) == ["V.G.KIN_STEP[1].ID[98].PARAM[0]", "V.G.KIN_STEP[1].ID[98].PARAM[1]",
                              "V.G.KIN_STEP[1].ID[98].PARAM[2]", "V.G.KIN_STEP[1].ID[98].PARAM[3]"]
    assert blocks[50].assignments == [Assignment("V.G.WZ_AKT.L", Num(80.0))]          # tool length 80 mm
    assert blocks[60].kinematics == [KinematicsWord("KIN", ids=(9, 98), line=blocks[60].line, column=6)]
    assert blocks[70].kinematics == [KinematicsWord("TRAFO", switch="ON", line=blocks[70].line, column=6)]
    assert blocks[80].g_codes == [0] and blocks[80].axes == {"Z": Num(10.0)}
    assert blocks[90].g_codes == [90] and blocks[90].axes == {"A": Num(-45.0)}
    assert [(n, c) for n, c in commands(program)] == [
        (100, Command3D(sensor_source=SensorSource.VARIABLE, sensor_var="V.E.SENSOR", line=blocks[100].line)),
        (110, Command3D(Action.ON, set_pos=1.0, mode=CompensationMode.ECS, direction="Z", line=blocks[110].line)),
        (120, Command3D(Action.OFF, wait=True, line=blocks[120].line)),
    ]
    surface = commands(program)[1][1]
    assert surface.surface and not surface.const_dist
    assert blocks[130].axes == {"Z": Num(0.0)} and blocks[140].ends_program


@pytest.mark.parametrize("path", EXAMPLES_3D, ids=lambda p: p.name)
def test_examples_run_through_the_fuzz_contract(path):
    text = path.read_text(encoding="utf-8")
    check(text)
    assert isinstance(parse_program(text), Program)


# ---------------------------------------------------------------- keywords and values

def test_every_keyword_lands_in_its_field():
    cmd = command("#DIST CTRL WAIT ON [CONST_DIST SET_DIST=1.5 MODE=MCS DIRECTION=Z KP=0.5 I_TN=2 D_TV=0.1 \\\n"
                  "  FILTER_TYPE=KALMAN_EXPO FILTER_TIME=20 N_CYCLES=10 FG_F0=40 ORDER=3 SMOOTH_FACT=0.25 \\\n"
                  "  KALMAN_SIGMA=100 SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.DIST VAL1=1 VAL2=2 VAL3=3 VAL4=4 VAL5=5]")
    assert cmd == Command3D(
        Action.ON, wait=True, const_dist=True, set_dist=1.5, mode=CompensationMode.MCS, direction="Z", kp=0.5,
        i_tn=2.0, d_tv=0.1, filter_type=FilterType.KALMAN_EXPO, filter_time=20, n_cycles=10, fg_f0=40.0,
        order=3, smooth_fact=0.25, kalman_sigma=100.0, sensor_source=SensorSource.VARIABLE,
        sensor_var="V.E.DIST", vals=(1.0, 2.0, 3.0, 4.0, 5.0), line=1)
    assert isinstance(cmd.filter_time, int) and isinstance(cmd.n_cycles, int) and isinstance(cmd.order, int)


@pytest.mark.parametrize("text, action, const_dist, no_move, surface", [
    ("#DIST CTRL ON", Action.ON, False, False, True),
    ("#DIST CTRL ON [SURFACE SET_POS=1]", Action.ON, False, False, True),
    ("#DIST CTRL ON [CONST_DIST SET_DIST=1]", Action.ON, True, False, False),
    ("#DIST CTRL DRYRUN [SURFACE SET_POS=1]", Action.DRYRUN, False, False, True),
    ("#DIST CTRL DRYRUN [CONST_DIST SET_DIST=1]", Action.DRYRUN, True, False, False),
    ("#DIST CTRL OFF", Action.OFF, False, False, False),
    ("#DIST CTRL OFF [NO_MOVE]", Action.OFF, False, True, False),
    ("#DIST CTRL FREEZE", Action.FREEZE, False, False, False),
    ("#DIST CTRL CHECK_POS", Action.CHECK_POS, False, False, False),
    ("#DIST CTRL REF", Action.REF, False, False, False),
    ("#DIST CTRL [KP=0.5]", Action.NONE, False, False, False),
    ("#DIST CTRL []", Action.NONE, False, False, False),
    ("#DIST CTRL", Action.NONE, False, False, False),
])
def test_actions(text, action, const_dist, no_move, surface):
    cmd = command(text)
    assert (cmd.action, cmd.const_dist, cmd.no_move, cmd.surface) == (action, const_dist, no_move, surface)
    assert cmd.ref_position is None                     # NC REF: "sensor zero" (SPEC §2)
    assert cmd.wait is False and cmd.is_select == (action in (Action.ON, Action.DRYRUN))


@pytest.mark.parametrize("outside, inside", [
    # PROG #DIST CTRL writes the action before the brackets, FCT-M3 §12.4.4 inside them
    ("#DIST CTRL ON [SURFACE SET_POS=1 MODE=ECS DIRECTION=Z]", "#DIST CTRL [ON SURFACE SET_POS=1 MODE=ECS DIRECTION=Z]"),
    ("#DIST CTRL WAIT OFF", "#DIST CTRL WAIT [OFF]"),
    ("#DIST CTRL WAIT OFF [NO_MOVE]", "#DIST CTRL WAIT [OFF NO_MOVE]"),
    ("#DIST CTRL WAIT ON [SET_POS=10]", "#DIST CTRL WAIT [ON SET_POS=10]"),
    ("#DIST CTRL WAIT ON [SET_POS=10]", "#DIST CTRL [WAIT ON SET_POS=10]"),
    ("#DIST CTRL OFF", "#DIST CTRL [OFF]"),
    ("#DIST CTRL FREEZE", "#DIST CTRL [FREEZE]"),
    ("#DIST CTRL DRYRUN [CONST_DIST SET_DIST=2]", "#DIST CTRL [CONST_DIST DRYRUN SET_DIST=2]"),
])
def test_keywords_inside_or_outside_the_brackets_mean_the_same(outside, inside):
    assert command(outside) == command(inside)
    assert word(outside).outside and not word(inside).outside[1:]


def test_the_forms_of_fct_m3_12_4_4():
    assert command("N220 #DIST CTRL WAIT [ON SET_POS=10]") == Command3D(Action.ON, wait=True, set_pos=10.0, line=1)
    assert command("N240 #DIST CTRL WAIT [OFF NO_MOVE]") == Command3D(Action.OFF, wait=True, no_move=True, line=1)
    assert command("N440 #DIST CTRL WAIT [OFF]") == Command3D(Action.OFF, wait=True, line=1)
    w = word("N120 #DIST CTRL WAIT OFF")
    assert w.outside == ("WAIT", "OFF") and w.keywords == ("WAIT", "OFF") and w.column == 6


def test_word_positions_and_accessors():
    w = word("N10 #DIST CTRL ON [CONST_DIST SET_DIST=1]")
    assert (w.line, w.column) == (1, 5)
    assert [(a.keyword, a.column) for a in w.args] == [("ON", 16), ("CONST_DIST", 20), ("SET_DIST", 31)]
    assert w.action == Action.ON and w.has("CONST_DIST") and w.arg("KP") is None and not w.wait


def test_continuation_lines_and_lower_case():
    program = parse_program("N10 #dist ctrl on [const_dist \\ ; set value next line\n"
                            "     set_dist=2 mode=acs direction=z]\nN20 G0 X1\n")
    assert [b.line for b in program.blocks] == [1, 3]
    cmd = program.blocks[0].dist_ctrl_3d[0].to_command3d({}, 1)
    assert (cmd.action, cmd.const_dist, cmd.set_dist, cmd.mode, cmd.direction) == \
        (Action.ON, True, 2.0, CompensationMode.ACS, "Z")


@pytest.mark.parametrize("mode", list(CompensationMode))
def test_mode_identifiers(mode):
    assert command(f"#DIST CTRL [MODE={mode.name}]").mode == mode


@pytest.mark.parametrize("direction", ["X", "Y", "Z", "z"])
def test_direction_identifiers(direction):
    assert command(f"#DIST CTRL [DIRECTION={direction}]").direction == direction.upper()


def test_sensor_source_default_means_variable():
    w = word("#DIST CTRL [SENSOR_SOURCE=DEFAULT SENSOR_VAR=SENSOR]")
    assert w.arg("SENSOR_SOURCE").value == SensorSource.DEFAULT   # as written
    cmd = w.to_command3d({}, 1)
    assert cmd.sensor_source == SensorSource.VARIABLE and cmd.sensor_var == "V.E.SENSOR"


@pytest.mark.parametrize("name", ["DEFAULT", "MOVING_AVERAGE", "LOWPASS", "KALMAN_MA", "EXPO_MEAN", "KALMAN_EXPO"])
def test_filter_types(name):
    assert command(f"#DIST CTRL [FILTER_TYPE={name}]").filter_type == FilterType[name]


def test_values_may_be_expressions_evaluated_at_to_command3d():
    w = word("#DIST CTRL ON [SURFACE SET_POS=V.E.TOP - 0.5 KP=V.E.K FILTER_TIME=V.E.N*2 VAL3=[1+2]]")
    assert isinstance(w.arg("SET_POS").value, BinOp)
    cmd = w.to_command3d({"V.E.TOP": 20.0, "V.E.K": 0.5, "V.E.N": 5}, 7)
    assert (cmd.set_pos, cmd.kp, cmd.filter_time, cmd.vals[2], cmd.line) == (19.5, 0.5, 10, 3.0, 7)
    with pytest.raises(NcSyntaxError, match="KP=3 is out of range") as info:
        w.to_command3d({"V.E.TOP": 20.0, "V.E.K": 3.0, "V.E.N": 5}, 7)
    assert (info.value.line, info.value.column) == (1, 46)
    with pytest.raises(NcSyntaxError, match="FILTER_TIME=2.5 is out of range"):
        w.to_command3d({"V.E.TOP": 20.0, "V.E.K": 1.0, "V.E.N": 1.25}, 7)
    with pytest.raises(NcSyntaxError, match="unknown variable V.E.TOP"):
        w.to_command3d({}, 7)


def test_core_command_is_the_axis_command_without_the_3d_options():
    cmd = command("#DIST CTRL WAIT ON [CONST_DIST SET_DIST=1 MODE=ECS DIRECTION=Z KP=0.5 FILTER_TIME=3 "
                  "SENSOR_SOURCE=DEFAULT SENSOR_VAR=V.E.S VAL2=4]")
    core = cmd.core_command()
    assert core == Command(Action.ON, const_dist=True, set_dist=1.0, kp=0.5, sensor_source=SensorSource.VARIABLE,
                           sensor_var="V.E.S", vals=(None, 4.0, None, None, None), line=1)
    assert command("#DIST CTRL REF").core_command().action == Action.REF
    assert command("#DIST CTRL REF").core_command().ref_position is None


# ---------------------------------------------------------------- ranges ("analogous" to the channel parameters)

@pytest.mark.parametrize("keyword, good, bad, expected", [
    ("KP", [0.001, 1, 2], [0, -1, 2.01], "expected 0 < KP <= 2"),
    ("I_TN", [0, 5, 50], [-0.1, 50.1], "expected 0 <= I_TN <= 50"),
    ("D_TV", [0, 2], [-1, 2.5], "expected 0 <= D_TV <= 2"),
    ("N_CYCLES", [0, 20, 99], [100, -1, 2.5], "expected an integer 0 <= N_CYCLES <= 99"),
    ("ORDER", [0, 6], [7, 1.5], "expected an integer 0 <= ORDER <= 6"),
    ("SMOOTH_FACT", [0.05, 1], [0, 1.1], "expected 0 < SMOOTH_FACT <= 1"),
    ("KALMAN_SIGMA", [1, 10000], [0.5, 10001], "expected 1 <= KALMAN_SIGMA <= 10000"),
    ("FG_F0", [0, 50], [-1], "expected 0 <= FG_F0"),
    ("FILTER_TIME", [0, 1, 1000], [-1, 0.5], "expected an integer 0 <= FILTER_TIME"),
])
def test_value_ranges(keyword, good, bad, expected):
    for value in good:
        assert command(f"#DIST CTRL [{keyword}={value}]") is not None
    for value in bad:
        exc = error(f"N10 #DIST CTRL [{keyword}={value}]")
        assert expected in exc.message and (exc.line, exc.column) == (1, 17), exc.message


@pytest.mark.parametrize("keyword", ["SET_POS", "SET_DIST", "VAL1", "VAL5"])
def test_set_values_and_vals_take_any_finite_number(keyword):
    prefix = "ON [CONST_DIST " if keyword == "SET_DIST" else "ON ["
    cmd = command(f"#DIST CTRL {prefix}{keyword}=-12.5]")
    assert -12.5 in (cmd.set_pos, cmd.set_dist, *cmd.vals)


# ---------------------------------------------------------------- rule violations

@pytest.mark.parametrize("text, column, fragment", [
    # the actions exclude one another (the 3D syntax writes ON | DRYRUN)
    ("#DIST CTRL ON [OFF]", 16, "OFF cannot be combined with ON"),
    ("#DIST CTRL ON DRYRUN", 15, "DRYRUN cannot be combined with ON"),
    ("#DIST CTRL [FREEZE REF]", 20, "REF cannot be combined with FREEZE"),
    ("#DIST CTRL CHECK_POS [ON]", 23, "ON cannot be combined with CHECK_POS"),
    # duplicates, also across the brackets
    ("#DIST CTRL ON [ON]", 16, "ON given twice in one #DIST CTRL command"),
    ("#DIST CTRL WAIT [WAIT OFF]", 18, "WAIT given twice"),
    ("#DIST CTRL [KP=1 KP=2]", 18, "KP given twice"),
    # SURFACE / CONST_DIST and their set values
    ("#DIST CTRL ON [SURFACE CONST_DIST]", 24, "SURFACE and CONST_DIST exclude one another"),
    ("#DIST CTRL [CONST_DIST SET_DIST=1]", 13, "CONST_DIST without ON or DRYRUN"),
    ("#DIST CTRL OFF [SURFACE]", 17, "SURFACE without ON or DRYRUN"),
    ("#DIST CTRL ON [CONST_DIST SET_POS=1]", 27, "SET_POS belongs to SURFACE, not CONST_DIST"),
    ("#DIST CTRL ON [SURFACE SET_DIST=1]", 24, "SET_DIST belongs to CONST_DIST, not SURFACE"),
    ("#DIST CTRL ON [SET_DIST=1]", 16, "SET_DIST with ON needs CONST_DIST"),
    # NO_MOVE, WAIT
    ("#DIST CTRL ON [NO_MOVE]", 16, "NO_MOVE without OFF"),
    ("#DIST CTRL [WAIT]", 13, "WAIT without ON, DRYRUN, OFF"),
    ("#DIST CTRL WAIT", 12, "WAIT without ON, DRYRUN, OFF"),
    # before the brackets only WAIT and the action, in this order
    ("#DIST CTRL OFF NO_MOVE", 16, "NO_MOVE must be written inside the brackets"),
    ("#DIST CTRL ON CONST_DIST [SET_DIST=1]", 15, "CONST_DIST must be written inside the brackets"),
    ("#DIST CTRL ON KP=1", 15, "KP must be written inside the brackets"),
    ("#DIST CTRL OFF WAIT", 16, "WAIT must come before OFF"),
    ("#DIST CTRL FOO", 12, "unknown #DIST CTRL keyword 'FOO', expected WAIT, ON"),
    ("#DIST CTRL WAIT FREZE", 17, "unknown #DIST CTRL keyword 'FREZE'"),
    # inside the brackets
    ("#DIST CTRL [FOO=1]", 13, "unknown #DIST CTRL keyword 'FOO', expected one of WAIT"),
    ("#DIST CTRL [DIST_CTRL ON]", 13, "unknown #DIST CTRL keyword 'DIST_CTRL'"),
    ("#DIST CTRL [ON=1]", 15, "ON takes no value, expected a #DIST CTRL keyword or ']'"),
    ("#DIST CTRL [KP 1]", 16, "expected '=' after KP, got '1'"),
    ("#DIST CTRL [KP=]", 16, "expected a value"),
    ("#DIST CTRL [ON\nN20 X1", 15, "expected a #DIST CTRL keyword or ']' after ON, got end of line"),
    ("#DIST CTRL [ON] [KP=1]", 17, "expected end of line after ']', got '['"),
    # identifiers
    ("#DIST CTRL [MODE=WCS]", 18, "unknown MODE 'WCS', expected one of OFF, PCS, MCS, ECS, ACS"),
    ("#DIST CTRL [MODE=V.E.M]", 18, "MODE takes a name, not the variable V.E.M"),
    ("#DIST CTRL [DIRECTION=A]", 23, "unknown DIRECTION 'A', expected one of X, Y, Z"),
    ("#DIST CTRL [SENSOR_SOURCE=SECOND_ENCODER]", 27, "unknown SENSOR_SOURCE 'SECOND_ENCODER' (3D"),
    ("#DIST CTRL [FILTER_TYPE=KALMAN]", 25, "unknown FILTER_TYPE 'KALMAN'"),
    ("#DIST CTRL [SENSOR_VAR=V.G.WZ_AKT.L]", 24, "expected the name of a V.E. variable"),
    # "#" commands stand alone in their block
    ("#DIST CTRL ON [SET_POS=1] X10", 27, "#DIST CTRL must stand alone in its block"),
    ("#DIST CTRL OFF G0", 16, "#DIST CTRL must stand alone in its block"),
    ("G0 #DIST CTRL OFF", 4, "#DIST CTRL must stand alone in its block"),
])
def test_rule_violations_are_reported_at_the_offending_keyword(text, column, fragment):
    exc = error(text)
    assert fragment in exc.message, exc.message
    assert (exc.file, exc.line, exc.column) == ("part.nc", 1, column), str(exc)


@pytest.mark.parametrize("text", ["Z[DIST_CTRL SURFACE]", "Z[DIST_CTRL ON FILTER_TIME=3]", "Z[DIST_CTRL MODE=ECS]",
                                  "Z[DIST_CTRL DIRECTION=Z]"])
def test_3d_only_keywords_are_unknown_in_the_axis_command(text):
    exc = error(text)
    assert "unknown DIST_CTRL keyword" in exc.message and "belongs to the 3D command #DIST CTRL" in exc.message


def test_the_axis_command_is_unchanged_next_to_3d_blocks():
    program = parse_program("N10 Z[DIST_CTRL ON SET_POS=30 KP=0.5]\nN20 #DIST CTRL ON [SURFACE SET_POS=30 KP=0.5]\n")
    axis = program.blocks[0].dist_ctrl[0].to_command({}, 1)
    cmd3d = program.blocks[1].dist_ctrl_3d[0].to_command3d({}, 2)
    assert axis == Command(Action.ON, set_pos=30.0, kp=0.5, line=1)
    assert cmd3d.core_command() == Command(Action.ON, set_pos=30.0, kp=0.5, line=2)
    assert not program.blocks[0].dist_ctrl_3d and not program.blocks[1].dist_ctrl


# ---------------------------------------------------------------- kinematics commands

@pytest.mark.parametrize("text, kind, switch, ids", [
    ("N060 #KIN ID[9.98]", "KIN", None, (9, 98)),
    ("#KIN ID[98]", "KIN", None, (98,)),
    ("#kin id [ 9.98 ]", "KIN", None, (9, 98)),
    ("N070 #TRAFO ON", "TRAFO", "ON", ()),
    ("#TRAFO OFF", "TRAFO", "OFF", ()),
    ("N220 #TRAFO [ 9, 98]", "TRAFO", "ON", (9, 98)),     # FCT-M3 §12.4.2.1: select the chain and switch on
    ("#TRAFO [98]", "TRAFO", "ON", (98,)),
    ("#CS OFF", "CS", "OFF", ()),
    ("#CHANNEL INIT", "CHANNEL_INIT", None, ()),
    ("N10 #channel  init ; re-synchronise", "CHANNEL_INIT", None, ()),
])
def test_kinematics_commands(text, kind, switch, ids):
    kin = kinematics(text)
    assert (kin.kind, kin.switch, kin.ids, kin.values) == (kind, switch, ids, ())
    assert kin.reinitialises_channel == (kind in ("TRAFO", "CS", "CHANNEL_INIT"))   # 51062 while active


def test_cs_on_with_six_values():
    kin = kinematics("N10 #CS ON [10, 0, -5.5, 0, V.E.ANGLE, [90/2]]")
    assert (kin.kind, kin.switch, kin.line, kin.column) == ("CS", "ON", 1, 5)
    assert kin.values[4] == Var("V.E.ANGLE")
    assert kin.cs_frame({"V.E.ANGLE": 30.0}) == (10.0, 0.0, -5.5, 0.0, 30.0, 45.0)
    assert kin.reinitialises_channel
    with pytest.raises(NcSyntaxError, match="#CS: unknown variable V.E.ANGLE"):
        kin.cs_frame({})


def test_kinematics_block_keeps_number_line_and_trailing_comments():
    program = parse_program("%K\nN10 #TRAFO ON (trafo) ; on\n\nN20 #KIN ID[98]\n")
    assert [(b.number, b.line) for b in program.blocks] == [(10, 2), (20, 4)]
    assert not program.blocks[0].is_empty and not program.blocks[0].ends_program


@pytest.mark.parametrize("text, column, fragment", [
    ("#KIN ID[9,98]", 10, "expected ']' after '9', got ','"),
    ("#KIN ID[0]", 9, "kinematic ID 0 does not exist"),
    ("#KIN ID[9.0]", 9, "kinematic ID 0 does not exist"),
    ("#KIN 98", 6, "expected ID after #KIN"),
    ("#KIN ID[]", 9, "expected kinematic IDs (e.g. 98 or 9.98)"),
    ("#TRAFO", 7, "expected ON or OFF or '[' after #TRAFO"),
    ("#TRAFO ON [9, 98]", 11, "expected end of line after ON, got '['"),
    ("#TRAFO [9 98]", 11, "expected ',' or ']' after '9', got '98'"),
    ("#TRAFO [9.98]", 10, "expected ',' or ']' after '9', got '.98'"),
    ("#TRAFO [0]", 9, "kinematic ID 0 does not exist"),
    ("#CS ON [1, 2, 3]", 5, "#CS ON needs six values [x, y, z, a, b, c]"),
    ("#CS ON", 5, "#CS ON needs six values"),
    ("#CS OFF [0, 0, 0, 0, 0, 0]", 5, "#CS OFF takes no values"),
    ("#CS ON [1, 2, 3, 4, 5, 1/0]", 1, "#CS: division by zero"),
    ("#CHANNEL", 1, "got '#CHANNEL'"),
    ("G0 X1 #TRAFO ON", 7, "#TRAFO must stand alone in its block"),
    ("#TRAFO ON G0", 11, "#TRAFO must stand alone in its block"),
    ("N10 (c) #KIN ID[98]", 9, "#KIN must stand alone in its block"),
    ("#CHANNEL INIT X1", 15, "#CHANNEL INIT must stand alone in its block"),
])
def test_kinematics_errors(text, column, fragment):
    exc = error(text)
    assert fragment in exc.message, exc.message
    assert (exc.line, exc.column) == (1, column), str(exc)


# ---------------------------------------------------------------- variables with indices

def test_indexed_variables_are_variable_names():
    program = parse_program("N10 V.G.KIN_STEP[1].ID[98].PARAM[2] = 600000\n"
                            "N20 V.E.X = V.G.KIN_STEP[ 1 ].ID[098].PARAM[2] / 10000 + V.G.WZ_AKT.L\n"
                            "N30 X[V.G.KIN_STEP[0].ID[9].PARAM[12]]\n"
                            "N40 v.g.kin_step[1].id[98].param[0] = 1000000\n")
    b = program.blocks
    assert b[0].assignments == [Assignment("V.G.KIN_STEP[1].ID[98].PARAM[2]", Num(600000.0))]
    expr = b[1].assignments[0].value
    assert expr.variables() == {"V.G.KIN_STEP[1].ID[98].PARAM[2]", "V.G.WZ_AKT.L"}
    assert expr.evaluate({"V.G.KIN_STEP[1].ID[98].PARAM[2]": 600000, "V.G.WZ_AKT.L": 80}) == 140.0
    assert b[2].axes["X"] == Var("V.G.KIN_STEP[0].ID[9].PARAM[12]")
    assert b[3].assignments[0].var == "V.G.KIN_STEP[1].ID[98].PARAM[0]"
    assert kin_param_var(1, 98, 3) == "V.G.KIN_STEP[1].ID[98].PARAM[3]"


def test_tool_length_is_assignable():
    (block,) = parse_program("N050 V.G.WZ_AKT.L = 80").blocks
    assert block.assignments == [Assignment("V.G.WZ_AKT.L", Num(80.0))]


@pytest.mark.parametrize("text, column, fragment", [
    ("V.G.KIN_STEP[1].ID[98].PARAM[4] = 1", 1, "kinematic 98 has PARAM[0] .. PARAM[3] (HD1 .. HD4)"),
    ("V.G.WZ_AKT.L = -80", 1, "expected a tool length >= 0 mm"),
    ("V.G.KIN_STEP[1].ID[98].PARAM = 1", 1, "got 'V.G.KIN_STEP'"),
    ("V.G.KIN_STEP[1].ID[98].PARAM[-1] = 1", 1, "got 'V.G.KIN_STEP'"),
    ("V.G.KIN_STEP[1].ID[98].PARAM[0] 1", 33, "expected '=' after V.G.KIN_STEP[1].ID[98].PARAM[0]"),
])
def test_indexed_variable_errors(text, column, fragment):
    exc = error(text)
    assert fragment in exc.message, exc.message
    assert (exc.line, exc.column) == (1, column), str(exc)


# ---------------------------------------------------------------- the parser contract on the new examples

@st.composite
def mutated_3d_example(draw) -> str:
    text = draw(st.sampled_from([p.read_text(encoding="utf-8") for p in EXAMPLES_3D]))
    for _ in range(draw(st.integers(1, 6))):
        kind = draw(st.sampled_from(["delete", "insert", "duplicate"]))
        at = draw(st.integers(0, len(text)))
        if kind == "delete":
            text = text[:at] + text[at + draw(st.integers(1, 8)):]
        elif kind == "insert":
            text = text[:at] + draw(st.text(alphabet=st.sampled_from(NC_ALPHABET_3D) | st.characters(),
                                             min_size=1, max_size=4)) + text[at:]
        else:
            piece = text[at:at + draw(st.integers(1, 20))]
            text = text[:at] + piece * draw(st.integers(2, 3)) + text[at:]
    return text


NC_ALPHABET_3D = NC_ALPHABET + "#KINTRAFOCSHWUPQMDJ,.[]=98"
KEYWORDS_3D = ["#DIST CTRL", "#KIN", "#TRAFO", "#CS", "#CHANNEL INIT", " ON", " OFF", " WAIT", " SURFACE", " [",
               "]", "MODE=", "DIRECTION=", "FILTER_TIME=", "ID[", "9.98", "V.G.KIN_STEP[1].ID[98].PARAM[0]", " = ",
               ",", "\\\n", "\n", "SET_POS=", "CONST_DIST", " NO_MOVE", " 1", "Z"]


@FUZZ
@given(mutated_3d_example())
def test_mutated_3d_examples(text):
    check(text)


@FUZZ
@given(st.lists(st.sampled_from(KEYWORDS_3D), max_size=12).map("".join))
def test_sequences_of_3d_keywords(text):
    check(text)
