"""Configuration errors: of the simulation models, the PLC process functions and the CLI options.

Every invalid key, type or value in a simulation configuration (a plain dict loaded from TOML/JSON,
or a constructor argument) raises :class:`ConfigError`. The message always names

* the key path (``surface.features[1].wavelength``),
* the offending value (``repr``), and
* what is allowed (a range, a list of values or a type),

so a user can fix the file without reading the source.
"""
from __future__ import annotations

from . import DistCtrlError


class _Missing:
    def __repr__(self) -> str:
        return "<missing>"


#: ``value`` of a :class:`ConfigError` for a required key that is absent
MISSING = _Missing()


class ConfigError(DistCtrlError, ValueError):
    """Invalid simulation configuration: names key path, value and the allowed values/range.

    ``problem`` is the phrase before the value (``"invalid value"``, ``"out of range:"``, ...).
    """

    def __init__(self, key: str, value: object, allowed: str, problem: str = "invalid value"):
        self.key = key
        self.value = value
        self.allowed = allowed
        self.problem = problem
        if value is MISSING:
            super().__init__(f"{key}: missing; required: {allowed}")
        else:
            super().__init__(f"{key}: {problem} {value!r}; allowed: {allowed}")

    def rekeyed(self, key: str) -> "ConfigError":
        """The same error reported under another key path."""
        return ConfigError(key, self.value, self.allowed, self.problem)


def _range_text(lo: float | None, hi: float | None, lo_open: bool, hi_open: bool) -> str:
    left = "(-inf" if lo is None else ("(" if lo_open else "[") + f"{lo:g}"
    right = "inf)" if hi is None else f"{hi:g}" + (")" if hi_open else "]")
    return f"{left}, {right}"


def require_number(value: object, key: str, *, lo: float | None = None, hi: float | None = None,
                   lo_open: bool = False, hi_open: bool = False) -> float:
    """Return ``value`` as a finite float inside the given range, else raise :class:`ConfigError`.

    ``bool`` is rejected although it is an ``int`` subclass: ``true`` for a length is a typo.
    """
    kind = "finite number"
    allowed = f"{kind} in {_range_text(lo, hi, lo_open, hi_open)}"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(key, value, allowed, "not a number:")
    x = float(value)
    if x != x or x in (float("inf"), float("-inf")):
        raise ConfigError(key, value, allowed)
    if lo is not None and (x < lo or (lo_open and x == lo)):
        raise ConfigError(key, value, allowed, "out of range:")
    if hi is not None and (x > hi or (hi_open and x == hi)):
        raise ConfigError(key, value, allowed, "out of range:")
    return x


#: longest dead time of a simulated delay line (a drive's fieldbus, a sensor): 100 s at 1 ms. Each
#: delay cycle holds one value in memory; 2**63 cycles, which an integer >= 0 allowed, ended the run
#: in MemoryError or OverflowError (issue 30)
MAX_DELAY_CYCLES = 100_000


def require_int(value: object, key: str, *, lo: int | None = None, hi: int | None = None) -> int:
    """Return ``value`` as an int inside ``[lo, hi]`` (integral floats such as ``3.0`` accepted)."""
    allowed = f"integer in {_range_text(lo, hi, False, False)}"
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value \
            or value in (float("inf"), float("-inf")) or int(value) != value:
        raise ConfigError(key, value, allowed, "not an integer:")
    n = int(value)
    if (lo is not None and n < lo) or (hi is not None and n > hi):
        raise ConfigError(key, value, allowed, "out of range:")
    return n


def require_choice(value: object, key: str, choices: tuple[str, ...]) -> str:
    """Return ``value`` if it is one of ``choices`` (exact, case-sensitive strings)."""
    if not isinstance(value, str) or value not in choices:
        raise ConfigError(key, value, "one of " + ", ".join(repr(c) for c in choices))
    return value


def require_mapping(value: object, key: str, allowed_keys: tuple[str, ...],
                    required: tuple[str, ...] = ()) -> dict:
    """Check ``value`` is a dict with only ``allowed_keys`` and all ``required`` keys present."""
    if not isinstance(value, dict):
        raise ConfigError(key, value, "a table/dict with keys " + ", ".join(allowed_keys), "not a table:")
    for k in value:
        if k not in allowed_keys:
            raise ConfigError(f"{key}.{k}", k, "one of the keys " + ", ".join(allowed_keys),
                              "unknown key")
    for k in required:
        if k not in value:
            raise ConfigError(f"{key}.{k}", MISSING, f"a value for {k!r}")
    return value
