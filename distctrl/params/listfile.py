"""The kernel's parameter list format: ``kenngr.distc.kp   0.3   # comment``.

One ``key value`` pair per line; ``#`` starts a comment; blank lines are ignored. Keys are the
documents' list keys (and the legacy/German aliases of their examples). Unknown keys, values of
the wrong type and values outside the documented range are load errors naming the file, line,
key, parameter ID (P-AXIS / P-CHAN), the value and the allowed range. A key given twice: the last
value counts (as in the kernel) and a warning is recorded, unless both values are equal.

The same reader serves every list kind: a :class:`ListFormat` says which table, which target
dataclass and which value conversions to use. :data:`AXIS_LIST` (the default of
:func:`parse_list_text` / :func:`load_list`) reads axis lists into ``AxisParameters``;
``distctrl.params.channel.CHANNEL_LIST`` reads channel lists into ``ChannelParameters``.
"""
from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

from ..base.kinds import FilterType
from ..base.text import read_text
from ..errors import ParameterError
from .axis import AxisParameters, check_internal, parse_axis_type, to_internal_value, to_interface_value
from .table import AXIS_PARAMETERS, BY_KEY, IGNORED_KEYS, ParamSpec

#: typo prefixes found in TF5200's parameter overview, accepted as aliases
_PREFIX_ALIASES = {"kenngnr.distsc.": "kenngr.distc."}
_INT_RE = re.compile(r"^[+-]?\d+$")
_FLOAT_RE = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


class KeyProblem(NamedTuple):
    """A known key written in a form the list kind does not allow (e.g. ``dist_ctrl[1].kp``)."""

    message: str
    allowed: str


def _no_problem(key: str) -> tuple[str, KeyProblem | None]:
    return canonical_key(key), None


def _filter_type_name(spec: ParamSpec, text: str) -> object:
    """A STRING value's list name: the filter type (P-AXIS-00782) or the axis type (P-AXIS-00018)."""
    if spec.field == "axis_type":
        return parse_axis_type(text)
    return FilterType.parse(text).name


@dataclass(frozen=True)
class ListFormat:
    """One kind of parameter list: its table and how values become the target dataclass.

    ``resolve_key`` maps a key as written to the table's key and may report a problem with the
    form (an index that does not exist); ``parse_string`` turns a STRING value into its interface
    value (raising ``ValueError`` for an unknown name); ``to_internal`` / ``to_interface`` convert
    interface values (list units) to the target's fields and back. The target has a no-argument
    constructor (the defaults) and ``replace(**fields)`` that validates.
    """

    name: str
    specs: tuple[ParamSpec, ...]
    target: type
    to_internal: Callable[[ParamSpec, object], object]
    to_interface: Callable[[ParamSpec, object], object]
    parse_string: Callable[[ParamSpec, str], object] = _filter_type_name
    resolve_key: Callable[[str], tuple[str, KeyProblem | None]] = _no_problem
    ignored_keys: frozenset[str] = frozenset()
    docs: str = "docs/parameters.md"
    rotary_field: str | None = None      # the field whose value makes the list's lengths degrees
    by_key: Mapping[str, ParamSpec] = field(default=None, repr=False)   # type: ignore[assignment]

    def __post_init__(self) -> None:
        if self.by_key is None:
            table: dict[str, ParamSpec] = {}
            for spec in self.specs:
                table[spec.key] = spec
                for alias in spec.aliases:
                    table[alias] = spec
            object.__setattr__(self, "by_key", table)

    def spec_of_field(self, field_name: str) -> ParamSpec:
        return next(s for s in self.specs if s.field == field_name)


AXIS_LIST = ListFormat("axis", AXIS_PARAMETERS, AxisParameters, to_internal_value, to_interface_value,
                       ignored_keys=IGNORED_KEYS, docs="docs/parameters.md", by_key=BY_KEY, rotary_field="axis_type")


@dataclass
class ParameterList:
    """A loaded list: the validated parameters plus where each value came from.

    ``params`` is an ``AxisParameters`` for axis lists, a ``ChannelParameters`` for channel lists.
    """

    params: Any
    source: str
    lines: dict[str, int] = field(default_factory=dict)      # list key -> line of its (last) value
    warnings: list[str] = field(default_factory=list)


def canonical_key(key: str) -> str:
    for typo, right in _PREFIX_ALIASES.items():
        if key.startswith(typo):
            return right + key[len(typo):]
    return key


def parse_value(spec: ParamSpec, text: str, *, file: str, line: int, key: str,
                parse_string: Callable[[ParamSpec, str], object] = _filter_type_name):
    """Convert the list text of one value to the interface value, checking type and range."""
    def fail(why: str, value: object = text) -> ParameterError:
        return ParameterError(f"{key} ({spec.id}) = {text!r}: {why}; allowed: {spec.range_text()}",
                              file=file, line=line, key=key, param_id=spec.id, value=value,
                              allowed=spec.range_text())

    if spec.type == "STRING":
        try:
            value: object = parse_string(spec, text)
        except ValueError:
            raise fail("unknown name") from None
        return value
    if spec.type in ("BOOLEAN", "SGN32", "UNS32", "UNS16"):
        if not _INT_RE.match(text):
            raise fail(f"expected an integer ({spec.type})")
        value = int(text)
    else:
        if not _FLOAT_RE.match(text):
            raise fail("expected a number (REAL64)")
        value = float(text)
    if not spec.check(value):
        raise fail("out of range", value)
    return value


def parse_list_text(text: str, source: str = "<string>", base: Any = None, *,
                    fmt: ListFormat = AXIS_LIST) -> ParameterList:
    """Parse list text into validated parameters (unlisted keys keep ``base`` or the defaults).

    ``fmt`` selects the list kind: :data:`AXIS_LIST` (default, ``AxisParameters``) or
    ``distctrl.params.channel.CHANNEL_LIST`` (``ChannelParameters``).
    """
    values: dict[str, object] = {}
    lines: dict[str, int] = {}
    warnings: list[str] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        body = raw.split("#", 1)[0].strip()
        if not body:
            continue
        parts = body.split()
        key, problem = fmt.resolve_key(parts[0])
        if key in fmt.ignored_keys:
            continue
        spec = fmt.by_key.get(key)
        if spec is None:
            raise ParameterError(f"unknown parameter key {parts[0]!r}", file=source, line=lineno,
                                 key=parts[0], allowed=f"a key of {fmt.docs}")
        if problem is not None:
            raise ParameterError(f"{parts[0]} ({spec.id}): {problem.message}; allowed: {problem.allowed}",
                                 file=source, line=lineno, key=parts[0], param_id=spec.id,
                                 value=parts[1] if len(parts) > 1 else None, allowed=problem.allowed)
        if len(parts) < 2:
            raise ParameterError(f"{parts[0]} ({spec.id}): missing value; allowed: {spec.range_text()}",
                                 file=source, line=lineno, key=parts[0], param_id=spec.id,
                                 allowed=spec.range_text())
        if len(parts) > 2:
            raise ParameterError(f"{parts[0]} ({spec.id}): unexpected text after the value: "
                                 f"{' '.join(parts[2:])!r} (comments start with '#')",
                                 file=source, line=lineno, key=parts[0], param_id=spec.id)
        value = parse_value(spec, parts[1], file=source, line=lineno, key=parts[0],
                            parse_string=fmt.parse_string)
        if spec.field in values and values[spec.field] != value:
            warnings.append(f"{source}:{lineno}: {parts[0]} ({spec.id}) given again "
                            f"(line {lines[spec.key]}); the last value {parts[1]} counts")
        values[spec.field] = value
        lines[spec.key] = lineno
    fields = {}
    rotary = None
    if fmt.rotary_field is not None:        # lengths of a rotary axis are degrees (P-AXIS-00018)
        rotary = values.get(fmt.rotary_field, None)
        rotary = getattr(base, "rotary", False) if rotary is None else parse_axis_type(rotary) == "ACHSTYP_ROTATOR"
    for field_name, value in values.items():
        spec = fmt.spec_of_field(field_name)
        fields[field_name] = fmt.to_internal(spec, value) if rotary is None else fmt.to_internal(spec, value, rotary)
    try:
        params = (base if base is not None else fmt.target()).replace(**fields)
    except ParameterError as exc:
        # a check across parameters (e.g. the sensor window): the line of the last of them in the
        # file, the value that completed the contradiction
        found = [lines[k] for k in _involved_keys(exc, fmt) if k in lines]
        raise ParameterError(str(exc), file=source, line=max(found) if found else None, key=exc.key,
                             param_id=exc.param_id, value=exc.value, allowed=exc.allowed) from None
    return ParameterList(params, source, lines, warnings)


def _involved_keys(exc: ParameterError, fmt: ListFormat) -> list[str]:
    """The table keys of the parameters a validation error names: its ``key`` (``a.b.c/d/e`` is
    ``a.b.c``, ``a.b.d``, ``a.b.e``) and its ``param_id`` (``P-AXIS-00177/00178`` is both IDs)."""
    keys: list[str] = []
    if exc.key:
        first, *rest = exc.key.split("/")
        prefix = first.rsplit(".", 1)[0] + "." if "." in first else ""
        keys += [first] + [k if "." in k else prefix + k for k in rest]
    if exc.param_id:
        first, *rest = str(exc.param_id).split("/")
        head = first.rsplit("-", 1)[0] + "-" if "-" in first else ""
        ids = {first} | {i if "-" in i else head + i for i in rest}
        keys += [spec.key for spec in fmt.specs if spec.id in ids]
    return keys


def load_list(path: str | Path, base: Any = None, *, fmt: ListFormat = AXIS_LIST) -> ParameterList:
    """Load a parameter list file (kernel format); an axis list unless ``fmt`` says otherwise."""
    p = Path(path)
    try:
        text = read_text(p)                  # UTF-8 (a BOM skipped) or Latin-1
    except OSError as exc:
        raise ParameterError(f"cannot read parameter list: {exc.strerror}", file=str(p)) from None
    return parse_list_text(text, str(p), base, fmt=fmt)


def list_entries(params: Any, *, only_changed: bool = False, fmt: ListFormat = AXIS_LIST) -> list[dict]:
    """The list's parameters as ``{key, id, value, unit, description}`` in the list's units (what
    :func:`format_list` writes and ``distctrl params --json`` prints)."""
    defaults = fmt.target()
    rotary = fmt.rotary_field is not None and getattr(params, "rotary", False)

    def interface(p, spec):
        v = getattr(p, spec.field)
        return fmt.to_interface(spec, v, rotary) if fmt.rotary_field is not None else fmt.to_interface(spec, v)
    out = []
    for spec in fmt.specs:
        value = interface(params, spec)
        if only_changed and value == interface(defaults, spec):
            continue
        unit = spec.unit_rotary if rotary and spec.unit_rotary else spec.unit
        out.append({"key": spec.key, "id": spec.id, "value": value, "unit": unit, "description": spec.description})
    return out


def format_list(params: Any, *, only_changed: bool = False, comments: bool = True,
                fmt: ListFormat = AXIS_LIST) -> str:
    """Write parameters in the kernel list format (loadable again by :func:`parse_list_text`)."""
    rows = []
    for e in list_entries(params, only_changed=only_changed, fmt=fmt):
        value = e["value"]
        text = f"{value:.12g}" if isinstance(value, float) else str(value)
        rows.append(f"{e['key']:<44} {text:<14}" + (f" # {e['id']} [{e['unit']}] {e['description']}"
                                                    if comments else ""))
    return "\n".join(r.rstrip() for r in rows) + "\n"


__all__ = ["ParameterList", "ListFormat", "KeyProblem", "AXIS_LIST", "parse_list_text", "load_list",
           "format_list", "list_entries", "parse_value", "canonical_key", "check_internal"]
