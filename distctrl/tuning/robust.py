"""The margin constraint of ``distctrl tune``: a parameter set is allowed only if the linearised loop of
``distctrl margins`` (:mod:`distctrl.workbench.margins`) has at least the required gain and phase margin
on the plant tuned on **and** on every variant of it within an allowance (the tolerances to which
``distctrl identify`` determines a plant: kv, dead time, sensor delay, resonance, damping).

Why: a fitted twin is never the machine. A set that is merely stable on the twin can be unstable on the
machine when the machine's resonance lies a few per cent lower or its damping is half the fitted one.
With the allowance the twin's margins cover what the fit does not know (issue 26).

The check is a frequency response on a dense logarithmic grid, evaluated block by block (the low-pass
filter section by section, as the core runs it, so that a high-order low cut-off is no polynomial of
badly conditioned coefficients), for all variants at once. For every crossing of 0 dB the phase margin,
for every crossing of -180 deg (and at the Nyquist frequency) the gain margin; the worst of all
crossings and variants counts (not only python-control's "closest to 1"); the phase margin is the angle
between L and -1 at the crossing (:func:`~distctrl.workbench.margins.analysis.phase_margin_deg`). The
open loop has no poles
outside the unit circle (drive, mode, filter are stable; the offset's and the I part's integrators sit on
it), so a loop whose every -180 deg crossing stays below 1 / (required gain margin) and whose phase does
not start below -180 deg is stable by the Nyquist criterion; a conditionally stable loop (a -180 deg
crossing above 0 dB) is not accepted.

A set that misses the constraint can be brought into it by a lower KP (:meth:`MarginConstraint.fit_kp`):
the tuner lowers the KP of its random points (down to :data:`KP_FLOOR`) instead of dropping them, so that
on a plant with a low, lightly damped mode it still searches filters and I/D parts at a KP the mode
allows.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass

import numpy as np

from ..control import law
from ..control.controller import AxisDistanceController
from ..workbench.margins import filter_coefficients, phase_margin_deg, resonance_polynomials

__all__ = ["PlantAllowance", "DEFAULT_ALLOWANCE", "MIN_GAIN_MARGIN", "MIN_PHASE_MARGIN_DEG", "KP_FLOOR",
           "MarginCheck", "MarginConstraint"]

#: required gain margin (factor, 6 dB) and phase margin (deg) on every plant of the allowance
MIN_GAIN_MARGIN = 2.0
MIN_PHASE_MARGIN_DEG = 30.0
#: the lowest KP the tuner goes to when it lowers a set's KP to meet the constraint (P-AXIS-00759 allows
#: 0 < KP <= 2; the tuner's resolution of KP is 0.001)
KP_FLOOR = 0.001
#: frequency grid: points per decade from F_MIN_HZ to the Nyquist frequency
POINTS_PER_DECADE = 800
F_MIN_HZ = 0.01


@dataclass(frozen=True)
class PlantAllowance:
    """How far the machine may lie from the plant tuned on: the tolerances of ``distctrl identify``
    (issue 26, met on all of 40 unseen plants: docs/identify.md). ``kv`` and ``resonance`` relative (±),
    ``damping`` a factor (the lighter mode, the worse), ``dead_cycles`` extra cycles of the drive's dead
    time and of the sensor delay each (1 ms at 1 ms)."""

    kv: float = 0.10
    resonance: float = 0.10
    damping: float = 0.5
    dead_cycles: int = 1

    def variants(self, kv: float, resonance_hz: float, damping: float) -> list[dict]:
        """The plants checked: every corner (kv ±, dead time +0/+1 on both delays, f0 -, 0, +, zeta x1 and
        x factor when there is a mode), the nominal one first."""
        kvs = (kv, kv * (1 - self.kv), kv * (1 + self.kv))
        deads = (0, self.dead_cycles) if self.dead_cycles else (0,)
        if resonance_hz:
            f0s = (resonance_hz, resonance_hz * (1 - self.resonance), resonance_hz * (1 + self.resonance))
            zetas = (damping, damping * self.damping)
        else:
            f0s, zetas = (0.0,), (damping,)
        out = []
        for k, d, f, z in itertools.product(kvs, deads, f0s, zetas):
            out.append({"kv": k, "extra_dead_cycles": d, "resonance_hz": f, "damping": z})
        return out

    def describe(self) -> str:
        return (f"kv ±{self.kv:.0%}, dead time and sensor delay +{self.dead_cycles} cycle, resonance "
                f"±{self.resonance:.0%}, damping x{self.damping:g}")

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


DEFAULT_ALLOWANCE = PlantAllowance()


@dataclass(frozen=True)
class MarginCheck:
    """The worst margins of one parameter set over the plants (None: no such crossing anywhere)."""

    ok: bool
    gain_margin: float | None          # smallest over every -180 deg crossing of every plant
    gain_margin_hz: float | None
    gain_margin_plant: dict | None
    phase_margin_deg: float | None     # smallest over every 0 dB crossing of every plant
    phase_margin_hz: float | None
    phase_margin_plant: dict | None
    nominal_gain_margin: float | None
    nominal_phase_margin_deg: float | None
    binding: str                       # "gain margin" or "phase margin": the one with the least slack

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


def _plant_text(p: dict | None, nominal: dict) -> str:
    if not p:
        return "-"
    parts = []
    if p["kv"] != nominal["kv"]:
        parts.append(f"kv {p['kv'] / nominal['kv'] - 1:+.0%}")
    if p["extra_dead_cycles"]:
        parts.append(f"dead time and sensor delay +{p['extra_dead_cycles']} cycle")
    if p["resonance_hz"] and p["resonance_hz"] != nominal["resonance_hz"]:
        parts.append(f"resonance {p['resonance_hz']:.3g} Hz")
    if p["resonance_hz"] and p["damping"] != nominal["damping"]:
        parts.append(f"damping {p['damping']:.3g}")
    return ", ".join(parts) or "the plant tuned on"


class MarginConstraint:
    """The constraint for one plant (``model``: :func:`distctrl.workbench.margins.loop_model` of the
    scenario, whose mode, encoders, sensor gain and delays it takes)."""

    def __init__(self, model, *, min_gain_margin: float = MIN_GAIN_MARGIN,
                 min_phase_margin_deg: float = MIN_PHASE_MARGIN_DEG, allowance: PlantAllowance = DEFAULT_ALLOWANCE):
        self.model = model
        self.min_gain_margin = float(min_gain_margin)
        self.min_phase_margin_deg = float(min_phase_margin_deg)
        self.allowance = allowance
        T = model.cycle_time
        self.T = T
        f_nyq = 0.5 / T
        n = int(math.ceil(POINTS_PER_DECADE * math.log10(f_nyq / F_MIN_HZ)))
        self.f = np.geomspace(F_MIN_HZ, f_nyq, n)
        zi = np.exp(-2j * math.pi * self.f * T)           # z^-1 on the grid
        self.zi = zi
        self.delta = 1.0 - zi
        self.plants = allowance.variants(model.kv, model.resonance_hz, model.damping)
        self.nominal = self.plants[0]
        # per plant: what the loop needs of the drive, mode and delays (rows: plants)
        pn_s, pn_enc, pd, zn = [], [], [], []
        ff = model.feedforward
        for p in self.plants:
            kvT = p["kv"] * T
            bus = model.bus_delay_cycles + p["extra_dead_cycles"]
            nd = model.dead_time_cycles + p["extra_dead_cycles"]
            pn = zi ** bus * ((kvT + ff) - ff * zi)
            d = 1.0 - (1.0 - kvT) * zi
            rn = rd = 1.0
            if p["resonance_hz"]:
                a, b = resonance_polynomials(p["resonance_hz"], p["damping"], T)
                rn = a[0] + a[1] * zi + a[2] * zi * zi
                rd = b[0] + b[1] * zi + b[2] * zi * zi
            pn_s.append(pn * rn)
            pn_enc.append(pn * rd)
            pd.append(d * rd)
            zn.append(zi ** nd)
        self._pn_s, self._pn_enc = np.array(pn_s), np.array(pn_enc)
        self._pd, self._zn = np.array(pd), np.array(zn)

    # -- the loop -----------------------------------------------------------------------------------------
    def _filter_response(self, fc) -> np.ndarray:
        zi = self.zi
        if int(fc[law.FC_KIND]) == law.LOWPASS:
            h = np.ones_like(zi)
            for s in range(int(fc[law.FC_NSEC])):
                o = law.FC_SOS + 6 * s
                b, a = fc[o:o + 3], fc[o + 3:o + 6]
                h = h * (b[0] + b[1] * zi + b[2] * zi * zi) / (a[0] + a[1] * zi + a[2] * zi * zi)
            return h
        b, a = filter_coefficients(fc)
        return np.polynomial.polynomial.polyval(zi, b) / np.polynomial.polynomial.polyval(zi, a)

    def loop_response(self, params) -> np.ndarray:
        """L on the grid for every plant (rows), the list ``params`` (AxisParameters) as the core runs it."""
        m = self.model
        ctrl = AxisDistanceController(params, self.T)
        c = ctrl.law_constants()
        kp, ti, g = float(ctrl.tuning.kp), float(c["i_gain"]), float(c["d_gain"])
        F = self._filter_response(c["fc"])
        delta, zi = self.delta, self.zi
        if ti > 0.0:
            cpi = kp * (delta + ti)
            cd = delta
            cn = cpi + g * delta * delta
        else:
            cpi = np.full_like(zi, kp)
            cd = np.ones_like(zi)
            cn = kp + g * delta
        d_o = m.sensor_gain * self._zn * self._pn_s
        if m.mode == "SET_POS":
            hn, sign = zi * self._pn_enc - d_o, -1.0
        elif m.both_encoders:
            hn, sign = d_o + zi * (self._pd - self._pn_enc), 1.0
        else:
            hn, sign = d_o, 1.0
        loop = sign * (cn * F) * hn / (cd * delta * self._pd)
        if m.mode == "SET_POS":
            loop = loop + cpi * zi / (cd * delta)
        return loop

    # -- the check ----------------------------------------------------------------------------------------
    def _margins(self, loop: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per plant: (smallest gain margin, its Hz, smallest phase margin, its Hz); inf / nan where none."""
        f = self.f
        nplants = loop.shape[0]
        gm = np.full(nplants, np.inf)
        gm_f = np.full(nplants, np.nan)
        pm = np.full(nplants, np.inf)
        pm_f = np.full(nplants, np.nan)
        mag = np.abs(loop)
        with np.errstate(divide="ignore", invalid="ignore"):
            lm = np.log(mag)
        for i in range(nplants):
            L, l = loop[i], lm[i]
            # 0 dB crossings: phase margins
            k = np.nonzero(np.signbit(l[:-1]) != np.signbit(l[1:]))[0]
            if k.size:
                t = l[k] / (l[k] - l[k + 1])
                lc = L[k] + t * (L[k + 1] - L[k])
                p = phase_margin_deg(lc)      # the distance to -1 (audit M2), not (arg mod 360) - 180
                j = int(np.argmin(p))
                pm[i], pm_f[i] = float(p[j]), float(f[k[j]] + t[j] * (f[k[j] + 1] - f[k[j]]))
            # -180 deg crossings: gain margins
            im = L.imag
            k = np.nonzero((np.signbit(im[:-1]) != np.signbit(im[1:])) & (L.real[:-1] < 0) & (L.real[1:] < 0))[0]
            vals, freqs = [], []
            if k.size:
                t = im[k] / (im[k] - im[k + 1])
                re = L.real[k] + t * (L.real[k + 1] - L.real[k])
                vals += list(1.0 / np.abs(re))
                freqs += list(f[k] + t * (f[k + 1] - f[k]))
            if L.real[-1] < 0:                                  # at the Nyquist frequency L is real
                vals.append(1.0 / abs(L.real[-1]))
                freqs.append(f[-1])
            if L.real[0] < 0 and im[0] > 0 and mag[i, 0] > 1.0:  # the phase starts below -180 deg
                vals.append(0.0)
                freqs.append(f[0])
            if vals:
                j = int(np.argmin(vals))
                gm[i], gm_f[i] = vals[j], freqs[j]
        return gm, gm_f, pm, pm_f

    def check(self, params) -> MarginCheck:
        """The worst margins of ``params`` over the plants and whether they meet the requirement."""
        gm, gm_f, pm, pm_f = self._margins(self.loop_response(params))
        ig, ip = int(np.argmin(gm)), int(np.argmin(pm))
        g, p = float(gm[ig]), float(pm[ip])
        ok = g >= self.min_gain_margin and p >= self.min_phase_margin_deg
        sg = g / self.min_gain_margin if self.min_gain_margin > 0 else math.inf
        sp = p / self.min_phase_margin_deg if self.min_phase_margin_deg > 0 else math.inf
        fin = math.isfinite
        return MarginCheck(ok=bool(ok),
                           gain_margin=g if fin(g) else None, gain_margin_hz=float(gm_f[ig]) if fin(g) else None,
                           gain_margin_plant=self.plants[ig] if fin(g) else None,
                           phase_margin_deg=p if fin(p) else None, phase_margin_hz=float(pm_f[ip]) if fin(p) else None,
                           phase_margin_plant=self.plants[ip] if fin(p) else None,
                           nominal_gain_margin=float(gm[0]) if fin(gm[0]) else None,
                           nominal_phase_margin_deg=float(pm[0]) if fin(pm[0]) else None,
                           binding="gain margin" if sg <= sp else "phase margin")

    def ok(self, params) -> bool:
        return self.check(params).ok

    def fit_kp(self, params, kp_floor: float = KP_FLOOR, resolution: float = 0.001):
        """``params`` with the largest KP (at most its own, rounded down to ``resolution``) that meets the
        constraint; None if not even ``kp_floor`` does. The D gain follows KP as in the core."""
        if self.ok(params):
            return params
        lo = params.replace(kp=kp_floor)
        if not self.ok(lo):
            return None
        a, b = math.log(kp_floor), math.log(float(params.kp))     # ok at a, not at b
        while b - a > math.log(1.02):
            mid = 0.5 * (a + b)
            if self.ok(params.replace(kp=math.exp(mid))):
                a = mid
            else:
                b = mid
        kp = max(kp_floor, math.floor(math.exp(a) / resolution + 1e-9) * resolution)
        out = params.replace(kp=round(kp, 10))
        return out if self.ok(out) else lo

    def describe(self) -> str:
        return (f"gain margin >= {self.min_gain_margin:g}, phase margin >= {self.min_phase_margin_deg:g} deg on the "
                f"plant tuned on and {len(self.plants) - 1} variants ({self.allowance.describe()})")

    def check_text(self, chk: MarginCheck) -> str:
        def g() -> str:
            if chk.gain_margin is None:
                return "gain margin - (no -180 deg crossing)"
            return (f"gain margin {chk.gain_margin:.3g} at {chk.gain_margin_hz:.3g} Hz "
                    f"({_plant_text(chk.gain_margin_plant, self.nominal)})")

        def p() -> str:
            if chk.phase_margin_deg is None:
                return "phase margin - (no 0 dB crossing)"
            return (f"phase margin {chk.phase_margin_deg:.1f} deg at {chk.phase_margin_hz:.3g} Hz "
                    f"({_plant_text(chk.phase_margin_plant, self.nominal)})")

        state = "met" if chk.ok else "NOT met"
        return f"{state}; worst {g()}, worst {p()}; binding: the {chk.binding}"
