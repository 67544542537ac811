"""The Butterworth low-pass of the LOWPASS filter type in numpy, for many designs at once (issue 27).

What ``scipy.signal.butter(order, fg, fs=1/T, output="sos")`` and ``sosfilt_zi`` compute for a
digital Butterworth low-pass, written for this one case and in the same arithmetic, so that the
coefficients are bit for bit those of scipy (the tests compare them over every order and the whole
cut-off grid the tuner uses, and over random cut-offs). It does not import scipy: importing
``scipy.signal`` took seconds, more than a small sweep, and one design through scipy about 1 ms.

The steps (the standard design: analog prototype, pre-warped cut-off, bilinear transform):

1. analog prototype: poles ``-exp(j pi m / 2N)``, ``m = -N+1, -N+3, ..., N-1``, no zeros, gain 1;
2. cut-off pre-warped, ``wo = 4 tan(pi Wn / 2)`` with ``Wn = fg / (fs/2)``; poles scaled by ``wo``,
   gain ``wo**N``;
3. bilinear transform (``fs = 2``): poles ``(4 + p) / (4 - p)``, N zeros at -1, gain
   ``wo**N * Re(1 / prod(4 - p))``;
4. second-order sections: the pole closest to the unit circle last, each pole paired with its
   conjugate (a real pole with the other real one, or with a pole at 0 for odd N), the zeros at -1
   (and 0) nearest to it; the gain in the first section;
5. the sections' initial states for a unit step (``sosfilt_zi``), each scaled by the DC gain of the
   sections before it.

Steps 2, 3 and 5 run over all designs of an order at once; the pairing (4) needs a few comparisons
per design.
"""
from __future__ import annotations

import numpy as np

__all__ = ["butter_lowpass", "MAX_ORDER"]

MAX_ORDER = 6

_PROTO: dict[int, np.ndarray] = {}


def _prototype(order: int) -> np.ndarray:
    p = _PROTO.get(order)
    if p is None:
        m = np.arange(-order + 1, order, 2, dtype=np.float64)
        p = -np.exp(1j * np.pi * m / (2 * order))       # the middle value (odd order) is exactly real
        _PROTO[order] = p
    return p


def _is_real(x) -> bool:
    return x.imag == 0


def _worst(p: np.ndarray) -> int:
    """Index of the pole closest to the unit circle (the first of equals)."""
    return int(np.argmin(np.abs(1 - np.abs(p))))


def _nearest(zeros: list, p1) -> int:
    """Index into ``zeros`` (all real here) of the zero nearest to ``p1`` (argsort's first)."""
    return int(np.argsort(np.abs(np.asarray(zeros, dtype=np.float64) - p1))[0])


def _sections(order: int, poles: np.ndarray) -> list[tuple[list, list]]:
    """The pole and zero pairs of the sections, first section first."""
    # the zeros: `order` at -1 (plus one at 0 with a pole at 0 for an odd order), real, sorted
    zeros = [-1.0] * order
    p = poles
    if order % 2:
        zeros.append(0.0)
        p = np.concatenate((p, [0.0]))
    # conjugate pairs as one pole (positive imaginary part), sorted by real part, then the real poles
    cplx = p[p.imag > 0]
    cplx = cplx[np.lexsort((np.abs(cplx.imag), cplx.real))]
    real = np.sort(p[p.imag == 0].real)
    p = np.concatenate((cplx, real))
    zeros = np.sort(np.asarray(zeros))
    zl = list(zeros)
    n_sections = (order + 1) // 2
    out: list = [None] * n_sections
    for si in range(n_sections - 1, -1, -1):
        i1 = _worst(p)
        p1 = p[i1]
        p = np.delete(p, i1)
        reals_left = int(np.sum(p.imag == 0))
        if _is_real(p1) and reals_left == 0:
            j = _nearest(zl, p1)
            z1 = zl.pop(j)
            out[si] = ([z1, 0.0], [p1, 0.0], True)
            continue
        if _is_real(p1):
            ridx = np.flatnonzero(p.imag == 0)
            i2 = int(ridx[_worst(p[ridx])])
            p2 = p[i2]
            p = np.delete(p, i2)
        else:
            p2 = np.conj(p1)
        j = _nearest(zl, p1)
        z1 = zl.pop(j)
        if zl:
            j = _nearest(zl, p1)
            z2 = zl.pop(j)
            out[si] = ([z1, z2], [p1, p2], False)
        else:                                   # pragma: no cover - a Butterworth low-pass has as many zeros
            out[si] = ([z1], [p1, p2], False)
    return out


def _poly(roots) -> np.ndarray:
    """Coefficients of prod (x - r) by successive convolution (real when the roots are conjugates)."""
    r = np.asarray(roots)
    a = np.ones((1,), dtype=r.dtype)
    one = np.ones_like(r[0])
    for zero in r:
        a = np.convolve(a, np.stack((one, -zero)), mode="full")
    if np.iscomplexobj(a):
        roots_c = np.asarray(r, dtype=np.complex128)
        if np.all(np.sort(np.imag(roots_c)) == np.sort(np.imag(np.conj(roots_c)))):
            a = np.asarray(np.real(a), copy=True)
    return a


def butter_lowpass(order: int, fg, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Second-order sections and their step initial states of the digital Butterworth low-pass of
    ``order`` (1..6) at the cut-offs ``fg`` (Hz, array of K, each in (0, fs/2)) at sampling rate ``fs``
    (Hz): ``sos`` (K, n_sections, 6) and ``zi`` (K, n_sections, 2), bit for bit
    ``scipy.signal.butter(order, fg, fs=fs, output="sos")`` and ``scipy.signal.sosfilt_zi`` of it."""
    order = int(order)
    fg = np.atleast_1d(np.asarray(fg, dtype=np.float64))
    fs = float(fs)
    if not 1 <= order <= MAX_ORDER:
        raise ValueError(f"Butterworth order {order}: 1..{MAX_ORDER}")
    wn = fg / (fs / 2)
    if np.any(wn <= 0) or np.any(wn >= 1):
        raise ValueError(f"cut-off must be 0 < fg < fs/2 (fs={fs})")
    k_n = len(fg)
    proto = _prototype(order)
    warped = 2 * 2.0 * np.tan(np.pi * wn / 2.0)
    # lp2lp: poles scaled by wo (a python float times a complex array: complex multiplication)
    p_lp = np.empty((k_n, order), dtype=np.complex128)
    k_lp = np.empty(k_n)
    for i in range(k_n):
        wo = float(warped[i])
        p_lp[i] = wo * proto
        k_lp[i] = 1.0 * wo ** order
    # bilinear transform, fs = 2
    p_z = (4.0 + p_lp) / (4.0 - p_lp)
    den = np.array([np.prod(4.0 - p_lp[i]) for i in range(k_n)])
    k_z = k_lp * np.real(np.float64(1.0) / den)
    n_sec = (order + 1) // 2
    sos = np.zeros((k_n, n_sec, 6))
    for i in range(k_n):
        for si, (zz, pp, _) in enumerate(_sections(order, p_z[i])):
            b = np.asarray(1.0) * _poly(np.asarray(zz, dtype=np.float64))
            a = _poly(np.asarray(pp))
            sos[i, si, 3 - len(b):3] = b
            sos[i, si, 6 - len(a):6] = np.real(a) if np.iscomplexobj(a) else a
        sos[i, 0, :3] *= k_z[i]
    zi = _step_states(sos)
    return sos, zi


def _step_states(sos: np.ndarray) -> np.ndarray:
    """``sosfilt_zi`` of every design: the states of a unit step in steady state."""
    k_n, n_sec, _ = sos.shape
    b = sos[:, :, :3]
    a = sos[:, :, 3:]
    # zi = A zi + B with A the transposed companion matrix of a (a[0] = 1 here)
    m = np.empty((k_n, n_sec, 2, 2))
    m[..., 0, 0] = 1.0 - (-a[..., 1] / (1.0 * a[..., 0]))
    m[..., 0, 1] = 0.0 - 1.0
    m[..., 1, 0] = 0.0 - (-a[..., 2] / (1.0 * a[..., 0]))
    m[..., 1, 1] = 1.0 - 0.0
    rhs = b[..., 1:] - a[..., 1:] * b[..., :1]
    zi = np.linalg.solve(m.reshape(-1, 2, 2), rhs.reshape(-1, 2)[..., None])[..., 0].reshape(k_n, n_sec, 2)
    scale = np.ones(k_n)
    for s in range(n_sec):
        zi[:, s] = scale[:, None] * zi[:, s]
        scale = scale * (b[:, s].sum(axis=1) / a[:, s].sum(axis=1))
    return zi
