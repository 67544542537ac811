"""The linearised loop of one distance-controlled axis: :class:`LoopModel` (its blocks, frequency
response, closed-loop poles) built from the core's numbers (:func:`model_from_parts`), the filter's
transfer function (:func:`filter_coefficients`) and the drive's resonance (:func:`resonance_polynomials`).

Part of :mod:`distctrl.workbench.margins` (docs/margins.md); the package face re-exports every name.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ...control import law
from ...control.controller import AxisDistanceController
from ...control.filters import FILTER_KINDS
from ...errors import DistCtrlError
from ...sim.physics import resonance_coefficients

if TYPE_CHECKING:  # pragma: no cover
    import control

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
    # python-control (about 1 s of import): only where the loop model is built
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
        # python-control (about 1 s of import): only where the loop model is built
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
        # python-control (about 1 s of import): only where the loop model is built
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
        # python-control (about 1 s of import): only where the loop model is built
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
