"""#WAIT FOR <condition> (TF5200 programming manual, "Waiting for event (#WAIT FOR)"): parsing and the
interpreter stopping until a V.E. variable fulfils the condition."""
from __future__ import annotations

import pytest

from distctrl.nc import Compare, NcSyntaxError, Var, parse_program
from distctrl.nc.interpreter import NC_RUNTIME_ERROR, NcInterpreter


class Channel:
    def __init__(self):
        self.positions = {"X": 0.0, "Z": 0.0}
        self.variables: dict[str, float] = {}
        self.moves = []

    def start_linear(self, target, feed):
        self.moves.append(target)

    def start_dwell(self, seconds):
        pass

    def motion_done(self):
        return True

    def dist_ctrl(self, axis, command):
        pass

    def dist_ctrl_done(self, axis, action):
        return True


def test_wait_for_parses_a_comparison_or_a_bare_expression():
    prog = parse_program("N10 #WAIT FOR V.E.DONE == 1\nN20 #wait for [V.E.A - 2]\nN30 #WAIT FOR V.E.A>=V.E.B*2\n")
    a, b, c = (blk.wait_for for blk in prog.blocks)
    assert a == Compare("==", Var("V.E.DONE"), a.right) and a.right.value == 1.0
    assert b.variables() == {"V.E.A"}
    assert c.op == ">=" and c.variables() == {"V.E.A", "V.E.B"}
    assert not prog.blocks[0].is_empty


@pytest.mark.parametrize("op, left, right, holds", [
    ("==", 5, 5, 1.0), ("==", 5, 4, 0.0), ("!=", 5, 4, 1.0), ("<", 4, 5, 1.0), ("<", 5, 5, 0.0),
    ("<=", 5, 5, 1.0), (">", 5, 4, 1.0), (">", 4, 4, 0.0), (">=", 4, 4, 1.0)])
def test_comparison_values(op, left, right, holds):
    prog = parse_program(f"N10 #WAIT FOR V.E.L {op} V.E.R\n")
    assert prog.blocks[0].wait_for.evaluate({"V.E.L": left, "V.E.R": right}) == holds


@pytest.mark.parametrize("text, words", [
    ("N10 #WAIT FOR 1 == 1\n", "constant condition"),
    ("N10 #WAIT FOR\n", "after #WAIT FOR"),
    ("N10 #WAIT FOR V.E.A = 1\n", "comparison"),
    ("N10 #WAIT FOR V.E.A == 1 X10\n", "end of line"),
    ("N10 X10 #WAIT FOR V.E.A\n", "#WAIT"),
])
def test_wait_for_errors_name_line_and_column(text, words):
    with pytest.raises(NcSyntaxError) as exc:
        parse_program(text, file="p.nc")
    assert exc.value.line == 1 and exc.value.column is not None and words in str(exc.value)


def test_the_program_waits_until_the_variable_fulfils_the_condition():
    ch = Channel()
    ch.variables["V.E.REQ"] = 0.0
    nc = NcInterpreter(parse_program("N10 V.E.REQ = 1\nN20 #WAIT FOR V.E.REQ == 0\nN30 X10\nN40 M30\n"), ch)
    for _ in range(5):                       # the PLC has not answered: the program stays in N20
        nc.tick()
        assert nc.line == 2 and ch.moves == [] and nc.running
    assert ch.variables["V.E.REQ"] == 1.0
    ch.variables["V.E.REQ"] = 0.0            # the PLC's answer
    nc.tick()
    assert ch.moves == [{"X": 10.0}] and nc.line == 3
    nc.tick()
    assert nc.ended and not nc.aborted


def test_a_condition_already_fulfilled_does_not_take_a_cycle():
    ch = Channel()
    nc = NcInterpreter(parse_program("N10 V.E.OK = 1\nN20 #WAIT FOR V.E.OK\nN30 X5\n"), ch)
    nc.tick()
    assert ch.moves == [{"X": 5.0}]


def test_an_undefined_variable_stops_the_program_with_900010_at_the_wait_line():
    ch = Channel()
    nc = NcInterpreter(parse_program("N10 X1\nN20 #WAIT FOR V.E.MISSING == 1\nN30 X2\n"), ch)
    nc.tick()
    nc.tick()
    assert nc.aborted and nc.error.id == NC_RUNTIME_ERROR and nc.error.line == 2
    assert "V.E.MISSING" in nc.error.message and ch.moves == [{"X": 1.0}]
