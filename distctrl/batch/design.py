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
(:func:`distctrl.control.butter.butter_lowpass_many`, vectorised over the cut-offs of one order, the same numbers
as the controller's own design) and fills the cache before the sets are checked one by one.

:func:`design_rows` is the design of many configurations given as arrays (a sweep's columns,
:mod:`distctrl.tuning.columns`): the coefficient rows of all of them at once, without a configuration
object per set; the tests compare every row with :func:`~distctrl.control.filters.design_coefficients`.

Importing this module imports neither numba nor scipy.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..base.kinds import FilterType
from ..control import law
from ..control.butter import butter_lowpass_many
from ..control.controller import AxisDistanceController
from ..control.filters import (FILTER_PARAMS, KALMAN_PROCESS_VARIANCE, FilterConfig,
                               design_coefficients)
from ..params.axis import AxisParameters

__all__ = ["filter_coefficients", "filter_config", "design_many", "design_rows", "kalman_predictions", "unique_rows",
           "check_cycle_time", "clear_cache", "cache_info"]

#: at most this many designs are kept (a tuner's long run with continuous values cannot grow it without bound)
MAX_ENTRIES = 1 << 16
_FIELDS = tuple(f.name for f in dataclasses.fields(FilterConfig))
_CACHE: dict = {}
_STATS = {"designs": 0, "hits": 0}
#: design_rows' Kalman predictions per (kind, n, alpha): (prediction variance, coefficients); they do not
#: depend on sigma
_KALMAN: dict = {}
#: design_rows' (rho^n, EXPO_MEAN sums) per (n, alpha): :func:`_decay_terms`
_DECAY: dict = {}


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
            sos, zi = butter_lowpass_many(order, [float(c.fg_f0) for _, c in items], 1.0 / cycle_time)
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
    _KALMAN.clear()
    _DECAY.clear()
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


#: the filter types :func:`design_rows` designs itself (others: one by one through design_coefficients)
_ROW_TYPES = frozenset(int(t) for t in (FilterType.DEFAULT, FilterType.MOVING_AVERAGE, FilterType.EXPO_MEAN,
                                         FilterType.LOWPASS, FilterType.KALMAN_MA, FilterType.KALMAN_EXPO))


def _field_errors(name: str, values: np.ndarray) -> dict:
    """FILTER_PARAMS[name].check of every distinct value: value -> the exception it raises. The values the
    table's range accepts are found with numpy first, only the others are checked one by one for their
    message (a sweep's random smoothing factors are thousands of distinct values, each a Python call)."""
    vals = np.unique(values)
    spec = FILTER_PARAMS[name].spec
    if not spec.choices and spec.type != "BOOLEAN" and (not spec.integer or vals.dtype.kind in "iu"):
        with np.errstate(invalid="ignore"):
            ok = vals == vals                                    # NaN: checked one by one (refused)
            if spec.lo is not None:
                ok &= (vals > spec.lo) if spec.lo_open else (vals >= spec.lo)
            if spec.hi is not None:
                ok &= (vals < spec.hi) if spec.hi_open else (vals <= spec.hi)
        vals = vals[~ok]
    out = {}
    for v in vals.tolist():
        try:
            FILTER_PARAMS[name].check(v)
        except Exception as exc:             # noqa: BLE001 - the message of the one-by-one check
            out[v] = exc
    return out


def design_rows(ftype, n_cycles, alpha, sigma, order, fg, cycle_time: float) -> tuple[np.ndarray, dict]:
    """The coefficient rows ``fc`` of K filter configurations given as arrays (filter type values, n_cycles,
    smoothing factor, Kalman sigma, low-pass order, cut-off), as :func:`design_coefficients` computes them
    one by one, bit for bit: ``(fc (K, law.FC_LEN), {row: exception})`` for the rows the check refuses
    (the exception :meth:`FilterConfig.check` raises for the first bad value, in its order).

    Per distinct value, not per row: the checks of every parameter, ``rho^n`` and the EXPO_MEAN sums (per
    distinct (n, alpha)) and the Kalman coefficients (per distinct (kind, n, alpha)); the low-passes over
    arrays (:func:`~distctrl.control.butter.butter_lowpass_many`), the Kalman gain over the sigmas."""
    ft = np.asarray(ftype, dtype=np.int64)
    n = np.asarray(n_cycles, dtype=np.int64)
    alpha = np.asarray(alpha, dtype=np.float64)
    sigma = np.asarray(sigma, dtype=np.float64)
    order = np.asarray(order, dtype=np.int64)
    fg = np.asarray(fg, dtype=np.float64)
    k_n = len(ft)
    fc = np.zeros((k_n, law.FC_LEN))
    errors: dict = {}
    if not k_n:
        return fc, errors
    # the checks of FilterConfig.check, in its order
    bad = np.zeros(k_n, dtype=bool)
    valid_type = np.isin(ft, [int(t) for t in FilterType if t != FilterType.PASS])
    for i in np.nonzero(~valid_type)[0].tolist():
        try:
            FilterConfig(FilterType(int(ft[i])) if int(ft[i]) in {int(t) for t in FilterType} else int(ft[i])
                         ).check(cycle_time)
        except Exception as exc:             # noqa: BLE001
            errors[i] = exc
    bad |= ~valid_type
    for name, vals in (("n_cycles", n), ("smoothing_factor", alpha), ("kalman_sigma", sigma), ("order", order)):
        errs = _field_errors(name, vals)
        if errs:
            for i in np.nonzero(~bad & np.isin(vals, list(errs)))[0].tolist():
                errors[i] = errs[vals[i].item()]
                bad[i] = True
    lowpass = (ft == int(FilterType.LOWPASS)) & (order > 0)
    nyquist = 0.5 / cycle_time
    for i in np.nonzero(~bad & lowpass & ~((0.0 < fg) & (fg < nyquist)))[0].tolist():
        try:
            _config(ft[i], n[i], alpha[i], sigma[i], order[i], fg[i]).check(cycle_time)
        except Exception as exc:             # noqa: BLE001
            errors[i] = exc
            bad[i] = True
    ok = ~bad
    other = ok & ~np.isin(ft, list(_ROW_TYPES))
    for i in np.nonzero(other)[0].tolist():      # a type this function does not know: one by one
        fc[i] = design_coefficients(_config(ft[i], n[i], alpha[i], sigma[i], order[i], fg[i]), cycle_time)
    ok &= ~other
    # the law's code in force (FILTER_KINDS[...].code) and n
    windowed = np.isin(ft, [int(FilterType.MOVING_AVERAGE), int(FilterType.KALMAN_MA), int(FilterType.KALMAN_EXPO)])
    kind = np.where(ft == int(FilterType.DEFAULT), law.MOVING_AVERAGE,
                    np.where(windowed, np.where(n <= 1, law.PASS, ft),
                             np.where(ft == int(FilterType.EXPO_MEAN),
                                      np.where((n <= 1) | (alpha >= 1.0), law.PASS, law.EXPO_MEAN),
                                      np.where(lowpass, law.LOWPASS, law.PASS))))
    eff_n = np.where(ft == int(FilterType.DEFAULT), 4, n)
    rows = np.nonzero(ok)[0]
    fc[rows, law.FC_KIND] = kind[rows]
    fc[rows, law.FC_N] = eff_n[rows]
    with np.errstate(divide="ignore"):
        fc[rows, law.FC_INV_N] = np.where(eff_n[rows] > 0, 1.0 / eff_n[rows], 0.0)
    fc[rows, law.FC_ALPHA] = alpha[rows]
    fc[rows, law.FC_SIGMA] = sigma[rows]
    fc[rows, law.FC_WSUM] = 1.0
    # rho^n (and the EXPO_MEAN sums): math per distinct (n, alpha), as design_coefficients does
    pairs, inv = unique_rows(np.stack((eff_n[rows].astype(np.float64), alpha[rows]), axis=1))
    if len(_DECAY) + len(pairs) > MAX_ENTRIES:
        _DECAY.clear()
    terms = []
    for key in map(tuple, pairs.tolist()):      # kept from call to call: a sweep's chunks repeat the pairs
        got = _DECAY.get(key)
        if got is None:
            got = _DECAY[key] = _decay_terms(int(key[0]), key[1])
        terms.append(got)
    decay, wsum, older = np.array(terms, dtype=np.float64).reshape(len(pairs), 3).T
    fc[rows, law.FC_DECAY_N] = decay[inv]
    expo = kind[rows] == law.EXPO_MEAN
    fc[rows[expo], law.FC_WSUM] = wsum[inv[expo]]
    fc[rows[expo], law.FC_EXPO_OLDER] = older[inv[expo]]
    # Kalman: the prediction per distinct (kind, n, alpha), the gain over the sigmas
    kal = rows[np.isin(kind[rows], [law.KALMAN_MA, law.KALMAN_EXPO])]
    if len(kal):
        keys, kinv = unique_rows(np.stack((kind[kal].astype(np.float64), eff_n[kal].astype(np.float64),
                                           np.where(kind[kal] == law.KALMAN_EXPO, alpha[kal], 0.0)), axis=1))
        v = np.empty(len(keys))
        pred = np.zeros((len(keys), law.MAX_N))          # the coefficients, zero beyond n
        todo = []
        for j, (kk, nn, a) in enumerate(keys.tolist()):
            kd = _KALMAN.get((int(kk), int(nn), a))
            if kd is None:
                todo.append(j)
            else:
                v[j] = kd[0]
                pred[j, :int(nn)] = kd[1]
        if todo:                                 # designed per (kind, n) at once, kept for the next call
            todo = np.array(todo)
            if len(_KALMAN) + len(todo) > MAX_ENTRIES:
                _KALMAN.clear()
            group, ginv = unique_rows(keys[todo, :2])
            for g, (kk, nn) in enumerate(group.tolist()):
                js = todo[ginv == g]
                vv, coef = kalman_predictions(int(kk), int(nn), keys[js, 2])
                v[js] = vv
                pred[js, :int(nn)] = coef
                for j, vj, cj in zip(js.tolist(), vv.tolist(), coef):
                    _KALMAN[(int(kk), int(nn), keys[j, 2].item())] = (vj, cj)
        fc[kal, law.FC_PRED:law.FC_PRED + law.MAX_N] = pred[kinv]
        p_prior = v[kinv] * sigma[kal] + KALMAN_PROCESS_VARIANCE
        fc[kal, law.FC_GAIN] = p_prior / (p_prior + sigma[kal])
        fc[kal, law.FC_P_PRIOR] = p_prior
    # the low-passes, per order over the cut-offs
    lp = rows[kind[rows] == law.LOWPASS]
    for o in np.unique(order[lp]).tolist():
        sel = lp[order[lp] == o]
        sos, zi = butter_lowpass_many(o, fg[sel], 1.0 / cycle_time)
        n_sec = sos.shape[1]
        fc[sel, law.FC_NSEC] = float(n_sec)
        fc[sel, law.FC_SOS:law.FC_SOS + 6 * n_sec] = sos.reshape(len(sel), 6 * n_sec)
        fc[sel, law.FC_ZI:law.FC_ZI + 2 * n_sec] = zi.reshape(len(sel), 2 * n_sec)
    return fc, errors


def _decay_terms(nn: int, a: float) -> tuple[float, float, float]:
    """``(rho^n, the EXPO_MEAN weight sum, its weight of the older values)`` of a window ``nn`` and smoothing
    factor ``a`` (the sums NaN where EXPO_MEAN does not use them), in math as :func:`design_coefficients`."""
    log_rho = math.log1p(-a) if a < 1.0 else -math.inf
    decay = math.exp(nn * log_rho)
    if nn >= 2 and a < 1.0:
        return decay, -math.expm1(nn * log_rho) / a, a / -math.expm1((nn - 1) * log_rho)
    return decay, math.nan, math.nan


def kalman_predictions(kind: int, n: int, alphas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The prediction variance ``(K,)`` and coefficients ``(K, n)`` of the Kalman filters ``kind`` with ``n``
    measurements for K smoothing factors (KALMAN_MA: the factors are not used), bit for bit
    :func:`~distctrl.control.filters.kalman_design` of each: the same operations over the rows, its dot
    products as ``np.matmul`` of the stacked rows, which calls the same BLAS dot per row as ``np.dot``
    (tests/batch/test_design.py compares them over thousands of keys). A random sweep's 10^4 sets have
    about 1 700 distinct keys: one by one they were a third of checking the sets."""
    alphas = np.asarray(alphas, dtype=np.float64)
    k = len(alphas)
    if kind == law.KALMAN_MA:
        w = np.full((k, n), 1.0 / n)
    else:                                               # expo_weights of each alpha, oldest first
        age = np.arange(n - 1, 0, -1, dtype=np.float64)
        older = np.power((1.0 - alphas)[:, None], (age - 1.0)[None, :])
        total = older.sum(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            older *= np.where(total > 0.0, (1.0 - alphas) / total, 0.0)[:, None]
        w = np.empty((k, n))
        w[:, :-1] = older
        w[:, -1] = alphas
    t = np.ascontiguousarray(np.broadcast_to(np.arange(n, dtype=np.float64), (k, n)))
    t_mean = np.matmul(w[:, None, :], t[:, :, None])[:, 0, 0]
    dev = t - t_mean[:, None]
    spread = np.matmul(w[:, None, :], np.ascontiguousarray(dev ** 2)[:, :, None])[:, 0, 0]
    sloped = spread > 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.where(sloped[:, None], w * (1.0 + dev * (float(n) - t_mean[:, None]) / spread[:, None]), w)
    v = np.matmul(c[:, None, :], c[:, :, None])[:, 0, 0]
    return v, c


def unique_rows(mat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct rows of a float matrix (sorted) and, per row, the index of its distinct row: what
    ``np.unique(mat, axis=0, return_inverse=True)`` gives, by a lexsort of the columns (np.unique sorts
    the rows as structured values, several times slower)."""
    k = len(mat)
    if not k:
        return mat[:0], np.zeros(0, dtype=np.int64)
    order = np.lexsort(mat.T[::-1])
    srt = mat[order]
    new = np.empty(k, dtype=bool)
    new[0] = True
    new[1:] = np.any(srt[1:] != srt[:-1], axis=1)
    inv = np.empty(k, dtype=np.int64)
    inv[order] = np.cumsum(new) - 1
    return srt[new], inv


def _config(ft, n, alpha, sigma, order, fg) -> FilterConfig:
    """One row as a FilterConfig (Python values, as a point gives them)."""
    t = int(ft)
    return FilterConfig(FilterType(t) if t in {int(x) for x in FilterType} else t, int(n), float(alpha),
                        float(sigma), int(order), float(fg))
