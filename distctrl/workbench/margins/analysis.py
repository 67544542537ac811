"""The margins of a loop: :func:`analyse` (gain and phase margins checked on the frequency response,
the closed loop's largest pole) and :func:`kp_limit` (the KP at the stability limit).

Part of :mod:`distctrl.workbench.margins` (docs/margins.md); the package face re-exports every name.
"""
from __future__ import annotations

import math
import warnings

import numpy as np

from .model import KP_SEARCH_MAX, POLE_TOLERANCE, LoopModel
from .result import MarginResult, _finite


def phase_margin_deg(resp):
    """The phase margin (deg) of the open-loop response ``resp`` (complex, scalar or array) at a gain
    crossover: the angle between L and -1, ``180 - |arg L|`` with ``arg L`` in (-180, 180], 0 to 180 deg.

    Not ``(arg L mod 360) - 180`` (python-control's stability_margins, 0.10.2): that turns a crossing in
    the upper half-plane into a negative margin; a resonance that carries the phase round to -356 deg
    crosses 0 dB at 1 at +4 deg, 176 deg away from -1, which it called -176 deg (new-user audit M2).
    Whether the loop is stable is decided elsewhere (the closed-loop poles; the gain margin at every
    -180 deg crossing)."""
    return 180.0 - np.abs(np.angle(resp, deg=True))


def _critical(model: LoopModel) -> tuple[float, float]:
    """(spectral radius, frequency of the pole with the largest |z| in Hz)."""
    poles = model.closed_loop_poles()
    if poles.size == 0:
        return 0.0, 0.0
    i = int(np.argmax(np.abs(poles)))
    return float(abs(poles[i])), abs(float(np.angle(poles[i]))) / (2.0 * math.pi * model.cycle_time)


def kp_limit(model: LoopModel, rel_tol: float = 1e-7) -> tuple[float | None, float | None]:
    """(KP, frequency in Hz) at which the closed loop reaches the stability limit, everything else as in
    ``model`` (the D gain follows KP as in the core). Searched from the model's KP: upwards while the
    loop is stable, downwards while it is not; bisection on the largest closed-loop pole."""
    def unstable(kp: float) -> bool:
        return model.with_kp(kp).spectral_radius() > 1.0 + POLE_TOLERANCE

    kp = model.kp
    if unstable(kp):
        hi, lo = kp, kp / 1.5
        while unstable(lo):
            hi, lo = lo, lo / 1.5
            if lo < 1e-9:
                return None, None
    else:
        lo, hi = kp, kp * 1.5
        while not unstable(hi):
            lo, hi = hi, hi * 1.5
            if lo > KP_SEARCH_MAX:
                return None, None
    while hi - lo > rel_tol * hi:
        mid = 0.5 * (lo + hi)
        if unstable(mid):
            hi = mid
        else:
            lo = mid
    _, freq = _critical(model.with_kp(hi))
    return 0.5 * (lo + hi), freq


#: the dense frequency grid on which :func:`analyse` looks for crossings python-control misses
GRID_F_MIN_HZ = 0.01
GRID_POINTS_PER_DECADE = 800


def _grid_crossings(response, loop_response, T: float) -> tuple[list[float], list[float], float]:
    """(phase crossovers, gain crossovers) in rad/s found on a dense logarithmic frequency grid (0.01 Hz to
    the Nyquist frequency, 800 points per decade) and refined on the response (scipy.optimize.brentq).
    python-control's stability_margins misses the two 0 dB crossings at the flanks of a lightly damped
    resonance peak that rises above 0 dB (seen: 13.5 Hz, zeta 0.018: it reported only the crossing at
    2.85 Hz with +53 deg, while the peak crosses at 13.0 and 14.0 Hz with negative phase margins).
    The third figure is the smallest |1 + L| on the grid (the stability margin)."""
    # scipy's optimize/signal/ndimage (0.2-0.5 s of import each): only on the path that needs it
    from scipy.optimize import brentq

    f_nyq = 0.5 / T
    n = int(math.ceil(GRID_POINTS_PER_DECADE * math.log10(f_nyq / GRID_F_MIN_HZ)))
    w = 2.0 * math.pi * np.geomspace(GRID_F_MIN_HZ, f_nyq, n)
    with np.errstate(all="ignore"):
        resp = np.asarray(loop_response(w), dtype=complex).reshape(-1)
        lm = np.log(np.abs(resp))
        dist = np.abs(1.0 + resp)
    sm = float(np.nanmin(dist)) if np.isfinite(dist).any() else math.inf
    pcs, gcs = [], []

    def refine(fun, a: float, b: float) -> float | None:
        try:
            return float(brentq(fun, a, b, xtol=1e-12, rtol=1e-13))
        except (ValueError, RuntimeError):
            return None

    ok = np.isfinite(lm[:-1]) & np.isfinite(lm[1:])
    for k in np.nonzero(ok & (np.signbit(lm[:-1]) != np.signbit(lm[1:])))[0]:
        r = refine(lambda x: math.log(abs(response(x))), w[k], w[k + 1])
        if r is not None:
            gcs.append(r)
    im, re = resp.imag, resp.real
    for k in np.nonzero((np.signbit(im[:-1]) != np.signbit(im[1:])) & (re[:-1] < 0) & (re[1:] < 0))[0]:
        r = refine(lambda x: response(x).imag, w[k], w[k + 1])
        if r is not None:
            pcs.append(r)
    return pcs, gcs, sm


def _checked_crossings(response, phase_candidates: list[float], gain_candidates: list[float],
                       w_nyq: float) -> tuple[dict[float, float], dict[float, float]]:
    """The candidate crossings (rad/s) that the response confirms, duplicates dropped: phase crossovers
    (frequency -> gain margin) and gain crossovers (frequency -> phase margin in deg)."""
    phase_x: dict[float, float] = {}          # frequency (rad/s) -> gain margin
    for w in phase_candidates:
        if not (math.isfinite(w) and 0.0 < w <= w_nyq * (1.0 + 1e-9)):
            continue
        resp = response(w)
        if resp.real < 0.0 and abs(resp.imag) <= 1e-6 * abs(resp) and \
                not any(math.isclose(w, v, rel_tol=1e-6) for v in phase_x):
            phase_x[w] = 1.0 / abs(resp)
    gain_x: dict[float, float] = {}           # frequency (rad/s) -> phase margin (deg)
    for w in gain_candidates:
        if not (math.isfinite(w) and 0.0 < w <= w_nyq * (1.0 + 1e-9)):
            continue
        resp = response(w)
        if abs(abs(resp) - 1.0) <= 1e-6 and not any(math.isclose(w, v, rel_tol=1e-6) for v in gain_x):
            gain_x[w] = float(phase_margin_deg(resp))
    return phase_x, gain_x


def analyse(model: LoopModel) -> MarginResult:
    """Gain and phase margins (``control.stability_margins`` of the open loop), the closed loop's
    largest pole, and the KP at the stability limit with its oscillation frequency."""
    # python-control (about 1 s of import): only where the loop model is built
    import control

    loop = model.loop()
    T = model.cycle_time
    with warnings.catch_warnings():
        # python-control falls back from its polynomial to its frequency-response method for some
        # discrete loops and says so; the fallback is what we want
        warnings.simplefilter("ignore")
        _, _, sms, wpcs, wgcs, _ = (np.atleast_1d(np.asarray(v, dtype=float))
                                    for v in control.stability_margins(loop, returnall=True))
    # python-control's polynomial method can report a crossing that is none (seen: a "phase crossover"
    # at 2e-4 Hz next to the offset integrator's pole, where the phase is -90 deg); every crossing is
    # checked on the frequency response itself, duplicates are dropped, and a phase crossover exactly at
    # the Nyquist frequency (z = -1, e.g. KP / (z - 1)), which python-control does not report, is added
    w_nyq = math.pi / T

    # the response factor by factor (LoopModel.response): the multiplied-out loop loses digits next to
    # z = 1 (a 4th-5th order low-pass at a low corner frequency: a gain margin of 2.6e9 at 91.6 Hz and
    # no phase margin, where the loop crosses 0 dB below 1 Hz and -180 deg near 4 Hz)
    def response(w: float) -> complex:
        return complex(model.response(np.array([w]))[0])

    grid_pcs, grid_gcs, grid_sm = _grid_crossings(response, model.response, T)
    phase_x, gain_x = _checked_crossings(response, list(wpcs) + grid_pcs + [w_nyq], list(wgcs) + grid_gcs, w_nyq)
    # as python-control's own choice: the gain margin closest to 1, the smallest phase margin
    gm = wpc = pm = wgc = math.inf
    if phase_x:
        wpc = min(phase_x, key=lambda w: abs(math.log(phase_x[w])))
        gm = phase_x[wpc]
    if gain_x:
        wgc = min(gain_x, key=lambda w: gain_x[w])
        pm = gain_x[wgc]
    # the stability margin (smallest |1 + L|) on the dense grid of the factor-by-factor response, not
    # python-control's figure from the multiplied-out loop
    sm = grid_sm
    del sms
    to_hz = 1.0 / (2.0 * math.pi)
    all_gm = tuple((float(phase_x[w]), float(w) * to_hz) for w in sorted(phase_x))
    all_pm = tuple((float(gain_x[w]), float(w) * to_hz) for w in sorted(gain_x))
    radius, f_pole = _critical(model)
    kpl, f_lim = kp_limit(model)
    return MarginResult(model=model, gain_margin=_finite(gm), phase_margin_deg=_finite(pm),
                        stability_margin=_finite(sm),
                        phase_crossover_hz=None if _finite(gm) is None or _finite(wpc) is None else wpc * to_hz,
                        gain_crossover_hz=None if _finite(pm) is None or _finite(wgc) is None else wgc * to_hz,
                        spectral_radius=radius, pole_frequency_hz=f_pole, kp_limit=kpl, limit_frequency_hz=f_lim,
                        gain_margins=all_gm, phase_margins=all_pm)
