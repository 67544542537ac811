"""Program structure, words, comments, continuation lines, expressions and error reports."""
from __future__ import annotations

import pickle

import pytest

from distctrl.nc import (
    BinOp, ExprError, NcSyntaxError, Neg, Num, Var, parse_file, parse_program,
)


def error(text: str, file: str | None = "part.nc") -> NcSyntaxError:
    with pytest.raises(NcSyntaxError) as info:
        parse_program(text, file)
    return info.value


# ---------------------------------------------------------------- structure

def test_header_blocks_numbers_and_lines():
    program = parse_program("%P1\n\nN10 G90\n; comment\nN20 G1 X1 F100\n   \nG0 Z5\nN999 M30\n")
    assert program.name == "P1" and program.source is None
    assert [(b.line, b.number) for b in program.blocks] == [(3, 10), (5, 20), (7, None), (8, 999)]


def test_program_without_header_and_empty_program():
    assert parse_program("G1 X1 F1").name is None
    assert parse_program("").blocks == []
    assert parse_program("\n\n; only comments\n(and this)\n").blocks == []


def test_block_number_alone_is_a_block():
    (block,) = parse_program("N5\n").blocks
    assert block.number == 5 and block.is_empty


def test_glued_words():
    (block,) = parse_program("N10G1X100Y-5Z[DIST_CTRL ON]F3000M3").blocks
    assert block.number == 10 and block.g_codes == [1] and block.m_codes == [3]
    assert block.axes == {"X": Num(100.0), "Y": Num(-5.0)}
    assert block.feed == Num(3000.0) and block.dist_ctrl[0].axis == "Z"


def test_crlf_and_byte_order_mark():
    program = parse_program("\ufeff%P\r\nN10 X1\r\nN20 X2\rN30 X3")
    assert program.name == "P" and [b.line for b in program.blocks] == [2, 3, 4]


@pytest.mark.parametrize("text, message", [
    ("%A\n%B\n", "second program header %B"),
    ("N10 X1\n%A\n", "program header %A after the first block"),
])
def test_one_header_at_the_start(text, message):
    assert message in error(text).message


# ---------------------------------------------------------------- Nxx placeholders (SPEC §12)

def test_nxx_placeholder_is_a_parse_error_naming_line_and_column():
    text = ("%DIST_1\nN10 Z[DIST_CTRL SET_POS=30]\nN20 Z[DIST_CTRL ON]\n; ...\n"
            "Nxx Z[DIST_CTRL OFF]\nN999 M30\n")
    exc = error(text)
    assert (exc.file, exc.line, exc.column) == ("part.nc", 5, 1)
    assert "expected a block number (N followed by digits), got 'Nxx'" in exc.message
    assert "placeholder" in exc.message
    assert str(exc).startswith("part.nc:5:1: expected a block number")


def test_indented_nxx_reports_its_column():
    exc = error("N10 X1\n   Nxx G1 X2")
    assert (exc.line, exc.column) == (2, 4)


# ---------------------------------------------------------------- comments and continuation

def test_semicolon_and_parenthesis_comments():
    (block,) = parse_program("N10 (move) G1 X1 (fast) F100 ; rest (ignored) X2\n").blocks
    assert block.axes == {"X": Num(1.0)} and block.feed == Num(100.0)


def test_parenthesis_inside_expression_is_not_a_comment():
    (block,) = parse_program("X[(1+2)*3] (comment)").blocks
    assert block.axes["X"].evaluate({}) == 9.0


def test_continuation_inside_dist_ctrl_brackets():
    text = ("%C\n"
            "N10 Z[DIST_CTRL ON \\\n"
            "        SET_POS=30 \\   ; comment after the separator\n"
            "        KP=0.5 I_TN=1]\n"
            "N20 G1 X1 F1000\n")
    program = parse_program(text)
    assert [(b.line, b.number) for b in program.blocks] == [(2, 10), (5, 20)]
    (word,) = program.blocks[0].dist_ctrl
    assert [(a.keyword, a.line, a.column) for a in word.args] == [
        ("ON", 2, 17), ("SET_POS", 3, 9), ("KP", 4, 9), ("I_TN", 4, 16)]
    cmd = word.to_command({}, program.blocks[0].line)
    assert (cmd.set_pos, cmd.kp, cmd.i_tn, cmd.line) == (30.0, 0.5, 1.0, 2)


def test_continuation_between_block_words():
    (block,) = parse_program("N10 G1 \\\n X10 \\\n F500\n").blocks
    assert block.line == 1 and block.axes == {"X": Num(10.0)} and block.feed == Num(500.0)


def test_error_after_continuation_reports_the_physical_line():
    exc = error("N10 Z[DIST_CTRL ON \\\n  KP=5]")
    assert (exc.line, exc.column) == (2, 3) and "KP=5" in exc.message


def test_missing_continuation_gives_a_hint():
    exc = error("N10 Z[DIST_CTRL ON\n  KP=1]")
    assert (exc.line, exc.column) == (1, 19)
    assert "'\\'" in exc.message


# ---------------------------------------------------------------- words

@pytest.mark.parametrize("text, axis, value", [
    ("Z40", "Z", 40.0), ("Z=40", "Z", 40.0), ("A=-45", "A", -45.0), ("X-12.5", "X", -12.5),
    ("Y+3", "Y", 3.0), ("B1.5e2", "B", 150.0), ("C.5", "C", 0.5), ("X1.", "X", 1.0), ("x7", "X", 7.0),
    ("Z1E-3", "Z", 0.001),
])
def test_axis_word_forms(text, axis, value):
    (block,) = parse_program(text).blocks
    assert block.axes[axis] == Num(value)


def test_axis_values_from_variables_and_expressions():
    (block,) = parse_program("Z=V.E.HEIGHT X[V.E.X0 + 2*3] Y-V.E.Y A=[-(1+1)] B V.G.WZ_AKT.L").blocks
    assert block.axes["Z"] == Var("V.E.HEIGHT")
    assert block.axes["X"] == BinOp("+", Var("V.E.X0"), BinOp("*", Num(2.0), Num(3.0)))
    assert block.axes["Y"] == Neg(Var("V.E.Y"))
    assert block.axes["A"].evaluate({}) == -2.0
    assert block.axes["B"] == Var("V.G.WZ_AKT.L")
    values = {"V.E.HEIGHT": 4.0, "V.E.X0": 1.0, "V.E.Y": 2.5}
    assert block.axes["X"].evaluate(values) == 7.0 and block.axes["Y"].evaluate(values) == -2.5


def test_g_m_feed_and_dwell():
    program = parse_program("G0 G90 X0\nG1 G91 F=2000 Y1\n#TIME 1.5\nF[V.E.F*2]\nM30\nM2\n")
    g0, g1, dwell, feed, m30, m2 = program.blocks
    assert g0.g_codes == [0, 90] and g1.g_codes == [1, 91] and g1.feed == Num(2000.0)
    assert dwell.dwell == Num(1.5)
    assert feed.feed.evaluate({"V.E.F": 10}) == 20.0
    assert m30.ends_program and m2.ends_program and not g0.ends_program


def test_assignments_with_expressions():
    (block,) = parse_program("N5 V.E.A = 2 * (V.E.B - 1) / 4 V.E.C=[1] X[V.E.A]").blocks
    assert [a.var for a in block.assignments] == ["V.E.A", "V.E.C"]
    assert block.assignments[0].value.evaluate({"V.E.B": 5}) == 2.0
    assert block.axes["X"] == Var("V.E.A")


@pytest.mark.parametrize("text, line, column, fragment", [
    ("G2 X1", 1, 1, "unsupported G code G2, expected one of G0, G1, G90, G91"),
    ("G0 G1", 1, 4, "G1 contradicts G0"),
    ("G90 X1 G91", 1, 8, "G91 contradicts G90"),
    ("X1 X2", 1, 4, "axis X given twice"),
    ("F1 F2", 1, 4, "F given twice"),
    ("#TIME 1 #TIME 2", 1, 9, "#TIME given twice"),
    ("F0", 1, 1, "expected F > 0"),
    ("#TIME -1", 1, 1, "expected a time >= 0"),
    ("X", 1, 2,
     "expected '=' or a value (number, V.E. variable or [expression]) after X, got end of program"),
    ("G1 X\n", 1, 5, "after X, got end of line"),
    ("X1 2", 1, 4, "expected end of line or an NC word"),
    ("S1000", 1, 1, "got 'S1000'"),
    ("X[1+]", 1, 5, "expected a value"),
    ("X[(1+2]", 1, 7, "')'"),
    ("X[1/0]", 1, 1, "division by zero"),
    ("X1e999", 1, 2, "too large"),
    ("V.G.WZ_AKT.L = -3", 1, 1, "expected a tool length >= 0 mm"),
    ("V.E.A 3", 1, 7, "expected '=' after V.E.A"),
    ("V.X.A=3", 1, 1, "got 'V.X.A'"),
    ("N10 X1 N20", 1, 8, "got 'N20'"),
    ("X1 @", 1, 4, "got '@'"),
])
def test_word_errors(text, line, column, fragment):
    exc = error(text)
    assert (exc.line, exc.column) == (line, column), str(exc)
    assert fragment in exc.message, exc.message


def test_deeply_nested_expressions_are_rejected_not_crashing():
    deep = "X[" + "+".join(["1"] * 500) + "]"
    assert "nested too deeply" in error(deep).message
    parse_program("X[" + "(" * 500 + "1" + ")" * 500 + "]")   # parentheses alone add no depth


# ---------------------------------------------------------------- expressions

def test_expression_precedence_and_unary_minus():
    (block,) = parse_program("V.E.R = -2 + 3 * 4 - 8 / 2 / 2 + -(1 - 3)").blocks
    assert block.assignments[0].value.evaluate({}) == -2 + 3 * 4 - 8 / 2 / 2 + -(1 - 3)


def test_expression_errors_are_expr_errors():
    expr = BinOp("/", Num(1.0), Var("V.E.Z"))
    with pytest.raises(ExprError, match="division by zero"):
        expr.evaluate({"V.E.Z": 0})
    with pytest.raises(ExprError, match="unknown variable V.E.Z"):
        expr.evaluate({})
    with pytest.raises(ExprError, match="not a number"):
        expr.evaluate({"V.E.Z": "abc"})
    with pytest.raises(ExprError, match="not finite"):
        BinOp("*", Num(1e308), Num(10.0)).evaluate({})
    assert expr.variables() == {"V.E.Z"} and not expr.is_constant


# ---------------------------------------------------------------- error object and files

def test_error_format_without_file_and_pickling():
    exc = error("Nxx", file=None)
    assert str(exc).startswith("<string>:1:1: ")
    copy = pickle.loads(pickle.dumps(exc))
    assert (copy.file, copy.line, copy.column, copy.message) == (exc.file, 1, 1, exc.message)


def test_parse_file_reports_the_path(tmp_path):
    path = tmp_path / "bad.nc"
    path.write_text("N10 X1\nN20 Z[DIST_CTRL KP]\n")
    with pytest.raises(NcSyntaxError) as info:
        parse_file(path)
    assert str(info.value) == f"{path}:2:19: expected '=' after KP, got ']'"


def test_parse_file_latin1_and_missing_file(tmp_path):
    path = tmp_path / "de.nc"
    path.write_bytes("N20 Z[DIST_CTRL ON]          ;Anwahl (Größe)\n".encode("latin-1"))
    assert parse_file(path).blocks[0].dist_ctrl[0].axis == "Z"
    with pytest.raises(NcSyntaxError, match="cannot read NC file"):
        parse_file(tmp_path / "missing.nc")


def test_non_string_input_is_a_type_error():
    with pytest.raises(TypeError):
        parse_program(b"N10 X1")   # type: ignore[arg-type]


def test_every_terminal_has_a_readable_name_for_messages():
    from distctrl.nc.parser import _TERMINAL_NAMES, _parser
    terminals = {t.name for t in _parser().terminals if not t.name.startswith("__")}   # __IGNORE_n
    assert terminals <= set(_TERMINAL_NAMES)


def test_a_syntax_error_pickles_where_dask_pickles_exceptions(monkeypatch):
    """dask.distributed installs tblib's exception pickling, which pickles ``__context__`` too: an
    NcSyntaxError raised while lark's exception (which holds the parser) was being handled could not
    cross from a sweep worker to the client (and made this file's pickling test fail after the
    tuning tests had started a dask cluster)."""
    import copyreg
    import types

    from tblib import pickling_support

    # what pickling_support.install() registers, undone after the test
    monkeypatch.setitem(copyreg.dispatch_table, types.TracebackType, pickling_support.pickle_traceback)
    monkeypatch.setitem(copyreg.dispatch_table, NcSyntaxError, pickling_support.pickle_exception)
    for text in ("Nxx", "N10 Z[DIST_CTRL KP]", "N10 G1 X(1+"):
        exc = error(text, file=None)
        assert exc.__context__ is None and exc.__cause__ is None
        copy = pickle.loads(pickle.dumps(exc))
        assert (copy.line, copy.column, copy.message) == (exc.line, exc.column, exc.message)
