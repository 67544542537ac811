"""Plasma arc voltage (issue 15): V = V0 + k·d, ripple and white noise, the kerf jump, and the PLC's
linearisation back into the distance variable (distctrl/plc/arc_voltage.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from distctrl.plc.arc_voltage import ArcVoltageLinearisation
from distctrl.plc.chain import chain
from distctrl.errors.config import ConfigError
from distctrl.sim.sensors import ArcVoltageSensor, Fault
from distctrl.sim.surface import Step, Surface

#: a 2 mm kerf through a sheet at z = 30: x in [100, 102)
KERF = Surface(30.0, [Step(at=100.0, height=-30.0, width=2.0)])


def test_arc_voltage_at_known_distances():
    s = ArcVoltageSensor(v0=95.0, k=6.0)
    assert s.read(0, 31.5, 30.0) == pytest.approx(95.0 + 6.0 * 1.5)      # 104 V at 1.5 mm
    assert s.read(1, 33.0, 30.0) == pytest.approx(113.0)
    assert s.read(2, 29.0, 30.0) == pytest.approx(95.0)                  # in the sheet: arc length 0
    assert s.read(3, 50.0, 30.0) == pytest.approx(95.0 + 6.0 * 10.0)     # clamped at range_max 10 mm
    assert s.voltage(2.0) == pytest.approx(107.0)


def test_noise_faults_and_dead_time_act_on_the_distance_before_the_conversion():
    s = ArcVoltageSensor(v0=100.0, k=5.0, delay_cycles=2,
                         faults=[Fault("jump", start_cycle=5, value=1.0), Fault("dropout", start_cycle=8, value=0.0)])
    v = [s.read(k, 32.0, 30.0) for k in range(12)]
    assert v[:7] == [110.0] * 7                    # 2 mm -> 110 V, the jump arrives 2 cycles late
    assert v[7] == pytest.approx(115.0)            # +1 mm = +5 V
    assert v[10] == pytest.approx(100.0)           # dropout: a 0 mm arc


def test_ripple_at_its_frequency_and_white_noise_in_volts():
    n = 20_000
    s = ArcVoltageSensor(v0=100.0, k=6.0, ripple=2.0, ripple_hz=50.0, voltage_noise_std=0.5, seed=3)
    v = np.array([s.read(k, 31.5, 30.0) for k in range(n)]) - 109.0
    spec = np.abs(np.fft.rfft(v)) * 2 / n
    f = np.fft.rfftfreq(n, 0.001)
    peak = np.argmax(spec)
    assert f[peak] == pytest.approx(50.0) and spec[peak] == pytest.approx(2.0, rel=0.03)
    t = np.arange(n) * 0.001
    white = v - 2.0 * np.sin(2 * np.pi * 50.0 * t)
    assert white.std() == pytest.approx(0.5, rel=0.03) and abs(white.mean()) < 0.02
    again = ArcVoltageSensor(v0=100.0, k=6.0, ripple=2.0, ripple_hz=50.0, voltage_noise_std=0.5, seed=3)
    assert [again.read(k, 31.5, 30.0) for k in range(100)] == list(v[:100] + 109.0)


def test_kerf_jump_follows_the_covered_fraction():
    s = ArcVoltageSensor(v0=95.0, k=6.0, kerf_jump=20.0, footprint_radius=1.5, surface=KERF)
    assert s.ideal(31.5, 30.0, 50.0, 0.0) == pytest.approx(104.0) and s.covered == 1.0
    # centre on the kerf's first edge: half the arc root over the kerf -> + jump / 2
    assert s.ideal(31.5, 30.0, 100.0, 0.0) == pytest.approx(104.0 + 10.0) and s.covered == 0.5
    # centre in the kerf's middle: the arc reaches the sheet on both sides (covered part at 1.5 mm)
    mid = s.ideal(31.5, 0.0, 101.0, 0.0)
    assert 0.0 < s.covered < 0.5 and mid == pytest.approx(104.0 + 20.0 * (1 - s.covered))
    # a point arc root (radius 0) over the kerf: nothing covered, the centre distance, full jump
    p = ArcVoltageSensor(v0=95.0, k=6.0, kerf_jump=20.0, range_max=10.0)
    assert p.read(0, 31.5, 0.0) == pytest.approx(95.0 + 60.0 + 20.0) and p.covered == 0.0
    assert p.read(1, 31.5, 30.0) == pytest.approx(104.0) and p.covered == 1.0


def test_arc_sensor_checks_its_values():
    with pytest.raises(ConfigError, match="ArcVoltageSensor.k"):
        ArcVoltageSensor(k=0.0)
    with pytest.raises(ConfigError, match="ArcVoltageSensor.ripple_hz"):
        ArcVoltageSensor(ripple_hz=500.0)                     # the Nyquist frequency at 1 ms
    with pytest.raises(ConfigError, match="ArcVoltageSensor.surface"):
        ArcVoltageSensor(footprint_radius=1.0)


# --- the PLC linearisation ---------------------------------------------------------------------
class _Machine:
    def __init__(self, **variables):
        self.variables = {f"V.E.{k}": v for k, v in variables.items()}


def test_linearisation_known_values_and_nan():
    plc = ArcVoltageLinearisation(95.0, 6.0, "ARC_VOLTAGE", "V.E.SENSOR")
    m = _Machine(ARC_VOLTAGE=104.0)
    plc(m, 0)
    assert m.variables["V.E.SENSOR"] == pytest.approx(1.5)
    m.variables["V.E.ARC_VOLTAGE"] = 95.0
    plc(m, 1)
    assert m.variables["V.E.SENSOR"] == 0.0
    m.variables["V.E.ARC_VOLTAGE"] = math.nan
    plc(m, 2)
    assert math.isnan(m.variables["V.E.SENSOR"])
    assert math.isnan(plc.distance(math.nan)) and plc.distance(113.0) == pytest.approx(3.0)
    missing = _Machine()
    plc(missing, 0)                                           # no voltage variable: NaN, not an exception
    assert math.isnan(missing.variables["V.E.SENSOR"])


def test_linearisation_inverts_the_arc_sensor():
    s = ArcVoltageSensor(v0=120.0, k=7.5)
    plc = ArcVoltageLinearisation(120.0, 7.5)
    for d in (0.5, 1.0, 2.25, 4.0, 9.5):
        assert plc.distance(s.read(0, 30.0 + d, 30.0)) == pytest.approx(d)


def test_linearisation_runs_a_chained_program_after_it():
    seen = []
    plc = chain(ArcVoltageLinearisation(100.0, 5.0), lambda m, k: seen.append((k, m.variables["V.E.SENSOR"])))
    m = _Machine(ARC_VOLTAGE=110.0)
    plc(m, 7)
    assert seen == [(7, 2.0)]


def test_linearisation_parameters_are_checked():
    with pytest.raises(ConfigError, match="ArcVoltageLinearisation.k"):
        ArcVoltageLinearisation(100.0, 0.0)
    with pytest.raises(ConfigError, match="ArcVoltageLinearisation.v0"):
        ArcVoltageLinearisation(-5.0, 6.0)


# --- the slow-down rise (issue 16) -------------------------------------------------------------
def _drive(s, speeds, z=31.5, start=0):
    """Read once per cycle with the nozzle moving along X at ``speeds`` (mm/s, one per cycle)."""
    x, out = (s._last_xy or (0.0, 0.0))[0], []       # go on from where the last call left the nozzle
    for k, v in enumerate(speeds, start):
        x += v * s.cycle_time
        out.append(s.read(k, z, 30.0, x, 0.0))
    return out


def test_slow_down_off_by_default_leaves_the_voltage_unchanged():
    s = ArcVoltageSensor(v0=95.0, k=6.0)
    assert s.speed_volts == 0.0
    assert _drive(s, [80.0] * 50 + [0.0] * 50) == [104.0] * 100


def test_slow_down_rises_with_the_relative_slow_down_in_a_cut():
    s = ArcVoltageSensor(v0=95.0, k=6.0, speed_volts=10.0, cut_speed=80.0, speed_tau=0.0)
    assert _drive(s, [0.0] * 20) == [104.0] * 20          # at rest before the cut: piercing, nothing
    assert _drive(s, [40.0] * 20, start=20) == [104.0] * 20   # accelerating out of the pierce (< 90 %)
    v = _drive(s, [80.0] * 10 + [40.0] * 10 + [0.0] * 10, start=40)
    assert s.in_cut
    assert v[:10] == pytest.approx([104.0] * 10)           # at the cut speed: no rise
    assert v[11:20] == pytest.approx([109.0] * 9)          # at half the cut speed: half of 10 V
    assert v[21:] == pytest.approx([114.0] * 9)            # at rest in the cut (a corner): all of it
    # the arc breaks when the torch lifts beyond range_max: the next rest is a pierce again
    s.read(100, 45.0, 30.0, 0.0, 0.0)
    assert not s.in_cut and _drive(s, [0.0] * 5, start=101) == [104.0] * 5


def test_slow_down_lags_the_speed_by_its_time_constant():
    s = ArcVoltageSensor(v0=95.0, k=6.0, speed_volts=10.0, cut_speed=80.0, speed_tau=0.02)
    _drive(s, [80.0] * 200)
    v = _drive(s, [0.0] * 100, start=200)
    # first-order lag: after one time constant (20 cycles) 1 - e^-1 of the 10 V
    a = 0.02 / 0.021                      # the discrete lag's pole: T / (tau + T) = 1 - a
    # (the first read has no previous position: speed 0, so 199 cycles at 80 mm/s)
    assert v[19] - 104.0 == pytest.approx(10.0 * (1 - (1 - a ** 199) * a ** 20), rel=1e-9)
    assert 6.0 < v[19] - 104.0 < 6.5 and v[-1] - 104.0 == pytest.approx(10.0, abs=0.1)


def test_slow_down_needs_the_cut_speed():
    with pytest.raises(ConfigError, match="cut_speed"):
        ArcVoltageSensor(speed_volts=5.0)
    with pytest.raises(ConfigError, match="speed_volts"):
        ArcVoltageSensor(speed_volts=-1.0, cut_speed=50.0)
