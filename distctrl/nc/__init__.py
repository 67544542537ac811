"""NC programs: the ISG dialect subset with the axis-specific ``<axis>[DIST_CTRL ...]`` command.

``parse_program(text)`` / ``parse_file(path)`` return a :class:`Program` of :class:`Block` s;
``DistCtrlWord.to_command(lookup)`` turns a DIST_CTRL word into the cycle core's ``Command``.
The accepted language and its rules are described in docs/nc.md.
"""
from __future__ import annotations

from .parser import parse_file, parse_program
from .program import (
    ACTION_KEYWORDS, FLAG_KEYWORDS, NAME_KEYWORDS, NUMBER_KEYWORDS, PROGRAM_END_M_CODES, VALUE_RANGES,
    Assignment, BinOp, Block, DistCtrlArg, DistCtrlWord, Expr, ExprError, Lookup, NcSyntaxError, Neg, Num,
    Program, ValueRange, Var, dist_ctrl_range_error,
)

__all__ = [
    "parse_program", "parse_file", "NcSyntaxError", "ExprError",
    "Program", "Block", "Assignment", "DistCtrlWord", "DistCtrlArg",
    "Expr", "Num", "Var", "BinOp", "Neg", "Lookup",
    "dist_ctrl_range_error", "ValueRange", "VALUE_RANGES",
    "ACTION_KEYWORDS", "FLAG_KEYWORDS", "NUMBER_KEYWORDS", "NAME_KEYWORDS", "PROGRAM_END_M_CODES",
]
