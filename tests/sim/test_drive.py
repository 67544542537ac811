"""Drive model: first-order step response, bus delay, limits, encoder resolution, stability bound."""
from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from distctrl.errors.config import ConfigError
from distctrl.sim.drive import Drive

T = 0.001


def test_small_step_response_is_first_order_with_bus_delay():
    kv = 30.0
    drive = Drive(T, kv=kv, bus_delay_cycles=1)
    c = 0.001  # small: kv*c = 0.03 mm/s, far from the velocity and acceleration limits
    out = [drive.step(c) for _ in range(400)]
    assert out[0] == 0.0  # the setpoint arrives one cycle late
    for k in range(1, 400):
        assert out[k] == pytest.approx(c * (1.0 - (1.0 - kv * T) ** k), rel=1e-12, abs=1e-18)
    # 63.2 % after one time constant (counted from the cycle the drive sees the setpoint)
    tau_cycles = drive.time_constant / T
    assert tau_cycles == pytest.approx(1.0 / (kv * T), rel=0.02)
    k63 = next(k for k, x in enumerate(out) if x >= c * (1.0 - math.exp(-1.0)))
    assert abs((k63 - 1) - tau_cycles) <= 1.0


@pytest.mark.parametrize("delay", [0, 1, 3])
def test_bus_delay_cycles(delay):
    drive = Drive(T, bus_delay_cycles=delay)
    out = [drive.step(0.01) for _ in range(6)]
    assert out[:delay] == [0.0] * delay
    assert out[delay] > 0.0
    assert list(drive.setpoint_history) == [0.01] * (delay + 1)


@pytest.mark.parametrize("delay", [0, 1, 2])
@pytest.mark.parametrize("ff", [0.0, 0.5, 1.0])
def test_ramp_following_error_and_feedforward(delay, ff):
    v, kv = 10.0, 30.0  # mm/s, 1/s
    drive = Drive(T, kv=kv, bus_delay_cycles=delay, velocity_feedforward=ff)
    for k in range(1, 3001):
        drive.step(v * k * T)
    # setpoint of the call minus returned actual: v*(1 - ff)/kv + (delay - 1)*v*T
    assert v * 3000 * T - drive.actual == pytest.approx(v * (1 - ff) / kv + (delay - 1) * v * T, abs=1e-9)
    assert drive.velocity == pytest.approx(v, rel=1e-9)


def test_large_step_respects_limits_and_settles():
    drive = Drive(T, kv=50.0, v_max=100.0, a_max=1000.0)
    prev_v = 0.0
    for _ in range(3000):
        drive.step(50.0)
        assert abs(drive.velocity) <= 100.0
        assert abs(drive.velocity - prev_v) <= 1000.0 * T * (1 + 1e-12)
        prev_v = drive.velocity
    assert drive.actual == pytest.approx(50.0, abs=1e-6)


def test_encoder_resolution_quantises_actual():
    drive = Drive(T, resolution=0.001)
    for _ in range(50):
        a = drive.step(0.1234567)
        assert a / 0.001 == pytest.approx(round(a / 0.001), abs=1e-9)
    for _ in range(2000):
        drive.step(0.1234567)
    assert abs(drive.actual - 0.1234567) <= 0.001


def test_hard_travel_limits_stop_the_axis():
    drive = Drive(T, kv=50.0, min_pos=-1.0, max_pos=2.0)
    for _ in range(2000):
        a = drive.step(10.0)
        assert -1.0 <= a <= 2.0
    assert drive.actual == 2.0 and drive.at_limit and drive.velocity == 0.0


@pytest.mark.parametrize("kwargs, key", [
    (dict(kv=1000.0), "Drive.kv"),         # kv*T = 1: not monotone any more
    (dict(kv=0.0), "Drive.kv"),
    (dict(a_max=-1.0), "Drive.a_max"),
    (dict(bus_delay_cycles=1.5), "Drive.bus_delay_cycles"),
    (dict(min_pos=1.0, max_pos=0.0), "Drive.max_pos"),
    (dict(max_pos=1.0, initial_position=2.0), "Drive.initial_position"),
])
def test_drive_validation_names_the_key(kwargs, key):
    with pytest.raises(ConfigError) as info:
        Drive(T, **kwargs)
    assert str(info.value).startswith(key + ":")


@settings(max_examples=60, deadline=None)
@given(kv_t=st.floats(0.001, 0.999), v_max=st.floats(1.0, 1000.0), a_max=st.floats(10.0, 20000.0),
       delay=st.integers(0, 3), ff=st.floats(0.0, 1.0),
       setpoints=st.lists(st.floats(-100.0, 100.0), min_size=1, max_size=40), hold=st.integers(1, 60))
def test_drive_never_exceeds_its_limits(kv_t, v_max, a_max, delay, ff, setpoints, hold):
    drive = Drive(T, kv=kv_t / T, v_max=v_max, a_max=a_max, bus_delay_cycles=delay, velocity_feedforward=ff)
    prev_x, prev_v = drive.position, 0.0
    for c in setpoints:
        for _ in range(hold):
            drive.step(c)
            v = drive.velocity
            assert abs(v) <= v_max * (1 + 1e-12)
            assert abs(v - prev_v) <= a_max * T * (1 + 1e-9)
            assert (drive.position - prev_x) / T == pytest.approx(v, rel=1e-6, abs=1e-6)
            prev_x, prev_v = drive.position, v


@settings(max_examples=40, deadline=None)
@given(kv_t=st.floats(0.001, 0.999), c=st.floats(-1e-3, 1e-3))
def test_unsaturated_loop_is_monotone_for_kv_t_below_one(kv_t, c):
    drive = Drive(T, kv=kv_t / T, v_max=1e6, a_max=1e9, bus_delay_cycles=0)
    prev = 0.0
    for _ in range(200):
        x = drive.step(c)
        # never overshoots the setpoint, moves towards it monotonically
        assert min(0.0, c) - 1e-15 <= x <= max(0.0, c) + 1e-15
        assert (x - prev) * c >= -1e-21
        prev = x
