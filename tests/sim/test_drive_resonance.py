"""The drive's mechanical resonance (issue 15): motor loop as before, nozzle = motor + deflection.

The discretisation is checked against two independent solutions of the continuous system
``n'' = -w0^2 (n - x) - 2 zeta w0 (n' - x')`` driven by the same piecewise-linear motor trajectory
``x(t)``: scipy.signal.lsim (first-order hold, exact for a piecewise-linear input) and an adaptive
ODE solver (solve_ivp, one segment per cycle), at several f0 up to 1/(4T).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, signal

from distctrl.errors.config import ConfigError
from distctrl.sim.drive import Drive
from distctrl.sim.physics import limit_velocity, quantise, resonance_coefficients, resonance_step

T = 0.001


def _profile(n: int) -> np.ndarray:
    """Setpoints: a step, a ramp, a chirp and a hold (mm), enough to move the motor around."""
    k = np.arange(n)
    t = k * T
    sp = np.where(k >= 5, 0.2, 0.0)
    sp = sp + np.clip((t - 0.05) * 20.0, 0.0, 1.0)
    chirp = 0.05 * np.sin(2 * np.pi * (5.0 * t + 400.0 * t * t)) * ((t > 0.12) & (t < 0.3))
    return sp + chirp


def _run(drive: Drive, setpoints) -> tuple[np.ndarray, np.ndarray]:
    """Motor and nozzle positions at t = 0, T, 2T, ... (the start, then the end of every cycle)."""
    motor, nozzle = [drive.position], [drive.nozzle]
    for c in setpoints:
        drive.step(float(c))
        motor.append(drive.position)
        nozzle.append(drive.nozzle)
    return np.array(motor), np.array(nozzle)


def _lsim_nozzle(motor: np.ndarray, f0: float, zeta: float) -> np.ndarray:
    w0 = 2 * math.pi * f0
    h = signal.lti([2 * zeta * w0, w0 * w0], [1.0, 2 * zeta * w0, w0 * w0])
    t = np.arange(len(motor)) * T
    # the system starts at rest at x(0): simulate the deviation from it (zero initial state)
    _, y, _ = signal.lsim(h, motor - motor[0], t, interp=True)
    return y + motor[0]


def _ode_nozzle(motor: np.ndarray, f0: float, zeta: float) -> np.ndarray:
    """Integrate [n, n'] cycle by cycle; within cycle k the motor moves at (x_k+1 - x_k)/T."""
    w0 = 2 * math.pi * f0
    state = np.array([motor[0], 0.0])
    out = [motor[0]]
    for k in range(len(motor) - 1):
        x0, v = motor[k], (motor[k + 1] - motor[k]) / T

        def rhs(t, s, x0=x0, v=v):
            return [s[1], -w0 * w0 * (s[0] - (x0 + v * t)) - 2 * zeta * w0 * (s[1] - v)]

        sol = integrate.solve_ivp(rhs, (0.0, T), state, method="DOP853", rtol=1e-12, atol=1e-15)
        state = sol.y[:, -1]
        out.append(state[0])
    return np.array(out)


@pytest.mark.parametrize("f0", [5.0, 40.0, 120.0, 250.0])       # 250 Hz = 1/(4T)
@pytest.mark.parametrize("zeta", [0.02, 0.05, 0.3, 1.0])
def test_nozzle_matches_lsim_of_the_continuous_mode(f0, zeta):
    drive = Drive(T, kv=60.0, v_max=200.0, a_max=20000.0, resonance_hz=f0, damping=zeta)
    motor, nozzle = _run(drive, _profile(400))
    ref = _lsim_nozzle(motor, f0, zeta)
    deflection = np.max(np.abs(nozzle - motor))
    assert deflection > 1e-6                  # the mode is excited at all
    assert np.max(np.abs(nozzle - ref)) <= 1e-9 * max(1.0, np.max(np.abs(motor)))


@pytest.mark.parametrize("f0", [10.0, 40.0, 250.0])
def test_nozzle_matches_an_ode_solver(f0):
    drive = Drive(T, kv=60.0, v_max=200.0, a_max=20000.0, resonance_hz=f0, damping=0.05)
    motor, nozzle = _run(drive, _profile(150))
    ref = _ode_nozzle(motor, f0, 0.05)
    assert np.max(np.abs(nozzle - ref)) <= 1e-9


def test_the_motor_loop_and_encoder_do_not_change_with_a_resonance():
    """The loop is closed on the motor encoder: motor, encoder and velocity are today's values."""
    sp = _profile(300)
    rigid = Drive(T, kv=50.0, resolution=1e-4, velocity_feedforward=0.3)
    res = Drive(T, kv=50.0, resolution=1e-4, velocity_feedforward=0.3, resonance_hz=40.0, damping=0.05)
    for c in sp:
        a, b = rigid.step(float(c)), res.step(float(c))
        assert a == b and rigid.position == res.position and rigid.velocity == res.velocity
        assert rigid.nozzle == rigid.position
    assert res.nozzle != res.position


def _reference_rigid(setpoints, *, kv, v_max, a_max, bus, res, ff):
    """The documented rigid drive (docs/sim-models.md "Drive"), written out independently."""
    hist = [0.0] * (bus + 1)
    x = a = v_prev = c_prev = 0.0
    out = []
    for sp in setpoints:
        hist = hist[1:] + [sp]
        c = hist[0]
        v = kv * (c - a)
        if ff:
            v += ff * (c - c_prev) * (1.0 / T)
        c_prev = c
        v = limit_velocity(v, v_max, v_prev, a_max * T)
        x = x + v * T
        v_prev = v
        a = quantise(x, res, 1.0 / res) if res else x
        out.append((x, a, v))
    return out


@pytest.mark.parametrize("res,ff,bus", [(0.0, 0.0, 1), (1e-4, 0.0, 0), (1e-3, 0.5, 2)])
def test_resonance_zero_is_the_rigid_drive_bit_for_bit(res, ff, bus):
    sp = [float(c) for c in _profile(500) * 3.0]
    ref = _reference_rigid(sp, kv=45.0, v_max=100.0, a_max=3000.0, bus=bus, res=res, ff=ff)
    for kwargs in ({}, {"resonance_hz": 0.0}, {"resonance_hz": 0.0, "damping": 0.7}):
        d = Drive(T, kv=45.0, v_max=100.0, a_max=3000.0, bus_delay_cycles=bus, resolution=res,
                  velocity_feedforward=ff, **kwargs)
        for c, (x, a, v) in zip(sp, ref):
            assert d.step(c) == a
            assert (d.position, d.velocity, d.nozzle) == (x, v, x)
            assert d.deflection == 0.0 and d.deflection_rate == 0.0


def test_static_deflection_under_constant_acceleration_and_rest():
    """At rest the nozzle returns to the motor; the phi coefficients are expm(A T)."""
    f0, zeta = 40.0, 0.05
    p = resonance_coefficients(f0, zeta, T)
    w0 = 2 * math.pi * f0
    wd = w0 * math.sqrt(1 - zeta * zeta)
    decay = math.exp(-zeta * w0 * T)
    assert p[1] == pytest.approx(decay * math.sin(wd * T) / wd, rel=1e-12)
    assert p[0] == pytest.approx(decay * (math.cos(wd * T) + zeta * w0 / wd * math.sin(wd * T)), rel=1e-12)
    e, de = resonance_step(0.0, 0.0, 1.0, *p)      # a velocity step of 1 mm/s
    assert e == pytest.approx(-p[1]) and de == pytest.approx(-p[3])
    drive = Drive(T, kv=40.0, resonance_hz=f0, damping=zeta)
    for _ in range(3000):
        drive.step(1.0)
    assert drive.nozzle == pytest.approx(drive.position, abs=1e-9)


@pytest.mark.parametrize("kwargs,key", [
    ({"resonance_hz": 250.001}, "resonance_hz"), ({"resonance_hz": -1.0}, "resonance_hz"),
    ({"resonance_hz": 40.0, "damping": 0.0}, "damping"), ({"resonance_hz": 40.0, "damping": 1.5}, "damping"),
    ({"resonance_hz": float("nan")}, "resonance_hz")])
def test_invalid_resonance_is_refused(kwargs, key):
    with pytest.raises(ConfigError, match=key):
        Drive(T, **kwargs)
