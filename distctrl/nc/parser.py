"""Parse NC programs (ISG dialect subset, docs/nc.md) into :class:`~distctrl.nc.program.Program`.

The grammar (grammar.lark) fixes the syntax; :class:`_ProgramBuilder` turns the parse into the data
model while lark parses (LALR with an inline transformer: no tree, no recursion) and checks what a
grammar cannot: DIST_CTRL keyword combinations, duplicates, constant value ranges. Every problem
becomes an :class:`NcSyntaxError` with file, physical line and column.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from os import PathLike

from lark import Lark, Token, Transformer
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput

from ..control.kinds import FILTER_TYPE_NAMES, FilterType, SensorSource
from .program import (
    ACTION_KEYWORDS, MAX_EXPR_DEPTH, Assignment, BinOp, Block, DistCtrlArg, DistCtrlWord, Expr, ExprError,
    NcSyntaxError, Neg, Num, Program, Var, dist_ctrl_range_error, no_variables,
)

__all__ = ["NcSyntaxError", "parse_program", "parse_file"]

#: G codes of the subset, by group: two codes of one group in a block contradict each other
G_CODE_GROUPS = {0: "motion", 1: "motion", 90: "dimension", 91: "dimension"}


# ---------------------------------------------------------------- building the model

@dataclass(frozen=True, slots=True)
class _Word:
    """A block item on its way into a :class:`Block`, with its position for error messages."""

    kind: str        # "g", "m", "feed", "axis", "dwell", "assign", "dist_ctrl"
    value: object
    line: int
    column: int
    name: str = ""   # axis letter for "axis"


@dataclass(frozen=True, slots=True)
class _Header:
    name: str
    line: int
    column: int


def _error(message: str, token: Token | _Word | DistCtrlArg) -> NcSyntaxError:
    return NcSyntaxError(message, line=token.line, column=token.column)


def _checked(expr: Expr, where: Token, what: str) -> Expr:
    """Reject expressions too deep to evaluate safely and constants that cannot be evaluated."""
    if expr.depth > MAX_EXPR_DEPTH:
        raise _error(f"expression after {what} is nested too deeply "
                     f"(more than {MAX_EXPR_DEPTH} levels)", where)
    if expr.is_constant:
        try:
            expr.evaluate(no_variables)
        except ExprError as exc:
            raise _error(f"{what}: {exc}", where) from None
    return expr


def _var_name(token: Token) -> str:
    """Canonical variable name: upper-case prefix, V.E. name as written."""
    text = str(token)
    if text[2] in "gG":
        return "V.G.WZ_AKT.L"
    return "V.E." + text[4:]


class _ProgramBuilder(Transformer):
    """Callbacks run by the LALR parser on each reduction. Stateless, so the parser is shared."""

    # ---- expressions
    def num(self, children):
        (token,) = children
        value = float(token)
        if not math.isfinite(value):
            raise _error(f"number {token} is too large", token)
        return Num(value)

    def var(self, children):
        return Var(_var_name(children[0]))

    def neg(self, children):
        (operand,) = children
        return Num(-operand.value) if isinstance(operand, Num) else Neg(operand)

    def add(self, children):
        return BinOp("+", *children)

    def sub(self, children):
        return BinOp("-", *children)

    def mul(self, children):
        return BinOp("*", *children)

    def div(self, children):
        return BinOp("/", *children)

    # ---- block words
    def g_word(self, children):
        (token,) = children
        code = int(token[1:])
        if code not in G_CODE_GROUPS:
            raise _error(f"unsupported G code {token.upper()}, expected one of G0, G1, G90, G91", token)
        return _Word("g", code, token.line, token.column)

    def m_word(self, children):
        (token,) = children
        return _Word("m", int(token[1:]), token.line, token.column)

    def feed_word(self, children):
        token, expr = children
        expr = _checked(expr, token, "F")
        if expr.is_constant and not expr.evaluate(no_variables) > 0:
            raise _error(f"F={expr.evaluate(no_variables):g} is out of range, expected F > 0 (mm/min)", token)
        return _Word("feed", expr, token.line, token.column)

    def axis_word(self, children):
        token, expr = children
        axis = token.upper()
        return _Word("axis", _checked(expr, token, axis), token.line, token.column, name=axis)

    def dwell(self, children):
        token, expr = children
        expr = _checked(expr, token, "#TIME")
        if expr.is_constant and expr.evaluate(no_variables) < 0:
            raise _error(f"#TIME {expr.evaluate(no_variables):g} is out of range, "
                         "expected a time >= 0 s", token)
        return _Word("dwell", expr, token.line, token.column)

    def assignment(self, children):
        token, expr = children
        name = _var_name(token)
        if not name.startswith("V.E."):
            raise _error(f"{name} is read-only, expected a V.E. variable to assign to", token)
        value = _checked(expr, token, name)
        return _Word("assign", Assignment(name, value), token.line, token.column)

    # ---- DIST_CTRL
    def dc_flag(self, children):
        (token,) = children
        return DistCtrlArg(token.upper(), None, token.line, token.column)

    def dc_number(self, children):
        token, expr = children
        keyword = token.upper()
        expr = _checked(expr, token, keyword)
        if expr.is_constant:
            problem = dist_ctrl_range_error(keyword, expr.evaluate(no_variables))
            if problem:
                raise _error(problem, token)
        return DistCtrlArg(keyword, expr, token.line, token.column)

    def dc_name(self, children):
        token, value = children
        keyword = token.upper()
        is_var = value.type == "VAR"
        if keyword == "SENSOR_VAR":
            name = _var_name(value) if is_var else "V.E." + str(value)
            if not name.startswith("V.E."):
                raise _error(f"SENSOR_VAR={name}: expected the name of a V.E. variable", value)
            return DistCtrlArg(keyword, name, token.line, token.column)
        try:
            if is_var:
                raise ValueError(f"{keyword} takes a name, not the variable {value}")
            parsed = FilterType.parse(value) if keyword == "FILTER_TYPE" else SensorSource.parse(value)
        except ValueError:
            allowed = FILTER_TYPE_NAMES if keyword == "FILTER_TYPE" else tuple(SensorSource.__members__)
            raise _error(f"unknown {keyword} {str(value)!r}, expected one of {', '.join(allowed)}",
                         value) from None
        return DistCtrlArg(keyword, parsed, token.line, token.column)

    def dist_ctrl(self, children):
        axis_token, _dist_ctrl_token, *args = children
        _check_dist_ctrl_rules(args)
        word = DistCtrlWord(axis_token.upper(), tuple(args), axis_token.line, axis_token.column)
        return _Word("dist_ctrl", word, axis_token.line, axis_token.column, name=word.axis)

    # ---- structure
    def header(self, children):
        (token,) = children
        return _Header(str(token)[1:], token.line, token.column)

    def block(self, children):
        return _build_block(children)

    def start(self, children):
        name: str | None = None
        blocks: list[Block] = []
        for child in children:
            if isinstance(child, _Header):
                if name is not None:
                    raise _error(f"second program header %{child.name}, expected one program per file "
                                 f"(the first is %{name})", child)
                if blocks:
                    raise _error(f"program header %{child.name} after the first block, "
                                 "expected it at the start of the program", child)
                name = child.name
            elif not child.is_empty or child.number is not None:   # drop comment-only lines
                blocks.append(child)
        return Program(name=name, blocks=blocks)


def _check_dist_ctrl_rules(args: list[DistCtrlArg]) -> None:
    """Keyword rules of seeds/000 §6 and seeds/003 §6 (order-independent)."""
    seen: dict[str, DistCtrlArg] = {}
    for arg in args:
        if arg.keyword in seen:
            raise _error(f"{arg.keyword} given twice in one DIST_CTRL command", arg)
        seen[arg.keyword] = arg
    actions = [arg for arg in args if arg.keyword in ACTION_KEYWORDS]
    for i, second in enumerate(actions):
        for first in actions[:i]:
            if {first.keyword, second.keyword} != {"ON", "DRYRUN"}:   # ON DRYRUN == DRYRUN (seeds/003)
                raise _error(f"{second.keyword} cannot be combined with {first.keyword}: ON/OFF, FREEZE, "
                             "DRYRUN, CHECK_POS and REF exclude one another in one command", second)
    if "CONST_DIST" in seen and not ({"ON", "DRYRUN"} & seen.keys()):
        raise _error("CONST_DIST without ON or DRYRUN, expected 'ON CONST_DIST' or 'DRYRUN CONST_DIST'",
                     seen["CONST_DIST"])
    if "NO_MOVE" in seen and "OFF" not in seen:
        raise _error("NO_MOVE without OFF, expected 'OFF NO_MOVE'", seen["NO_MOVE"])
    if "WAIT" in seen and not actions:
        raise _error("WAIT without ON, DRYRUN, OFF, FREEZE, CHECK_POS or REF: WAIT waits for a command",
                     seen["WAIT"])


def _build_block(children: list) -> Block:
    number: int | None = None
    words: list[_Word] = []
    line = None
    for child in children:
        if isinstance(child, Token):
            if line is None:
                line = child.line
            if child.type == "BLOCK_NUMBER":
                number = int(child[1:])
            continue   # PAREN_COMMENT
        if line is None:
            line = child.line
        words.append(child)
    block = Block(line=line if line is not None else 0, number=number)
    groups: dict[str, _Word] = {}
    for word in words:
        if word.kind == "g":
            group = G_CODE_GROUPS[word.value]
            if group in groups:
                raise _error(f"G{word.value} contradicts G{groups[group].value} in the same block, "
                             f"expected one {group} G code", word)
            groups[group] = word
            block.g_codes.append(word.value)
        elif word.kind == "m":
            block.m_codes.append(word.value)
        elif word.kind == "feed":
            if block.feed is not None:
                raise _error("F given twice in one block", word)
            block.feed = word.value
        elif word.kind == "dwell":
            if block.dwell is not None:
                raise _error("#TIME given twice in one block", word)
            block.dwell = word.value
        elif word.kind == "axis":
            if word.name in block.axes:
                raise _error(f"axis {word.name} given twice in one block", word)
            block.axes[word.name] = word.value
        elif word.kind == "assign":
            block.assignments.append(word.value)
        elif word.kind == "dist_ctrl":
            if any(other.axis == word.name for other in block.dist_ctrl):
                raise _error(f"{word.name}[DIST_CTRL ...] given twice in one block", word)
            block.dist_ctrl.append(word.value)
    return block


@lru_cache(maxsize=1)
def _parser() -> Lark:
    grammar = resources.files(__package__).joinpath("grammar.lark").read_text(encoding="utf-8")
    return Lark(grammar, parser="lalr", lexer="contextual", transformer=_ProgramBuilder(),
                maybe_placeholders=False)


# ---------------------------------------------------------------- error messages

#: readable names of the grammar's terminals, in the order they are listed in messages
_TERMINAL_NAMES = {
    "_NL": "end of line",
    "$END": "end of program",
    "HEADER": "a program header (%NAME)",
    "BLOCK_NUMBER": "a block number (N followed by digits)",
    "G_CODE": "a G code",
    "M_CODE": "an M code",
    "FEED": "F",
    "TIME": "#TIME",
    "AXIS": "an axis letter (X Y Z A B C)",
    "VAR": "a V.E. variable",
    "DIST_CTRL": "DIST_CTRL",
    "DC_FLAG": "a DIST_CTRL keyword",
    "DC_NUMBER_KEY": "a DIST_CTRL keyword",
    "DC_NAME_KEY": "a DIST_CTRL keyword",
    "NUMBER": "a number",
    "NAME": "a name",
    "EQUAL": "'='",
    "PLUS": "'+'",
    "MINUS": "'-'",
    "STAR": "'*'",
    "SLASH": "'/'",
    "LPAR": "'('",
    "RPAR": "')'",
    "LSQB": "'['",
    "RSQB": "']'",
    "PAREN_COMMENT": "a comment",
}
_GROUPS = (
    # (trigger terminal, terminals replaced, readable phrase)
    ("G_CODE", {"G_CODE", "M_CODE", "FEED", "AXIS", "TIME", "VAR"},
     "an NC word (G, M, F, X Y Z A B C, #TIME or V.E.NAME=)"),
    ("DC_FLAG", {"DC_FLAG", "DC_NUMBER_KEY", "DC_NAME_KEY"}, "a DIST_CTRL keyword"),
    ("STAR", {"STAR", "SLASH", "PLUS", "MINUS"}, "an operator (+ - * /)"),
    ("NUMBER", {"NUMBER", "VAR", "LSQB", "LPAR", "MINUS", "PLUS"},
     "a value (number, V.E. variable or [expression])"),
)
#: order of phrases in a message: terminals not listed come last
_ORDER = ["$END", "_NL", "HEADER", "BLOCK_NUMBER", "G_CODE", "M_CODE", "FEED", "AXIS", "TIME", "DIST_CTRL",
          "EQUAL", "DC_FLAG", "STAR", "NUMBER", "VAR", "NAME", "LPAR", "LSQB", "PLUS", "MINUS", "RPAR", "RSQB"]
_KEYWORD_LIST = ("ON, OFF, NO_MOVE, FREEZE, DRYRUN, CONST_DIST, CHECK_POS, REF, WAIT, SET_POS=, SET_DIST=, "
                 "SENSOR_SOURCE=, SENSOR_VAR=, VAL1= .. VAL5=, KP=, I_TN=, D_TV=, FILTER_TYPE=, N_CYCLES=, "
                 "FG_F0=, ORDER=, SMOOTH_FACT=, KALMAN_SIGMA=")
_WORD_AT = re.compile(r"[A-Za-z0-9_.%#]+")


def _readable_expected(expected: set[str]) -> str:
    remaining = set(expected) - {"PAREN_COMMENT"}
    if "_NL" in remaining:   # "end of line" says it: the last line may end the program
        remaining.discard("$END")
    phrases: list[tuple[int, str]] = []
    for trigger, members, phrase in _GROUPS:
        if trigger in remaining:
            remaining -= members
            phrases.append((_ORDER.index(trigger), phrase))
    for name in remaining:
        rank = _ORDER.index(name) if name in _ORDER else len(_ORDER)
        phrases.append((rank, _TERMINAL_NAMES.get(name, name)))
    names = list(dict.fromkeys(phrase for _, phrase in sorted(phrases)))
    if not names:
        return "nothing more"
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"


def _found_at(text: str, offset: int) -> str:
    """What the reader sees at the error position."""
    if offset >= len(text):
        return "end of program"
    if text[offset] == "\n":
        return "end of line"
    match = _WORD_AT.match(text, offset)
    found = match.group() if match else text[offset]
    if len(found) > 24:
        found = found[:24] + "..."
    return repr(found) if not found.isprintable() or "'" in found else f"'{found}'"


def _previous_token(exc: UnexpectedInput) -> Token | None:
    parser = getattr(exc, "interactive_parser", None)
    stack = getattr(getattr(parser, "parser_state", None), "value_stack", None)
    candidates = [stack[-1] if stack else None, (getattr(exc, "token_history", None) or [None])[-1]]
    for token in candidates:
        if isinstance(token, Token):
            return None if token.type == "PAREN_COMMENT" else token
    return None


def _describe_previous(token: Token) -> str:
    text = str(token)
    if token.type in ("NUMBER", "EQUAL", "LSQB", "RSQB", "LPAR", "RPAR", "PLUS", "MINUS", "STAR", "SLASH"):
        return f"'{text}'"
    if token.type in ("DC_FLAG", "DC_NUMBER_KEY", "DC_NAME_KEY", "DIST_CTRL", "AXIS", "FEED", "TIME",
                      "G_CODE", "M_CODE", "BLOCK_NUMBER"):
        return text.upper()
    return text


def _acceptable(exc: UnexpectedInput) -> set[str]:
    """Terminals that would have been accepted at the error.

    LALR merges look-ahead sets of similar states, so ``expected`` can name terminals that are
    not valid here; the interactive parser tries each one (without running callbacks).
    """
    parser = getattr(exc, "interactive_parser", None)
    if parser is not None:
        accepted = parser.accepts()
        if accepted:
            return set(accepted)
    if isinstance(exc, UnexpectedCharacters):
        return set(exc.allowed or ())
    return set(getattr(exc, "expected", ()) or ())


def _offset_of(text: str, line: int, column: int) -> int:
    offset = 0
    for _ in range(line - 1):
        offset = text.index("\n", offset) + 1
    return offset + column - 1


def _end_position(text: str) -> tuple[int, int]:
    return text.count("\n") + 1, len(text) - (text.rfind("\n") + 1) + 1


def _convert_lark_error(exc: UnexpectedInput, text: str) -> NcSyntaxError:
    token = getattr(exc, "token", None)
    if isinstance(exc, UnexpectedEOF) or (isinstance(token, Token) and token.type == "$END"):
        line, column = _end_position(text)
        offset = len(text)
    else:
        line, column = int(exc.line), int(exc.column)
        offset = getattr(exc, "pos_in_stream", None)
        if not isinstance(offset, int):
            offset = _offset_of(text, line, column)
    expected = _acceptable(exc)
    found = _found_at(text, offset)
    previous = _previous_token(exc)
    after = f" after {_describe_previous(previous)}" if previous is not None else ""
    word = found.strip("'")
    looks_like_word = found.startswith("'") and word[:1].isalpha() and not word.upper().startswith("V.")

    if "BLOCK_NUMBER" in expected and looks_like_word and re.fullmatch(r"[Nn]([^0-9].*)?", word):
        message = f"expected a block number (N followed by digits), got {found}"
        if re.fullmatch(r"[Nn][Xx]+", word):
            message += "; the documents' 'Nxx' placeholder is not valid NC"
    elif "DC_FLAG" in expected and looks_like_word:
        message = (f"unknown DIST_CTRL keyword {found}, expected one of {_KEYWORD_LIST} or ']'")
    elif "DIST_CTRL" in expected and looks_like_word:
        message = f"expected DIST_CTRL as the first keyword after '[', got {found}"
    elif previous is not None and previous.type == "DC_FLAG" and found == "'='":
        message = (f"{previous.upper()} takes no value, expected a DIST_CTRL keyword or ']'")
    else:
        message = f"expected {_readable_expected(expected)}{after}, got {found}"
        if "RSQB" in expected and found == "end of line":
            message += " (end a line with '\\' to continue inside '[...]')"
    return NcSyntaxError(message, line=line, column=column)


# ---------------------------------------------------------------- API

def _normalise(text: str) -> str:
    """Unix line ends, no byte-order mark: lark counts lines by '\\n' only."""
    if text.startswith("\ufeff"):
        text = text[1:]
    return text.replace("\r\n", "\n").replace("\r", "\n")


def parse_program(text: str, file: str | None = None) -> Program:
    """Parse NC program text. Raises :class:`NcSyntaxError` (and nothing else) for any bad input."""
    if not isinstance(text, str):
        raise TypeError(f"NC program text must be str, not {type(text).__name__}")
    text = _normalise(text)
    try:
        program = _parser().parse(text)
    except NcSyntaxError as exc:
        raise NcSyntaxError(exc.message, file=file, line=exc.line, column=exc.column) from None
    except UnexpectedInput as exc:
        try:
            error = _convert_lark_error(exc, text)
        except Exception as inner:   # never hide the original position behind a formatting bug
            error = NcSyntaxError(f"syntax error ({type(inner).__name__} while describing it)",
                                  line=getattr(exc, "line", None), column=getattr(exc, "column", None))
        raise NcSyntaxError(error.message, file=file, line=error.line, column=error.column) from None
    except RecursionError:
        raise NcSyntaxError("program is nested too deeply", file=file) from None
    except Exception as exc:   # contract: only NcSyntaxError leaves this function
        raise NcSyntaxError(f"internal parser error: {type(exc).__name__}: {exc}", file=file) from exc
    program.source = file
    return program


def parse_file(path: str | PathLike[str]) -> Program:
    """Read and parse an NC file (UTF-8, or Latin-1 as ISG editors often write it)."""
    name = str(path)
    try:
        with open(path, "rb") as handle:
            data = handle.read()
    except OSError as exc:
        raise NcSyntaxError(f"cannot read NC file: {exc.strerror or exc}", file=name) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    return parse_program(text, file=name)
