"""Filter coefficients designed once per distinct filter configuration, and shared (issue 27).

A sweep of 10 000 sets has a few hundred distinct filters at most (the tuner and ``--random``
round every value to what the parameter list accepts, a grid repeats them); designing each set's
Butterworth low-pass with scipy (about 1 ms) was most of a sweep's time. :func:`filter_coefficients`
calls :func:`distctrl.control.filters.design_coefficients` once per distinct ``(filter type, n,
alpha, sigma, order, fg_f0)`` and cycle time, and hands out the same read-only buffer afterwards; a
configuration that the design refuses (the low-pass cut-off above Nyquist, ...) raises the same
:class:`~distctrl.errors.ParameterError` every time.

The tuner rounds the low-pass cut-off to 0.1 Hz, which still leaves thousands of distinct (order, fg_f0) in a
random sweep: :func:`design_many` designs all low-passes of a list of sets at once
(:func:`distctrl.control.butter.butter_lowpass`, vectorised over the cut-offs of one order, the same numbers
as the controller's own design) and fills the cache before the sets are checked one by one.

Importing this module imports neither numba nor scipy.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..base.kinds import FilterType
from ..control import law
from ..control.butter import butter_lowpass
from ..control.controller import AxisDistanceController
from ..control.filters import FilterConfig, design_coefficients
from ..params.axis import AxisParameters

__all__ = ["filter_coefficients", "filter_config", "design_many", "check_cycle_time", "clear_cache", "cache_info"]

#: at most this many designs are kept (a tuner's long run with continuous values cannot grow it without bound)
MAX_ENTRIES = 1 << 16
_FIELDS = tuple(f.name for f in dataclasses.fields(FilterConfig))
_CACHE: dict = {}
_STATS = {"designs": 0, "hits": 0}


def filter_config(p) -> FilterConfig:
    """The filter configuration of an :class:`~distctrl.params.AxisParameters` set (as the controller's
    ``Tuning.from_params`` builds it)."""
    return FilterConfig(p.filter_type, p.n_cycles, p.smoothing_factor, p.kalman_sigma,
                        p.low_pass_filter_order, p.low_pass_filter_fg_f0)


def _key(config: FilterConfig, cycle_time: float):
    # the types are part of the key: 4 == 4.0, but a float n_cycles is refused by the design
    values = tuple(getattr(config, f) for f in _FIELDS)
    return values, tuple(type(v) for v in values), cycle_time, type(cycle_time)


def filter_coefficients(config: FilterConfig, cycle_time: float) -> np.ndarray:
    """The law's coefficient buffer ``fc`` of ``config`` at ``cycle_time`` (read-only float64 array),
    designed by :func:`~distctrl.control.filters.design_coefficients` on the first request; raises what
    the design raises (every time)."""
    key = _key(config, cycle_time)
    try:
        hit = _CACHE[key]
    except (KeyError, TypeError):          # TypeError: an unhashable value (designed, not kept)
        hit = None
    if hit is not None:
        _STATS["hits"] += 1
        if isinstance(hit, BaseException):
            raise hit.with_traceback(None)
        return hit
    _STATS["designs"] += 1
    try:
        fc = np.asarray(design_coefficients(config, cycle_time), dtype=np.float64)
    except Exception as exc:                # noqa: BLE001 - kept and raised again for the same configuration
        _store(key, exc)
        raise
    fc.flags.writeable = False
    _store(key, fc)
    return fc


def design_many(configs, cycle_time: float) -> int:
    """Design the distinct LOWPASS configurations among ``configs`` that are not cached yet, all at once
    (per order, over the cut-offs), and cache their buffers; returns how many were designed. Configurations
    the design refuses are left to :func:`filter_coefficients` (which raises for them)."""
    todo: dict = {}
    for c in configs:
        if c.filter_type != FilterType.LOWPASS:
            continue
        try:
            key = _key(c, cycle_time)
            if key in _CACHE or key in todo:
                continue
            c.check(cycle_time)
            if c.effective_kind != law.LOWPASS:
                continue
        except Exception:                   # noqa: BLE001 - refused or unhashable: the one-by-one path
            continue
        todo[key] = c
    by_order: dict = {}
    for key, c in todo.items():
        by_order.setdefault(int(c.order), []).append((key, c))
    for order, items in by_order.items():
        try:
            sos, zi = butter_lowpass(order, [float(c.fg_f0) for _, c in items], 1.0 / cycle_time)
        except (ValueError, TypeError):     # pragma: no cover - check() refuses these first
            continue
        for i, (key, c) in enumerate(items):
            fc = np.asarray(design_coefficients(c, cycle_time, lowpass=(sos[i], zi[i])), dtype=np.float64)
            fc.flags.writeable = False
            _STATS["designs"] += 1
            _store(key, fc)
    return sum(len(v) for v in by_order.values())


def _store(key, value) -> None:
    if len(_CACHE) >= MAX_ENTRIES:
        _CACHE.clear()
    try:
        _CACHE[key] = value
    except TypeError:                       # unhashable
        pass


def clear_cache() -> None:
    _CACHE.clear()
    _STATS.update(designs=0, hits=0)


def cache_info() -> dict:
    """``{"designs": n, "hits": n, "entries": n}`` since the last :func:`clear_cache`."""
    return {**_STATS, "entries": len(_CACHE)}


def check_cycle_time(cycle_time) -> None:
    """Raise what :class:`~distctrl.control.controller.AxisDistanceController` raises for a cycle time
    out of its range (the sets' checks that do not build a controller per set start with it)."""
    if isinstance(cycle_time, (int, float)) and math.isfinite(cycle_time) and 1e-5 <= cycle_time <= 1.0:
        return

    AxisDistanceController(AxisParameters(), cycle_time)       # raises the controller's own ParameterError
    raise AssertionError("the controller accepted a cycle time this check refuses")  # pragma: no cover
