"""Data model of a parsed NC program (see docs/nc.md and, for the 3D commands, docs/nc-3d.md).

The model is plain data: expressions stay unevaluated (:class:`Expr`) because V.E. variables
only have values when the program runs. The interpreter evaluates them with a *lookup*, either a
mapping or a callable from the full variable name (``"V.E.HEIGHT"``, ``"V.G.WZ_AKT.L"``) to a
float. Lengths are mm, feeds mm/min, times s (SPEC §1).
"""
from __future__ import annotations

import math
import operator
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Union

from ..control.commands import Action, Command
from ..control.commands3d import Command3D, CompensationMode
from ..base.kinds import FilterType, SensorSource
from ..errors import DistCtrlError
from ..params.table import BY_NC_WORD

Lookup = Union[Callable[[str], float], Mapping[str, float]]

#: deepest expression tree the parser accepts; keeps evaluation far from Python's recursion limit
MAX_EXPR_DEPTH = 100


class NcSyntaxError(DistCtrlError):
    """An NC program is not valid: syntax, a DIST_CTRL rule or a value range.

    ``line`` and ``column`` are 1-based physical positions (``None`` if unknown, e.g. for an
    unreadable file). ``str()`` gives ``file:line:column: message``.
    """

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None,
                 column: int | None = None):
        self.message, self.file, self.line, self.column = message, file, line, column
        super().__init__(self._format())

    def _format(self) -> str:
        where = [self.file if self.file is not None else "<string>"]
        if self.line is not None:
            where.append(str(self.line))
            if self.column is not None:
                where.append(str(self.column))
        return f"{':'.join(where)}: {self.message}"

    def __str__(self) -> str:
        return self._format()

    def __reduce__(self):  # keyword-only __init__: make it survive pickling (process pools)
        return (_rebuild_nc_error, (self.message, self.file, self.line, self.column))


def _rebuild_nc_error(message, file, line, column) -> NcSyntaxError:
    return NcSyntaxError(message, file=file, line=line, column=column)


class ExprError(DistCtrlError):
    """An expression cannot be evaluated: unknown variable, division by zero, non-finite value."""


# ---------------------------------------------------------------- expressions

class Expr:
    """Base of the expression AST. Subclasses are frozen dataclasses."""

    __slots__ = ()
    depth: int

    def evaluate(self, lookup: Lookup) -> float:
        raise NotImplementedError

    def variables(self) -> frozenset[str]:
        """Names of the variables the expression reads."""
        raise NotImplementedError

    @property
    def is_constant(self) -> bool:
        return not self.variables()


@dataclass(frozen=True, slots=True)
class Num(Expr):
    value: float
    depth: int = field(default=1, init=False, repr=False, compare=False)

    def evaluate(self, lookup: Lookup) -> float:
        return self.value

    def variables(self) -> frozenset[str]:
        return frozenset()


@dataclass(frozen=True, slots=True)
class Var(Expr):
    name: str   # full name: "V.E.HEIGHT" or "V.G.WZ_AKT.L"
    depth: int = field(default=1, init=False, repr=False, compare=False)

    def evaluate(self, lookup: Lookup) -> float:
        try:
            raw = lookup[self.name] if isinstance(lookup, Mapping) else lookup(self.name)
        except LookupError:
            raise ExprError(f"unknown variable {self.name}") from None
        try:
            value = float(raw)
        except (TypeError, ValueError):
            raise ExprError(f"variable {self.name} is not a number: {raw!r}") from None
        if not math.isfinite(value):
            raise ExprError(f"variable {self.name} is not finite: {value}")
        return value

    def variables(self) -> frozenset[str]:
        return frozenset((self.name,))


@dataclass(frozen=True, slots=True)
class Neg(Expr):
    operand: Expr
    depth: int = field(default=0, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "depth", self.operand.depth + 1)

    def evaluate(self, lookup: Lookup) -> float:
        return -self.operand.evaluate(lookup)

    def variables(self) -> frozenset[str]:
        return self.operand.variables()


_OPERATIONS: dict[str, Callable[[float, float], float]] = {
    "+": operator.add, "-": operator.sub, "*": operator.mul, "/": operator.truediv}


@dataclass(frozen=True, slots=True)
class BinOp(Expr):
    op: str   # one of + - * /
    left: Expr
    right: Expr
    depth: int = field(default=0, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.op not in _OPERATIONS:
            raise ValueError(f"unknown operator {self.op!r}")
        object.__setattr__(self, "depth", max(self.left.depth, self.right.depth) + 1)

    def evaluate(self, lookup: Lookup) -> float:
        left, right = self.left.evaluate(lookup), self.right.evaluate(lookup)
        try:
            value = _OPERATIONS[self.op](left, right)
        except ZeroDivisionError:
            raise ExprError("division by zero") from None
        if not math.isfinite(value):
            raise ExprError(f"result of {left!r} {self.op} {right!r} is not finite")
        return value

    def variables(self) -> frozenset[str]:
        return self.left.variables() | self.right.variables()


_COMPARISONS: dict[str, Callable[[float, float], bool]] = {
    "==": operator.eq, "!=": operator.ne, "<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge}


@dataclass(frozen=True, slots=True)
class Compare(Expr):
    """``left op right`` with ``op`` one of ``== != < <= > >=``: 1.0 when it holds, else 0.0 (the
    condition of ``#WAIT FOR``)."""

    op: str
    left: Expr
    right: Expr
    depth: int = field(default=0, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.op not in _COMPARISONS:
            raise ValueError(f"unknown comparison {self.op!r}")
        object.__setattr__(self, "depth", max(self.left.depth, self.right.depth) + 1)

    def evaluate(self, lookup: Lookup) -> float:
        return 1.0 if _COMPARISONS[self.op](self.left.evaluate(lookup), self.right.evaluate(lookup)) else 0.0

    def variables(self) -> frozenset[str]:
        return self.left.variables() | self.right.variables()


def no_variables(name: str) -> float:
    """Lookup for constant expressions: any variable is unknown."""
    raise KeyError(name)


# ---------------------------------------------------------------- DIST_CTRL keywords

#: keywords without value; the first six select what the command does
ACTION_KEYWORDS = ("ON", "OFF", "FREEZE", "DRYRUN", "CHECK_POS", "REF")
FLAG_KEYWORDS = ACTION_KEYWORDS + ("NO_MOVE", "CONST_DIST", "WAIT")
#: keywords with a numeric value (an expression)
NUMBER_KEYWORDS = ("SET_POS", "SET_DIST", "VAL1", "VAL2", "VAL3", "VAL4", "VAL5", "KP", "I_TN", "D_TV",
                   "N_CYCLES", "FG_F0", "ORDER", "SMOOTH_FACT", "KALMAN_SIGMA")
#: keywords with a name value
NAME_KEYWORDS = ("SENSOR_SOURCE", "SENSOR_VAR", "FILTER_TYPE")


@dataclass(frozen=True, slots=True)
class ValueRange:
    """Documented range of a numeric DIST_CTRL value (FCT-M3 §6)."""

    low: float | None = None
    high: float | None = None
    low_open: bool = False     # True: low < value, False: low <= value
    high_open: bool = False
    integer: bool = False

    def contains(self, value: float) -> bool:
        if not math.isfinite(value):
            return False
        if self.integer and value != int(value):
            return False
        if self.low is not None and (value <= self.low if self.low_open else value < self.low):
            return False
        if self.high is not None and (value >= self.high if self.high_open else value > self.high):
            return False
        return True

    def describe(self, keyword: str) -> str:
        text = keyword
        if self.low is not None:
            text = f"{_fmt(self.low)} {'<' if self.low_open else '<='} {text}"
        if self.high is not None:
            text = f"{text} {'<' if self.high_open else '<='} {_fmt(self.high)}"
        if self.low is None and self.high is None:
            text = f"a finite number for {keyword}"
        return f"an integer {text}" if self.integer else text


def _fmt(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else repr(value)


def _value_range(spec) -> ValueRange:
    """The NC range of a parameter's keyword: the parameter table's range (an integer's open bound as
    the closed one next to it, so ``0 <= n < 100`` reads ``0 <= N_CYCLES <= 99``)."""
    low, high, low_open, high_open = spec.lo, spec.hi, spec.lo_open, spec.hi_open
    if spec.integer:
        if low is not None and low_open:
            low, low_open = low + 1, False
        if high is not None and high_open:
            high, high_open = high - 1, False
    return ValueRange(low, high, low_open, high_open, integer=spec.integer)


#: checked ranges, from the parameter table (params/table.py); keywords not listed only need a finite value
VALUE_RANGES: dict[str, ValueRange] = {
    **{word: _value_range(spec) for word, spec in BY_NC_WORD.items() if not spec.choices},
    # 3D only: sin² blend of activation/deactivation, in interpolator cycles (FCT-M3 §12.2)
    "FILTER_TIME": ValueRange(0, None, integer=True),
}


def dist_ctrl_range_error(keyword: str, value: float) -> str | None:
    """Check a numeric DIST_CTRL value; return ``None`` if valid, else a readable message.

    The parser applies this to constant values; the interpreter applies it to evaluated
    expressions (then reported as error 900005).
    """
    keyword = keyword.upper()
    allowed = VALUE_RANGES.get(keyword, ValueRange())
    if allowed.contains(value):
        return None
    return f"{keyword}={_fmt(value) if math.isfinite(value) else value} is out of range, " \
           f"expected {allowed.describe(keyword)}"


# ---------------------------------------------------------------- DIST_CTRL word

DistCtrlValue = Union[Expr, FilterType, SensorSource, CompensationMode, str, None]

#: numeric keyword -> Command field (the keyword in lower case); the tuning words come from the parameter table
_FLOAT_FIELDS = {"SET_POS": "set_pos", "SET_DIST": "set_dist",
                 **{w: w.lower() for w, spec in BY_NC_WORD.items() if spec.type == "REAL64"}}
_INT_FIELDS = {w: w.lower() for w, spec in BY_NC_WORD.items() if spec.integer}
#: keywords with a name as value (MODE and DIRECTION exist only in the 3D command)
_NAME_FIELDS = {"FILTER_TYPE": "filter_type", "SENSOR_SOURCE": "sensor_source", "SENSOR_VAR": "sensor_var",
                "MODE": "mode", "DIRECTION": "direction"}


@dataclass(frozen=True, slots=True)
class DistCtrlArg:
    """One keyword of a DIST_CTRL command.

    ``value`` is ``None`` for flags (ON, NO_MOVE ...), an :class:`Expr` for numeric keywords,
    a :class:`FilterType` / :class:`SensorSource` for FILTER_TYPE / SENSOR_SOURCE and the full
    variable name (``"V.E.SENSOR"``) for SENSOR_VAR. ``line``/``column`` locate the keyword.
    """

    keyword: str
    value: DistCtrlValue = None
    line: int = 0
    column: int = 0


class _KeywordCommand:
    """Keyword access shared by the axis ``DIST_CTRL`` word and the 3D ``#DIST CTRL`` word."""

    __slots__ = ()
    args: tuple  # tuple[DistCtrlArg, ...], declared by the dataclasses

    @property
    def keywords(self) -> tuple[str, ...]:
        return tuple(arg.keyword for arg in self.args)

    def arg(self, keyword: str) -> DistCtrlArg | None:
        for arg in self.args:
            if arg.keyword == keyword:
                return arg
        return None

    def has(self, keyword: str) -> bool:
        return self.arg(keyword) is not None

    @property
    def wait(self) -> bool:
        """WAIT: the block completes only when the select has reached its target once, the OFF has
        reached INACTIVE, the FREEZE has braked (SPEC §8; the 3D syntax's option, also accepted in
        the axis command)."""
        return self.has("WAIT")

    def _argument_fields(self, lookup: Lookup, file: str | None,
                         int_fields: dict[str, str]) -> tuple[dict[str, object], list[float | None]]:
        """Command fields and VAL1-VAL5 from the keyword arguments (numbers evaluated now)."""
        fields: dict[str, object] = {}
        vals: list[float | None] = [None] * 5
        for arg in self.args:
            if isinstance(arg.value, Expr):
                value = self._evaluate(arg, lookup, file)
                if arg.keyword.startswith("VAL"):
                    vals[int(arg.keyword[3]) - 1] = value
                elif arg.keyword in int_fields:
                    fields[int_fields[arg.keyword]] = int(value)
                else:
                    fields[_FLOAT_FIELDS[arg.keyword]] = value
            elif arg.keyword in _NAME_FIELDS:
                fields[_NAME_FIELDS[arg.keyword]] = arg.value
        return fields, vals

    @staticmethod
    def _evaluate(arg: DistCtrlArg, lookup: Lookup, file: str | None) -> float:
        assert isinstance(arg.value, Expr)
        try:
            value = arg.value.evaluate(lookup)
        except ExprError as exc:
            raise NcSyntaxError(f"{arg.keyword}: {exc}", file=file, line=arg.line,
                                column=arg.column) from None
        problem = dist_ctrl_range_error(arg.keyword, value)
        if problem:
            raise NcSyntaxError(problem, file=file, line=arg.line, column=arg.column)
        return value


@dataclass(frozen=True, slots=True)
class DistCtrlWord(_KeywordCommand):
    """``<axis>[DIST_CTRL ...]``: the axis and its keywords in source order (already validated)."""

    axis: str
    args: tuple[DistCtrlArg, ...] = ()
    line: int = 0
    column: int = 0


    @property
    def action(self) -> Action:
        """ON DRYRUN is DRYRUN (TF5200 Abstandskontrolle §6); no action keyword only sets values."""
        if self.has("DRYRUN"):
            return Action.DRYRUN
        for keyword in ("ON", "OFF", "FREEZE", "CHECK_POS", "REF"):
            if self.has(keyword):
                return Action[keyword]
        return Action.NONE

    def to_command(self, lookup: Lookup = no_variables, line: int | None = None, *,
                   file: str | None = None) -> Command:
        """Evaluate the values and build the cycle core's :class:`Command`.

        ``line`` is the NC line recorded in the command (pass the block's line; defaults to the
        line of the axis letter). Unknown variables, division by zero and values out of range
        raise :class:`NcSyntaxError` at the keyword's position.
        """
        action = self.action
        fields, vals = self._argument_fields(lookup, file, _INT_FIELDS)
        # NC REF has no value: it references "sensor zero" (ref_position None, SPEC §2)
        return Command(action=action, const_dist=self.has("CONST_DIST"), no_move=self.has("NO_MOVE"),
                       vals=tuple(vals), line=self.line if line is None else line, **fields)


# ---------------------------------------------------------------- #DIST CTRL (3D distance control)

#: the 3D command's keywords (FCT-M3 §12.2, PROG #DIST CTRL); the actions are ACTION_KEYWORDS
FLAG_KEYWORDS_3D = ACTION_KEYWORDS + ("NO_MOVE", "SURFACE", "CONST_DIST", "WAIT")
NUMBER_KEYWORDS_3D = NUMBER_KEYWORDS + ("FILTER_TIME",)
NAME_KEYWORDS_3D = NAME_KEYWORDS + ("MODE", "DIRECTION")
#: keywords that may be written before the brackets: "#DIST CTRL [WAIT] <action> [...]"
OUTSIDE_KEYWORDS_3D = ("WAIT",) + ACTION_KEYWORDS

_INT_FIELDS_3D = {**_INT_FIELDS, "FILTER_TIME": "filter_time"}


@dataclass(frozen=True, slots=True)
class DistCtrl3DWord(_KeywordCommand):
    """``#DIST CTRL ...``: the 3D distance-control command, keywords in source order (validated).

    ``args`` holds every keyword, those written before the brackets first; ``outside`` names the
    keywords written before the brackets (``("WAIT", "OFF")`` for ``#DIST CTRL WAIT OFF``).
    Values as in :class:`DistCtrlArg`; MODE is a :class:`CompensationMode`, DIRECTION the axis
    letter, SENSOR_SOURCE the :class:`SensorSource` as written (DEFAULT stays DEFAULT here and
    becomes VARIABLE in :meth:`to_command3d`). ``line``/``column`` locate ``#DIST``.
    """

    args: tuple[DistCtrlArg, ...] = ()
    outside: tuple[str, ...] = ()
    line: int = 0
    column: int = 0


    @property
    def action(self) -> Action:
        """The action keyword (ON, DRYRUN, OFF, FREEZE, CHECK_POS, REF); none only sets values."""
        for keyword in ACTION_KEYWORDS:
            if self.has(keyword):
                return Action[keyword]
        return Action.NONE

    def to_command3d(self, lookup: Lookup = no_variables, line: int | None = None, *,
                     file: str | None = None) -> Command3D:
        """Evaluate the values and build a :class:`~distctrl.control.commands3d.Command3D`.

        ``line`` is the NC line recorded in the command (pass the block's line; defaults to the
        line of ``#DIST``). Unknown variables, division by zero and values out of range raise
        :class:`NcSyntaxError` at the keyword's position.
        """
        action = self.action
        fields, vals = self._argument_fields(lookup, file, _INT_FIELDS_3D)
        if "sensor_source" in fields:
            # "If DEFAULT is selected as the sensor source, the CNC automatically sets to the
            # VARIABLE sensor source internally" (FCT-M3 §12.2)
            fields["sensor_source"] = SensorSource.VARIABLE
        # REF (no value): "sensor zero", as the axis command (ref_position None)
        return Command3D(action=action, wait=self.wait, const_dist=self.has("CONST_DIST"),
                         no_move=self.has("NO_MOVE"), vals=tuple(vals),
                         line=self.line if line is None else line, **fields)


# ---------------------------------------------------------------- kinematics commands

#: kinds of :class:`KinematicsWord`
KINEMATICS_KINDS = ("KIN", "TRAFO", "CS", "CHANNEL_INIT")
#: kinematic 98 (minimum-distance monitoring) parameters V.G.KIN_STEP[i].ID[98].PARAM[j], j = 0..3:
#: HD1 clamping-point offset (1e-4 mm), HD2 start angle, HD3 end angle, HD4 maximum angle (1e-4 °)
KIN98_PARAM_COUNT = 4


@dataclass(frozen=True, slots=True)
class KinematicsWord:
    """A kinematics command (its own block):

    ============================  ======================================================
    ``#KIN ID[9.98]``             ``kind="KIN"``, ``ids=(9, 98)`` (one ID per step)
    ``#TRAFO ON`` / ``OFF``       ``kind="TRAFO"``, ``switch="ON"`` / ``"OFF"``
    ``#TRAFO [9, 98]``            ``kind="TRAFO"``, ``switch="ON"``, ``ids=(9, 98)``
    ``#CS ON [x, y, z, a, b, c]`` ``kind="CS"``, ``switch="ON"``, six ``values`` (mm, °)
    ``#CS OFF``                   ``kind="CS"``, ``switch="OFF"``
    ``#CHANNEL INIT``             ``kind="CHANNEL_INIT"``
    ============================  ======================================================

    ``#CS ON`` values: the offset vector x, y, z (mm) and the rotation angles a, b, c (°) about
    X, Y, Z of the programming coordinate system; they stay expressions until run time.
    """

    kind: str
    switch: str | None = None
    ids: tuple[int, ...] = ()
    values: tuple[Expr, ...] = ()
    line: int = 0
    column: int = 0

    @property
    def reinitialises_channel(self) -> bool:
        """#CS, #TRAFO and #CHANNEL INIT re-initialise the channel position: error 51062 while
        3D distance control is active (FCT-M3 §12.4.5)."""
        return self.kind in ("TRAFO", "CS", "CHANNEL_INIT")

    def cs_frame(self, lookup: Lookup = no_variables, *, file: str | None = None) -> tuple[float, ...]:
        """``#CS ON``: the six values evaluated (x, y, z in mm, a, b, c in degrees)."""
        out = []
        for expr in self.values:
            try:
                out.append(expr.evaluate(lookup))
            except ExprError as exc:
                raise NcSyntaxError(f"#CS: {exc}", file=file, line=self.line, column=self.column) from None
        return tuple(out)


def kin_param_var(step: int, kin_id: int, index: int) -> str:
    """Name of a kinematic parameter variable: ``kin_param_var(1, 98, 2)`` ->
    ``"V.G.KIN_STEP[1].ID[98].PARAM[2]"``."""
    return f"V.G.KIN_STEP[{int(step)}].ID[{int(kin_id)}].PARAM[{int(index)}]"


# ---------------------------------------------------------------- blocks and program

@dataclass(frozen=True, slots=True)
class Assignment:
    """``V.E.NAME = expr``, ``V.G.WZ_AKT.L = expr`` (tool length, mm) or
    ``V.G.KIN_STEP[i].ID[k].PARAM[j] = expr`` (kinematic parameter, 1e-4 mm / 1e-4 °)."""

    var: str
    value: Expr


#: M functions that end the program
PROGRAM_END_M_CODES = (2, 30)


@dataclass(slots=True)
class Block:
    """One NC block. ``line`` is the physical line where it starts.

    Execution order within a block (for the interpreter): assignments first, in source order;
    then G codes, feed, axis values, DIST_CTRL commands, dwell, M functions.
    ``dist_ctrl_3d`` (``#DIST CTRL``) and ``kinematics`` (``#KIN``, ``#TRAFO``, ``#CS``,
    ``#CHANNEL INIT``) commands stand alone in their block, so such a block has exactly one of
    them and nothing else.
    """

    line: int
    number: int | None = None
    g_codes: list[int] = field(default_factory=list)
    feed: Expr | None = None                                 # mm/min
    axes: dict[str, Expr] = field(default_factory=dict)      # axis letter -> target (mm or deg)
    m_codes: list[int] = field(default_factory=list)
    dwell: Expr | None = None                                # s (#TIME)
    assignments: list[Assignment] = field(default_factory=list)
    dist_ctrl: list[DistCtrlWord] = field(default_factory=list)
    dist_ctrl_3d: list[DistCtrl3DWord] = field(default_factory=list)
    kinematics: list[KinematicsWord] = field(default_factory=list)
    #: ``#WAIT FOR <condition>``: the block completes once the condition is > 0.5 (stands alone)
    wait_for: Expr | None = None

    @property
    def ends_program(self) -> bool:
        return any(m in PROGRAM_END_M_CODES for m in self.m_codes)

    @property
    def is_empty(self) -> bool:
        return not (self.g_codes or self.feed is not None or self.axes or self.m_codes
                    or self.dwell is not None or self.assignments or self.dist_ctrl
                    or self.dist_ctrl_3d or self.kinematics or self.wait_for is not None)


@dataclass(slots=True)
class Program:
    """A parsed NC program. ``name`` is the ``%NAME`` header without ``%``; ``source`` the file."""

    name: str | None = None
    blocks: list[Block] = field(default_factory=list)
    source: str | None = None
