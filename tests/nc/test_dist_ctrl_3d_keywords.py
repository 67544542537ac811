"""#DIST CTRL: where the parameterisation keywords may be written (PROG #DIST CTRL, FCT-M3 §12.2).

PROG #DIST CTRL: "Syntax for additional parameterisation (optionally, can also be programmed in
combination with select/deselect): #DIST CTRL [ [ MODE=<ident> ] [DIRECTION=<axis_name>] [ KP=.. ] …".
The parameter keywords are written inside the brackets, alone (no action) or with a select or
deselect; before the brackets only WAIT and the action are written (a parameter keyword there is
refused, naming it).
"""
from __future__ import annotations

import pytest

from distctrl.control.commands import Action
from distctrl.control.commands3d import Command3D, CompensationMode
from distctrl.nc import NcSyntaxError, parse_program

PARAMETERS = "MODE=MCS DIRECTION=Z KP=0.5 I_TN=2 D_TV=0.1 N_CYCLES=10 SMOOTH_FACT=0.25 KALMAN_SIGMA=100"
VALUES = dict(mode=CompensationMode.MCS, direction="Z", kp=0.5, i_tn=2.0, d_tv=0.1, n_cycles=10,
              smooth_fact=0.25, kalman_sigma=100.0)


def command(text: str) -> Command3D:
    (block,) = parse_program(text).blocks
    (word,) = block.dist_ctrl_3d
    return word.to_command3d({}, 1)


def test_parameter_keywords_alone_inside_the_brackets():
    """Alone: no select or deselect; the block only parameterises (action NONE) and every value lands."""
    cmd = command(f"#DIST CTRL [{PARAMETERS}]")
    assert cmd == Command3D(Action.NONE, line=1, **VALUES)


@pytest.mark.parametrize("text, action, extra", [
    (f"#DIST CTRL ON [CONST_DIST SET_DIST=1 {PARAMETERS}]", Action.ON, dict(const_dist=True, set_dist=1.0)),
    (f"#DIST CTRL [ON CONST_DIST SET_DIST=1 {PARAMETERS}]", Action.ON, dict(const_dist=True, set_dist=1.0)),
    (f"#DIST CTRL WAIT ON [SURFACE SET_POS=2 {PARAMETERS}]", Action.ON, dict(wait=True, set_pos=2.0)),
    (f"#DIST CTRL OFF [{PARAMETERS}]", Action.OFF, {}),
    (f"#DIST CTRL OFF [NO_MOVE {PARAMETERS}]", Action.OFF, dict(no_move=True)),
    (f"#DIST CTRL FREEZE [{PARAMETERS}]", Action.FREEZE, {}),
])
def test_parameter_keywords_together_with_a_select_or_deselect(text, action, extra):
    cmd = command(text)
    assert cmd.action == action
    for field, value in {**VALUES, **extra}.items():
        assert getattr(cmd, field) == value, field


@pytest.mark.parametrize("text, keyword", [
    ("#DIST CTRL KP=0.5", "KP"),
    ("#DIST CTRL ON KP=0.5 [CONST_DIST SET_DIST=1]", "KP"),
    ("#DIST CTRL OFF MODE=MCS", "MODE"),
    ("#DIST CTRL WAIT ON DIRECTION=Z", "DIRECTION"),
    ("#DIST CTRL FREEZE N_CYCLES=3", "N_CYCLES"),
])
def test_parameter_keywords_outside_the_brackets_are_refused(text, keyword):
    """Before the brackets only WAIT and the action: a parameter keyword there is a syntax error that
    names the keyword and says where it belongs."""
    with pytest.raises(NcSyntaxError) as info:
        parse_program(text, "part.nc")
    exc = info.value
    assert f"{keyword} must be written inside the brackets" in exc.message
    assert (exc.file, exc.line) == ("part.nc", 1) and exc.column == text.index(keyword) + 1
