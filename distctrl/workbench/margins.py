"""Frequency domain of distance control: the linearised loop of one axis and its stability margins.

``distctrl margins SCENARIO`` (docs/margins.md). The loop is built with python-control as discrete
transfer functions in the GEO cycle ``T`` (the scenario's ``cycle_time``), from the very numbers the
cycle core and the virtual machine use:

* **filter** ``F(z)``: the coefficient buffer the core designs for the axis list's filter
  (:func:`distctrl.control.filters.design_coefficients`), read back as the transfer function the law
  computes (:func:`distctrl.control.law.filter_step`): MOVING_AVERAGE and EXPO_MEAN are FIR filters
  over the last n measurements, the Kalman filters FIR over the current one and the n before it
  (``K x + (1 - K) * prediction``), LOWPASS the Butterworth sections;
* **PID** on the offset step (:func:`distctrl.control.law.pid_step`):
  ``u = KP e + KP (T/T_n) e / (1 - z^-1) + g (m - m_prev)`` with the core's per-cycle D gain
  ``g = derivative_gain(KP, T_v, T)``, D on the measurement part ``m`` of the error;
* **offset integration** without the slope limiter: ``o_k = o_(k-1) + u_k``, i.e. ``1 / (1 - z^-1)``;
* **drive** (:class:`distctrl.sim.drive.Drive`): ``bus_delay_cycles`` of fieldbus delay, the P position
  loop ``kv`` and the velocity feed-forward ``ff`` discretised as the simulator does,
  ``X/C = z^-B ((kv T + ff) - ff z^-1) / (1 - (1 - kv T) z^-1)``; with a mechanical resonance
  (``resonance_hz`` f0, ``damping`` zeta) the sensor sees the nozzle ``N = R X`` with the simulator's
  exact discretisation ``R = 1 - (p12 / T) (1 - z^-1)^2 / (1 - tr(Phi) z^-1 + det(Phi) z^-2)``,
  ``Phi = expm(A T)`` (:func:`resonance_polynomials`), while the motor encoder (both encoders, SET_POS)
  reports ``X``;
* **dead time** of the measurement: one cycle because the machine's sensor reads the axis position of
  the previous cycle (:meth:`distctrl.sim.machine.Machine._step_axes` reads the sensor before the
  drives step), the sensor's ``delay_cycles``, and one more cycle when the list's
  ``optimized_scheduling`` (P-AXIS-00426) is off (the core then uses the reading of the last cycle);
* the **mode's feedback** (:func:`distctrl.control.law.feedback_value`, ``mode_error``): CONST_DIST with
  one encoder (the distance), with both encoders (P-AXIS-00500: ``d + c - a``), or SET_POS (the surface
  ``a - d`` against ``SET_POS + o``).

What the model leaves out (it is linear and small-signal): the slope limiter (v_max, a_max, the
braking bound ``sqrt(2 a |e|)``, the bounds of the offset), the drive's velocity and acceleration
limits, encoder and sensor quantisation, the sensor's range and noise. A loop the model calls
unstable grows until one of those limits it (a limit cycle whose amplitude and frequency the limits
decide, not the linear loop); a stable one settles from a small disturbance.

:func:`loop_model` reads a scenario (the tuning in force when the program first selects distance
control, e.g. the KP of the NC block), :func:`analyse` computes the margins
(:func:`control.stability_margins`) and the KP at the stability limit, :class:`MarginResult` prints,
exports (:meth:`MarginResult.to_dict`) and plots (:meth:`MarginResult.plot`, Bode and Nyquist).
"""
from __future__ import annotations

import dataclasses
import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..base.kinds import SensorSource
from ..base.states import HliState, Mode
from ..control import law
from ..control.controller import AxisDistanceController
from ..control.filters import FILTER_KINDS
from ..errors import DistCtrlError
from .plotfiles import PLOT_SUFFIXES, check_plot_suffix  # noqa: F401  (PLOT_SUFFIXES: part of the API)

if TYPE_CHECKING:  # pragma: no cover
    import control
    from matplotlib.figure import Figure

    from ..sim.scenario import Scenario

__all__ = ["MarginsError", "LoopModel", "MarginResult", "filter_coefficients", "loop_model", "analyse",
           "model_from_parts", "KP_SEARCH_MAX", "PLOT_SUFFIXES"]

#: KP range of the NC (P-AXIS-00759): 0 < KP <= 2
KP_RANGE = (0.0, 2.0)
#: the KP at the stability limit is searched up to this value
KP_SEARCH_MAX = 1000.0
#: a closed-loop pole further out than 1 + this is unstable
POLE_TOLERANCE = 1e-9
#: the machine time a scenario is run at most to find the first select (s)
SELECT_SEARCH_S = 60.0
#: crossings listed in the text (all of them in to_dict)
MAX_CROSSINGS_SHOWN = 8
#: one cycle: the machine's sensor reads the axis position the drive reached in the previous cycle
READ_DELAY_CYCLES = 1


class MarginsError(DistCtrlError, ValueError):
    """Bad input to the margins workbench (scenario not supported, axis, KP, plot path)."""


# ------------------------------------------------------------------------------------------------------
# blocks
# ------------------------------------------------------------------------------------------------------
def filter_coefficients(fc: list[float]) -> tuple[list[float], list[float]]:
    """The transfer function of the filter the law runs with the coefficient buffer ``fc``
    (:func:`distctrl.control.filters.design_coefficients`), as polynomials in ``z^-1``:
    ``(b, a)`` with ``F(z) = (b0 + b1 z^-1 + ...) / (a0 + a1 z^-1 + ...)``.

    Each filter type's :attr:`~distctrl.control.filters.FilterKind.polynomials`, read off
    :func:`distctrl.control.law.filter_step`: PASS ``1``; MOVING_AVERAGE the mean of the last n
    values; EXPO_MEAN ``alpha x + beta sum_(k=1..n-1) rho^k x_(-k)``; KALMAN_MA / KALMAN_EXPO
    ``K x + (1 - K) sum_i c_i x_(-(n-i))`` (the prediction from the n previous measurements, c oldest
    first); LOWPASS the product of the second-order sections.
    """
    kind = int(fc[law.FC_KIND])
    desc = FILTER_KINDS.get(kind)
    if desc is None or desc.polynomials is None:
        raise MarginsError(f"filter kind {kind} has no linear model")  # pragma: no cover - every core kind has one
    return desc.polynomials(fc)


def _zinv(b, a, T: float) -> "control.TransferFunction":
    """``(b0 + b1 z^-1 + ...) / (a0 + a1 z^-1 + ...)`` as a python-control transfer function in z."""
    import control

    m = max(len(b), len(a))
    return control.tf(list(b) + [0.0] * (m - len(b)), list(a) + [0.0] * (m - len(a)), dt=T)


def _delay(n: int, T: float) -> "control.TransferFunction":
    """``z^-n``."""
    return _zinv([0.0] * n + [1.0], [1.0], T)


# ------------------------------------------------------------------------------------------------------
# the model
# ------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LoopModel:
    """The linearised loop of one distance-controlled axis (mm, s, Hz; gains dimensionless).

    ``filter_b`` / ``filter_a`` are the filter's polynomials in ``z^-1`` (:func:`filter_coefficients`);
    ``i_gain`` is the core's ``T / T_n`` (0 without I part), ``d_gain`` its per-cycle D gain for this
    ``kp``. Use :meth:`with_kp` to change KP (the D gain follows it as in the core).
    """

    axis: str
    mode: str                          # "CONST_DIST" or "SET_POS"
    both_encoders: bool                # P-AXIS-00500 (CONST_DIST only)
    cycle_time: float                  # s
    kp: float
    i_tn: float                        # s, 0: no I part
    d_tv: float                        # s, 0: no D part
    i_gain: float                      # T / T_n as the core bounds it
    d_gain: float                      # per-cycle D gain g (law.derivative_gain)
    filter_label: str
    filter_b: tuple[float, ...]
    filter_a: tuple[float, ...]
    sensor_gain: float                 # reported distance per true distance (1; slope of a characteristic)
    sensor_delay_cycles: int           # scenario sensor.delay_cycles
    optimized_scheduling: bool         # P-AXIS-00426: off adds one cycle
    kv: float                          # 1/s
    feedforward: float                 # 0..1
    bus_delay_cycles: int
    scenario: str = ""
    kp_source: str = "parameter list"
    notes: tuple[str, ...] = ()
    resonance_hz: float = 0.0          # the drive's mechanical resonance f0 (0: rigid)
    damping: float = 0.05              # its damping ratio zeta
    #: LOWPASS: the Butterworth's second-order sections ``(b0, b1, b2, a0, a1, a2)`` as the law runs them;
    #: the frequency response and the closed loop's poles are computed from them, not from
    #: ``filter_b`` / ``filter_a`` (their product loses digits next to z = 1 for 4th-5th order filters)
    filter_sos: tuple[tuple[float, ...], ...] = ()

    # -- derived ----------------------------------------------------------------------------------------
    @property
    def dead_time_cycles(self) -> int:
        """Cycles between the drive's position and the reading the filter gets: the machine's read (1),
        the sensor's dead time and, without optimized scheduling, the core's one-cycle delay."""
        return READ_DELAY_CYCLES + self.sensor_delay_cycles + (0 if self.optimized_scheduling else 1)

    def with_kp(self, kp: float) -> "LoopModel":
        """The same loop with another KP; the D gain follows KP as the core computes it."""
        return dataclasses.replace(self, kp=float(kp), d_gain=law.derivative_gain(float(kp), self.d_tv,
                                                                                   self.cycle_time))

    # -- blocks -----------------------------------------------------------------------------------------
    def blocks(self) -> dict[str, "control.TransferFunction"]:
        """The blocks as python-control transfer functions: ``filter``, ``pid`` (the offset step per
        remaining error, P + I + D as one block where D acts on the error's measurement part, see
        :meth:`loop`), ``pi`` (P + I only), ``d`` (the D part), ``integration`` (offset), ``dead_time``
        (the measurement's ``z^-N``), ``drive`` (setpoint -> position)."""
        T = self.cycle_time
        kvT = self.kv * T
        ff = self.feedforward
        integ = _zinv([1.0], [1.0, -1.0], T)
        pi = self.kp + self.kp * self.i_gain * integ
        d = self.d_gain * _zinv([1.0, -1.0], [1.0], T)
        drive = _delay(self.bus_delay_cycles, T) * _zinv([kvT + ff, -ff], [1.0, -(1.0 - kvT)], T)
        blocks = {"filter": _zinv(self.filter_b, self.filter_a, T), "pi": pi, "d": d, "pid": pi + d,
                  "integration": integ, "dead_time": _delay(self.dead_time_cycles, T), "drive": drive}
        if self.resonance_hz:
            blocks["resonance"] = _zinv(*resonance_polynomials(self.resonance_hz, self.damping, T), T)
        return blocks

    def _polynomials(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(L_num, den, G_w_num): the open loop ``L = L_num / den`` and the path from the surface the
        sensor sees (a rise w, mm) to the offset, ``G_w = G_w_num / den``, as polynomials in ``z^-1``
        (ascending powers) over **one** denominator, so that ``o = G_w_num / (den + L_num) w`` and the
        closed loop's poles are the roots of ``den + L_num``. (Adding transfer functions multiplies
        their denominators: a pole and a zero would cancel only up to rounding and leave spurious
        closed-loop poles, e.g. on the unit circle.)

        With ``Delta = 1 - z^-1``, the drive ``P = Pn / Pd``, the filter ``F = Fb / Fa``, the dead time
        ``z^-N`` and the PID ``C = Cn / Cd`` (``Cd = Delta`` with an I part, else 1):

        * the filter input (law.feedback_value) is ``fb = Hn / Pd o + Hw w``: one encoder
          ``Hn = ks z^-N Pn`` (the distance d), both encoders ``ks z^-N Pn + z^-1 (Pd - Pn)`` (d + c - a,
          c = p + o_(k-1), a = z^-1 X), SET_POS ``z^-1 Pn - ks z^-N Pn`` (a - d); ``Hw = -+ks z^-(N-1)``;
        * law.mode_error: CONST_DIST ``e = m = -F fb``, so ``Delta o = -C F fb``; SET_POS ``e = F fb -
          z^-1 o``, ``m = F fb``, so ``Delta o = C F fb - C_PI z^-1 o`` (the D part is on m only).

        A resonant drive (``R = Rn / Rd`` from motor to nozzle): the sensor's ``Pn`` becomes ``Pn Rn``,
        the motor encoder's ``Pn`` becomes ``Pn Rd`` and every ``Pd`` ``Pd Rd``.
        """
        P = np.polynomial.polynomial
        T = self.cycle_time
        kvT, ff = self.kv * T, self.feedforward
        n, ks = self.dead_time_cycles, self.sensor_gain
        delta = np.array([1.0, -1.0])
        z1 = np.array([0.0, 1.0])
        zn = np.r_[np.zeros(n), 1.0]
        zn1 = np.r_[np.zeros(n - 1), 1.0]
        pn = np.r_[np.zeros(self.bus_delay_cycles), kvT + ff, -ff]
        pd = np.array([1.0, -(1.0 - kvT)])
        pn_enc = pn                                                     # what the motor encoder reports
        if self.resonance_hz:
            rn, rd = resonance_polynomials(self.resonance_hz, self.damping, T)
            pn, pn_enc, pd = P.polymul(pn, rn), P.polymul(pn, rd), P.polymul(pd, rd)
        fb, fa = np.asarray(self.filter_b, dtype=float), np.asarray(self.filter_a, dtype=float)
        kp, ti, g = self.kp, self.i_gain, self.d_gain
        if ti > 0.0:
            cpi = kp * P.polyadd(delta, [ti])                           # KP (Delta + T/T_n) / Delta
            cd = delta
            cn = P.polyadd(cpi, g * P.polymul(delta, delta))
        else:
            cpi, cd = np.array([kp]), np.array([1.0])
            cn = P.polyadd([kp], g * delta)
        d_o = ks * P.polymul(zn, pn)
        if self.mode == "SET_POS":
            hn, hw, sign = P.polysub(P.polymul(z1, pn_enc), d_o), ks * zn1, -1.0
        elif self.both_encoders:
            hn, hw, sign = P.polyadd(d_o, P.polymul(z1, P.polysub(pd, pn_enc))), -ks * zn1, 1.0
        else:
            hn, hw, sign = d_o, -ks * zn1, 1.0
        den = P.polymul(P.polymul(cd, fa), P.polymul(pd, delta))
        forward = P.polymul(cn, fb)                                     # C F over Cd Fa
        l_num = sign * P.polymul(forward, hn)
        if self.mode == "SET_POS":
            l_num = P.polyadd(l_num, P.polymul(P.polymul(cpi, z1), P.polymul(fa, pd)))
        g_num = -sign * P.polymul(P.polymul(forward, hw), pd)
        return l_num, den, g_num

    def _factors(self, zi: np.ndarray) -> dict[str, np.ndarray]:
        """The loop's low-order factors evaluated at ``zi`` (= z^-1), as :meth:`_polynomials` multiplies
        them out: ``cn``, ``cd``, ``cpi`` (PID), ``F`` (filter, by sections for LOWPASS), ``hn`` (the
        mode's feedback numerator), ``pd`` (drive denominator), ``delta``, ``sign``."""
        P = np.polynomial.polynomial
        T = self.cycle_time
        kvT, ff = self.kv * T, self.feedforward
        zi = np.asarray(zi, dtype=complex)
        delta = 1.0 - zi
        pn = zi ** self.bus_delay_cycles * ((kvT + ff) - ff * zi)
        pd = 1.0 - (1.0 - kvT) * zi
        pn_enc = pn
        if self.resonance_hz:
            rn, rd = (P.polyval(zi, c) for c in resonance_polynomials(self.resonance_hz, self.damping, T))
            pn, pn_enc, pd = pn * rn, pn * rd, pd * rd
        if self.filter_sos:
            F = np.ones_like(zi)
            for sec in self.filter_sos:
                F = F * P.polyval(zi, sec[:3]) / P.polyval(zi, sec[3:])
        else:
            F = P.polyval(zi, np.asarray(self.filter_b, float)) / P.polyval(zi, np.asarray(self.filter_a, float))
        kp, ti, g = self.kp, self.i_gain, self.d_gain
        if ti > 0.0:
            cpi, cd = kp * (delta + ti), delta
            cn = cpi + g * delta * delta
        else:
            cpi, cd = np.full_like(zi, kp), np.ones_like(zi)
            cn = kp + g * delta
        d_o = self.sensor_gain * zi ** self.dead_time_cycles * pn
        if self.mode == "SET_POS":
            hn, sign = zi * pn_enc - d_o, -1.0
        elif self.both_encoders:
            hn, sign = d_o + zi * (pd - pn_enc), 1.0
        else:
            hn, sign = d_o, 1.0
        return {"cn": cn, "cd": cd, "cpi": cpi, "F": F, "hn": hn, "pd": pd, "delta": delta, "sign": sign,
                "zi": zi}

    def response(self, w) -> np.ndarray:
        """The open loop's frequency response ``L(e^(j w T))`` at ``w`` (rad/s), evaluated factor by factor
        (the filter by its sections): the same loop as :meth:`loop`, without the digits its multiplied-out
        polynomials lose next to z = 1."""
        w = np.asarray(w, dtype=float)
        f = self._factors(np.exp(-1j * w * self.cycle_time))
        with np.errstate(all="ignore"):
            L = f["sign"] * (f["cn"] * f["F"]) * f["hn"] / (f["cd"] * f["delta"] * f["pd"])
            if self.mode == "SET_POS":
                L = L + f["cpi"] * f["zi"] / (f["cd"] * f["delta"])
        return L

    def loop_state_space(self) -> "control.StateSpace":
        """The open loop as a series of small state-space blocks (the PID and offset integration, each
        filter section, the feedback path ``sign Hn / Pd``; SET_POS adds ``C_PI z^-1`` in parallel ahead
        of the integration), so that the closed loop's poles are eigenvalues of a matrix built from
        low-order pieces instead of roots of one high-order polynomial."""
        import control

        P = np.polynomial.polynomial
        T = self.cycle_time
        kvT, ff = self.kv * T, self.feedforward
        n = self.dead_time_cycles
        delta = np.array([1.0, -1.0])
        z1 = np.array([0.0, 1.0])
        pn = np.r_[np.zeros(self.bus_delay_cycles), kvT + ff, -ff]
        pd = np.array([1.0, -(1.0 - kvT)])
        pn_enc = pn
        if self.resonance_hz:
            rn, rd = resonance_polynomials(self.resonance_hz, self.damping, T)
            pn, pn_enc, pd = P.polymul(pn, rn), P.polymul(pn, rd), P.polymul(pd, rd)
        kp, ti, g = self.kp, self.i_gain, self.d_gain
        if ti > 0.0:
            cpi, cd = kp * P.polyadd(delta, [ti]), delta
            cn = P.polyadd(cpi, g * P.polymul(delta, delta))
        else:
            cpi, cd = np.array([kp]), np.array([1.0])
            cn = P.polyadd([kp], g * delta)
        d_o = self.sensor_gain * P.polymul(np.r_[np.zeros(n), 1.0], pn)
        if self.mode == "SET_POS":
            hn, sign = P.polysub(P.polymul(z1, pn_enc), d_o), -1.0
        elif self.both_encoders:
            hn, sign = P.polyadd(d_o, P.polymul(z1, P.polysub(pd, pn_enc))), 1.0
        else:
            hn, sign = d_o, 1.0
        sections = self.filter_sos or ((tuple(self.filter_b), tuple(self.filter_a)),)
        blocks = [control.ss(_zinv(cn, [1.0], T))]
        for sec in sections:
            b, a = (sec[:3], sec[3:]) if self.filter_sos else sec
            blocks.append(control.ss(_zinv(b, a, T)))
        blocks.append(control.ss(_zinv(sign * np.asarray(hn), pd, T)))
        G = blocks[0]
        for blk in blocks[1:]:
            G = control.series(G, blk)
        if self.mode == "SET_POS":
            G = control.parallel(G, control.ss(_zinv(P.polymul(cpi, z1), [1.0], T)))
        return control.series(G, control.ss(_zinv([1.0], P.polymul(cd, delta), T)))

    def loop(self) -> "control.TransferFunction":
        """The open loop L(z) (negative feedback): filter x PID x offset integration x dead time x drive
        in the mode's feedback. For plain CONST_DIST it is exactly the product of :meth:`blocks`."""
        l_num, den, _ = self._polynomials()
        return _zinv(l_num, den, self.cycle_time)

    def closed_loop(self) -> "control.TransferFunction":
        """From a rise of the surface the sensor sees (mm) to the offset (mm)."""
        l_num, den, g_num = self._polynomials()
        return _zinv(g_num, np.polynomial.polynomial.polyadd(den, l_num), self.cycle_time)

    def closed_loop_poles(self) -> np.ndarray:
        """The closed loop's poles: eigenvalues of the feedback of :meth:`loop_state_space` (the roots of
        ``den + L_num`` agree for low-order loops, but lose digits for a 4th-5th order low-pass whose poles
        crowd next to z = 1 with the drive's, the resonance's and the integrator's; seen: |z| 1.0037
        instead of 0.9970). Poles the series connection adds at z = 0 (delays) do not matter here."""
        import control

        cl = control.feedback(self.loop_state_space(), 1)
        return np.linalg.eigvals(np.asarray(cl.A, dtype=float)) if cl.nstates else np.zeros(0, dtype=complex)

    def spectral_radius(self) -> float:
        """The largest |z| of the closed loop's poles (> 1: unstable)."""
        p = self.closed_loop_poles()
        return float(np.max(np.abs(p))) if p.size else 0.0

    def offset_response(self, w_mm: float, cycles: int) -> np.ndarray:
        """The offset (mm) over ``cycles`` cycles after the surface the sensor sees rises by ``w_mm``
        (the reading changes in cycle 0); the linear prediction of the simulator's ``<axis>.dc.offset``."""
        import control

        resp = control.step_response(self.closed_loop(), T=np.arange(cycles) * self.cycle_time)
        return w_mm * np.asarray(resp.outputs, dtype=float).reshape(-1)

    def describe(self) -> dict[str, Any]:
        """The model's parameters (JSON-ready; units in the key names)."""
        return {"axis": self.axis, "mode": self.mode, "both_encoders": self.both_encoders,
                "cycle_time_s": self.cycle_time, "kp": self.kp, "kp_source": self.kp_source,
                "i_tn_s": self.i_tn, "d_tv_s": self.d_tv, "i_gain_per_cycle": self.i_gain,
                "d_gain_per_cycle": self.d_gain, "filter": self.filter_label,
                "filter_b": list(self.filter_b), "filter_a": list(self.filter_a),
                "sensor_gain": self.sensor_gain, "sensor_delay_cycles": self.sensor_delay_cycles,
                "optimized_scheduling": self.optimized_scheduling,
                "dead_time_cycles": self.dead_time_cycles, "dead_time_s": self.dead_time_cycles * self.cycle_time,
                "drive_kv_per_s": self.kv, "drive_feedforward": self.feedforward,
                "drive_bus_delay_cycles": self.bus_delay_cycles,
                "drive_resonance_hz": self.resonance_hz, "drive_damping": self.damping if self.resonance_hz else None,
                "notes": list(self.notes)}


def resonance_polynomials(resonance_hz: float, damping: float, cycle_time: float) -> tuple[np.ndarray, np.ndarray]:
    """``(Rn, Rd)``: the nozzle per motor position of a resonant drive, polynomials in ``z^-1``
    (ascending), exactly as :class:`distctrl.sim.drive.Drive` steps it.

    The deflection e after cycle k is ``s_k = Phi (s_(k-1) - [0, dv_k])``, with ``dv_k = (1 - z^-1)^2 x / T``
    the change of the motor velocity; its first row gives ``E / dv = -p12 / (1 - tr(Phi) z^-1 + det(Phi) z^-2)``
    and the nozzle ``N = X + E``: ``Rd = [1, -tr, det]``, ``Rn = Rd - (p12 / T) [1, -2, 1]`` (static gain 1)."""
    from ..sim.physics import resonance_coefficients

    p11, p12, p21, p22 = resonance_coefficients(resonance_hz, damping, cycle_time)
    rd = np.array([1.0, -(p11 + p22), p11 * p22 - p12 * p21])
    rn = rd - (p12 / cycle_time) * np.array([1.0, -2.0, 1.0])
    return rn, rd


def model_from_parts(params, cycle_time: float, *, axis: str = "Z", mode: str = "CONST_DIST",
                     kv: float = 40.0, feedforward: float = 0.0, bus_delay_cycles: int = 1,
                     sensor_delay_cycles: int = 0, sensor_gain: float = 1.0, scenario: str = "",
                     kp_source: str = "parameter list", tuning=None, notes: tuple[str, ...] = (),
                     resonance_hz: float = 0.0, damping: float = 0.05) -> LoopModel:
    """The loop of an axis from its parameter list (``AxisParameters``), drive and sensor data.

    ``tuning`` (a :class:`distctrl.control.controller.Tuning`) overrides the list's KP / T_n / T_v and
    filter (e.g. the values an NC block programmed). The gains and the filter coefficients are the
    ones the core itself derives (``AxisDistanceController.law_constants``).
    """
    mode_u = str(mode).upper()
    if mode_u not in ("CONST_DIST", "SET_POS"):
        raise MarginsError(f"mode = {mode!r}; allowed: CONST_DIST or SET_POS")
    if tuning is not None:
        f = tuning.filter
        params = params.replace(kp=tuning.kp, i_tn=tuning.i_tn, d_tv=tuning.d_tv, filter_type=f.filter_type,
                                n_cycles=f.n_cycles, smoothing_factor=f.smoothing_factor,
                                kalman_sigma=f.kalman_sigma, low_pass_filter_order=f.order,
                                low_pass_filter_fg_f0=f.fg_f0)
    ctrl = AxisDistanceController(params, cycle_time)
    c = ctrl.law_constants()
    fc = c["fc"]
    b, a = filter_coefficients(fc)
    sos = ()
    if int(fc[law.FC_KIND]) == law.LOWPASS:
        sos = tuple(tuple(float(v) for v in fc[law.FC_SOS + 6 * s:law.FC_SOS + 6 * s + 6])
                    for s in range(int(fc[law.FC_NSEC])))
    t = ctrl.tuning
    return LoopModel(axis=axis, mode=mode_u, both_encoders=bool(params.use_both_encoders) and mode_u == "CONST_DIST",
                     cycle_time=float(cycle_time), kp=float(t.kp), i_tn=float(t.i_tn), d_tv=float(t.d_tv),
                     i_gain=float(c["i_gain"]), d_gain=float(c["d_gain"]), filter_label=t.filter.label(),
                     filter_b=tuple(b), filter_a=tuple(a), sensor_gain=float(sensor_gain),
                     sensor_delay_cycles=int(sensor_delay_cycles),
                     optimized_scheduling=bool(params.optimized_scheduling), kv=float(kv),
                     feedforward=float(feedforward), bus_delay_cycles=int(bus_delay_cycles),
                     scenario=scenario, kp_source=kp_source, notes=tuple(notes),
                     resonance_hz=float(resonance_hz), damping=float(damping), filter_sos=sos)


def _pick_axis(sc: "Scenario", axis: str | None) -> str:
    dc = [n for n, a in sc.axes.items() if a.params.enabled]
    if axis is not None:
        if axis not in sc.axes:
            raise MarginsError(f"scenario {sc.name!r}: no axis {axis!r}; allowed: one of {', '.join(sc.axes)}")
        if axis not in dc:
            raise MarginsError(f"scenario {sc.name!r}: axis {axis} has no distance control "
                               f"(lr_param.distance_control_on = 0); allowed: {', '.join(dc) or 'none'}")
        return axis
    sensor_axis = sc.sensor.axis if sc.sensor is not None else None
    if sensor_axis in dc:
        return sensor_axis
    if len(dc) == 1:
        return dc[0]
    if not dc:
        raise MarginsError(f"scenario {sc.name!r}: no axis with distance control (P-AXIS-00328 = 1 in a "
                           f"parameter list); allowed: a scenario with a distance-controlled axis")
    raise MarginsError(f"scenario {sc.name!r}: several distance-controlled axes ({', '.join(dc)}); "
                       f"name one with --axis")


def _sensor_gain(sc: "Scenario", distance: float) -> tuple[float, str | None]:
    """The slope of the distance sensor's characteristic at ``distance`` (reported mm), 1 without one."""
    s = sc.sensor
    if s is None or s.kind != "distance" or s.characteristic is None:
        return 1.0, None
    xs = np.array([p[0] for p in s.characteristic])
    ys = np.array([p[1] for p in s.characteristic])
    slopes = np.diff(ys) / np.diff(xs)
    # the segment in which the reported value equals the operating distance (first one found)
    for i, (y0, y1) in enumerate(zip(ys[:-1], ys[1:])):
        if min(y0, y1) <= distance <= max(y0, y1) and slopes[i] != 0.0:
            return float(slopes[i]), (f"sensor characteristic: slope {slopes[i]:.4g} mm/mm at the reported "
                                      f"distance {distance:g} mm")
    return 0.0, (f"sensor characteristic: the reported distance {distance:g} mm is outside the table or on "
                 f"a flat part; slope 0 mm/mm (the loop is open)")


def loop_model(scenario: "Scenario | str | os.PathLike", axis: str | None = None, kp: float | None = None,
               ) -> LoopModel:
    """The linearised loop of ``axis`` (default: the sensor's axis) of a scenario.

    The machine runs the scenario until the program (or a PLC event) first selects distance control on
    the axis, so the mode (CONST_DIST / SET_POS) and the tuning are the ones in force then (KP, I_TN,
    D_TV and the filter of the NC block or the list). A program that never selects it within the
    scenario's duration (at most 60 s) is modelled with the list's values in CONST_DIST, with a note.
    ``kp`` overrides KP (0 < KP <= 2). 3D (channel) distance control is not supported.
    """
    from ..sim.machine import Machine
    from ..sim.runner import load_program
    from ..sim.scenario import Scenario, load_scenario

    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if sc.has_3d or (sc.sensor is not None and sc.sensor.orthogonal):
        raise MarginsError(f"scenario {sc.name!r}: 3D (channel) distance control is not supported by "
                           f"distctrl margins; allowed: a scenario with axis-specific distance control "
                           f"(the axis variant, FCT-M3 ch. 2-11)")
    name = _pick_axis(sc, axis)
    if kp is not None:
        if isinstance(kp, bool) or not isinstance(kp, (int, float)) or not math.isfinite(kp) \
                or not KP_RANGE[0] < kp <= KP_RANGE[1]:
            raise MarginsError(f"KP = {kp!r} is out of range; allowed: {KP_RANGE[0]:g} < KP <= {KP_RANGE[1]:g} "
                               f"(P-AXIS-00759)")
    if sc.sensor is None or sc.sensor.axis != name:
        what = "no [sensor]" if sc.sensor is None else f"the sensor measures axis {sc.sensor.axis}"
        raise MarginsError(f"scenario {sc.name!r}: {what}, so nothing closes the loop of axis {name}; allowed: "
                           f"a scenario whose [sensor] axis is {name}")
    ax = sc.axes[name]
    notes: list[str] = []
    machine = Machine(sc, load_program(sc))
    ctrl = machine.controllers[name]
    limit = SELECT_SEARCH_S if sc.duration is None else min(sc.duration, SELECT_SEARCH_S)
    tracking = (HliState.ACTIVE, HliState.ACTIVE_CONST_DIST)
    selected = False
    for _ in range(int(round(limit / sc.cycle_time))):
        machine.step()
        if ctrl.state.hli_state in tracking:
            selected = True
            break
    if selected:
        mode = "CONST_DIST" if ctrl.state.mode == Mode.CONST_DIST else "SET_POS"
        tuning = ctrl.tuning
        source = f"in force at the first select (t = {machine.cycle * sc.cycle_time:.3f} s)"
        distance = ctrl.state.set_dist if mode == "CONST_DIST" else machine.outputs[name].measured_distance
        if sc.sensor.kind == "distance" and ctrl.state.sensor_source != SensorSource.VARIABLE:
            notes.append(f"the sensor writes V.E.{sc.sensor.variable} but {name} reads encoder 2 (no "
                         f"SENSOR_SOURCE=VARIABLE): in the simulator the loop is open; the model assumes it is read")
    else:
        mode, tuning, distance = "CONST_DIST", None, 0.0
        source = "parameter list"
        notes.append(f"the program does not select distance control on {name} within {limit:g} s: the "
                     f"parameter list's KP, I_TN, D_TV and filter, CONST_DIST assumed")
    gain, note = _sensor_gain(sc, distance)
    if note:
        notes.append(note)
    model = model_from_parts(ax.params, sc.cycle_time, axis=name, mode=mode, kv=ax.kv, feedforward=ax.feedforward,
                             bus_delay_cycles=ax.bus_delay_cycles,
                             sensor_delay_cycles=sc.sensor.delay_cycles if sc.sensor is not None else 0,
                             sensor_gain=gain, scenario=str(sc.path or sc.name), kp_source=source,
                             tuning=tuning, notes=tuple(notes), resonance_hz=ax.resonance_hz, damping=ax.damping)
    if kp is not None:
        model = dataclasses.replace(model.with_kp(kp), kp_source="--kp")
    return model


# ------------------------------------------------------------------------------------------------------
# analysis
# ------------------------------------------------------------------------------------------------------
def _finite(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


@dataclass(frozen=True)
class MarginResult:
    """Margins of one loop (python-control's ``stability_margins`` and the KP search).

    ``gain_margin`` (factor; < 1: unstable, the loop gain must fall by it) and ``gain_margin_db``,
    ``phase_margin_deg``, the frequencies in Hz (``phase_crossover_hz``: where the phase is -180 deg and
    the gain margin is read; ``gain_crossover_hz``: where |L| = 1 and the phase margin is read); None
    where a margin does not exist. ``kp_limit``: the KP at which the loop (with I and D as set, the D
    gain following KP as the core computes it) reaches the stability limit, searched up to
    :data:`KP_SEARCH_MAX`; ``limit_frequency_hz`` the oscillation there (the critical closed-loop pole).
    ``kp_times_gain_margin`` is KP x gain margin (equal to ``kp_limit`` when the D part is off).
    ``spectral_radius`` is the largest |z| of the closed loop's poles and ``pole_frequency_hz`` that
    pole's frequency: a small disturbance decays (or grows) by the factor |z| per cycle, oscillating
    at that frequency.
    """

    model: LoopModel
    gain_margin: float | None
    phase_margin_deg: float | None
    stability_margin: float | None
    phase_crossover_hz: float | None
    gain_crossover_hz: float | None
    spectral_radius: float
    pole_frequency_hz: float
    kp_limit: float | None
    limit_frequency_hz: float | None
    #: every crossing python-control found: (gain margin, phase crossover in Hz) and (phase margin in
    #: deg, gain crossover in Hz), lowest frequency first
    gain_margins: tuple[tuple[float, float], ...] = ()
    phase_margins: tuple[tuple[float, float], ...] = ()

    @property
    def stable(self) -> bool:
        return self.spectral_radius <= 1.0 + POLE_TOLERANCE

    @property
    def marginal(self) -> bool:
        """At the stability limit: the largest closed-loop pole on the unit circle (within 1e-6)."""
        return abs(self.spectral_radius - 1.0) <= 1e-6

    @property
    def gain_margin_db(self) -> float | None:
        gm = self.gain_margin
        return None if gm is None or gm <= 0.0 else 20.0 * math.log10(gm)

    @property
    def kp_times_gain_margin(self) -> float | None:
        return None if self.gain_margin is None else self.model.kp * self.gain_margin

    @property
    def verdict(self) -> str:
        if self.marginal:
            return "AT THE STABILITY LIMIT (a small disturbance oscillates without decaying)"
        if not self.stable:
            return "UNSTABLE (a small disturbance grows until the slope limiter or the drive limits it)"
        return "stable (a small disturbance decays)"

    def growth_per_cycle(self) -> float:
        return self.spectral_radius

    def to_dict(self) -> dict[str, Any]:
        """One JSON-ready object; units in the key names; None where a figure does not exist."""
        r = self.spectral_radius
        return {"scenario": self.model.scenario, "model": self.model.describe(),
                "stable": self.stable, "at_stability_limit": self.marginal,
                "verdict": self.verdict.split(" (")[0].lower(),
                "gain_margin": self.gain_margin, "gain_margin_db": self.gain_margin_db,
                "phase_margin_deg": self.phase_margin_deg, "stability_margin": self.stability_margin,
                "phase_crossover_hz": self.phase_crossover_hz, "gain_crossover_hz": self.gain_crossover_hz,
                "kp": self.model.kp, "kp_limit": self.kp_limit, "kp_times_gain_margin": self.kp_times_gain_margin,
                "limit_frequency_hz": self.limit_frequency_hz,
                "all_gain_margins": [{"gain_margin": g, "phase_crossover_hz": f} for g, f in self.gain_margins],
                "all_phase_margins": [{"phase_margin_deg": p, "gain_crossover_hz": f} for p, f in self.phase_margins],
                "closed_loop_pole_max_abs": r, "closed_loop_pole_hz": self.pole_frequency_hz,
                "closed_loop_growth_per_s": math.log(r) / self.model.cycle_time if r > 0 else None}

    # -- text -------------------------------------------------------------------------------------------
    def format_text(self) -> str:
        m = self.model
        T = m.cycle_time
        lines = [f"margins of the distance-control loop of axis {m.axis} ({m.scenario})",
                 f"  mode {m.mode}" + (" with both encoders (P-AXIS-00500)" if m.both_encoders else
                                       " with one encoder" if m.mode == "CONST_DIST" else ""),
                 f"  cycle time T = {T * 1e3:g} ms",
                 "  loop (linear, limiter-free, small signals):",
                 f"    filter       {m.filter_label}",
                 f"    PID          KP = {m.kp:g} ({m.kp_source}), I_TN = " +
                 (f"{m.i_tn:g} s" if m.i_tn > 0 else "0 s (no I part)") +
                 f", D_TV = {m.d_tv:g} s (D gain {m.d_gain:.4g} per cycle)",
                 "    offset       integration of the PID output, 1/(1 - z^-1), no slope limiter",
                 f"    dead time    {_cycles(m.dead_time_cycles)} = {m.dead_time_cycles * T * 1e3:g} ms "
                 f"(machine read 1, sensor delay_cycles {m.sensor_delay_cycles}, optimized_scheduling "
                 f"{'on: 0' if m.optimized_scheduling else 'off: 1'})",
                 f"    drive        kv = {m.kv:g} 1/s, feed-forward {m.feedforward:g}, bus delay "
                 f"{_cycles(m.bus_delay_cycles)}"
                 + (f", resonance {m.resonance_hz:g} Hz (damping {m.damping:g}) between motor and nozzle"
                    if m.resonance_hz else "")
                 + (f"; sensor gain {m.sensor_gain:.4g} mm/mm" if m.sensor_gain != 1.0 else "")]
        for note in m.notes:
            lines.append(f"    note: {note}")
        gm = self.gain_margin
        lines.append(f"  verdict: {self.verdict}")
        lines.append("  gain margin:      " + ("- (no phase crossover)" if gm is None else
                                                f"{gm:.4g} ({self.gain_margin_db:+.2f} dB)"
                                                + (" at " + _hz(self.phase_crossover_hz) if
                                                   self.phase_crossover_hz is not None else "")))
        lines.append("  phase margin:     " + ("- (no gain crossover)" if self.phase_margin_deg is None else
                                                f"{self.phase_margin_deg:.2f} deg"
                                                + (" at " + _hz(self.gain_crossover_hz) if
                                                   self.gain_crossover_hz is not None else "")))
        lines.append(f"  phase crossover:  {_hz(self.phase_crossover_hz)} (-180 deg)")
        lines.append(f"  gain crossover:   {_hz(self.gain_crossover_hz)} (|L| = 1)")
        n_cross = len(self.gain_margins) + len(self.phase_margins)
        if n_cross > 2:
            lines.append(f"  {n_cross} crossings in all (the figures above are the ones closest to the limit, as "
                         f"python-control chooses them" + ("; --json lists every one)" if n_cross > MAX_CROSSINGS_SHOWN
                                                            else "):"))
            if n_cross <= MAX_CROSSINGS_SHOWN:
                lines.extend(f"    gain margin {g:.4g} ({20 * math.log10(g):+.2f} dB) at {_hz(f)}"
                             for g, f in self.gain_margins)
                lines.extend(f"    phase margin {p:.2f} deg at {_hz(f)}" for p, f in self.phase_margins)
            elif self.phase_margins and self.phase_margins[0][1] != self.gain_crossover_hz:
                p, f = self.phase_margins[0]
                lines.append(f"    the lowest gain crossover: phase margin {p:.2f} deg at {_hz(f)}")
        if self.kp_limit is None:
            lines.append(f"  KP at the stability limit: - (none up to KP = {KP_SEARCH_MAX:g})")
        else:
            extra = ""
            kgm = self.kp_times_gain_margin
            if kgm is not None and abs(kgm - self.kp_limit) > 1e-3 * self.kp_limit:
                extra = (f"; KP x gain margin = {kgm:.4g}, which differs because the D gain follows KP"
                         if m.d_tv > 0 else f"; KP x gain margin = {kgm:.4g}")
            beyond = " (beyond the documented 0 < KP <= 2)" if self.kp_limit > KP_RANGE[1] else ""
            lines.append(f"  KP at the stability limit: {self.kp_limit:.4g}{beyond}, oscillating there at "
                         f"{_hz(self.limit_frequency_hz)}{extra}")
        r = self.spectral_radius
        rate = math.log(r) / T if r > 0 else -math.inf
        if r == 0.0:
            lines.append("  closed loop: every pole at z = 0: a small disturbance is gone after a few cycles "
                         "(dead-beat)")
            return "\n".join(lines) + "\n"
        how = "decays" if r < 1 - 1e-6 else "grows" if r > 1 + 1e-6 else "neither grows nor decays"
        rate_text = "" if abs(r - 1.0) <= 1e-6 else \
            f" ({rate:+.1f} 1/s, time constant {abs(1.0 / rate) * 1e3:.1f} ms)"
        lines.append(f"  closed loop: largest pole |z| = {r:.6f} per cycle at {_hz(self.pole_frequency_hz)}: "
                     f"a small disturbance {how}{rate_text}")
        return "\n".join(lines) + "\n"

    # -- plot -------------------------------------------------------------------------------------------
    def plot(self, path: str | os.PathLike | None = None, nyquist: bool = True) -> "Figure":
        """Bode plot of the open loop (magnitude in dB, phase in deg over Hz up to the Nyquist frequency,
        the margins marked by python-control), and beside it the Nyquist plot. Returns the Figure (Agg
        canvas, no pyplot); with ``path`` it is saved too (.png, .svg, .pdf)."""
        import control
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        if path is not None:
            path = check_plot_path(path)
        m = self.model
        T = m.cycle_time
        loop = control.tf(m.loop(), name="L")
        fig = Figure(figsize=(13.0 if nyquist else 8.5, 6.4), layout="constrained")
        FigureCanvasAgg(fig)
        if nyquist:
            grid = fig.add_gridspec(2, 2, width_ratios=(1.5, 1.0))
            ax_mag = fig.add_subplot(grid[0, 0])
            ax_ph = fig.add_subplot(grid[1, 0], sharex=ax_mag)
            ax_ny = fig.add_subplot(grid[:, 1])
        else:
            ax_mag, ax_ph = fig.subplots(2, 1, sharex=True)
        w_lo = 2.0 * math.pi * 0.1
        omega = np.logspace(math.log10(w_lo), math.log10(math.pi / T * 0.999), 2000)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            control.bode_plot(loop, omega, ax=np.array([[ax_mag], [ax_ph]]), Hz=True, dB=True, deg=True,
                              display_margins=True, title="", label="L(z)")
        ax_mag.set_ylabel("|L| [dB]")
        ax_ph.set_ylabel("phase of L [deg]")
        ax_ph.set_xlabel("frequency [Hz]")
        if self.limit_frequency_hz:
            for ax in (ax_mag, ax_ph):
                ax.axvline(self.limit_frequency_hz, color="C3", linestyle=":", linewidth=1.0)
        if nyquist:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                control.nyquist_plot(loop, omega, ax=ax_ny, title="", max_curve_magnitude=5.0,
                                     unit_circle=True)
            ax_ny.set_xlim(-3.0, 1.5)
            ax_ny.set_ylim(-2.5, 2.5)
            ax_ny.set_aspect("equal", adjustable="box")
            ax_ny.set_xlabel("Re L")
            ax_ny.set_ylabel("Im L")
            ax_ny.set_title("Nyquist (zoom on -1)", fontsize="medium")
        gm = self.gain_margin
        head = (f"axis {m.axis} {m.mode}{' both encoders' if m.both_encoders else ''}, KP = {m.kp:g}, "
                f"{m.filter_label}, dead time {_cycles(m.dead_time_cycles)}, kv = {m.kv:g} 1/s")
        tail = (f"gain margin {'-' if gm is None else f'{gm:.3g} ({self.gain_margin_db:+.1f} dB)'}, "
                f"phase margin {'-' if self.phase_margin_deg is None else f'{self.phase_margin_deg:.1f} deg'}, "
                f"KP limit {'-' if self.kp_limit is None else f'{self.kp_limit:.3g}'} at "
                f"{_hz(self.limit_frequency_hz)} — {self.verdict.split(' (')[0].lower()}")
        fig.suptitle(f"Open loop of distance control: {head}\n{tail}", fontsize="medium")
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            fig.savefig(path, dpi=110)
        return fig


def _cycles(n: int) -> str:
    return f"{n} cycle" if n == 1 else f"{n} cycles"


def _hz(f: float | None) -> str:
    return "-" if f is None else f"{f:.2f} Hz"


def check_plot_path(path: str | os.PathLike) -> Path:
    return check_plot_suffix(path, MarginsError)


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


def analyse(model: LoopModel) -> MarginResult:
    """Gain and phase margins (``control.stability_margins`` of the open loop), the closed loop's
    largest pole, and the KP at the stability limit with its oscillation frequency."""
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
    phase_x: dict[float, float] = {}          # frequency (rad/s) -> gain margin
    for w in list(wpcs) + grid_pcs + [w_nyq]:
        if not (math.isfinite(w) and 0.0 < w <= w_nyq * (1.0 + 1e-9)):
            continue
        resp = response(w)
        if resp.real < 0.0 and abs(resp.imag) <= 1e-6 * abs(resp) and \
                not any(math.isclose(w, v, rel_tol=1e-6) for v in phase_x):
            phase_x[w] = 1.0 / abs(resp)
    gain_x: dict[float, float] = {}           # frequency (rad/s) -> phase margin (deg)
    for w in list(wgcs) + grid_gcs:
        if not (math.isfinite(w) and 0.0 < w <= w_nyq * (1.0 + 1e-9)):
            continue
        resp = response(w)
        if abs(abs(resp) - 1.0) <= 1e-6 and not any(math.isclose(w, v, rel_tol=1e-6) for v in gain_x):
            gain_x[w] = float(np.remainder(np.angle(resp, deg=True), 360.0) - 180.0)
    # as python-control's own choice: the gain margin closest to 1, the smallest |phase margin|
    gm = wpc = pm = wgc = math.inf
    if phase_x:
        wpc = min(phase_x, key=lambda w: abs(math.log(phase_x[w])))
        gm = phase_x[wpc]
    if gain_x:
        wgc = min(gain_x, key=lambda w: abs(gain_x[w]))
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
