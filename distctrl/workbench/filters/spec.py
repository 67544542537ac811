"""The filter workbench's errors and filter specs: ``TYPE:key=v1,v2,...`` parsed into
:class:`FilterConfig` (:func:`parse_filter_spec`), and the default comparison (:data:`DEFAULT_SPECS`).

Part of :mod:`distctrl.workbench.filters` (docs/workbench-filters.md); the package face re-exports every name.
"""
from __future__ import annotations

import difflib
import itertools
import math
from typing import Sequence

from ...base.kinds import FILTER_TYPE_NAMES, FilterType
from ...control.filters import FILTER_KINDS, FILTER_PARAMS, FilterConfig
from ...errors import DistCtrlError, ParameterError


# ------------------------------------------------------------------------------------------------------
# errors
# ------------------------------------------------------------------------------------------------------
class WorkbenchError(DistCtrlError, ValueError):
    """Bad input to a workbench tool (spec text, file, column, unit, edge time, output path)."""


class FilterSpecError(WorkbenchError):
    """A filter spec (``TYPE:key=value,...``) that cannot be parsed or is out of range."""


class RecordingError(WorkbenchError):
    """A sensor recording that cannot be read: names the file, line or column and what is allowed."""


class WorkbenchWarning(UserWarning):
    """A usable input with a flaw the result depends on (reported, not fatal)."""


class RecordingWarning(WorkbenchWarning):
    """A usable recording with a flaw (e.g. a sample interval that is not uniform within 1 %)."""


# ------------------------------------------------------------------------------------------------------
# filter specs
# ------------------------------------------------------------------------------------------------------
SPEC_SYNTAX = ("TYPE[:key=value[,value...][,key=value[,value...]...]], e.g. MOVING_AVERAGE:n_cycles=10,20,40 "
               "or KALMAN_MA:n_cycles=30,kalman_sigma=100,1000; several specs separated by ';'")

#: accepted key spellings -> FilterConfig field (the parameter table's short keys and the kernel's parameter names)
KEY_ALIASES: dict[str, str] = {k: p.name for p in FILTER_PARAMS.values() for k in p.keys}

#: the keys that have an effect, per filter type (a key that does nothing is an error, not silence)
KEYS_BY_TYPE: dict[FilterType, tuple[str, ...]] = {t: k.params for t, k in FILTER_KINDS.items()
                                                   if t != FilterType.PASS}

#: the parameters of a filter type in the order the JSON, CSV and table list them
KEY_ORDER = ("n_cycles", "smoothing_factor", "kalman_sigma", "order", "fg_f0")

_INT_KEYS = {p.name for p in FILTER_PARAMS.values() if p.spec.integer}
_RANGES = {p.name: p.range_label() for p in FILTER_PARAMS.values()}

#: the comparison ``distctrl filters`` runs without a SPEC: each filter kind's example
#: (control/filters.FILTER_KINDS) in this order, the documents' example values (FCT-M3 §4.1 n 20, §4.2 n 30 alpha 0.3, §4.3 order 2 at 30 Hz, §4.4 n 30 sigma 1000, §4.5, §9.3 n 20
#: sigma 1000) and the default sigma 4, so the plain filters and the Kalman filters of the same n
#: (shorter dead time, overshoot growing with n and sigma) are side by side
_COMPARISON_ORDER = (FilterType.MOVING_AVERAGE, FilterType.KALMAN_MA, FilterType.EXPO_MEAN,
                     FilterType.KALMAN_EXPO, FilterType.LOWPASS)
DEFAULT_SPECS: tuple[str, ...] = tuple(
    FILTER_KINDS[t].example for t in sorted(FILTER_KINDS, key=lambda t: _COMPARISON_ORDER.index(t)
                                            if t in _COMPARISON_ORDER else len(_COMPARISON_ORDER))
    if FILTER_KINDS[t].example)


def _keys_text(ft: FilterType) -> str:
    keys = KEYS_BY_TYPE[ft]
    if not keys:
        return "none (DEFAULT is the moving average with n = 4)"
    out = []
    for k in keys:
        aliases = [a for a, c in KEY_ALIASES.items() if c == k and a != k]
        out.append(k + (f" (alias {', '.join(aliases)})" if aliases else ""))
    return ", ".join(out)


def _convert(spec: str, key: str, text: str) -> float | int:
    try:
        value = float(text)
    except ValueError:
        raise FilterSpecError(f"filter spec {spec!r}: {key} = {text!r} is not a number; "
                              f"allowed: {_RANGES[key]}") from None
    if not math.isfinite(value):
        raise FilterSpecError(f"filter spec {spec!r}: {key} = {text!r} is not finite; allowed: {_RANGES[key]}")
    if key in _INT_KEYS:
        if value != int(value):
            raise FilterSpecError(f"filter spec {spec!r}: {key} = {text!r} is not an integer; "
                                  f"allowed: {_RANGES[key]}")
        return int(value)
    return value


def _check_config(spec: str, cfg: FilterConfig, cycle_time: float | None) -> None:
    if cfg.filter_type == FilterType.LOWPASS and cfg.order > 0 and not cfg.fg_f0 > 0.0:
        raise FilterSpecError(f"filter spec {spec!r}: fg_f0 = {cfg.fg_f0:g} out of range; allowed: {_RANGES['fg_f0']}")
    try:
        # without a cycle time only the Nyquist bound is left open (checked again when the filter is built)
        cfg.check(cycle_time if cycle_time else 1e-300)
    except ParameterError as exc:
        raise FilterSpecError(f"filter spec {spec!r}: {exc}") from None


def _parse_one(spec: str, cycle_time: float | None) -> list[FilterConfig]:
    name, sep, rest = spec.partition(":")
    try:
        ft = FilterType.parse(name)
    except ValueError:
        raise FilterSpecError(f"filter spec {spec!r}: unknown filter type {name.strip()!r}; allowed: "
                              f"{', '.join(FILTER_TYPE_NAMES)}; syntax: {SPEC_SYNTAX}") from None
    allowed = KEYS_BY_TYPE[ft]
    values: dict[str, list] = {}
    if sep:
        if not rest.strip():
            raise FilterSpecError(f"filter spec {spec!r}: nothing after ':'; allowed keys for {ft.name}: "
                                  f"{_keys_text(ft)}; syntax: {SPEC_SYNTAX}")
        current: str | None = None
        for tok in rest.split(","):
            tok = tok.strip()
            if "=" in tok:
                raw_key, _, tok = tok.partition("=")
                key = raw_key.strip().lower()
                canon = KEY_ALIASES.get(key)
                if canon is None:
                    near = difflib.get_close_matches(key, list(KEY_ALIASES), n=1)
                    hint = f" (did you mean {near[0]}?)" if near else ""
                    raise FilterSpecError(f"filter spec {spec!r}: unknown key {raw_key.strip()!r}{hint}; "
                                          f"allowed keys for {ft.name}: {_keys_text(ft)}")
                if canon not in allowed:
                    raise FilterSpecError(f"filter spec {spec!r}: key {raw_key.strip()!r} has no effect on "
                                          f"{ft.name}; allowed keys for {ft.name}: {_keys_text(ft)}")
                if canon in values:
                    raise FilterSpecError(f"filter spec {spec!r}: key {canon!r} given twice; list several "
                                          f"values after one key: {canon}=v1,v2")
                values[canon] = []
                current = canon
                tok = tok.strip()
            elif current is None:
                raise FilterSpecError(f"filter spec {spec!r}: value {tok!r} before any key; syntax: {SPEC_SYNTAX}")
            if not tok:
                raise FilterSpecError(f"filter spec {spec!r}: empty value for {current}; allowed: {_RANGES[current]}")
            values[current].append(_convert(spec, current, tok))
    keys = [k for k in allowed if k in values]
    configs = []
    for combo in itertools.product(*(values[k] for k in keys)):
        cfg = FilterConfig(ft, **dict(zip(keys, combo)))
        _check_config(spec, cfg, cycle_time)
        configs.append(cfg)
    return configs


def parse_filter_spec(text: str, cycle_time: float | None = None) -> list[FilterConfig]:
    """Configs of one spec text: ``TYPE[:key=v1[,v2...][,key=v...]]`` (several specs joined by ``;``).

    A value list continues until the next ``key=``; keys with several values expand into their
    cartesian product, e.g. ``KALMAN_MA:n_cycles=30,kalman_sigma=100,1000`` gives two configs.
    Unnamed parameters keep the :class:`FilterConfig` defaults. Keys: ``n_cycles``,
    ``smoothing_factor`` (``smooth_fact``), ``kalman_sigma`` (``sigma``), ``order``
    (``low_pass_filter_order``), ``fg_f0`` (``low_pass_filter_fg_f0``), each only where it has an
    effect. With ``cycle_time`` the low-pass cut-off is also checked against Nyquist.
    Raises :class:`FilterSpecError` naming the spec and what is allowed.
    """
    if not isinstance(text, str) or not text.strip():
        raise FilterSpecError(f"empty filter spec {text!r}; syntax: {SPEC_SYNTAX}")
    configs: list[FilterConfig] = []
    for part in text.split(";"):
        if part.strip():
            configs.extend(_parse_one(part.strip(), cycle_time))
    if not configs:
        raise FilterSpecError(f"empty filter spec {text!r}; syntax: {SPEC_SYNTAX}")
    return configs


def parse_filter_specs(texts: Sequence[str], cycle_time: float | None = None) -> list[FilterConfig]:
    """All configs of several spec texts, in order."""
    return [cfg for text in texts for cfg in parse_filter_spec(text, cycle_time)]


def default_configs(cycle_time: float | None = None) -> list[FilterConfig]:
    """The default comparison (:data:`DEFAULT_SPECS`): 9 configs."""
    return parse_filter_specs(DEFAULT_SPECS, cycle_time)
