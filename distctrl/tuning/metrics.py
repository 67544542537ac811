"""Quality figures of closed-loop runs, vectorised over parameter sets (rows) and cycles (columns).

Input: the kernel's ``offset`` and ``distance`` arrays ``(n_sets, n_cycles)`` in mm
(:func:`distctrl.batch.closed_loop.run_batch`), the wanted distance and the limits of each set.
All figures are computed over the *tracking window*: the cycles from the select
(``k_on``) plus ``skip`` seconds to the end. Definitions (docs/tuning.md):

``rms_error`` / ``max_error`` (mm)
    RMS and largest absolute value of the distance error ``e = distance - wanted``.
``overshoot`` (mm)
    The largest excursion of ``e`` to the side *opposite* to its largest peak, within
    ``overshoot_window`` seconds (0.25) after that peak: ``max(0, max(-sign(e_peak) * e))``. A
    well damped loop returns to the wanted distance from the side it was pushed to; a loop that
    overshoots crosses it. (Noise and a disturbance inside the window add to it.)
``osc_index`` (1/s)
    Ringing rate: sign changes of ``e`` per second, counted with a hysteresis band ``±band``
    (``band`` = 0.05 mm: a change counts only when ``e`` goes from above ``+band`` to below
    ``-band`` or back), so noise inside the band does not count.
``hf_rms`` (mm)
    RMS of the part of ``e`` above ``f_osc`` Hz (one-sided FFT over the window, mean removed):
    the energy of fast oscillation. The tuner's oscillation penalty.
``offset_hf_rms`` (mm)
    RMS of the part of the *offset* above ``f_osc`` Hz: the axis's own high-frequency motion
    (chatter), which the distance error does not show when it is fast enough to follow the noise.
``settle_time_50um`` (s)
    Time from the select until ``|e| <= band`` holds for ``hold`` seconds without a break
    (NaN: never within the run). Not ``distctrl run``'s ``settle_time`` (±0.01 mm on the last
    entry, docs/run.md): a band of 0.05 mm held 0.1 s, first entry.
``sat_share`` (0..1)
    Share of the window's cycles where the offset runs at the slope limiter's velocity or
    acceleration limit: ``|v| >= (1 - 1e-3) v_lim`` or ``|a| >= (1 - 1e-3) a_lim`` with
    ``v = diff(offset)/T``, ``a = diff(v)/T``; when moving down (v < 0) the lowering weights
    apply; with adaptive acceleration ``a_lim`` follows the set's ramp (a_min .. a_max) over
    ``|e|`` (the law uses the filtered deviation, so this is an approximation).

A set that ran into a controller error (NaN outputs from the error cycle) gets ``rms_error`` etc.
from the cycles before it and ``failed = True``; the tuner treats it as infinitely bad.
"""
from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..batch import numba_available
from ..control import law

__all__ = ["METRIC_NAMES", "METRIC_UNITS", "wanted_distance", "compute_metrics", "limits_from_packed", "cost",
           "reference_metrics", "SAT_WEIGHT", "CHATTER_WEIGHT"]

METRIC_NAMES = ("rms_error", "max_error", "overshoot", "osc_index", "hf_rms", "offset_hf_rms", "settle_time_50um",
                "sat_share")

#: the unit of every metric (and of ``cost``), for tables and JSON
METRIC_UNITS = {"cost": "mm", "rms_error": "mm", "max_error": "mm", "overshoot": "mm", "osc_index": "1/s",
                "hf_rms": "mm", "offset_hf_rms": "mm", "settle_time_50um": "s", "sat_share": "0..1"}

_TOL = 1e-3


def wanted_distance(inputs, n: int | None = None) -> np.ndarray:
    """The wanted distance per cycle (mm): SET_DIST in CONST_DIST, ``prog - SET_POS`` in SET_POS."""
    # numba (the [batch] extra) loads only when a batch runs
    from ..batch.closed_loop import MODE_CONST_DIST

    n = inputs.n_cycles if n is None else n
    if inputs.mode == MODE_CONST_DIST:
        return np.full(n, float(inputs.set_value))
    return np.asarray(inputs.prog[:n], dtype=np.float64) - inputs.set_value


def limits_from_packed(packed: np.ndarray) -> dict[str, np.ndarray]:
    """Per-set limiter data (v_max, a_base, weights, adaptive ramp) from packed rows."""
    from ..batch import closed_loop as CL  # numba (the [batch] extra) loads only when a batch runs

    q = packed[:, law.FC_LEN:]
    return {"v_lim": q[:, CL.Q_V_MAX], "a_lim": q[:, CL.Q_A_BASE], "w_v": q[:, CL.Q_W_V],
            "w_a": q[:, CL.Q_W_A], "adaptive": q[:, CL.Q_ADAPTIVE] != 0.0, "a_min": q[:, CL.Q_A_MIN],
            "dev_a_min": q[:, CL.Q_DEV_A_MIN], "dev_a_max": q[:, CL.Q_DEV_A_MAX], "T": q[:, CL.Q_T]}


def _ff_nonzero(state: np.ndarray) -> np.ndarray:
    """Forward-fill the last nonzero value along axis 1 (zeros before the first stay 0)."""
    n = state.shape[1]
    idx = np.where(state != 0, np.arange(n)[None, :], 0)
    np.maximum.accumulate(idx, axis=1, out=idx)
    filled = np.take_along_axis(state, idx, axis=1)
    return filled


def compute_metrics(offset: np.ndarray, distance: np.ndarray, wanted, cycle_time: float, k_on: int,
                    limits: dict | None = None, *, skip: float = 0.0, band: float = 0.05,
                    hold: float = 0.1, f_osc: float = 20.0,
                    overshoot_window: float = 0.25) -> dict[str, np.ndarray]:
    """The figures of the module docstring, each an array of length ``n_sets``; plus ``failed``.

    ``wanted``: scalar or per-cycle array (:func:`wanted_distance`); ``limits``: from
    :func:`limits_from_packed` (without: ``sat_share`` is NaN).

    With numba installed, one compiled pass over the traces
    (:func:`distctrl.batch.metrics_kernel.chunk_metrics`) computes them, bit for bit equal to
    :func:`reference_metrics` (numpy, the definition; used without numba).
    """
    if not numba_available():
        return reference_metrics(offset, distance, wanted, cycle_time, k_on, limits, skip=skip, band=band,
                                 hold=hold, f_osc=f_osc, overshoot_window=overshoot_window)
    from ..batch import metrics_kernel as MK   # numba (the [batch] extra) loads only when a batch runs

    offset = np.ascontiguousarray(np.atleast_2d(np.asarray(offset, dtype=np.float64)))
    distance = np.ascontiguousarray(np.atleast_2d(np.asarray(distance, dtype=np.float64)))
    n_sets, n = distance.shape
    T = float(cycle_time)
    k0 = min(n, int(k_on) + int(round(skip / T)))
    # np.array copies: a read-only view (broadcast_to) is another numba type, which the warm-up did not
    # compile (tests/batch/test_warm.py)
    wanted = np.array(np.broadcast_to(np.asarray(wanted, dtype=np.float64), (n,)), order="C") \
        if np.ndim(wanted) else np.full(n, float(wanted))
    m = n - k0
    if m == 0 or offset.shape != distance.shape:
        return reference_metrics(offset, distance, wanted, cycle_time, k_on, limits, skip=skip, band=band,
                                 hold=hold, f_osc=f_osc, overshoot_window=overshoot_window)
    h = max(1, int(round(hold / T)))
    ow = max(1, int(round(overshoot_window / T)))
    if limits is None:
        z = np.zeros(n_sets)
        lim = (False, z, z, z, z, np.zeros(n_sets, np.bool_), z, z, z)
    else:
        col = [np.array(np.broadcast_to(np.asarray(limits[k], dtype=np.float64), (n_sets,)), order="C")
               for k in ("v_lim", "a_lim", "w_v", "w_a")]
        ad = np.array(np.broadcast_to(np.asarray(limits["adaptive"], dtype=np.bool_), (n_sets,)), order="C")
        rest = [np.array(np.broadcast_to(np.asarray(limits[k], dtype=np.float64), (n_sets,)), order="C")
                for k in ("a_min", "dev_a_min", "dev_a_max")]
        lim = (True, *col, ad, *rest)
    fig = np.empty((n_sets, MK.N_FIG))
    ex, ox, spec, a, ospec, oa = _scratch(n_sets, m)
    MK.chunk_metrics(offset, distance, wanted, k0, int(k_on), T, float(band), h, ow, *lim, fig, ex, ox)
    cnt = fig[:, MK.F_CNT].astype(np.int64)
    out: dict[str, np.ndarray] = {"failed": fig[:, MK.F_FAILED] != 0.0}
    for name, c in (("rms_error", MK.F_RMS), ("max_error", MK.F_MAX), ("overshoot", MK.F_OVERSHOOT),
                    ("osc_index", MK.F_OSC)):
        out[name] = fig[:, c].copy()
    w = _hf_weights(m, T, f_osc)
    if n_sets >= _FFT_SPLIT_ROWS and MK.thread_count() >= 2:
        # the two transforms at once, the offset's in a second thread (numpy's FFT releases the GIL): they were
        # a third of a sweep's time beside the kernel, on one core; numba's thread count is the budget (1 on a
        # single-threaded cluster worker: no second thread there)
        offset_part = _fft_pool().submit(_hf_rms, ox, w, m, cnt, ospec, oa)
        out["hf_rms"] = _hf_rms(ex, w, m, cnt, spec, a)
        out["offset_hf_rms"] = offset_part.result()
    else:
        out["hf_rms"] = _hf_rms(ex, w, m, cnt, spec, a)
        out["offset_hf_rms"] = _hf_rms(ox, w, m, cnt, ospec, oa)
    out["settle_time_50um"] = fig[:, MK.F_SETTLE].copy()
    out["sat_share"] = fig[:, MK.F_SAT].copy()
    return out


def _hf_weights(m: int, T: float, f_osc: float) -> np.ndarray:
    """One-sided spectrum weights of the part above ``f_osc`` (Parseval)."""
    freqs = np.fft.rfftfreq(m, T)
    w = np.where(freqs >= f_osc, 2.0, 0.0)
    w[freqs == 0] = 0.0
    if m % 2 == 0:
        w[-1] = np.where(freqs[-1] >= f_osc, 1.0, 0.0)
    return w


_SCRATCH = threading.local()

#: below this many rows the two FFTs run one after the other (a thread's hand-over costs more than it saves)
_FFT_SPLIT_ROWS = 16
_FFT_POOL: list = []
_FFT_POOL_LOCK = threading.Lock()


def _fft_pool() -> ThreadPoolExecutor:
    """The one thread that transforms the offset while the calling thread transforms the error (made on first
    use; shared by the calling threads of this process, a task waits for it only when two pass at once)."""
    with _FFT_POOL_LOCK:
        if not _FFT_POOL:
            _FFT_POOL.append(ThreadPoolExecutor(1, thread_name_prefix="distctrl-fft"))
        return _FFT_POOL[0]


def _scratch(n_sets: int, m: int):
    """The pass's work arrays (FFT inputs ``ex``, ``ox``; the spectrum and its power of each) for this shape:
    the first ``n_sets`` rows of arrays reused from call to call in this thread, made again only for a longer
    window or more rows. A sweep's blocks have one window and at most one number of rows, but a chunk's last
    block is shorter: arrays made to its exact shape were made again twice per chunk, and fresh arrays of
    megabytes cost page faults (allocating them took about as long as the FFTs)."""
    got = getattr(_SCRATCH, "arrays", None)
    if got is None or got[0][1] != m or got[0][0] < n_sets:
        k = m // 2 + 1
        got = _SCRATCH.arrays = ((n_sets, m), (np.empty((n_sets, m)), np.empty((n_sets, m)),
                                               np.empty((n_sets, k), dtype=np.complex128), np.empty((n_sets, k)),
                                               np.empty((n_sets, k), dtype=np.complex128), np.empty((n_sets, k))))
    return tuple(a[:n_sets] for a in got[1])


def _hf_rms(x: np.ndarray, w: np.ndarray, m: int, cnt: np.ndarray, spec=None, a=None) -> np.ndarray:
    """RMS of the part of the rows of ``x`` (mean-free, zero where not valid) above ``f_osc`` (``spec``,
    ``a``: work arrays for the spectrum and its power, or None)."""
    spec = np.fft.rfft(x, axis=1, out=spec)
    a = np.abs(spec, out=a)
    np.square(a, out=a)                      # (np.abs(spec) ** 2 * w).sum(axis=1), without the temporaries
    a *= w[None, :]
    power = a.sum(axis=1) / (m * m)
    return np.sqrt(power * m / np.maximum(cnt, 1))


def reference_metrics(offset: np.ndarray, distance: np.ndarray, wanted, cycle_time: float, k_on: int,
                      limits: dict | None = None, *, skip: float = 0.0, band: float = 0.05,
                      hold: float = 0.1, f_osc: float = 20.0,
                      overshoot_window: float = 0.25) -> dict[str, np.ndarray]:
    """:func:`compute_metrics` in numpy over 2-D arrays: the definition (and the path without numba)."""
    offset = np.atleast_2d(np.asarray(offset, dtype=np.float64))
    distance = np.atleast_2d(np.asarray(distance, dtype=np.float64))
    n_sets, n = distance.shape
    T = float(cycle_time)
    k0 = min(n, int(k_on) + int(round(skip / T)))
    wanted = np.broadcast_to(np.asarray(wanted, dtype=np.float64), (n,)) if np.ndim(wanted) else \
        np.full(n, float(wanted))
    e = distance[:, k0:] - wanted[None, k0:]
    m = e.shape[1]
    out: dict[str, np.ndarray] = {}
    failed = np.isnan(e).any(axis=1) if m else np.zeros(n_sets, bool)
    out["failed"] = failed
    if m == 0:
        for name in METRIC_NAMES:
            out[name] = np.full(n_sets, np.nan)
        return out
    valid = ~np.isnan(e)
    cnt = valid.sum(axis=1)
    ez = np.where(valid, e, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        out["rms_error"] = np.where(cnt > 0, np.sqrt((ez * ez).sum(axis=1) / np.maximum(cnt, 1)), np.nan)
    absz = np.abs(ez)
    out["max_error"] = np.where(cnt > 0, absz.max(axis=1), np.nan)

    # overshoot: opposite-side excursion after the largest peak
    kpk = absz.argmax(axis=1)
    sgn = np.sign(ez[np.arange(n_sets), kpk])
    ow = max(1, int(round(overshoot_window / T)))
    after = (np.arange(m)[None, :] >= kpk[:, None]) & (np.arange(m)[None, :] < kpk[:, None] + ow)
    opp = np.where(after & valid, -sgn[:, None] * ez, -np.inf)
    out["overshoot"] = np.maximum(0.0, opp.max(axis=1))

    # ringing rate with hysteresis
    state = np.where(ez > band, 1, np.where(ez < -band, -1, 0)).astype(np.int8)
    filled = _ff_nonzero(state)
    changes = ((filled[:, 1:] != filled[:, :-1]) & (filled[:, :-1] != 0)).sum(axis=1)
    out["osc_index"] = changes / np.maximum(cnt * T, T)

    # high-frequency RMS (FFT, Parseval): NaN tails are zeroed, which only failed sets have
    spec = np.fft.rfft(ez - (ez.sum(axis=1) / np.maximum(cnt, 1))[:, None] * valid, axis=1)
    freqs = np.fft.rfftfreq(m, T)
    w = np.where(freqs >= f_osc, 2.0, 0.0)
    w[freqs == 0] = 0.0
    if m % 2 == 0:
        w[-1] = np.where(freqs[-1] >= f_osc, 1.0, 0.0)
    power = (np.abs(spec) ** 2 * w[None, :]).sum(axis=1) / (m * m)
    out["hf_rms"] = np.sqrt(power * m / np.maximum(cnt, 1))

    # high-frequency RMS of the offset: the axis's own chatter
    oz = np.where(valid, offset[:, k0:], 0.0)
    ospec = np.fft.rfft(oz - (oz.sum(axis=1) / np.maximum(cnt, 1))[:, None] * valid, axis=1)
    opower = (np.abs(ospec) ** 2 * w[None, :]).sum(axis=1) / (m * m)
    out["offset_hf_rms"] = np.sqrt(opower * m / np.maximum(cnt, 1))

    # settling: first cycle from which |e| <= band holds for `hold` seconds
    h = max(1, int(round(hold / T)))
    inb = (valid & (absz <= band)).astype(np.int32)
    cs = np.concatenate([np.zeros((n_sets, 1), np.int64), np.cumsum(inb, axis=1)], axis=1)
    if m >= h:
        settled = (cs[:, h:] - cs[:, :m - h + 1]) == h          # e[k:k+h] all in band, k = 0..m-h
    else:
        settled = np.zeros((n_sets, 1), bool)
    has = settled.any(axis=1)
    first = settled.argmax(axis=1)
    out["settle_time_50um"] = np.where(has, (k0 - int(k_on) + first) * T, np.nan)

    # limiter saturation share
    if limits is None:
        out["sat_share"] = np.full(n_sets, np.nan)
    else:
        o = offset[:, max(k0 - 2, 0):]
        v = np.diff(o, axis=1) / T
        a = np.diff(v, axis=1) / T
        v = v[:, -a.shape[1]:] if a.shape[1] else v[:, :0]
        lim = {k: np.asarray(val)[:, None] for k, val in limits.items()}
        a_lim = np.broadcast_to(lim["a_lim"], a.shape).astype(np.float64)
        if np.any(limits["adaptive"]):
            ev = np.abs(ez[:, -a.shape[1]:]) if a.shape[1] else absz[:, :0]
            span = np.maximum(lim["dev_a_max"] - lim["dev_a_min"], 1e-12)
            frac = np.clip((ev - lim["dev_a_min"]) / span, 0.0, 1.0)
            ramp = lim["a_min"] + (lim["a_lim"] - lim["a_min"]) * frac
            a_lim = np.where(lim["adaptive"], ramp, a_lim)
        down = v < 0
        v_l = np.where(down, lim["v_lim"] * lim["w_v"], lim["v_lim"])
        a_l = np.where(down, a_lim * lim["w_a"], a_lim)
        with np.errstate(invalid="ignore"):
            sat = (np.abs(v) >= (1 - _TOL) * v_l) | (np.abs(a) >= (1 - _TOL) * a_l)
        sat &= ~np.isnan(v) & ~np.isnan(a)
        out["sat_share"] = sat.sum(axis=1) / np.maximum(cnt, 1)
    return out


#: default weights of the chatter terms in :func:`cost`: ``sat_weight`` mm per unit of ``sat_share`` (a set at
#: the limiter a third of the time pays 0.017 mm, several times what separates the best sets of a sweep),
#: ``chatter_weight`` per mm of ``offset_hf_rms``
SAT_WEIGHT = 0.05
CHATTER_WEIGHT = 0.25


def cost(metrics: dict, osc_weight: float = 1.0, overshoot_weight: float = 0.0, *,
         sat_weight: float = SAT_WEIGHT, chatter_weight: float = CHATTER_WEIGHT) -> np.ndarray:
    """The tuner's objective (mm, smaller is better)::

        rms_error + osc_weight * hf_rms + overshoot_weight * overshoot
                  + sat_weight * sat_share + chatter_weight * offset_hf_rms

    The last two terms penalise chatter: time at the limiter's velocity / acceleration limit and
    high-frequency motion of the offset, which the distance error alone rewards when the axis follows
    the probe noise. ``inf`` for sets that failed (controller error) or have NaN; a NaN ``sat_share``
    (no limits known) or a missing chatter metric adds nothing."""
    c = np.asarray(metrics["rms_error"], dtype=np.float64) + osc_weight * np.asarray(metrics["hf_rms"])
    if overshoot_weight:
        c = c + overshoot_weight * np.asarray(metrics["overshoot"])
    if sat_weight and "sat_share" in metrics:
        sat = np.asarray(metrics["sat_share"], dtype=np.float64)
        c = c + sat_weight * np.where(np.isnan(sat), 0.0, sat)
    if chatter_weight and "offset_hf_rms" in metrics:
        c = c + chatter_weight * np.asarray(metrics["offset_hf_rms"], dtype=np.float64)
    bad = np.asarray(metrics["failed"], dtype=bool) | ~np.isfinite(c)
    return np.where(bad, np.inf, c)
