"""Metrics on synthetic arrays with known answers."""
from __future__ import annotations

import numpy as np
import pytest

from distctrl.tuning.metrics import compute_metrics, cost

T = 0.001


def _limits(n, v=100.0, a=1000.0):
    return {"v_lim": np.full(n, v), "a_lim": np.full(n, a), "w_v": np.ones(n), "w_a": np.ones(n),
            "adaptive": np.zeros(n, bool), "a_min": np.zeros(n), "dev_a_min": np.zeros(n),
            "dev_a_max": np.ones(n), "T": np.full(n, T)}


def test_rms_max_and_window():
    d = np.ones((2, 1000))
    d[0, 100:] += 0.1                      # constant error 0.1 after the select
    d[1, 100:] += np.where(np.arange(900) % 2, 0.2, -0.2)
    d[:, :100] = 9.0                        # before the select: ignored
    m = compute_metrics(np.zeros_like(d), d, 1.0, T, k_on=100, limits=_limits(2))
    assert m["rms_error"] == pytest.approx([0.1, 0.2])
    assert m["max_error"] == pytest.approx([0.1, 0.2])
    assert not m["failed"].any()


def test_overshoot_settling_and_ringing():
    t = np.arange(3000) * T
    # a step response from e = +0.5 that undershoots by about 0.07 mm, then decays
    e = 0.5 * np.exp(-t / 0.01) - 0.2 * (1 - np.exp(-t / 0.01)) * np.exp(-t / 0.05)
    m = compute_metrics(np.zeros((1, 3000)), 1.0 + e[None, :], 1.0, T, k_on=0, band=0.05, hold=0.1)
    assert m["max_error"][0] == pytest.approx(0.5)
    assert m["overshoot"][0] == pytest.approx(-e[:250].min())
    assert 0.05 < m["overshoot"][0] < 0.1
    inb = np.abs(e) <= 0.05
    first_in = next(k for k in range(3000) if inb[k:k + 100].all())
    assert m["settle_time_50um"][0] == pytest.approx(first_in * T)
    assert m["osc_index"][0] == pytest.approx(1 / 3.0)       # one crossing +band -> -band in 3 s
    # a 50 Hz oscillation of 0.1 mm: 100 crossings per second, hf_rms = its RMS
    s = 0.1 * np.sin(2 * np.pi * 50 * t)
    m2 = compute_metrics(np.zeros((1, 3000)), 1.0 + s[None, :], 1.0, T, k_on=0, band=0.05, f_osc=20.0)
    assert m2["osc_index"][0] == pytest.approx(100, rel=0.02)
    assert m2["hf_rms"][0] == pytest.approx(0.1 / np.sqrt(2), rel=1e-3)
    assert np.isnan(m2["settle_time_50um"][0])
    m3 = compute_metrics(np.zeros((1, 3000)), 1.0 + s[None, :], 1.0, T, k_on=0, f_osc=60.0)
    assert m3["hf_rms"][0] < 1e-6


def test_saturation_share():
    n = 1000
    o = np.zeros((3, n))
    o[0] = np.arange(n) * 100.0 * T           # at v_lim the whole time
    o[1] = np.arange(n) * 50.0 * T            # half v_lim, no acceleration
    o[2, 500:] = np.arange(500) * 100.0 * T   # one acceleration step of 100 mm/s in one cycle
    d = np.ones((3, n))
    m = compute_metrics(o, d, 1.0, T, k_on=0, limits=_limits(3, v=100.0, a=1000.0))
    assert m["sat_share"][0] == pytest.approx(1.0, abs=0.003)
    assert m["sat_share"][1] == 0.0
    assert m["sat_share"][2] == pytest.approx(0.5, abs=0.003)


def test_failed_set_costs_inf():
    d = np.ones((2, 100))
    d[1, 50:] = np.nan
    m = compute_metrics(np.zeros((2, 100)), d, 1.0, T, k_on=0)
    assert m["failed"].tolist() == [False, True]
    c = cost(m)
    assert c[0] == 0.0 and np.isinf(c[1])
