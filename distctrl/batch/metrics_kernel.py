"""The sweep's quality figures in one compiled pass over a chunk's traces (issue 27).

:func:`distctrl.tuning.metrics.compute_metrics` defines the figures with numpy over 2-D arrays; a
chunk of 256 sets x 2 000 cycles went through some forty temporary arrays of that size, which cost
more than the kernel that produced the traces. :func:`chunk_metrics` computes the same numbers, bit
for bit, in one loop per set:

* sums are numpy's: ``np.add.reduce`` along a contiguous row starts from 0.0 and adds the row by
  pairwise summation (blocks of at most 128 values summed in eight interleaved accumulators,
  :func:`pairwise_sum`); the tests compare the result with numpy's over thousands of random rows;
* every other figure is a count, a maximum or one elementwise expression, written in numpy's order
  of operations (no fastmath, so no reassociation and no fused multiply-add);
* the loops index 1-D views from 0 (``b = a[lo:lo + n]; b[i]``) rather than ``a[lo + i]``: numba handles
  a negative index of unknown sign with a wraparound test per access, which kept LLVM from vectorising
  them (the pass over 10^4 sets on one thread: 0.130 -> 0.094 s, the same bits);
* the two FFT-based figures (``hf_rms``, ``offset_hf_rms``) keep numpy's FFT: the pass writes their
  inputs (the mean-free error and offset of the window) and ``compute_metrics`` transforms them.

Importing this module imports numba.
"""
from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

__all__ = ["pairwise_sum", "chunk_metrics", "thread_count", "N_FIG", "F_FAILED", "F_CNT", "F_RMS", "F_MAX",
           "F_OVERSHOOT", "F_OSC", "F_SETTLE", "F_SAT"]

#: columns of :func:`chunk_metrics`' figure array
F_FAILED, F_CNT, F_RMS, F_MAX, F_OVERSHOOT, F_OSC, F_SETTLE, F_SAT = range(8)
N_FIG = 8

_PW_BLOCK = 128          # numpy's PW_BLOCKSIZE


def thread_count() -> int:
    """numba's thread count in this thread (:func:`distctrl.batch.closed_loop.numba_threads` sets it): the
    metrics' budget of threads."""
    return numba.get_num_threads()


@njit(cache=True, nogil=True)
def _pairwise_leaf(a, lo, n):
    """numpy's ``pairwise_sum`` for ``n <= 128``: sequential below 8, else 8 interleaved accumulators."""
    b = a[lo:lo + n]                      # indices from 0: no wraparound test (module docstring)
    if n < 8:
        res = 0.0
        for i in range(n):
            res += b[i]
        return res
    r0 = b[0]
    r1 = b[1]
    r2 = b[2]
    r3 = b[3]
    r4 = b[4]
    r5 = b[5]
    r6 = b[6]
    r7 = b[7]
    for q in range(1, n // 8):
        i = 8 * q
        r0 += b[i]
        r1 += b[i + 1]
        r2 += b[i + 2]
        r3 += b[i + 3]
        r4 += b[i + 4]
        r5 += b[i + 5]
        r6 += b[i + 6]
        r7 += b[i + 7]
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    for i in range(n - n % 8, n):
        res += b[i]
    return res


@njit(cache=True, nogil=True)
def pairwise_sum(a, lo, n):
    """``a[lo:lo+n]`` summed as numpy's pairwise summation does (``@TYPE@_pairwise_sum``): above 128
    values, the sum of the halves (the first rounded down to a multiple of 8). numpy recurses; this walks
    the same tree with an explicit stack (a recursive function loaded from numba's disk cache crashes)."""
    if n <= _PW_BLOCK:
        return _pairwise_leaf(a, lo, n)
    f_lo = np.empty(64, np.int64)          # depth <= log2(n / 64): 64 frames hold any array
    f_n = np.empty(64, np.int64)
    f_stage = np.empty(64, np.int64)       # 0: nothing summed yet, 1: left half under way, 2: right half
    f_left = np.empty(64)
    sp = 0
    f_lo[0] = lo
    f_n[0] = n
    f_stage[0] = 0
    ret = 0.0
    have = False                           # ret is the value of a child of frame sp
    while True:
        fl = f_lo[sp]
        k = f_n[sp]
        n2 = k // 2
        n2 -= n2 % 8
        if not have:                       # start the left half
            f_stage[sp] = 1
            if n2 <= _PW_BLOCK:
                ret = _pairwise_leaf(a, fl, n2)
                have = True
            else:
                sp += 1
                f_lo[sp] = fl
                f_n[sp] = n2
                f_stage[sp] = 0
        elif f_stage[sp] == 1:             # left half done: start the right half
            f_left[sp] = ret
            f_stage[sp] = 2
            if k - n2 <= _PW_BLOCK:
                ret = _pairwise_leaf(a, fl + n2, k - n2)
            else:
                have = False
                sp += 1
                f_lo[sp] = fl + n2
                f_n[sp] = k - n2
                f_stage[sp] = 0
        else:                              # both halves done
            ret = f_left[sp] + ret
            if sp == 0:
                return ret
            sp -= 1


@njit(cache=True, nogil=True)
def row_sum(a):
    """``a.sum()`` of a 1-D float64 array as numpy computes it (0.0 + the pairwise sum)."""
    return 0.0 + pairwise_sum(a, 0, a.size)


@njit(cache=True, nogil=True)
def _sat_count(o, s, n_a, T, ez, k0, ramp, dev_lo, span, acc_lo, acc_hi, w_acc, v_up, v_down, tol, vel):
    """The cycles of a set at the velocity or the acceleration limit, from its offset ``o`` (the cycles
    ``s + 2 ..``), in the numpy definition's order of operations. The velocities first (``np.diff / T``, into
    ``vel``), then counts without branches (selects), so that both loops vectorise (the pass over 10^4 sets
    on one thread: 0.142 -> 0.129 s; the check had been a quarter of it, a division-bound scalar loop)."""
    ov = o[s:s + n_a + 2]
    for j in range(n_a + 1):
        vel[j] = (ov[j + 1] - ov[j]) / T
    nsat = 0
    ev = ez[s + 2 - k0:]
    if ramp:                                 # adaptive acceleration: the limit follows |e| (a_min .. a_lim)
        for j in range(n_a):
            v = vel[j + 1]
            acc = (v - vel[j]) / T
            frac = (abs(ev[j]) - dev_lo) / span
            frac = min(max(frac, 0.0), 1.0)
            al = acc_lo + (acc_hi - acc_lo) * frac
            down = v < 0
            vl = v_down if down else v_up
            al = al * w_acc if down else al
            nsat += ((abs(v) >= vl) | (abs(acc) >= tol * al)) & (v == v) & (acc == acc)
    else:
        al_down = acc_hi * w_acc
        for j in range(n_a):
            v = vel[j + 1]
            acc = (v - vel[j]) / T
            down = v < 0
            vl = v_down if down else v_up
            al = al_down if down else acc_hi
            nsat += ((abs(v) >= vl) | (abs(acc) >= tol * al)) & (v == v) & (acc == acc)
    return nsat


@njit(cache=True, nogil=True, parallel=True)
def chunk_metrics(offset, distance, wanted, k0, k_on, T, band, h, ow, has_limits, v_lim, a_lim, w_v, w_a,
                  adaptive, a_min, dev_a_min, dev_a_max, fig, ex, ox):
    """The figures of :func:`distctrl.tuning.metrics.compute_metrics` but the FFT ones, for every row.

    ``offset``, ``distance``: ``(n_sets, n)``; ``wanted``: ``(n,)``; ``k0``: first cycle of the window
    (``m = n - k0 >= 1`` cycles); ``h``, ``ow``: the hold and overshoot windows in cycles; the limits
    per set (ignored without ``has_limits``: ``sat_share`` NaN). Writes ``fig`` ``(n_sets, N_FIG)``
    and the FFT inputs ``ex`` (error) and ``ox`` (offset), ``(n_sets, m)``: zero where the error is
    NaN, minus the window's mean where it is not. The rows run in parallel over numba's threads (each row's
    numbers do not depend on the others).

    One pass over the window gathers the error and offset (into ``ex``/``ox``, which hold them until the
    means are removed), the count, the largest ``|e|``, the ringing count and the settling cycle: the
    traces are read once and the window walked once instead of four times, which halved the pass's time."""
    n_sets, n = distance.shape
    m = n - k0
    tol = 1.0 - 1e-3
    s = max(k0 - 2, 0)
    n_a = n - s - 2                      # length of the acceleration series (np.diff twice)
    for i in prange(n_sets):             # the sets in parallel (numba's threads): each row is its own
        ez = ex[i]                       # the error, zero where NaN (the mean is removed at the end)
        oz = ox[i]                       # the offset, zero where the error is NaN
        vb = np.empty(m, dtype=np.bool_)
        sq = np.empty(m)
        cnt = 0
        failed = False
        kpk = 0                          # largest |e| and where it is first reached
        amax = -1.0
        last = 0                         # ringing with hysteresis: the last side left, the changes
        changes = 0
        run = 0                          # settling: cycles in the band so far, the first cycle of h of them
        first = -1
        drow = distance[i, k0:]
        orow = offset[i, k0:]
        wrow = wanted[k0:]
        for j in range(m):
            e = drow[j] - wrow[j]
            if np.isnan(e):
                failed = True
                vb[j] = False
                e = 0.0
                oz[j] = 0.0
                run = 0
            else:
                vb[j] = True
                cnt += 1
                oz[j] = orow[j]
                if first < 0:
                    if abs(e) <= band:
                        run += 1
                        if run >= h:
                            first = j - h + 1
                    else:
                        run = 0
            ez[j] = e
            sq[j] = e * e
            a = abs(e)
            if a > amax:
                amax = a
                kpk = j
            st = 1 if e > band else (-1 if e < -band else 0)
            if st != 0:
                if last != 0 and st != last:
                    changes += 1
                last = st
        c1 = max(cnt, 1)
        fig[i, F_FAILED] = 1.0 if failed else 0.0
        fig[i, F_CNT] = cnt
        fig[i, F_RMS] = np.sqrt(row_sum(sq) / c1) if cnt > 0 else np.nan
        fig[i, F_MAX] = amax if cnt > 0 else np.nan
        # overshoot: opposite-side excursion after the largest peak
        sgn = np.sign(ez[kpk])
        opp = -np.inf
        for j in range(kpk, min(m, kpk + ow)):
            if vb[j]:
                x = -sgn * ez[j]
                if x > opp:
                    opp = x
        fig[i, F_OVERSHOOT] = opp if opp >= 0.0 else 0.0      # np.maximum(0.0, -0.0) is -0.0
        fig[i, F_OSC] = changes / max(cnt * T, T)
        fig[i, F_SETTLE] = (k0 - k_on + first) * T if first >= 0 else np.nan
        # limiter saturation share (before the means are removed: the adaptive ramp reads |e|)
        nsat = 0
        if has_limits and n_a > 0:
            nsat = _sat_count(offset[i], s, n_a, T, ez, k0, adaptive[i], dev_a_min[i],
                              max(dev_a_max[i] - dev_a_min[i], 1e-12), a_min[i], a_lim[i], w_a[i],
                              tol * v_lim[i], tol * (v_lim[i] * w_v[i]), tol, np.empty(n_a + 1))
        fig[i, F_SAT] = nsat / c1 if has_limits else np.nan
        # the FFT inputs: mean removed where valid
        me = row_sum(ez) / c1
        mo = row_sum(oz) / c1
        for j in range(m):
            w = 1.0 if vb[j] else 0.0
            ez[j] = ez[j] - me * w
            oz[j] = oz[j] - mo * w
