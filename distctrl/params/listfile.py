"""The kernel's parameter list format: ``kenngr.distc.kp   0.3   # comment``.

One ``key value`` pair per line; ``#`` starts a comment; blank lines are ignored. Keys are the
documents' list keys (and the legacy/German aliases of their examples). Unknown keys, values of
the wrong type and values outside the documented range are load errors naming the file, line,
key, P-AXIS ID, the value and the allowed range. A key given twice: the last value counts (as in
the kernel) and a warning is recorded, unless both values are equal.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from ..control.kinds import FilterType
from ..errors import ParameterError
from .axis import AxisParameters, check_internal, to_internal_value, to_interface_value
from .table import AXIS_PARAMETERS, BY_KEY, IGNORED_KEYS, ParamSpec

#: typo prefixes found in seeds/003's parameter overview, accepted as aliases
_PREFIX_ALIASES = {"kenngnr.distsc.": "kenngr.distc."}
_INT_RE = re.compile(r"^[+-]?\d+$")
_FLOAT_RE = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


@dataclass
class ParameterList:
    """A loaded list: the validated parameters plus where each value came from."""

    params: AxisParameters
    source: str
    lines: dict[str, int] = field(default_factory=dict)      # list key -> line of its (last) value
    warnings: list[str] = field(default_factory=list)


def canonical_key(key: str) -> str:
    for typo, right in _PREFIX_ALIASES.items():
        if key.startswith(typo):
            return right + key[len(typo):]
    return key


def parse_value(spec: ParamSpec, text: str, *, file: str, line: int, key: str):
    """Convert the list text of one value to the interface value, checking type and range."""
    def fail(why: str, value: object = text) -> ParameterError:
        return ParameterError(f"{key} ({spec.id}) = {text!r}: {why}; allowed: {spec.range_text()}",
                              file=file, line=line, key=key, param_id=spec.id, value=value,
                              allowed=spec.range_text())

    if spec.type == "STRING":
        try:
            value: object = FilterType.parse(text).name
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


def parse_list_text(text: str, source: str = "<string>", base: AxisParameters | None = None) -> ParameterList:
    """Parse list text into validated AxisParameters (unlisted keys keep ``base`` or the defaults)."""
    values: dict[str, object] = {}
    lines: dict[str, int] = {}
    warnings: list[str] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        body = raw.split("#", 1)[0].strip()
        if not body:
            continue
        parts = body.split()
        key = canonical_key(parts[0])
        if key in IGNORED_KEYS:
            continue
        spec = BY_KEY.get(key)
        if spec is None:
            raise ParameterError(f"unknown parameter key {parts[0]!r}", file=source, line=lineno, key=parts[0],
                                 allowed="a key of docs/parameters.md")
        if len(parts) < 2:
            raise ParameterError(f"{parts[0]} ({spec.id}): missing value; allowed: {spec.range_text()}",
                                 file=source, line=lineno, key=parts[0], param_id=spec.id,
                                 allowed=spec.range_text())
        if len(parts) > 2:
            raise ParameterError(f"{parts[0]} ({spec.id}): unexpected text after the value: "
                                 f"{' '.join(parts[2:])!r} (comments start with '#')",
                                 file=source, line=lineno, key=parts[0], param_id=spec.id)
        value = parse_value(spec, parts[1], file=source, line=lineno, key=parts[0])
        if spec.field in values and values[spec.field] != value:
            warnings.append(f"{source}:{lineno}: {parts[0]} ({spec.id}) given again "
                            f"(line {lines[spec.key]}); the last value {parts[1]} counts")
        values[spec.field] = value
        lines[spec.key] = lineno
    fields = {}
    for field_name, value in values.items():
        spec = next(s for s in AXIS_PARAMETERS if s.field == field_name)
        fields[field_name] = to_internal_value(spec, value)
    try:
        params = (base or AxisParameters()).replace(**fields)
    except ParameterError as exc:
        line = None
        if exc.key:
            line = next((lines[k] for k in exc.key.split("/") if k in lines), None)
        raise ParameterError(str(exc), file=source, line=line, key=exc.key, param_id=exc.param_id,
                             value=exc.value, allowed=exc.allowed) from None
    return ParameterList(params, source, lines, warnings)


def load_list(path: str | Path, base: AxisParameters | None = None) -> ParameterList:
    """Load an axis parameter list file (kernel format)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        text = p.read_text(encoding="latin-1")
    except OSError as exc:
        raise ParameterError(f"cannot read parameter list: {exc.strerror}", file=str(p)) from None
    return parse_list_text(text, str(p), base)


def format_list(params: AxisParameters, *, only_changed: bool = False, comments: bool = True) -> str:
    """Write parameters in the kernel list format (loadable again by :func:`parse_list_text`)."""
    default = AxisParameters().to_interface()
    rows = []
    for spec in AXIS_PARAMETERS:
        value = to_interface_value(spec, getattr(params, spec.field))
        if only_changed and value == default[spec.key]:
            continue
        text = f"{value:.12g}" if isinstance(value, float) else str(value)
        rows.append(f"{spec.key:<44} {text:<14}" + (f" # {spec.id} [{spec.unit}] {spec.description}"
                                                    if comments else ""))
    return "\n".join(r.rstrip() for r in rows) + "\n"


__all__ = ["ParameterList", "parse_list_text", "load_list", "format_list", "check_internal"]
