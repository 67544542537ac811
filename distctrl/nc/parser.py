"""Parse NC programs (ISG dialect subset, docs/nc.md, docs/nc-3d.md)
into :class:`~distctrl.nc.program.Program`.

The grammar (grammar.lark) fixes the syntax; :class:`_ProgramBuilder` turns the parse into the data
model while lark parses (LALR with an inline transformer: no tree, no recursion) and checks what a
grammar cannot: DIST_CTRL / #DIST CTRL keyword combinations, duplicates, constant value ranges,
keyword positions of #DIST CTRL. Every problem becomes an :class:`NcSyntaxError` with
file, physical line and column.
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

from ..control.commands3d import DIRECTION_NAMES, SENSOR_SOURCES_3D, CompensationMode
from ..base.kinds import FILTER_TYPE_NAMES, FilterType, SensorSource
from .program import (
    ACTION_KEYWORDS, FLAG_KEYWORDS_3D, KIN98_PARAM_COUNT, MAX_EXPR_DEPTH, NAME_KEYWORDS_3D,
    NUMBER_KEYWORDS_3D, OUTSIDE_KEYWORDS_3D, Assignment, BinOp, Block, Compare, DistCtrl3DWord, DistCtrlArg, DistCtrlWord, Expr, ExprError,
    KinematicsWord, NcSyntaxError, Neg, Num, Program, Var, dist_ctrl_range_error, kin_param_var, no_variables,
)

__all__ = ["NcSyntaxError", "parse_program", "parse_file"]

#: G codes of the subset, by group: two codes of one group in a block contradict each other
G_CODE_GROUPS = {0: "motion", 1: "motion", 90: "dimension", 91: "dimension"}


# ---------------------------------------------------------------- building the model

@dataclass(frozen=True, slots=True)
class _Word:
    """A block item on its way into a :class:`Block`, with its position for error messages."""

    kind: str        # "g", "m", "feed", "axis", "dwell", "assign", "dist_ctrl", "dist_ctrl_3d", "kinematics"
    value: object
    line: int
    column: int
    name: str = ""   # axis letter for "axis"; the command ("#TRAFO" ...) for "#" commands


@dataclass(frozen=True, slots=True)
class _Outside:
    """A #DIST CTRL keyword written before the brackets."""

    arg: DistCtrlArg


@dataclass(frozen=True, slots=True)
class _Group:
    """The bracketed keywords of a #DIST CTRL command."""

    args: tuple[DistCtrlArg, ...]


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


TOOL_LENGTH_VAR = "V.G.WZ_AKT.L"
_KIN_PARAM_VAR = re.compile(r"V\.G\.KIN_STEP\[\s*([0-9]+)\s*\]\.ID\[\s*([0-9]+)\s*\]"
                            r"\.PARAM\[\s*([0-9]+)\s*\]", re.IGNORECASE)


def _var_name(token: Token) -> str:
    """Canonical variable name: upper-case prefix, V.E. name as written, indices without blanks or
    leading zeros (``V.G.KIN_STEP[1].ID[98].PARAM[2]``)."""
    text = str(token)
    if text[2] in "gG":
        match = _KIN_PARAM_VAR.fullmatch(text)
        if match is not None:
            return kin_param_var(*(int(group) for group in match.groups()))
        return TOOL_LENGTH_VAR
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
        value = _checked(expr, token, name)
        match = _KIN_PARAM_VAR.fullmatch(name)
        if match is not None:
            kin_id, index = int(match.group(2)), int(match.group(3))
            if kin_id == 98 and index >= KIN98_PARAM_COUNT:
                raise _error(f"{name}: kinematic 98 has PARAM[0] .. PARAM[{KIN98_PARAM_COUNT - 1}] "
                             "(HD1 .. HD4), expected an index 0 .. 3", token)
        elif name == TOOL_LENGTH_VAR and value.is_constant and value.evaluate(no_variables) < 0:
            raise _error(f"{name} = {value.evaluate(no_variables):g} is out of range, "
                         "expected a tool length >= 0 mm", token)
        return _Word("assign", Assignment(name, value), token.line, token.column)

    # ---- DIST_CTRL
    def dc_flag(self, children):
        (token,) = children
        _axis_keyword(token)
        return DistCtrlArg(token.upper(), None, token.line, token.column)

    def dc_number(self, children):
        token, expr = children
        _axis_keyword(token)
        return self._number(token, expr)

    def _number(self, token, expr):
        keyword = token.upper()
        expr = _checked(expr, token, keyword)
        if expr.is_constant:
            problem = dist_ctrl_range_error(keyword, expr.evaluate(no_variables))
            if problem:
                raise _error(problem, token)
        return DistCtrlArg(keyword, expr, token.line, token.column)

    def dc_name(self, children):
        token, value = children
        _axis_keyword(token)
        return self._sensor_var_or_name(token, value)

    def _sensor_var_or_name(self, token, value):
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

    # ---- #DIST CTRL (3D)
    def dc3_outside(self, children):
        (token,) = children
        return _Outside(DistCtrlArg(token.upper(), None, token.line, token.column))

    def dc3_flag(self, children):
        (token,) = children
        return DistCtrlArg(token.upper(), None, token.line, token.column)

    def dc3_number(self, children):
        token, expr = children
        return self._number(token, expr)

    def dc3_name(self, children):
        token, value = children
        keyword = token.upper()
        if keyword == "SENSOR_VAR":
            return self._sensor_var_or_name(token, value)
        if value.type == "VAR":
            raise _error(f"{keyword} takes a name, not the variable {value}", value)
        name = str(value).upper()
        if keyword == "FILTER_TYPE":
            allowed: tuple[str, ...] = FILTER_TYPE_NAMES
            parsed: object = FilterType[name] if name in allowed else None
        elif keyword == "SENSOR_SOURCE":
            allowed = SENSOR_SOURCES_3D
            parsed = SensorSource[name] if name in allowed else None
        elif keyword == "MODE":
            allowed = tuple(CompensationMode.__members__)
            parsed = CompensationMode[name] if name in allowed else None
        else:   # DIRECTION
            allowed = DIRECTION_NAMES
            parsed = name if name in allowed else None
        if parsed is None:
            what = " (3D distance control)" if keyword == "SENSOR_SOURCE" else ""
            raise _error(f"unknown {keyword} {str(value)!r}{what}, expected one of {', '.join(allowed)}",
                         value)
        return DistCtrlArg(keyword, parsed, token.line, token.column)

    def dc3_group(self, children):
        return _Group(tuple(children))

    def dist_ctrl_3d(self, children):
        token, *rest = children
        outside = [child.arg for child in rest if isinstance(child, _Outside)]
        inside = [arg for child in rest if isinstance(child, _Group) for arg in child.args]
        _check_dist_ctrl_3d_rules(outside, inside)
        word = DistCtrl3DWord(tuple(outside + inside), tuple(arg.keyword for arg in outside),
                              token.line, token.column)
        return _Word("dist_ctrl_3d", word, token.line, token.column, name="#DIST CTRL")

    # ---- kinematics
    def kin_cmd(self, children):
        token, _id, ids_token = children
        ids = _kinematic_ids([ids_token], str(ids_token).split("."))
        return _kinematics(token, KinematicsWord("KIN", ids=ids, line=token.line, column=token.column))

    def trafo_cmd(self, children):
        token, *rest = children
        if rest[0].type == "SWITCH":
            word = KinematicsWord("TRAFO", switch=rest[0].upper(), line=token.line, column=token.column)
        else:   # #TRAFO [9, 98]: select this chain and switch the transformation on
            ids = _kinematic_ids(rest, [str(t) for t in rest])
            word = KinematicsWord("TRAFO", switch="ON", ids=ids, line=token.line, column=token.column)
        return _kinematics(token, word)

    def cs_cmd(self, children):
        token, switch, *values = children
        state = switch.upper()
        if state == "OFF" and values:
            raise _error("#CS OFF takes no values, expected '#CS OFF'", switch)
        if state == "ON" and len(values) != 6:
            raise _error(f"#CS ON needs six values [x, y, z, a, b, c] (offset in mm, rotation about X, Y, Z "
                         f"in degrees), got {len(values)}", switch)
        exprs = tuple(_checked(expr, token, "#CS") for expr in values)
        return _kinematics(token, KinematicsWord("CS", switch=state, values=exprs, line=token.line,
                                                 column=token.column))

    def wait_for(self, children):
        token, left, *rest = children
        cond = _checked(left, token, "#WAIT FOR")
        if rest:
            op, right = rest
            cond = Compare(str(op), cond, _checked(right, token, "#WAIT FOR"))
        if cond.is_constant:
            raise _error("#WAIT FOR needs a condition on a variable (e.g. '#WAIT FOR V.E.DONE == 1'): "
                         "a constant condition waits for ever or not at all", token)
        return _Word("wait_for", cond, token.line, token.column, name="#WAIT FOR")

    def channel_init(self, children):
        (token,) = children
        return _kinematics(token, KinematicsWord("CHANNEL_INIT", line=token.line, column=token.column))

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


#: keywords of #DIST CTRL that the axis command does not have (they share the grammar's terminals)
_ONLY_3D = ("SURFACE", "FILTER_TIME", "MODE", "DIRECTION")


def _axis_keyword(token: Token) -> None:
    keyword = token.upper()
    if keyword in _ONLY_3D:
        raise _error(f"unknown DIST_CTRL keyword '{token}', expected one of {_KEYWORD_LIST} or ']' "
                     f"({keyword} belongs to the 3D command #DIST CTRL)", token)


def _check_dist_ctrl_rules(args: list[DistCtrlArg]) -> None:
    """Keyword rules of FCT-M3 §6 and TF5200 Abstandskontrolle §6 (order-independent)."""
    seen: dict[str, DistCtrlArg] = {}
    for arg in args:
        if arg.keyword in seen:
            raise _error(f"{arg.keyword} given twice in one DIST_CTRL command", arg)
        seen[arg.keyword] = arg
    actions = [arg for arg in args if arg.keyword in ACTION_KEYWORDS]
    for i, second in enumerate(actions):
        for first in actions[:i]:
            if {first.keyword, second.keyword} != {"ON", "DRYRUN"}:   # ON DRYRUN == DRYRUN (TF5200 Abstandskontrolle)
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


def _check_dist_ctrl_3d_rules(outside: list[DistCtrlArg], inside: list[DistCtrlArg]) -> None:
    """Keyword rules of ``#DIST CTRL`` (FCT-M3 §12.2, PROG #DIST CTRL), order-independent inside [...]."""
    args = outside + inside
    seen: dict[str, DistCtrlArg] = {}
    for arg in args:
        if arg.keyword in seen:
            raise _error(f"{arg.keyword} given twice in one #DIST CTRL command", arg)
        seen[arg.keyword] = arg
    for arg in outside:
        if arg.keyword not in OUTSIDE_KEYWORDS_3D:
            raise _error(f"{arg.keyword} must be written inside the brackets, expected "
                         f"'#DIST CTRL ... [{arg.keyword} ...]' (only WAIT and ON, DRYRUN, OFF, FREEZE, "
                         "CHECK_POS, REF may come before '[')", arg)
    if "WAIT" in seen and seen["WAIT"] in outside and outside[0].keyword != "WAIT":
        raise _error(f"WAIT must come before {outside[0].keyword}, expected '#DIST CTRL WAIT "
                     f"{outside[0].keyword} ...'", seen["WAIT"])
    actions = [arg for arg in args if arg.keyword in ACTION_KEYWORDS]
    if len(actions) > 1:
        raise _error(f"{actions[1].keyword} cannot be combined with {actions[0].keyword}: ON, DRYRUN, OFF, "
                     "FREEZE, CHECK_POS and REF exclude one another in one command", actions[1])
    action = actions[0].keyword if actions else None
    if "SURFACE" in seen and "CONST_DIST" in seen:
        later = max(seen["SURFACE"], seen["CONST_DIST"], key=args.index)
        raise _error("SURFACE and CONST_DIST exclude one another, expected 'ON [SURFACE SET_POS=..]' or "
                     "'ON [CONST_DIST SET_DIST=..]'", later)
    for mode in ("SURFACE", "CONST_DIST"):
        if mode in seen and action not in ("ON", "DRYRUN"):
            value = "SET_POS" if mode == "SURFACE" else "SET_DIST"
            raise _error(f"{mode} without ON or DRYRUN, expected '#DIST CTRL ON [{mode} {value}=..]'",
                         seen[mode])
    if "CONST_DIST" in seen and "SET_POS" in seen:
        raise _error("SET_POS belongs to SURFACE, not CONST_DIST: expected SET_DIST=.. with CONST_DIST",
                     seen["SET_POS"])
    if "SURFACE" in seen and "SET_DIST" in seen:
        raise _error("SET_DIST belongs to CONST_DIST, not SURFACE: expected SET_POS=.. with SURFACE",
                     seen["SET_DIST"])
    if "SET_DIST" in seen and action in ("ON", "DRYRUN") and "CONST_DIST" not in seen:
        raise _error(f"SET_DIST with {action} needs CONST_DIST (without it {action} selects SURFACE mode), "
                     f"expected '{action} [CONST_DIST SET_DIST=..]'", seen["SET_DIST"])
    if "NO_MOVE" in seen and action != "OFF":
        raise _error("NO_MOVE without OFF, expected '#DIST CTRL OFF [NO_MOVE]'", seen["NO_MOVE"])
    if "WAIT" in seen and action is None:
        raise _error("WAIT without ON, DRYRUN, OFF, FREEZE, CHECK_POS or REF: WAIT waits for a command",
                     seen["WAIT"])


def _kinematic_ids(tokens: list[Token], texts: list[str]) -> tuple[int, ...]:
    ids = tuple(int(text) for text in texts)
    if any(kin_id < 1 for kin_id in ids):
        raise _error("kinematic ID 0 does not exist, expected IDs >= 1 (e.g. 9, 98)", tokens[0])
    return ids


def _kinematics(token: Token, word: KinematicsWord) -> _Word:
    return _Word("kinematics", word, token.line, token.column, name=_HASH_NAMES[word.kind])


_HASH_NAMES = {"KIN": "#KIN", "TRAFO": "#TRAFO", "CS": "#CS", "CHANNEL_INIT": "#CHANNEL INIT"}


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
        elif word.kind == "dist_ctrl_3d":
            block.dist_ctrl_3d.append(word.value)
        elif word.kind == "kinematics":
            block.kinematics.append(word.value)
        elif word.kind == "wait_for":
            block.wait_for = word.value
    return block


@lru_cache(maxsize=1)
def _parser() -> Lark:
    grammar = resources.files(__package__).joinpath("grammar.lark").read_text(encoding="utf-8")
    # cache=True: lark keeps the analysed grammar in the temp folder (keyed on grammar, options and lark's
    # version) and loads it in a fraction of the analysis' time (0.3-0.4 s of every CLI call that parses a
    # program, issue 27); an unreadable cache file is ignored and rebuilt
    return Lark(grammar, parser="lalr", lexer="contextual", transformer=_ProgramBuilder(),
                maybe_placeholders=False, cache=True)


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
    "DIST_CTRL_3D": "#DIST CTRL",
    "KIN": "#KIN",
    "KIN_ID": "ID",
    "KIN_IDS": "kinematic IDs (e.g. 98 or 9.98)",
    "TRAFO": "#TRAFO",
    "CS": "#CS",
    "SWITCH": "ON or OFF",
    "CHANNEL_INIT": "#CHANNEL INIT",
    "WAIT_FOR": "#WAIT FOR",
    "CMP_OP": "a comparison (== != < <= > >=)",
    "INT": "a kinematic ID (integer)",
    "COMMA": "','",
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
    ("G_CODE", {"G_CODE", "M_CODE", "FEED", "AXIS", "TIME", "VAR", "DIST_CTRL_3D", "KIN", "TRAFO", "CS",
                "CHANNEL_INIT", "WAIT_FOR"},
     "an NC word (G, M, F, X Y Z A B C, #TIME, #DIST CTRL, #KIN, #TRAFO, #CS, #CHANNEL INIT, #WAIT FOR "
     "or V.E.NAME=)"),
    ("DC_FLAG", {"DC_FLAG", "DC_NUMBER_KEY", "DC_NAME_KEY"}, "a DIST_CTRL keyword"),
    ("STAR", {"STAR", "SLASH", "PLUS", "MINUS"}, "an operator (+ - * /)"),
    ("NUMBER", {"NUMBER", "VAR", "LSQB", "LPAR", "MINUS", "PLUS"},
     "a value (number, V.E. variable or [expression])"),
)
#: order of phrases in a message: terminals not listed come last
_ORDER = ["$END", "_NL", "HEADER", "BLOCK_NUMBER", "G_CODE", "M_CODE", "FEED", "AXIS", "TIME", "DIST_CTRL",
          "DIST_CTRL_3D", "KIN", "TRAFO", "CS", "CHANNEL_INIT", "WAIT_FOR", "KIN_ID", "SWITCH",
          "EQUAL", "DC_FLAG", "STAR", "NUMBER", "VAR", "NAME", "KIN_IDS", "INT", "LPAR", "LSQB",
          "PLUS", "MINUS", "COMMA", "RPAR", "RSQB"]
_KEYWORD_LIST = ("ON, OFF, NO_MOVE, FREEZE, DRYRUN, CONST_DIST, CHECK_POS, REF, WAIT, SET_POS=, SET_DIST=, "
                 "SENSOR_SOURCE=, SENSOR_VAR=, VAL1= .. VAL5=, KP=, I_TN=, D_TV=, FILTER_TYPE=, N_CYCLES=, "
                 "FG_F0=, ORDER=, SMOOTH_FACT=, KALMAN_SIGMA=")
_KEYWORD_LIST_3D = ("WAIT, ON, DRYRUN, OFF, NO_MOVE, FREEZE, CHECK_POS, REF, SURFACE, CONST_DIST, SET_POS=, "
                    "SET_DIST=, MODE=, DIRECTION=, KP=, I_TN=, D_TV=, FILTER_TYPE=, FILTER_TIME=, N_CYCLES=, "
                    "FG_F0=, ORDER=, SMOOTH_FACT=, KALMAN_SIGMA=, SENSOR_SOURCE=, SENSOR_VAR=, "
                    "VAL1= .. VAL5=")
_KNOWN_3D = set(FLAG_KEYWORDS_3D) | set(NUMBER_KEYWORDS_3D) | set(NAME_KEYWORDS_3D)
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
                      "G_CODE", "M_CODE", "BLOCK_NUMBER", "KIN", "KIN_ID", "TRAFO", "CS", "SWITCH"):
        return text.upper()
    if token.type in ("DIST_CTRL_3D", "CHANNEL_INIT"):
        return " ".join(text.upper().split())
    if token.type in ("KIN_IDS", "INT", "COMMA"):
        return f"'{text}'"
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
    hash_command = _hash_command(exc)
    in_3d = hash_command == "#DIST CTRL"
    outside_word = _outside_word_3d(text, offset)
    hash_at = _HASH_AT.match(text, offset)

    if hash_at is not None and ("G_CODE" in expected or "_NL" in expected) and "BLOCK_NUMBER" not in expected:
        # "G0 #TRAFO ON": a "#" command after other words
        name = " ".join(hash_at.group().upper().split())
        message = (f"{name} must stand alone in its block, expected it on its own line "
                   "(only a block number may come before it)")
    elif outside_word is not None and _looks_like_nc_word(outside_word[0]):
        message = (f"#DIST CTRL must stand alone in its block, expected end of line or '[', got "
                   f"'{outside_word[0]}' (only comments may follow it)")
    elif outside_word is not None:
        # "#DIST CTRL FOO": the lexer may have taken the F of FOO as a feed word; report the whole word
        bad, start = outside_word
        column -= offset - start
        if bad.upper() in _KNOWN_3D:
            message = (f"{bad.upper()} must be written inside the brackets, "
                       f"expected '#DIST CTRL [{bad.upper()}...]'")
        else:
            message = (f"unknown #DIST CTRL keyword '{bad}', expected WAIT, ON, DRYRUN, OFF, FREEZE, "
                       "CHECK_POS, REF, '[' or end of line")
    elif "BLOCK_NUMBER" in expected and looks_like_word and re.fullmatch(r"[Nn]([^0-9].*)?", word):
        message = f"expected a block number (N followed by digits), got {found}"
        if re.fullmatch(r"[Nn][Xx]+", word):
            message += "; the documents' 'Nxx' placeholder is not valid NC"
    elif "DC_FLAG" in expected and looks_like_word and in_3d and "RSQB" in expected:
        message = f"unknown #DIST CTRL keyword {found}, expected one of {_KEYWORD_LIST_3D} or ']'"
    elif "DC_FLAG" in expected and looks_like_word and not in_3d:
        message = (f"unknown DIST_CTRL keyword {found}, expected one of {_KEYWORD_LIST} or ']'")
    elif "DIST_CTRL" in expected and looks_like_word:
        message = f"expected DIST_CTRL as the first keyword after '[', got {found}"
    elif previous is not None and previous.type == "DC_FLAG" and found == "'='":
        message = (f"{previous.upper()} takes no value, expected a DIST_CTRL keyword or ']'")
        if in_3d:
            message = message.replace("DIST_CTRL", "#DIST CTRL")
    elif hash_command is not None and "_NL" in expected and "G_CODE" not in expected and looks_like_word:
        message = (f"expected {_readable_expected(expected)}{after}, got {found}: {hash_command} must stand "
                   "alone in its block (only comments may follow it)")
    else:
        message = f"expected {_readable_expected(expected)}{after}, got {found}"
        if "RSQB" in expected and found == "end of line":
            message += " (end a line with '\\' to continue inside '[...]')"
        if in_3d:
            message = message.replace("a DIST_CTRL keyword", "a #DIST CTRL keyword")
    return NcSyntaxError(message, line=line, column=column)


_HASH_TOKENS = {"DIST_CTRL_3D": "#DIST CTRL", "KIN": "#KIN", "TRAFO": "#TRAFO", "CS": "#CS",
                "CHANNEL_INIT": "#CHANNEL INIT"}
_HASH_AT = re.compile(r"#(DIST[ \t]+CTRL|KIN|TRAFO|CS|CHANNEL[ \t]+INIT)(?![A-Za-z0-9_])", re.IGNORECASE)


def _hash_command(exc: UnexpectedInput) -> str | None:
    """The "#" command the error is in ("#DIST CTRL", "#KIN" ...), None outside of one (also inside
    an axis ``<axis>[DIST_CTRL ...]``)."""
    parser = getattr(exc, "interactive_parser", None)
    stack = getattr(getattr(parser, "parser_state", None), "value_stack", None) or ()
    for item in reversed(stack):
        if isinstance(item, Token):
            if item.type in _HASH_TOKENS:
                return _HASH_TOKENS[item.type]
            if item.type in ("DIST_CTRL", "BLOCK_NUMBER", "_NL"):
                return None
        elif isinstance(item, (Block, _Header, _Word)):
            return None
    return None


def _looks_like_nc_word(word: str) -> bool:
    """A word that starts another NC word (G1, X10, F100, M30), not a misspelt keyword."""
    return re.fullmatch(r"[GMFXYZABCgmfxyzabc][0-9]*", word) is not None


_OUTSIDE_3D = re.compile(r"[ \t]*(?:[Nn][0-9]+[ \t]*)?(?:\([^)\n]*\)[ \t]*)*#DIST[ \t]+CTRL"
                         r"(?:[ \t]+(?:WAIT|ON|OFF|DRYRUN|FREEZE|CHECK_POS|REF)(?![A-Za-z0-9_]))*[ \t]+"
                         r"([A-Za-z_][A-Za-z0-9_]*)", re.IGNORECASE)


def _outside_word_3d(text: str, offset: int) -> tuple[str, int] | None:
    """The word at the error if it is a bad keyword before the brackets of ``#DIST CTRL``."""
    line_start = text.rfind("\n", 0, offset) + 1
    match = _OUTSIDE_3D.match(text, line_start)
    if match is None or not match.start(1) <= offset < match.end(1):
        return None
    return match.group(1), match.start(1)


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
    # the error is raised after the except block, not inside it: an exception raised while lark's is
    # handled carries it as __context__, and lark's holds the parser, which cannot be pickled where
    # exceptions are pickled with their context (dask.distributed's tblib, a sweep worker's error)
    error: NcSyntaxError | None = None
    try:
        program = _parser().parse(text)
    except NcSyntaxError as exc:
        error = NcSyntaxError(exc.message, file=file, line=exc.line, column=exc.column)
    except UnexpectedInput as exc:
        try:
            found = _convert_lark_error(exc, text)
        except Exception as inner:   # never hide the original position behind a formatting bug
            found = NcSyntaxError(f"syntax error ({type(inner).__name__} while describing it)",
                                  line=getattr(exc, "line", None), column=getattr(exc, "column", None))
        error = NcSyntaxError(found.message, file=file, line=found.line, column=found.column)
    except RecursionError:
        error = NcSyntaxError("program is nested too deeply", file=file)
    except Exception as exc:   # contract: only NcSyntaxError leaves this function
        raise NcSyntaxError(f"internal parser error: {type(exc).__name__}: {exc}", file=file) from exc
    if error is not None:
        raise error
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
