"""The configuration list of external variables (V.E.), as FCT-M3 §12.8.4 configures the sensor variable.

The 3D distance control (and the axis variant with ``SENSOR_SOURCE=VARIABLE``) reads its sensor value
from a V.E. variable that the PLC writes. The CNC declares such variables in a list of its own::

    number_used_variables 1
    #
    var[0].name           SENSOR
    var[0].type           REAL64
    var[0].scope          CHANNEL
    var[0].synchronisation TRUE
    var[0].access_rights  READ_ONLY

:func:`load_external_variables` reads that list and validates every entry at load: an error names
the file, the line, the key, the value and what is allowed. A scenario's ``external_variables`` key
loads it; the declared names are then the V.E. variables a program may name in ``SENSOR_VAR``.

The list format is documented in the kernel's [EXTV] description, which is not among the documents
distctrl follows; the keys and values accepted here are those of FCT-M3 §12.8.4 and the obvious
siblings (the integer and real types, the scope GLOBAL, READ_WRITE). ``scope``, ``synchronisation``
and ``access_rights`` are read and validated; the simulator does not enforce them (the simulated PLC
writes the variable every cycle, the NC program reads it).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from ..base.text import decode_text
from ..errors import ParameterError

#: the numeric V.E. types (a sensor value must be a number)
TYPES = ("BOOLEAN", "SGN08", "UNS08", "SGN16", "UNS16", "SGN32", "UNS32", "SGN64", "UNS64", "REAL32", "REAL64")
SCOPES = ("CHANNEL", "GLOBAL")
ACCESS_RIGHTS = ("READ_ONLY", "READ_WRITE")
BOOLEANS = {"TRUE": True, "FALSE": False, "1": True, "0": False}
#: upper bound of ``number_used_variables`` (a list is read into memory; the kernel's bound is not documented)
MAX_VARIABLES = 10_000

_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_ENTRY_RE = re.compile(r"^var\[(\d+)\]\.(name|type|scope|synchronisation|access_rights)$")
_FIELDS = ("name", "type", "scope", "synchronisation", "access_rights")
_DEFAULTS = {"type": "REAL64", "scope": "CHANNEL", "synchronisation": False, "access_rights": "READ_WRITE"}


@dataclass(frozen=True)
class ExternalVariable:
    """One declared V.E. variable (``name`` without the ``V.E.`` prefix)."""

    name: str
    type: str = "REAL64"
    scope: str = "CHANNEL"
    synchronisation: bool = False
    access_rights: str = "READ_WRITE"
    line: int = 0               # the line of its name in the list


def _choice(value: str, allowed: tuple, *, file: str, line: int, key: str) -> str:
    if value.upper() not in allowed:
        raise ParameterError(f"{key}: {value!r} is not allowed; allowed: {', '.join(allowed)}",
                             file=file, line=line, key=key, value=value, allowed=", ".join(allowed))
    return value.upper()


def parse_external_variables(text: str, source: str = "<string>") -> dict[str, ExternalVariable]:
    """Parse the list text; returns ``{name: ExternalVariable}`` in the order of the indices."""
    count: int | None = None
    count_line = 0
    entries: dict[int, dict] = {}
    for lineno, raw in enumerate(text.splitlines(), start=1):
        body = raw.split("#", 1)[0].strip()
        if not body:
            continue
        parts = body.split()
        key = parts[0]
        if len(parts) != 2:
            problem = "missing value" if len(parts) < 2 else f"unexpected text after the value: {' '.join(parts[2:])!r}"
            raise ParameterError(f"{key}: {problem} (comments start with '#')", file=source, line=lineno, key=key)
        value = parts[1]
        if key == "number_used_variables":
            if not re.fullmatch(r"\d+", value) or not 0 <= int(value) <= MAX_VARIABLES:
                raise ParameterError(f"{key}: {value!r} is not allowed; allowed: an integer 0 ... {MAX_VARIABLES}",
                                     file=source, line=lineno, key=key, value=value,
                                     allowed=f"0 ... {MAX_VARIABLES}")
            count, count_line = int(value), lineno
            continue
        m = _ENTRY_RE.match(key)
        if m is None:
            allowed = "number_used_variables, var[i]." + ", var[i].".join(_FIELDS)
            raise ParameterError(f"unknown key {key!r}; allowed: {allowed}", file=source, line=lineno, key=key,
                                 allowed=allowed)
        index, what = int(m.group(1)), m.group(2)
        entry = entries.setdefault(index, {"lines": {}})
        if what == "name":
            name = value[4:] if value[:4].upper() == "V.E." else value
            if not _NAME_RE.match(name):
                raise ParameterError(f"{key}: {value!r} is not a variable name; allowed: a letter or '_', then "
                                     "letters, digits, '_'", file=source, line=lineno, key=key, value=value,
                                     allowed="a letter or '_', then letters, digits, '_'")
            entry["name"] = name
        elif what == "type":
            entry["type"] = _choice(value, TYPES, file=source, line=lineno, key=key)
        elif what == "scope":
            entry["scope"] = _choice(value, SCOPES, file=source, line=lineno, key=key)
        elif what == "access_rights":
            entry["access_rights"] = _choice(value, ACCESS_RIGHTS, file=source, line=lineno, key=key)
        else:
            flag = value.upper()
            if flag not in BOOLEANS:
                raise ParameterError(f"{key}: {value!r} is not allowed; allowed: TRUE, FALSE, 1, 0", file=source,
                                     line=lineno, key=key, value=value, allowed="TRUE, FALSE, 1, 0")
            entry["synchronisation"] = BOOLEANS[flag]
        entry["lines"][what] = lineno
    if count is None:
        raise ParameterError("number_used_variables is missing", file=source, key="number_used_variables",
                             allowed=f"an integer 0 ... {MAX_VARIABLES}")
    variables: dict[str, ExternalVariable] = {}
    for index in sorted(entries):
        entry = entries[index]
        first = min(entry["lines"].values())
        if index >= count:
            raise ParameterError(f"var[{index}] is beyond number_used_variables {count} (line {count_line})",
                                 file=source, line=first, key=f"var[{index}]", value=index,
                                 allowed=f"var[0] ... var[{count - 1}]" if count else "no var[i] (count 0)")
        if "name" not in entry:
            raise ParameterError(f"var[{index}].name is missing", file=source, line=first,
                                 key=f"var[{index}].name")
        name = entry["name"]
        if name in variables:
            raise ParameterError(f"var[{index}].name {name!r} is declared twice (line {variables[name].line})",
                                 file=source, line=entry["lines"]["name"], key=f"var[{index}].name", value=name,
                                 allowed="a name not used by another var[i]")
        variables[name] = ExternalVariable(name=name, line=entry["lines"]["name"],
                                           **{k: entry.get(k, _DEFAULTS[k]) for k in _DEFAULTS})
    missing = [i for i in range(count) if i not in entries]
    if missing:
        raise ParameterError(f"number_used_variables is {count} but var[{missing[0]}] is not declared",
                             file=source, line=count_line, key="number_used_variables", value=count,
                             allowed=f"var[0] ... var[{count - 1}] each with a name")
    return variables


def load_external_variables(path: str | Path) -> dict[str, ExternalVariable]:
    """Read and validate the list file; an unreadable file is a ParameterError naming it."""
    path = Path(path)
    try:
        text = decode_text(path.read_bytes(), fallback=None)     # a BOM skipped
    except (OSError, UnicodeDecodeError) as exc:
        raise ParameterError(f"cannot read the external-variable list ({exc})", file=str(path)) from None
    return parse_external_variables(text, str(path))
