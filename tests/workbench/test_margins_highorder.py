"""distctrl margins with 4th-5th order LOWPASS filters at a low corner frequency (issue 26).

Multiplying the filter's sections and the loop's other blocks out into one pair of polynomials loses
the precision the margins need: the poles of a 5th order Butterworth at 11.8 Hz in a 1 ms cycle, the
drive's, the resonance's and the offset integrator's all sit close to z = 1, and the expanded
polynomials evaluated there (or their roots) are off by percent. Seen on the tuned settings of an
unseen plant (generator seed 217): gain margin 2.6e9 at 91.6 Hz, no phase margin at all, while the
loop crosses 0 dB below 1 Hz and -180 deg at about 4 Hz.

The oracle is independent of margins.py: the loop's frequency response evaluated block by block
(the filter's second-order sections with ``scipy.signal.sosfreqz``, every other block with
``scipy.signal.freqz``), its crossings found on a dense grid (python-control's ``stability_margins`` of
that frequency response data), and the closed loop's stability read off the Nyquist criterion
(the open loop has no pole outside the unit circle: stable exactly when the gain margin > 1 for a loop
whose phase crosses -180 deg once while |L| < 1 beyond its gain crossover).
"""
from __future__ import annotations

import math
import warnings

import control
import numpy as np
import pytest
from scipy import signal

from distctrl.base.kinds import FilterType
from distctrl.params import AxisParameters
from distctrl.workbench.margins import analyse, model_from_parts, resonance_polynomials

T = 0.001
#: the true plant of generator seed 217 (tests/workbench/unseen_plants.py), rounded
KV = 49.156
RES_HZ, ZETA = 10.26, 0.0474
SENSOR_DELAY = 4
BUS_DELAY = 0


def _model(order: int, fg: float, kp: float, tv: float = 0.0):
    kvd = -math.expm1(-KV * T) / T
    p = AxisParameters(enabled=True, kp=kp, d_tv=tv, filter_type=FilterType.LOWPASS,
                       low_pass_filter_order=order, low_pass_filter_fg_f0=fg)
    return model_from_parts(p, T, kv=kvd, bus_delay_cycles=BUS_DELAY, sensor_delay_cycles=SENSOR_DELAY,
                            resonance_hz=RES_HZ, damping=ZETA)


def _oracle_response(m, order: int, fg: float, w: np.ndarray) -> np.ndarray:
    """L(e^(j w T)) block by block: Butterworth sections x PID x offset integration x dead time x drive x
    resonance (CONST_DIST, one encoder: L = ks F C / (1 - z^-1) z^-N P R)."""
    wd = w * T
    sos = signal.butter(order, fg, btype="low", fs=1.0 / T, output="sos")
    _, hf = signal.sosfreqz(sos, worN=wd)
    g = m.d_gain
    _, hc = signal.freqz([m.kp + g, -g], [1.0], worN=wd)             # KP e + g (m - m_prev), no I part
    _, hi = signal.freqz([1.0], [1.0, -1.0], worN=wd)
    _, hd = signal.freqz(np.r_[np.zeros(m.dead_time_cycles), 1.0], [1.0], worN=wd)
    kvT = m.kv * T
    _, hp = signal.freqz(np.r_[np.zeros(m.bus_delay_cycles), kvT], [1.0, -(1.0 - kvT)], worN=wd)
    rn, rd = resonance_polynomials(RES_HZ, ZETA, T)
    _, hr = signal.freqz(rn, rd, worN=wd)
    return hf * hc * hi * hd * hp * hr


def _oracle_margins(m, order, fg):
    f = np.geomspace(0.01, 0.4999 / T, 20000)
    w = 2.0 * math.pi * f
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gm, pm, _, wpc, wgc, _ = control.stability_margins(control.frd(_oracle_response(m, order, fg, w), w))
    return gm, pm, wpc / (2 * math.pi), wgc / (2 * math.pi)


CASES = [  # order, fg (Hz), KP, T_v (s): seed 217's tuned settings, seed 201's and 218's, a lower corner
    (5, 11.8, 0.005, 0.0),
    (4, 11.8, 0.011, 0.0),
    (4, 11.8, 0.009, 0.0),
    (5, 5.0, 0.005, 0.0),
    (5, 23.6, 0.003, 0.0),
]


@pytest.mark.parametrize("order,fg,kp,tv", CASES)
def test_high_order_lowpass_margins_match_the_block_by_block_oracle(order, fg, kp, tv):
    m = _model(order, fg, kp, tv)
    gm, pm, f_pc, f_gc = _oracle_margins(m, order, fg)
    assert 1.5 < gm < 50.0 and 20.0 < pm < 90.0          # the oracle sees an ordinary, stable loop
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = analyse(m)
    assert r.gain_margin == pytest.approx(gm, rel=2e-3)
    assert r.phase_crossover_hz == pytest.approx(f_pc, rel=2e-3)
    assert r.phase_margin_deg == pytest.approx(pm, abs=0.1)
    assert r.gain_crossover_hz == pytest.approx(f_gc, rel=2e-3)
    # the closed loop is stable (Nyquist: no open-loop pole outside the unit circle, gain margin > 1)
    assert r.stable and r.spectral_radius < 1.0
    # without a D part the KP at the stability limit is KP x gain margin (the poles agree with the
    # frequency response)
    assert r.kp_limit == pytest.approx(kp * gm, rel=2e-3)
    assert r.limit_frequency_hz == pytest.approx(f_pc, rel=1e-2)
    # the stability margin (smallest |1 + L|) is at most 1 - 1/GM's neighbourhood and positive
    assert 0.0 < r.stability_margin < 1.0


def test_seed_217_tuned_settings_with_d_part_have_sane_margins():
    """The exact tuned settings of seed 217 (KP 0.005, T_v 0.2 ms): one gain crossover below 1 Hz with
    a positive phase margin, the gain margin of the crossover near 4 Hz (not 2.6e9 at 91.6 Hz)."""
    m = _model(5, 11.8, 0.005, 0.0002)
    gm, pm, f_pc, f_gc = _oracle_margins(m, 5, 11.8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = analyse(m)
    assert r.gain_margin == pytest.approx(gm, rel=2e-3) and r.gain_margin < 100.0
    assert r.phase_margin_deg == pytest.approx(pm, abs=0.1)
    assert r.stable
