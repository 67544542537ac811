"""The margin constraint of distctrl tune (distctrl/tuning/robust.py): its frequency response is the
loop of distctrl margins, it sees every crossing of a lightly damped peak, and lowering KP brings a set
into it."""
from __future__ import annotations

import math

import numpy as np
import pytest

from distctrl.base.kinds import FilterType
from distctrl.params.axis import AxisParameters
from distctrl.tuning.robust import KP_FLOOR, MarginConstraint, PlantAllowance
from distctrl.workbench.margins import analyse, model_from_parts

T = 0.001


def _model(**params):
    """The fitted twin of unseen plant 11 (13.5 Hz, zeta 0.018, dead time 4 + 3 + 1 cycles)."""
    p = AxisParameters().replace(**{"kp": 0.05, "i_tn": 0.0, "d_tv": 0.0, "filter_type": FilterType.MOVING_AVERAGE,
                                    "n_cycles": 4, "use_both_encoders": False, **params})
    return p, model_from_parts(p, T, kv=32.56, bus_delay_cycles=4, sensor_delay_cycles=3, sensor_gain=0.97121,
                               resonance_hz=13.5312, damping=0.017831)


@pytest.mark.parametrize("params", [{}, {"kp": 0.02, "n_cycles": 1}, {"kp": 0.01, "i_tn": 0.5, "d_tv": 0.005},
                                    {"kp": 0.01, "filter_type": FilterType.LOWPASS, "low_pass_filter_order": 2,
                                     "low_pass_filter_fg_f0": 6.0}])
def test_the_nominal_response_is_the_margins_loop(params):
    p, model = _model(**params)
    c = MarginConstraint(model)
    mine = c.loop_response(p)[0]
    z = np.exp(2j * math.pi * c.f * T)
    ref = np.asarray(model.loop()(z), dtype=complex)
    sel = c.f > 0.5                                   # the polynomial form loses digits next to z = 1
    np.testing.assert_allclose(mine[sel], ref[sel], rtol=1e-4, atol=1e-9)
    chk = c.check(p)
    r = analyse(model)
    assert chk.nominal_phase_margin_deg == pytest.approx(min(pm for pm, _ in r.phase_margins), abs=0.5)


def test_a_peak_above_0_db_is_refused_and_a_lower_kp_meets_it():
    p, model = _model()
    c = MarginConstraint(model)
    assert len(c.plants) == 36 and len(PlantAllowance().variants(30.0, 0.0, 0.05)) == 6
    chk = c.check(p)
    # the peak crosses 0 dB 19 deg from -1 on the twin itself (audit M2: the distance to -1, no longer
    # "-19 deg"), and a variant's curve passes closer still
    assert not chk.ok and 0.0 <= chk.phase_margin_deg < 30.0 and chk.nominal_phase_margin_deg < 30.0
    q = c.fit_kp(p)
    assert q is not None and KP_FLOOR <= q.kp < p.kp
    good = c.check(q)
    assert good.ok and good.gain_margin >= 2.0 and good.phase_margin_deg >= 30.0
    assert not c.ok(q.replace(kp=round(q.kp * 1.1 + 0.001, 3)))    # the largest KP (to the resolution)
