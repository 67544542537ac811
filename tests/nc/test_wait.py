"""WAIT in the axis DIST_CTRL command (SPEC §8)."""
from __future__ import annotations

import pytest

from distctrl.control import Action
from distctrl.nc import NcSyntaxError, parse_program


def test_wait_parses_with_an_action_in_any_position():
    prog = parse_program("N10 Z[DIST_CTRL WAIT ON SET_POS=30]\nN20 Z[DIST_CTRL OFF WAIT]\n")
    first, second = (b.dist_ctrl[0] for b in prog.blocks)
    assert first.wait and first.action == Action.ON
    assert second.wait and second.action == Action.OFF
    assert not parse_program("N10 Z[DIST_CTRL ON SET_POS=1]").blocks[0].dist_ctrl[0].wait


def test_wait_without_an_action_is_rejected_with_line_and_column():
    with pytest.raises(NcSyntaxError) as exc:
        parse_program("N10 Z[DIST_CTRL SET_POS=30]\nN20 Z[DIST_CTRL WAIT KP=0.5]\n", file="p.nc")
    assert exc.value.line == 2 and exc.value.column is not None and "WAIT" in str(exc.value)
