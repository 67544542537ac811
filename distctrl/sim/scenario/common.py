"""What every section of a scenario shares: :class:`ScenarioError` and the small validators
(strings, V.E. names, booleans, axis references, files, HLI transitions) that put the key path,
the value and what is allowed into their :class:`~distctrl.errors.config.ConfigError`."""
from __future__ import annotations

import math
import re
from pathlib import Path

from distctrl.base.states import HliTransition
from distctrl.errors.config import ConfigError

_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


# --- errors ------------------------------------------------------------------------------------------
class ScenarioError(ConfigError):
    """A :class:`ConfigError` in a scenario: the message starts with the file (and line if known).

    ``key`` stays the bare key path (``axes.Z.kv``); ``file`` and ``line`` hold the location.
    """

    def __init__(self, file: str, key: str, value: object, allowed: str, problem: str = "invalid value",
                 line: int | None = None):
        super().__init__(key, value, allowed, problem)
        self.file = file
        self.line = line
        where = file if line is None else f"{file}:{line}"
        self.args = (f"{where}: {self.args[0]}",)

    def rekeyed(self, key: str) -> "ScenarioError":
        return ScenarioError(self.file, key, self.value, self.allowed, self.problem, self.line)


def _rekey(exc: ConfigError, prefix: str, path: str) -> ConfigError:
    """``Fault.value`` -> ``events[3].sensor_fault.value`` (other keys: under ``path``)."""
    key = exc.key
    if key.startswith(prefix + "."):
        return exc.rekeyed(path + key[len(prefix):])
    return exc.rekeyed(f"{path} ({key})")


# --- small validators ---------------------------------------------------------------------------------
def _string(value: object, key: str, what: str) -> str:
    if not isinstance(value, str) or not value:
        raise ConfigError(key, value, what, "not a non-empty string:" if not isinstance(value, str)
                          else "empty:")
    return value


def _var_name(value: object, key: str) -> str:
    """A V.E. variable name; an optional ``V.E.`` prefix is dropped."""
    allowed = "a V.E. variable name: letter or '_' then letters, digits, '_' (optional prefix 'V.E.')"
    if isinstance(value, str):
        name = value[4:] if value[:4].upper() == "V.E." else value
        if _NAME_RE.match(name):
            return name
    raise ConfigError(key, value, allowed)


def _bool(value: object, key: str) -> bool:
    if not isinstance(value, bool):
        raise ConfigError(key, value, "true or false", "not a boolean:")
    return value


def _axis_ref(value: object, key: str, axes: dict) -> str:
    if not isinstance(value, str) or value not in axes:
        raise ConfigError(key, value, "one of the configured axes " + ", ".join(repr(a) for a in axes))
    return value


def _file(value: object, key: str, base_dir: Path, what: str) -> Path:
    text = _string(value, key, f"a path to {what} (relative to {str(base_dir)!r})")
    path = Path(text)
    full = path if path.is_absolute() else base_dir / path
    try:
        found = full.is_file()
    except OSError as exc:          # e.g. a name too long for the OS (ENAMETOOLONG): no such file either
        raise ConfigError(key, text, f"an existing {what} (relative paths: to {str(base_dir)!r})",
                          f"file not readable ({exc.strerror}):") from None
    if not found:
        raise ConfigError(key, text, f"an existing {what} (relative paths: to {str(base_dir)!r})",
                          f"file not found ({full}):")
    return full


def _transition(value: object, key: str) -> int:
    names = [t.name for t in HliTransition]
    lo, hi = min(HliTransition), max(HliTransition)
    allowed = ("one of " + ", ".join(f"{t.name} ({int(t)})" for t in HliTransition)
               + f": a name or a number {int(lo)}..{int(hi)}")
    if isinstance(value, str):
        if value.upper() in names:
            return int(HliTransition[value.upper()])
        raise ConfigError(key, value, allowed, "unknown transition")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value \
            or value in (math.inf, -math.inf) or int(value) != value:
        raise ConfigError(key, value, allowed)
    if not lo <= int(value) <= hi:
        raise ConfigError(key, value, allowed, "out of range:")
    return int(value)
