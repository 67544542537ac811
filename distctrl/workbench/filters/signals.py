"""The signals the filters are compared on: the documents' obstacle test (:func:`obstacle_signal`) and
the edges of a signal (:func:`find_edges`, checked by ``_check_edges``).

Part of :mod:`distctrl.workbench.filters` (docs/workbench-filters.md); the package face re-exports every name.
"""
from __future__ import annotations

import math

import numpy as np

from .spec import WorkbenchError


def obstacle_signal(cycle_time: float = 0.001, *, height: float = 2.8, level: float = 0.0,
                    flat_before: float = 0.5, top: float = 0.5, flat_after: float = 0.5,
                    ramp_time: float = 0.0, noise_std: float = 0.05, seed: int | None = 1
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The documents' filter test (FCT-M3 ch. 4): a sensor crossing an obstacle ``height`` mm high.

    Flat (``flat_before`` s at ``level``), rising edge, top (``top`` s at ``level + height``),
    falling edge, flat (``flat_after`` s), sampled every ``cycle_time`` s, plus Gaussian noise of
    standard deviation ``noise_std`` mm from ``numpy.random.default_rng(seed)``.

    Returns ``(t, values, edges)``; ``edges`` holds the times of the rising and the falling edge.
    With ``ramp_time = 0`` (default) the edges are steps: the signal has its new level from the edge
    sample on. With ``ramp_time > 0`` each edge is a linear ramp and the edge time is the ramp's
    middle (where the raw signal has made half the step). ``height`` is signed: the default +2.8
    rises like the sensor data in the documents' figures; a distance sensor at a standoff whose
    distance drops over the obstacle is ``level=5, height=-2.8`` (the metrics follow the sign).
    """
    T = float(cycle_time)
    if not (T > 0.0 and math.isfinite(T)):
        raise WorkbenchError(f"cycle_time = {cycle_time!r}; allowed: a finite number > 0 s")
    for name, v in (("flat_before", flat_before), ("top", top), ("flat_after", flat_after)):
        if not (v > 0.0 and math.isfinite(v)):
            raise WorkbenchError(f"{name} = {v!r} s; allowed: a finite number > 0")
    if not (ramp_time >= 0.0 and ramp_time < top and math.isfinite(ramp_time)):
        raise WorkbenchError(f"ramp_time = {ramp_time!r} s; allowed: 0 <= ramp_time < top ({top!r} s)")
    if not (noise_std >= 0.0 and math.isfinite(noise_std)):
        raise WorkbenchError(f"noise_std = {noise_std!r} mm; allowed: a finite number >= 0")
    i1 = int(round(flat_before / T))
    i2 = i1 + int(round(top / T))
    n = i2 + int(round(flat_after / T))
    k = np.arange(n, dtype=np.float64)
    if ramp_time > 0.0:
        r = ramp_time / T
        profile = np.clip((k - i1) / r + 0.5, 0.0, 1.0) - np.clip((k - i2) / r + 0.5, 0.0, 1.0)
    else:
        profile = (k >= i1).astype(np.float64) - (k >= i2).astype(np.float64)
    t = k * T
    values = level + height * profile
    if noise_std > 0.0:
        values = values + np.random.default_rng(seed).normal(0.0, noise_std, n)
    return t, values, np.array([i1 * T, i2 * T])


def _check_edges(t: np.ndarray, edges) -> list[float] | None:
    if edges is None:
        return None
    out = sorted(float(e) for e in edges)
    if not out:
        return None
    for e in out:
        if not (math.isfinite(e) and t[0] < e <= t[-1]):
            raise WorkbenchError(f"edge time {e!r} s outside the signal; allowed: {t[0]:g} < edge <= {t[-1]:g} s")
    return out


def find_edges(t, values, window: int = 21) -> list[float]:
    """Estimate the obstacle edges of a recording: the largest level change and, after it, the
    largest change back (each more than 8 noise RMS). Times where the moving median makes half of
    the change; [] if there is no clear edge. A helper for ``--edge auto``; check it on the plot."""
    # scipy's optimize/signal/ndimage (0.2-0.5 s of import each): only on the path that needs it
    from scipy.ndimage import median_filter

    x = np.asarray(values, dtype=np.float64)
    tt = np.asarray(t, dtype=np.float64)
    w = int(window) | 1
    k = w // 2
    if x.size < 4 * w:
        return []
    m = median_filter(x, size=w, mode="nearest")
    resid = x - m
    noise = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
    d = np.zeros_like(x)
    d[k:-k] = m[2 * k:] - m[:-2 * k]
    thresh = max(8.0 * noise, 1e-12)

    def locate(i: int) -> float:
        a, b = max(i - k, 0), min(i + k, x.size - 1)
        z = (m[a:b + 1] - m[a]) / (m[b] - m[a])
        j = int(np.flatnonzero(z >= 0.5)[0])
        return float(tt[a + j])
    i1 = int(np.argmax(np.abs(d)))
    if abs(d[i1]) <= thresh:
        return []
    found = [i1]
    back = -math.copysign(1.0, d[i1]) * d             # the change back, anywhere but at the first one
    back[max(i1 - w, 0):i1 + w + 1] = -np.inf
    j = int(np.argmax(back))
    if back[j] > max(thresh, 0.5 * abs(d[i1])):
        found.append(j)
    return [locate(i) for i in sorted(found)]
