"""The filter comparison: every config run over a signal by the cycle core's own filter and measured
(:func:`compare`: noise RMS, delay, dead time, overshoot).

Part of :mod:`distctrl.workbench.filters` (docs/workbench-filters.md); the package face re-exports every name.
"""
from __future__ import annotations

import math
import warnings
from typing import Sequence

import numpy as np

from ...base.kinds import FilterType
from ...control.filters import FilterConfig, SensorFilter
from ...errors import ParameterError
from .result import FilterResult
from .signals import _check_edges
from .spec import FilterSpecError, WorkbenchError, WorkbenchWarning


def warmup_samples(config: FilterConfig, cycle_time: float) -> int:
    """Samples skipped before measuring noise: max(n, 50); for the low-pass n is one period of fg."""
    n = config.effective_n
    if config.filter_type == FilterType.LOWPASS:
        n = int(math.ceil(1.0 / (config.fg_f0 * cycle_time))) if config.order > 0 and config.fg_f0 > 0 else 0
    return max(int(n), 50)


def _median_window(warmup: int) -> int:
    return 4 * int(warmup) + 1


def _rms_about_mean(x: np.ndarray) -> float:
    if x.size < 10:
        return math.nan
    return float(np.sqrt(np.mean((x - x.mean()) ** 2)))


def signal_noise_rms(y: np.ndarray, t: np.ndarray, edges: Sequence[float] | None = None, warmup: int = 50,
                     median_window: int | None = None) -> float:
    """Noise RMS [mm] of a signal: about its mean on the flat part before the first edge (after
    ``warmup`` samples); without edges, of the signal minus its moving median (window
    ``median_window``, default ``4 warmup + 1``) after ``warmup`` samples. NaN if < 10 samples remain."""
    y = np.asarray(y, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    if edges is not None and len(edges):
        i_edge = int(np.searchsorted(t, float(min(edges)), side="left"))
        return _rms_about_mean(y[warmup:i_edge])
    # scipy's optimize/signal/ndimage (0.2-0.5 s of import each): only on the path that needs it
    from scipy.ndimage import median_filter

    w = median_window or _median_window(warmup)
    rest = y - median_filter(y, size=int(w), mode="nearest")
    return _rms_about_mean(rest[warmup:] + 0.0) if rest.size > warmup else math.nan


def _levels(x: np.ndarray, i1: int, i2: int) -> tuple[float, float]:
    """Base (median before the edge) and top (median of the middle 80 % between the edges)."""
    base = float(np.median(x[:i1]))
    m = (i2 - i1) // 10
    seg = x[i1 + m:i2 - m] if i2 - i1 - 2 * m >= 1 else x[i1:i2]
    return base, float(np.median(seg))


def _crossing(y: np.ndarray, t: np.ndarray, edge: float, i1: int, i2: int, base: float, step: float,
              fraction: float) -> float:
    """Time from ``edge`` until ``y`` has made ``fraction`` of ``step`` (linear between samples)."""
    z = (y[i1:i2] - base) / step
    hit = np.flatnonzero(z >= fraction)
    if not hit.size:
        return math.nan
    j = int(hit[0])
    if j == 0:
        return float(t[i1] - edge)
    z0, z1 = z[j - 1], z[j]
    frac = (fraction - z0) / (z1 - z0) if z1 != z0 else 1.0
    return float(t[i1 + j - 1] + frac * (t[i1 + j] - t[i1 + j - 1]) - edge)


def compare(signal, t, configs: Sequence[FilterConfig], cycle_time: float | None = None,
            edges: Sequence[float] | None = None) -> list[FilterResult]:
    """Run each config over ``signal`` (sampled at ``t``) and measure it.

    The filter is the cycle core's own (:meth:`SensorFilter.apply`: fresh, seeded with the first
    sample). ``cycle_time`` defaults to the median sample interval. Metrics (SPEC §4, docs):

    * noise RMS: on the flat part before the first edge, after a warm-up of
      :func:`warmup_samples` (max(n, 50)); without edges, the output minus its moving median
      (one window, ``4 * max(warm-up) + 1`` samples, for all configs so they compare),
    * delay / dead time: from the first edge until the output has made 50 % / 10 % of the step,
    * overshoot: the largest excursion beyond the top level between the first and the second edge.

    Base and top level are the medians of the raw signal before the first edge and between the
    edges (its middle 80 %; up to the end if there is one edge only). Without edges, or when the
    level changes by no more than 5 times the raw noise RMS at the first edge (then with a
    :class:`WorkbenchWarning`), the step metrics are NaN. Overshoot on a noisy signal includes
    the output's remaining noise.
    """
    x = np.asarray(signal, dtype=np.float64).ravel()
    tt = np.asarray(t, dtype=np.float64).ravel()
    if x.size != tt.size:
        raise WorkbenchError(f"signal has {x.size} samples, t has {tt.size}; allowed: equal lengths")
    if x.size < 3:
        raise WorkbenchError(f"signal has {x.size} samples; allowed: at least 3")
    if not np.all(np.isfinite(x)) or not np.all(np.isfinite(tt)):
        raise WorkbenchError("signal or t contains NaN or infinite values; allowed: finite numbers")
    if cycle_time is None:
        cycle_time = float(np.median(np.diff(tt)))
    if not (cycle_time > 0.0 and math.isfinite(cycle_time)):
        raise WorkbenchError(f"cycle_time = {cycle_time!r}; allowed: a finite number > 0 s")
    ed = _check_edges(tt, edges)
    warm = [warmup_samples(c, cycle_time) for c in configs]
    median_window = _median_window(max(warm, default=50))
    step_ctx = None
    if ed:
        e1 = ed[0]
        i1 = int(np.searchsorted(tt, e1, side="left"))
        i2 = int(np.searchsorted(tt, ed[1], side="left")) if len(ed) > 1 else x.size
        if i1 < 1 or i2 - i1 < 2:
            raise WorkbenchError(f"edges {ed} leave no flat part before or no top after the first edge; "
                                 "allowed: at least 1 sample before and 2 between the edges")
        base, top = _levels(x, i1, i2)
        step = top - base
        raw_noise = float(np.std(x[:i1]))
        if abs(step) > 5.0 * raw_noise and step != 0.0:
            step_ctx = (e1, i1, i2, base, top, step)
        else:
            warnings.warn(f"no step at the edge t = {e1:g} s: the level changes by {step:.4g} mm, the raw noise "
                          f"RMS before it is {raw_noise:.4g} mm; delay, dead time and overshoot need a change "
                          "of more than 5 noise RMS (check the edge times)", WorkbenchWarning, stacklevel=2)
    results = []
    for cfg, w in zip(configs, warm):
        try:
            y = SensorFilter(cfg, cycle_time).apply(x)
        except ParameterError as exc:
            raise FilterSpecError(f"{cfg.label()}: {exc}") from None
        noise = signal_noise_rms(y, tt, ed, w, median_window)
        delay = dead = os_mm = os_pct = math.nan
        if step_ctx is not None:
            e1, i1, i2, base, top, step = step_ctx
            delay = _crossing(y, tt, e1, i1, i2, base, step, 0.5)
            dead = _crossing(y, tt, e1, i1, i2, base, step, 0.1)
            os_mm = max(0.0, float(np.max((y[i1:i2] - top) * math.copysign(1.0, step))))
            os_pct = 100.0 * os_mm / abs(step)
        results.append(FilterResult(cfg, cfg.label(), y, noise, delay, dead, os_mm, os_pct, t=tt, signal=x,
                                    edges=tuple(ed) if ed else None))
    return results
