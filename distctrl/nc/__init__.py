"""NC programs: the ISG dialect subset with the axis-specific ``<axis>[DIST_CTRL ...]`` command and the
3D distance control's ``#DIST CTRL`` with the kinematics commands (``#KIN``, ``#TRAFO``, ``#CS``,
``#CHANNEL INIT``).

``parse_program(text)`` / ``parse_file(path)`` return a :class:`Program` of :class:`Block` s;
``DistCtrlWord.to_command(lookup)`` turns a DIST_CTRL word into the cycle core's ``Command``,
``DistCtrl3DWord.to_command3d(lookup)`` a #DIST CTRL word into a
:class:`~distctrl.control.commands3d.Command3D`. The accepted language and its rules are described
in docs/nc.md and docs/nc-3d.md.
"""
from __future__ import annotations

from .parser import parse_file, parse_program
from .program import (
    ACTION_KEYWORDS, FLAG_KEYWORDS, FLAG_KEYWORDS_3D, KIN98_PARAM_COUNT, KINEMATICS_KINDS, NAME_KEYWORDS,
    NAME_KEYWORDS_3D, NUMBER_KEYWORDS, NUMBER_KEYWORDS_3D, OUTSIDE_KEYWORDS_3D, PROGRAM_END_M_CODES,
    VALUE_RANGES, Assignment, BinOp, Block, Compare, DistCtrl3DWord, DistCtrlArg, DistCtrlWord, Expr, ExprError,
    KinematicsWord, Lookup, NcSyntaxError, Neg, Num, Program, ValueRange, Var, dist_ctrl_range_error,
    kin_param_var,
)

__all__ = [
    "parse_program", "parse_file", "NcSyntaxError", "ExprError",
    "Program", "Block", "Assignment", "DistCtrlWord", "DistCtrlArg", "DistCtrl3DWord", "KinematicsWord",
    "Expr", "Num", "Var", "BinOp", "Neg", "Compare", "Lookup",
    "dist_ctrl_range_error", "ValueRange", "VALUE_RANGES", "kin_param_var",
    "ACTION_KEYWORDS", "FLAG_KEYWORDS", "NUMBER_KEYWORDS", "NAME_KEYWORDS", "PROGRAM_END_M_CODES",
    "FLAG_KEYWORDS_3D", "NUMBER_KEYWORDS_3D", "NAME_KEYWORDS_3D", "OUTSIDE_KEYWORDS_3D", "KINEMATICS_KINDS",
    "KIN98_PARAM_COUNT",
]
