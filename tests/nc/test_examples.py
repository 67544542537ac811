"""The documents' programs %DIST_1 .. %DIST_5 (examples/) parse to the expected commands."""
from __future__ import annotations

from pathlib import Path

import pytest

from distctrl.control.commands import Action, Command
from distctrl.base.kinds import FilterType
from distctrl.nc import Program, parse_file

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def commands(program: Program) -> list[tuple[int | None, Command]]:
    return [(block.number, word.to_command({}, block.line))
            for block in program.blocks for word in block.dist_ctrl]


@pytest.mark.parametrize("number", [1, 2, 3, 4, 5])
def test_example_parses_with_name_and_program_end(number):
    program = parse_file(EXAMPLES / f"dist_{number}.nc")
    assert program.name == f"DIST_{number}"
    assert program.source == str(EXAMPLES / f"dist_{number}.nc")
    assert program.blocks[-1].number == 999 and program.blocks[-1].ends_program
    assert all(word.axis == "Z" for block in program.blocks for word in block.dist_ctrl)
    # block numbers are concrete and ascending (no Nxx placeholders)
    numbers = [block.number for block in program.blocks]
    assert None not in numbers and numbers == sorted(numbers)
    # the documents' "; ..." became motion
    assert any(block.g_codes == [1] and "X" in block.axes for block in program.blocks)


def test_dist_1_set_pos_then_on_then_off():
    cmds = commands(parse_file(EXAMPLES / "dist_1.nc"))
    assert [(n, c.action) for n, c in cmds] == [(10, Action.NONE), (20, Action.ON), (40, Action.OFF)]
    assert cmds[0][1].set_pos == 30.0
    assert cmds[1][1].set_pos is None and not cmds[1][1].const_dist
    assert cmds[2][1].no_move is False
    assert [c.line for _, c in cmds] == [3, 4, 6]


def test_dist_2_on_freeze_lift_off():
    program = parse_file(EXAMPLES / "dist_2.nc")
    cmds = commands(program)
    assert [c.action for _, c in cmds] == [Action.ON, Action.FREEZE, Action.OFF]
    assert cmds[0][1].set_pos == 30.0
    lift = next(b for b in program.blocks if b.number == 40)
    assert lift.g_codes == [0] and lift.axes["Z"].evaluate({}) == 60.0


def test_dist_3_off_no_move_then_g0():
    program = parse_file(EXAMPLES / "dist_3.nc")
    cmds = commands(program)
    assert cmds[0][1] == Command(Action.ON, set_pos=50.0, line=3)
    assert cmds[1][1] == Command(Action.OFF, no_move=True, line=6)
    last_move = program.blocks[-2]
    assert (last_move.number, last_move.g_codes, last_move.axes["Z"].evaluate({})) == (40, [0], 100.0)


def test_dist_4_set_pos_mode_then_const_dist_mode():
    cmds = commands(parse_file(EXAMPLES / "dist_4.nc"))
    assert [(n, c.action, c.const_dist) for n, c in cmds] == [
        (10, Action.NONE, False), (20, Action.ON, False), (40, Action.OFF, False),
        (60, Action.NONE, False), (70, Action.ON, True), (90, Action.OFF, False)]
    assert cmds[0][1].set_pos == 30.0
    assert cmds[3][1].set_dist == 10.0 and cmds[3][1].set_pos is None


def test_dist_5_filter_dryrun_pid_const_dist():
    program = parse_file(EXAMPLES / "dist_5.nc")
    assert program.blocks[0].number == 10 and program.blocks[0].line == 3   # glued "N10Z[...]"
    by_number = {n: c for n, c in commands(program)}
    assert by_number[10] == Command(filter_type=FilterType.KALMAN_MA, line=3)
    assert (by_number[20].n_cycles, by_number[20].kalman_sigma) == (30, 1000.0)
    assert isinstance(by_number[20].n_cycles, int)
    assert by_number[25].set_pos == 30.0
    assert by_number[30].action == Action.DRYRUN and not by_number[30].const_dist
    assert (by_number[50].kp, by_number[50].i_tn, by_number[50].d_tv) == (0.3, 0.0, 0.01)
    assert by_number[50].action == Action.NONE
    assert (by_number[60].action, by_number[60].const_dist, by_number[60].set_dist) == (Action.ON, True, 1.0)
    assert (by_number[80].filter_type, by_number[80].smooth_fact) == (FilterType.KALMAN_EXPO, 0.3)
    assert by_number[100].action == Action.OFF
