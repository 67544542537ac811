"""``distctrl identify``, the nozzle side (issue 26): resonance, damping, sensor delay and noise from
the path that sees the nozzle, motor encoder -> sensor, in the time domain.

The motor encoder sees the motor, the sensor sees the nozzle; the motor -> nozzle mode is therefore
in the transfer from the *actual* position to the sensor reading, whatever the drive's kv attenuates
between the command and the motor. The complete model of that path::

    n   = M(f0, zeta) x            M(s) = (w0^2 + 2 zeta w0 s) / (s^2 + 2 zeta w0 s + w0^2)
    y_k = C(n(t_k - delay)) + noise

is fitted to every sample of every recording by least squares: the motor samples are taken as a
band-limited signal (their line through the first and last sample removed, zero-padded), the mode
and the delay are applied exactly in the frequency domain (FFT), and the characteristic ``C`` is a
piecewise-linear function of the nozzle position (knots every 0.1 mm, a light smoothness penalty),
solved linearly for every (f0, zeta, delay) (variable projection). The three non-linear parameters
start from a grid (the delay with a rigid model, then f0 x zeta) and are refined with
:func:`scipy.optimize.least_squares`; their uncertainties come from its Jacobian, the damping's with
the term :func:`between_samples_rel` added (what the samples cannot tell). The resonant model is
kept when it explains the data much better than the rigid one (likelihood ratio) and its frequency is
determined to a few per cent. ``noise_std`` is what the complete model leaves over, divided by the
characteristic's local slope (in mm of true distance), less the sensor's quantisation.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: knot spacing of the characteristic in the time-domain model (mm of nozzle position)
KNOT = 0.1
#: zero padding of the FFT (s): the mode's ringing after the end does not wrap onto the start
PAD_S = 1.0
#: samples at each end left out of the cost (the edges of the band-limited interpolation)
EDGE = 32
#: the resonant model is kept when N ln(RSS_rigid / RSS_res) exceeds this ...
LR_MIN = 50.0
#: ... and the resonance is known to this relative standard deviation
F0_REL_SD_MAX = 0.05
#: searched sensor delay (s)
DELAY_MAX = 0.012


def between_samples_rel(f0: float, T: float) -> float:
    """The relative uncertainty of the damping that the motor's path *between* samples leaves (issue 26).

    The fit takes the motor samples as a band-limited signal. A drive that holds its setpoint over the
    cycle (the NC's bus) moves with a velocity step every cycle; its motion has images at ``k/T +- f``
    which alias onto the samples. The mode acts on the continuous motion, so the motor's motion at f0
    differs from what the samples say by about the two nearest images, relative
    ``A = (x / (1 - x))^2 + (x / (1 + x))^2`` with ``x = f0 T`` (a P position loop, kv well below f0).
    The mode's peak height is ~1 / (2 zeta), so the damping carries that fraction: the recordings cannot
    tell a smooth motor (drive interpolating the setpoint) from a kinked one, and the fit does not
    guess. Seen on unseen plants with held setpoints: damping 1.3 % high at 79 Hz (A = 1.3 %), 3.4 %
    high at 114 Hz (A = 2.7 %), while the Jacobian alone said 0.1-0.3 %."""
    x = f0 * T
    if not (0.0 < x < 0.5):
        return 0.0
    return (x / (1.0 - x)) ** 2 + (x / (1.0 + x)) ** 2


@dataclass
class _Path:
    n: int          # samples
    nfft: int
    Xf: np.ndarray  # rfft of the motor minus its line
    line0: float
    slope: float    # the line: x0 + slope * k
    Y: np.ndarray
    f: np.ndarray   # frequencies of Xf (Hz)


def _paths(recs, T: float) -> list[_Path]:
    out = []
    pad = int(PAD_S / T)
    for r in recs:
        X = np.asarray(r.X, float)
        n = X.size
        k = np.arange(n)
        slope = (X[-1] - X[0]) / max(n - 1, 1)
        d = X - (X[0] + slope * k)
        nfft = 1 << int(math.ceil(math.log2(n + pad)))
        out.append(_Path(n=n, nfft=nfft, Xf=np.fft.rfft(d, nfft), line0=float(X[0]), slope=float(slope),
                         Y=np.asarray(r.Y, float), f=np.fft.rfftfreq(nfft, T)))
    return out


def mode_response(f: np.ndarray, f0: float | None, zeta: float | None) -> np.ndarray:
    """Motor -> nozzle at the frequencies f (Hz); 1 for a rigid drive."""
    if not f0:
        return np.ones_like(f, dtype=complex)
    s = 2j * np.pi * f
    w0 = 2 * np.pi * f0
    return (w0 * w0 + 2 * zeta * w0 * s) / (s * s + 2 * zeta * w0 * s + w0 * w0)


def nozzle_delayed(p: _Path, T: float, f0: float | None, zeta: float | None, delay: float) -> np.ndarray:
    """The nozzle at t_k - delay from the motor samples (mode and delay exact in the frequency domain)."""
    G = mode_response(p.f, f0, zeta) * np.exp(-2j * np.pi * p.f * delay)
    d = np.fft.irfft(p.Xf * G, p.nfft)[: p.n]
    k = np.arange(p.n) - delay / T
    return d + p.line0 + p.slope * k     # the line is rigid (M(0) = 1, no curvature): only delayed


class _Basis:
    """Hat functions on knots every KNOT mm over the nozzle positions of all recordings."""

    def __init__(self, lo: float, hi: float):
        self.x0 = math.floor(lo / KNOT) * KNOT - KNOT
        self.m = int(math.ceil((hi - self.x0) / KNOT)) + 2
        self._pen = None

    def locate(self, n: np.ndarray):
        u = (n - self.x0) / KNOT
        i = np.clip(np.floor(u).astype(np.int64), 0, self.m - 2)
        w = np.clip(u - i, 0.0, 1.0)
        return i, w

    def solve(self, ns: list[np.ndarray], ys: list[np.ndarray], slopes: bool = False):
        """Least-squares knot values c (with a light second-difference penalty) and the residuals (and
        the characteristic's slope at every sample)."""
        m = self.m
        n = np.concatenate(ns)
        y = np.concatenate(ys)
        i, w = self.locate(n)
        a0 = 1.0 - w
        A = np.zeros((m, m))
        A[np.diag_indices(m)] = np.bincount(i, a0 * a0, m) + np.bincount(i + 1, w * w, m)
        off = np.bincount(i, a0 * w, m)[:-1]
        A[np.arange(m - 1), np.arange(1, m)] = off
        A[np.arange(1, m), np.arange(m - 1)] = off
        b = np.bincount(i, a0 * y, m) + np.bincount(i + 1, w * y, m)
        if self._pen is None:
            D = np.diff(np.eye(m), 2, axis=0)
            self._pen = D.T @ D
        lam = 1e-3 * max(float(np.mean(np.diag(A))), 1.0)
        self._normal = A + lam * self._pen
        c = np.linalg.solve(self._normal, b)
        self.support = np.bincount(i, a0, m) + np.bincount(i + 1, w, m)
        r = y - (c[i] * a0 + c[i + 1] * w)
        return c, r, (np.diff(c)[i] / KNOT if slopes else None)


class SensorPath:
    """The time-domain model of motor -> sensor over all recordings."""

    def __init__(self, recs, T: float):
        self.T = T
        self.paths = _paths(recs, T)
        lo = min(float(np.min(r.X)) for r in recs) - 0.5
        hi = max(float(np.max(r.X)) for r in recs) + 0.5
        self.basis = _Basis(lo, hi)
        self.n_used = sum(max(p.n - 2 * EDGE, 0) for p in self.paths)

    def residuals(self, f0, zeta, delay, full: bool = False):
        ns = [nozzle_delayed(p, self.T, f0, zeta, delay)[EDGE:-EDGE] for p in self.paths]
        ys = [p.Y[EDGE:-EDGE] for p in self.paths]
        c, r, slopes = self.basis.solve(ns, ys, slopes=full)
        if full:
            return r, c, ns, slopes
        return r

    def jacobian(self, f0, zeta, delay) -> np.ndarray:
        """d residual / d (ln f0, ln zeta, delay), the characteristic held (variable projection's
        approximation): -C'(n) dn/dp, dn/dp exact in the frequency domain."""
        ns = [nozzle_delayed(p, self.T, f0, zeta, delay)[EDGE:-EDGE] for p in self.paths]
        ys = [p.Y[EDGE:-EDGE] for p in self.paths]
        _, _, slopes = self.basis.solve(ns, ys, slopes=True)
        cols = []
        for p in self.paths:
            s = 2j * np.pi * p.f
            w0 = 2 * np.pi * f0
            N = w0 * w0 + 2 * zeta * w0 * s
            D = s * s + 2 * zeta * w0 * s + w0 * w0
            E = np.exp(-s * delay)
            dM_dlnf = w0 * ((2 * w0 + 2 * zeta * s) * D - N * (2 * zeta * s + 2 * w0)) / (D * D)
            dM_dlnz = zeta * 2 * w0 * s * s * s / (D * D)
            M = N / D
            parts = [np.fft.irfft(p.Xf * g, p.nfft)[: p.n] for g in (dM_dlnf * E, dM_dlnz * E, -s * M * E)]
            # the line (rigid, delayed) contributes to d/d delay only
            parts[2] = parts[2] - p.slope / self.T
            cols.append(np.column_stack(parts)[EDGE:-EDGE])
        return -np.concatenate(cols) * slopes[:, None]

    def rss(self, f0, zeta, delay) -> float:
        r = self.residuals(f0, zeta, delay)
        return float(np.dot(r, r))


def _quantum(Y: np.ndarray) -> float:
    """The sensor's resolution if its readings lie on a grid (0: continuous)."""
    d = np.abs(np.diff(Y))
    d = d[d > 1e-12]
    if d.size < 100:
        return 0.0
    q = float(np.min(d))
    if q <= 0 or np.max(np.abs(Y / q - np.round(Y / q))) > 0.05:
        return 0.0
    return q


def residual_lag1(r: np.ndarray) -> float | None:
    """The lag-1 autocorrelation of what the model leaves over: about 0 for noise (white, also a
    quantised reading's), near 1 for a slow signal the model does not explain."""
    r = np.asarray(r, float) - float(np.mean(r))
    den = float(np.dot(r, r))
    return float(np.dot(r[1:], r[:-1]) / den) if den > 0 and r.size > 2 else None


def fit_sensor_path(recs, T: float, f_hint: float | None = None) -> dict:
    """Resonance, damping, sensor delay, noise and their uncertainties from the motor -> sensor path.

    Returns a dict with ``resonance_hz``, ``damping`` (None for a rigid drive), ``delay`` (s),
    ``noise_std`` (mm of true distance), ``gain`` (the characteristic's median slope), ``sd`` (standard
    deviations of f0, zeta, delay, noise), ``lr`` (the likelihood ratio resonant : rigid), ``rss``."""
    # scipy's optimize/signal/ndimage (0.2-0.5 s of import each): only on the path that needs it
    from scipy.optimize import least_squares

    sp = SensorPath(recs, T)
    N = max(sp.n_used, 1)
    # 1. the delay with a rigid model (the mode's phase is second order at low frequency)
    taus = np.arange(0.0, DELAY_MAX + 1e-12, T)
    c_r = np.array([sp.rss(None, None, tau) for tau in taus])
    tau0 = float(taus[int(np.argmin(c_r))])

    def rigid_fun(p):
        return sp.residuals(None, None, p[0])

    lo_t = max(tau0 - T, 0.0)
    fr = least_squares(rigid_fun, [min(max(tau0, lo_t + 1e-6), DELAY_MAX)], bounds=([lo_t - 1e-9], [tau0 + T]),
                       x_scale=[T], diff_step=[1e-3])
    rss_rigid = float(2 * fr.cost)
    tau_rigid = float(fr.x[0])
    # 2. f0 x zeta on a grid at that delay
    fmax = 0.4 / T
    f_grid = np.exp(np.linspace(math.log(3.0), math.log(fmax), 24))
    if f_hint:
        f_grid = np.append(f_grid, f_hint)
    z_grid = (0.02, 0.07, 0.25)
    cand = []
    for f0 in f_grid:
        for z in z_grid:
            cand.append((sp.rss(f0, z, tau_rigid), f0, z))
    cand.sort()
    # 3. refine the best distinct starts: log f0, log zeta, delay
    starts = []
    for c, f0, z in cand:
        if all(abs(math.log(f0 / s[1])) > 0.15 for s in starts):
            starts.append((c, f0, z))
        if len(starts) == 2:
            break

    def fun(p):
        return sp.residuals(math.exp(p[0]), math.exp(p[1]), p[2])

    def jac(p):
        return sp.jacobian(math.exp(p[0]), math.exp(p[1]), p[2])

    best = None
    lb = [math.log(1.0), math.log(0.002), 0.0]
    ub = [math.log(0.45 / T), math.log(1.5), DELAY_MAX]
    for _, f0, z in starts:
        x0 = [math.log(f0), math.log(z), min(max(tau_rigid, 0.0), DELAY_MAX)]
        try:
            r = least_squares(fun, x0, jac=jac, bounds=(lb, ub), x_scale=[0.05, 0.2, T], max_nfev=40)
        except ValueError:
            continue
        if best is None or r.cost < best.cost:
            best = r
    out = {"rss_rigid": rss_rigid, "n": N}
    f0 = zeta = None
    tau = tau_rigid
    sd = {}
    lr = 0.0
    if best is not None:
        rss_res = float(2 * best.cost)
        lr = N * math.log(rss_rigid / rss_res) if rss_res > 0 else math.inf
        sigma2 = rss_res / max(N - 3, 1)
        J = best.jac
        try:
            cov = np.linalg.inv(J.T @ J) * sigma2
            var = np.maximum(np.diag(cov), 0.0)
        except np.linalg.LinAlgError:
            var = np.full(3, np.inf)
        f_b, z_b, t_b = math.exp(best.x[0]), math.exp(best.x[1]), float(best.x[2])
        f_rel = math.sqrt(var[0])                   # sd of log f0 = relative sd of f0
        at_bound = best.x[0] <= lb[0] + 1e-3 or best.x[0] >= ub[0] - 1e-3 or best.x[1] >= ub[1] - 1e-3
        out["candidate"] = {"resonance_hz": f_b, "damping": z_b, "delay": t_b, "lr": lr,
                            "resonance_rel_sd": f_rel}
        if lr >= LR_MIN and f_rel <= F0_REL_SD_MAX and not at_bound:
            f0, zeta, tau = f_b, z_b, t_b
            sd = {"resonance_hz": f_b * f_rel, "delay": math.sqrt(var[2]),
                  "damping": z_b * math.hypot(math.sqrt(var[1]), between_samples_rel(f_b, T))}
    if f0 is None:
        J = fr.jac
        try:
            sd = {"delay": float(math.sqrt(max(np.linalg.inv(J.T @ J)[0, 0], 0.0) * rss_rigid / max(N - 1, 1)))}
        except np.linalg.LinAlgError:
            sd = {"delay": math.inf}
    # 4. noise: what the complete model leaves over, in mm of true distance
    r, c, ns, slopes = sp.residuals(f0, zeta, tau, full=True)
    g = float(np.median(np.abs(slopes))) or 1.0
    sl = np.clip(np.abs(slopes), 0.2 * g, 5.0 * g)
    q = _quantum(np.concatenate([p.Y for p in sp.paths]))
    z = r / sl
    var = float(np.mean(z * z)) * N / max(N - c.size, 1)
    var_q = (q / g) ** 2 / 12.0
    noise = math.sqrt(max(var - var_q, 0.25 * var))
    # the characteristic in motor coordinates at the knots the samples support
    b = sp.basis
    knots = b.x0 + KNOT * np.arange(b.m)
    ok = b.support >= 20.0
    out["points_motor"] = [(float(x), float(v)) for x, v in zip(knots[ok], c[ok])]
    try:       # the knots' standard deviations (noise of the reading through the normal equations)
        cvar = np.diag(np.linalg.inv(b._normal)) * float(np.dot(r, r)) / max(N - c.size, 1)
        sd["characteristic"] = float(np.sqrt(np.max(cvar[ok]))) if ok.any() else None
    except np.linalg.LinAlgError:
        sd["characteristic"] = None
    out.update(resonance_hz=f0, damping=zeta, delay=max(tau, 0.0), noise_std=noise, gain=g, lr=lr,
               quantum=q, rss=float(np.dot(r, r)), residual_lag1=residual_lag1(r))
    sd["noise_std"] = noise / math.sqrt(2.0 * N)
    out["sd"] = sd
    return out
