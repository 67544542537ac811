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


def _worst(p: list) -> int:
    """Index of the pole closest to the unit circle (the first of equals; abs of a complex is hypot, as in
    numpy)."""
    d = [abs(1 - abs(z)) for z in p]
    return d.index(min(d))


def _nearest(zeros: list, p1: complex) -> int:
    """Index into ``zeros`` (all real here) of the zero nearest to ``p1`` (the first of equals)."""
    d = [abs(complex(z) - p1) for z in zeros]
    return d.index(min(d))


def _sections(order: int, poles) -> list[tuple[list, list]]:
    """The zero and pole pairs of the sections, first section first (plain Python numbers: a handful of
    comparisons per design)."""
    p = [complex(z) for z in poles]
    zl = [-1.0] * order
    if order % 2:                                  # odd: a pole and a zero at 0 make the pairs even
        zl.append(0.0)
        p.append(0j)
    zl.sort()
    # conjugate pairs as one pole (positive imaginary part), sorted by real part, then the real poles
    cplx = sorted((z for z in p if z.imag > 0), key=lambda z: (z.real, abs(z.imag)))
    real = sorted(z.real for z in p if z.imag == 0)
    p = cplx + [complex(r, 0.0) for r in real]
    n_sections = (order + 1) // 2
    out: list = [None] * n_sections
    for si in range(n_sections - 1, -1, -1):
        p1 = p.pop(_worst(p))
        reals = [i for i, z in enumerate(p) if z.imag == 0]
        if p1.imag == 0 and not reals:
            z1 = zl.pop(_nearest(zl, p1))
            out[si] = ((z1, 0.0), (p1, 0j))
            continue
        if p1.imag == 0:
            p2 = p.pop(reals[_worst([p[i] for i in reals])])
        else:
            p2 = p1.conjugate()
        z1 = zl.pop(_nearest(zl, p1))
        z2 = zl.pop(_nearest(zl, p1))             # a Butterworth low-pass has as many zeros as poles
        out[si] = ((z1, z2), (p1, p2))
    return out


_ZPOLY: dict = {}


def _zeros_poly(zeros: tuple) -> np.ndarray:
    """The numerator of a section (its zeros are -1 or 0: a handful of distinct tuples, each computed once)."""
    b = _ZPOLY.get(zeros)
    if b is None:
        b = _ZPOLY[zeros] = np.asarray(1.0) * _poly(np.asarray(zeros, dtype=np.float64))
    return b


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


def _checked_prototype(order, fg, fs):
    """The arguments checked and converted, the analog prototype's poles and the pre-warped cut-offs
    (bilinear transform with fs = 2: ``4 tan(pi wn / 2)``), as scipy.signal.butter computes them."""
    order = int(order)
    fg = np.atleast_1d(np.asarray(fg, dtype=np.float64))
    fs = float(fs)
    if not 1 <= order <= MAX_ORDER:
        raise ValueError(f"Butterworth order {order}: 1..{MAX_ORDER}")
    wn = fg / (fs / 2)
    if np.any(wn <= 0) or np.any(wn >= 1):
        raise ValueError(f"cut-off must be 0 < fg < fs/2 (fs={fs})")
    return order, fg, fs, _prototype(order), 2 * 2.0 * np.tan(np.pi * wn / 2.0)


def butter_lowpass(order: int, fg, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Second-order sections and their step initial states of the digital Butterworth low-pass of
    ``order`` (1..6) at the cut-offs ``fg`` (Hz, array of K, each in (0, fs/2)) at sampling rate ``fs``
    (Hz): ``sos`` (K, n_sections, 6) and ``zi`` (K, n_sections, 2), bit for bit
    ``scipy.signal.butter(order, fg, fs=fs, output="sos")`` and ``scipy.signal.sosfilt_zi`` of it."""
    order, fg, fs, proto, warped = _checked_prototype(order, fg, fs)
    k_n = len(fg)
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
        for si, (zz, (p1, p2)) in enumerate(_sections(order, p_z[i].tolist())):
            b = _zeros_poly(zz)
            sos[i, si, 3 - len(b):3] = b
            # (x - p1)(x - p2) = x^2 + (-p1 - p2) x + p1 p2: the real parts of the convolution's terms
            sos[i, si, 3] = 1.0
            # (the convolution's dot products start from 0.0: a -0.0 product comes out as 0.0)
            sos[i, si, 4] = 0.0 + ((-p1.real) + (-p2.real))
            sos[i, si, 5] = 0.0 + ((-p1.real) * (-p2.real) - (-p1.imag) * (-p2.imag))
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


def butter_lowpass_many(order: int, fg, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`butter_lowpass` with the pairing of step 4 done over all designs at once as well (no Python
    per design but a power per design): the same numbers bit for bit (tests/control/test_butter.py
    compares them over thousands of random orders, cut-offs and sampling rates).

    The pairing of :func:`_sections`, over arrays: the poles are listed as there (the upper half-plane
    poles sorted by real part and |imag|, then the real ones, with a pole at 0 for an odd order); taking
    the pole closest to the unit circle first, again and again, is the stable sort of that list by the
    distance; a real pole takes the other real one (there are exactly two or none), a complex one its
    conjugate. The zeros are -1 (and 0 for an odd order): a section takes the 0 while it is left and
    strictly nearer to its pole than -1 (the -1 come first in the list, so a tie takes -1), or when no -1
    is left."""
    order, fg, fs, proto, warped = _checked_prototype(order, fg, fs)
    k_n = len(fg)
    p_lp = warped[:, None] * proto[None, :]
    # a Python power per design: numpy's vectorised power is not libm's pow
    k_lp = np.array([1.0 * wo ** order for wo in warped.tolist()])
    p_z = (4.0 + p_lp) / (4.0 - p_lp)
    den = np.prod(4.0 - p_lp, axis=1)              # (numpy's reduction: not the same as a loop of products)
    k_z = k_lp * np.real(np.float64(1.0) / den)
    n_sec = (order + 1) // 2
    # the list of _sections: complex representatives (imag > 0) by (real, |imag|), then the reals
    up = np.nonzero(proto.imag > 0)[0]             # the upper half-plane poles (the same for every design)
    cp = p_z[:, up]
    srt = np.lexsort((np.abs(cp.imag), cp.real), axis=-1)
    cp = np.take_along_axis(cp, srt, axis=1)
    lst_re = [cp.real]
    lst_im = [cp.imag]
    if order % 2:
        mid = p_z[:, order // 2].real              # the real pole
        reals = np.sort(np.stack((mid, np.zeros(k_n)), axis=1), axis=1)
        lst_re.append(reals)
        lst_im.append(np.zeros((k_n, 2)))
    re = np.concatenate(lst_re, axis=1)
    im = np.concatenate(lst_im, axis=1)
    n_c = cp.shape[1]
    is_real = np.zeros(re.shape[1], dtype=bool)
    is_real[n_c:] = True
    dist = np.abs(1.0 - np.hypot(re, im))
    pop = np.argsort(dist, axis=1, kind="stable")
    # in pop order, drop the second real (it goes with the first)
    taken = np.zeros(k_n, dtype=np.int64)
    sec_idx = np.empty((k_n, n_sec), dtype=np.int64)
    real_seen = np.zeros(k_n, dtype=bool)
    rows = np.arange(k_n)
    for j in range(re.shape[1]):
        c = pop[:, j]
        r = is_real[c]
        use = ~(r & real_seen)
        real_seen |= r
        sel = rows[use]
        # sections are filled from the last one backwards
        sec_idx[sel, n_sec - 1 - taken[sel]] = c[sel]
        taken[sel] += 1
    assert np.all(taken == n_sec)
    other_real = np.zeros(k_n, dtype=np.int64) + n_c   # for a real section: the other real pole
    sos = np.zeros((k_n, n_sec, 6))
    zero_left = np.full(k_n, bool(order % 2))
    minus_left = np.full(k_n, order, dtype=np.int64)
    polys = {}
    for si in range(n_sec - 1, -1, -1):            # in pop order
        c = sec_idx[:, si]
        p1r = re[rows, c]
        p1i = im[rows, c]
        r = is_real[c]
        o = np.where(c == n_c, n_c + 1, other_real)
        p2r = np.where(r, re[rows, np.minimum(o, re.shape[1] - 1)], p1r)
        p2i = np.where(r, 0.0, -p1i)
        d_minus = np.hypot(-1.0 - p1r, 0.0 - p1i)
        d_zero = np.hypot(0.0 - p1r, 0.0 - p1i)
        zs = []
        for _ in range(2):
            take_zero = zero_left & ((d_zero < d_minus) | (minus_left == 0))
            zs.append(np.where(take_zero, 0.0, -1.0))
            zero_left &= ~take_zero
            minus_left -= ~take_zero
        z1, z2 = zs
        for key in {(a, b) for a, b in zip(z1.tolist(), z2.tolist())}:
            if key not in polys:
                polys[key] = _zeros_poly(key)
            m = (z1 == key[0]) & (z2 == key[1])
            sos[m, si, :3] = polys[key]
        sos[:, si, 3] = 1.0
        sos[:, si, 4] = 0.0 + ((-p1r) + (-p2r))
        sos[:, si, 5] = 0.0 + ((-p1r) * (-p2r) - (-p1i) * (-p2i))
    sos[:, 0, :3] *= k_z[:, None]
    return sos, _step_states(sos)
