"""Sensors: encoder-probe scaling against the core's formula, range, delay, noise and every fault."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from distctrl.errors.config import ConfigError
from distctrl.sim.sensors import NOISE_BLOCK, DistanceSensor, EncoderProbe, Fault


def core_increments_to_mm(inc: float, num: int, denom: int, sign_reversal: bool, ref_offset: float) -> float:
    """The cycle core's conversion of encoder-2 increments (SPEC §2), written out independently."""
    s = inc * denom / num * 1e-4
    if sign_reversal:
        s = -s
    return s + ref_offset


def run(sensor, axis_z, surface_z=0.0, start=0):
    """Read once per cycle; ``axis_z`` is a sequence of axis positions."""
    return [sensor.read(start + k, z, surface_z) for k, z in enumerate(axis_z)]


# --- encoder probe ------------------------------------------------------------------------------
def test_probe_known_increments():
    # default 1 increment = 0.1 um; tool 1 mm above the surface: s = -d = -1 mm
    assert EncoderProbe().read(0, 21.0, 20.0) == -10000.0
    assert EncoderProbe(sign_reversal=True).read(0, 21.0, 20.0) == 10000.0
    # 4 increments per 10 x 0.1 um = 4 increments per um
    assert EncoderProbe(resolution_num=4, resolution_denom=10).read(0, 21.0, 20.0) == -4000.0
    assert EncoderProbe(ref_offset=-0.5).read(0, 21.0, 20.0) == -5000.0


@settings(max_examples=300, deadline=None)
@given(s=st.floats(-10.0, 10.0), num=st.integers(1, 100000), denom=st.integers(1, 100000),
       rev=st.booleans(), ref=st.floats(-5.0, 5.0))
def test_probe_round_trips_through_core_formula(s, num, denom, rev, ref):
    probe = EncoderProbe(resolution_num=num, resolution_denom=denom, sign_reversal=rev, ref_offset=ref,
                         range_min=-20.0, range_max=20.0)
    raw = probe.read(0, 0.0, s)  # axis at 0, surface at s: reading s
    assert raw == int(raw)
    back = core_increments_to_mm(raw, num, denom, rev, ref)
    half_increment = 0.5 * denom / num * 1e-4
    assert abs(back - s) <= half_increment * (1 + 1e-9) + 1e-12
    assert probe.to_mm(raw) == pytest.approx(back, abs=1e-15)


def test_probe_clamps_to_mechanical_range():
    probe = EncoderProbe(range_min=-5.0, range_max=1.0)
    assert probe.to_mm(probe.read(0, 30.0, 20.0)) == pytest.approx(-5.0)  # far above: stroke end
    assert probe.to_mm(probe.read(1, 15.0, 20.0)) == pytest.approx(1.0)   # pushed in beyond stroke
    assert probe.to_mm(probe.read(2, 22.0, 20.0)) == pytest.approx(-2.0)


def test_probe_reading_is_minus_distance():
    probe = EncoderProbe(resolution_num=1, resolution_denom=10)
    for d in (0.0, 0.3, 1.234, 4.0):
        assert probe.to_mm(probe.read(0, 10.0 + d, 10.0)) == pytest.approx(-d, abs=5e-4)


# --- distance sensor -----------------------------------------------------------------------------
def test_distance_sensor_range_and_quantisation():
    ds = DistanceSensor(range_max=5.0, resolution=0.01)
    assert ds.read(0, 21.2345, 20.0) == pytest.approx(1.23)
    assert ds.read(1, 19.0, 20.0) == 0.0   # tool below the surface: clamped at 0
    assert ds.read(2, 40.0, 20.0) == 5.0   # beyond the range


def test_distance_sensor_characteristic():
    ds = DistanceSensor(range_max=10.0, characteristic=[(0.0, 0.0), (2.0, 2.2), (10.0, 10.0)])
    assert ds.read(0, 1.0, 0.0) == pytest.approx(1.1)
    assert ds.read(1, 2.0, 0.0) == pytest.approx(2.2)
    assert ds.read(2, 6.0, 0.0) == pytest.approx(2.2 + 4.0 * 7.8 / 8.0)
    assert ds.ideal(6.0, 0.0) == pytest.approx(2.2 + 4.0 * 7.8 / 8.0)
    with pytest.raises(ConfigError, match=r"DistanceSensor\.characteristic"):
        DistanceSensor(characteristic=[(0.0, 0.0), (0.0, 1.0)])


# --- dead time -----------------------------------------------------------------------------------
@pytest.mark.parametrize("k", [0, 1, 2, 5])
def test_delay_is_exactly_k_cycles(k):
    ds = DistanceSensor(delay_cycles=k)
    axis = [1.0] * 10 + [2.0] * 10 + [3.0 + 0.1 * i for i in range(10)]
    out = run(ds, axis)
    assert out[k:] == pytest.approx(axis[:len(axis) - k])
    assert out[:k] == [1.0] * k  # starts filled with the first value: no start-up jump


# --- noise ---------------------------------------------------------------------------------------
def test_noise_is_seeded_gaussian_across_blocks():
    n = 3 * NOISE_BLOCK + 17
    a = np.array(run(DistanceSensor(noise_std=0.01, seed=7), [5.0] * n))
    b = np.array(run(DistanceSensor(noise_std=0.01, seed=7), [5.0] * n))
    c = np.array(run(DistanceSensor(noise_std=0.01, seed=8), [5.0] * n))
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    assert abs(a.mean() - 5.0) < 4 * 0.01 / math.sqrt(n)
    assert a.std() == pytest.approx(0.01, rel=0.05)
    assert len(set(a[:NOISE_BLOCK]) & set(a[NOISE_BLOCK:2 * NOISE_BLOCK])) == 0  # fresh block


# --- faults --------------------------------------------------------------------------------------
def test_fault_jump():
    ds = DistanceSensor(faults=[Fault("jump", start_cycle=5, value=0.5)])
    assert run(ds, [1.0] * 10) == pytest.approx([1.0] * 5 + [1.5] * 5)
    ds = DistanceSensor(faults=[Fault("jump", start_cycle=2, value=-0.2, duration_cycles=3)])
    assert run(ds, [1.0] * 7) == pytest.approx([1.0, 1.0, 0.8, 0.8, 0.8, 1.0, 1.0])


def test_fault_jump_on_probe_in_mm():
    probe = EncoderProbe(faults=[Fault("jump", start_cycle=1, value=0.25)])
    out = run(probe, [21.0, 21.0], surface_z=20.0)
    assert [probe.to_mm(v) for v in out] == pytest.approx([-1.0, -0.75])


def test_fault_drift():
    T = 0.001
    ds = DistanceSensor(T, faults=[Fault("drift", start_time=0.003, rate=2.0)])  # 2 mm/s from cycle 3
    out = run(ds, [1.0] * 8)
    assert out == pytest.approx([1.0, 1.0, 1.0, 1.0, 1.0 + 2 * T, 1.0 + 4 * T, 1.0 + 6 * T, 1.0 + 8 * T])


def test_fault_freeze_holds_last_value():
    ds = DistanceSensor(faults=[Fault("freeze", start_cycle=3, duration_cycles=4)])
    axis = [float(i) for i in range(10)]
    assert run(ds, axis) == [0.0, 1.0, 2.0, 2.0, 2.0, 2.0, 2.0, 7.0, 8.0, 9.0]
    ds = DistanceSensor(faults=[Fault("freeze", start_cycle=0)])
    assert run(ds, [1.0, 2.0, 3.0]) == [1.0, 1.0, 1.0]


def test_fault_dropout():
    ds = DistanceSensor(faults=[Fault("dropout", start_cycle=2, duration_cycles=2)])
    assert run(ds, [3.0] * 6) == [3.0, 3.0, 0.0, 0.0, 3.0, 3.0]
    ds = DistanceSensor(faults=[Fault("dropout", start_cycle=1, duration=0.002, value=9.9)])
    assert run(ds, [3.0] * 4) == [3.0, 9.9, 9.9, 3.0]
    probe = EncoderProbe(faults=[Fault("dropout", start_cycle=1, value=-0.5)])
    assert run(probe, [21.0, 21.0], surface_z=20.0) == [-10000.0, -5000.0]


def test_fault_nan_and_inf():
    ds = DistanceSensor(faults=[Fault("nan", start_cycle=1, duration_cycles=2)])
    out = run(ds, [3.0] * 4)
    assert out[0] == 3.0 and math.isnan(out[1]) and math.isnan(out[2]) and out[3] == 3.0
    ds = DistanceSensor(faults=[Fault("nan", start_cycle=0, duration_cycles=1, value=float("-inf"))])
    assert run(ds, [3.0, 3.0]) == [float("-inf"), 3.0]
    with pytest.raises(ConfigError, match=r"Fault\.value"):
        Fault("nan", start_cycle=0, value=1.0)


def test_fault_noise_burst_only_in_window_and_keeps_base_noise():
    base = run(DistanceSensor(noise_std=0.001, seed=3), [5.0] * 3000)
    ds = DistanceSensor(noise_std=0.001, seed=3,
                        faults=[Fault("noise_burst", start_cycle=1000, duration_cycles=1000, value=0.1)])
    out = run(ds, [5.0] * 3000)
    assert out[:1000] == base[:1000] and out[2000:] == base[2000:]
    extra = np.array(out[1000:2000]) - np.array(base[1000:2000])
    assert extra.std() == pytest.approx(0.1, rel=0.1)


def test_fault_injected_at_runtime_and_seen_after_delay():
    ds = DistanceSensor(delay_cycles=2)
    out = [ds.read(k, 1.0, 0.0) for k in range(3)]
    ds.inject(Fault("jump", value=1.0), at_cycle=4)
    out += [ds.read(k, 1.0, 0.0) for k in range(3, 9)]
    assert out == pytest.approx([1.0] * 6 + [2.0] * 3)  # fault at cycle 4 reaches the control at 6


def test_nan_wins_over_freeze():
    ds = DistanceSensor(faults=[Fault("freeze", start_cycle=1),
                                Fault("nan", start_cycle=2, duration_cycles=1)])
    out = run(ds, [1.0, 2.0, 3.0, 4.0])
    assert out[:2] == [1.0, 1.0] and math.isnan(out[2]) and out[3] == 1.0


@pytest.mark.parametrize("kwargs, key", [
    (dict(kind="spike", start_cycle=0), "Fault.kind"),
    (dict(kind="jump", start_cycle=0), "Fault.value"),
    (dict(kind="jump", start_cycle=-1, value=1.0), "Fault.start_cycle"),
    (dict(kind="drift", start_cycle=0, start_time=0.1), "Fault.start_time"),
    (dict(kind="noise_burst", start_cycle=0, value=-1.0), "Fault.value"),
    (dict(kind="dropout", start_cycle=0, duration=-1.0), "Fault.duration"),
])
def test_fault_validation_names_the_key(kwargs, key):
    with pytest.raises(ConfigError) as info:
        Fault(**kwargs)
    assert str(info.value).startswith(key + ":")


def test_fault_without_start_needs_inject_cycle():
    with pytest.raises(ConfigError, match="start_cycle"):
        DistanceSensor(faults=[Fault("freeze")])


@pytest.mark.parametrize("cls, kwargs, key", [
    (EncoderProbe, dict(range_min=1.0, range_max=0.0), "EncoderProbe.range_max"),
    (EncoderProbe, dict(resolution_num=0), "EncoderProbe.resolution_num"),
    (EncoderProbe, dict(delay_cycles=-1), "EncoderProbe.delay_cycles"),
    (DistanceSensor, dict(noise_std=-0.1), "DistanceSensor.noise_std"),
    (DistanceSensor, dict(cycle_time=0.0), "DistanceSensor.cycle_time"),
])
def test_sensor_validation_names_the_key(cls, kwargs, key):
    with pytest.raises(ConfigError) as info:
        cls(**kwargs)
    assert str(info.value).startswith(key + ":")
