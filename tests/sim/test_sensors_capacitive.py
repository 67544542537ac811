"""Capacitive distance sensor (issue 15): the edge effect over the footprint, the characteristic on
top of it, and plume/spark bursts."""
from __future__ import annotations

import math

import numpy as np
import pytest

from distctrl.errors.config import ConfigError
from distctrl.sim.sensors import (D_MIN, Bursts, DistanceSensor, Fault, footprint_offsets)
from distctrl.sim.surface import Step, Surface

EDGE_X = 100.0
#: a sheet at z = 30 for x < 100 mm; beyond the edge the support is 40 mm lower (out of reach)
SHEET = Surface(30.0, [Step(at=EDGE_X, height=-40.0)])


def disc_fraction_over_half_plane(s: float, r: float) -> float:
    """Area fraction of a disc of radius r whose centre is s (|s| <= r) inside the half-plane,
    written out independently: the circular segment beyond the line at distance s."""
    s = max(-r, min(r, s))
    seg = (r * r * math.acos(s / r) - s * math.sqrt(r * r - s * s)) / (math.pi * r * r)
    return 1.0 - seg


# --- footprint sample points -------------------------------------------------------------------
def test_footprint_points_are_point_symmetric_off_the_axes_and_inside_the_disc():
    pts = footprint_offsets(2.0)
    assert len(pts) == 16
    assert all(math.hypot(x, y) < 2.0 for x, y in pts)
    assert all(abs(x) > 1e-9 and abs(y) > 1e-9 for x, y in pts)
    mirrored = {(round(-x, 12), round(-y, 12)) for x, y in pts}
    assert mirrored == {(round(x, 12), round(y, 12)) for x, y in pts}
    # equal-area rings: radius^2 spread evenly, the mean of r^2 is that of the disc (r^2 / 2)
    assert np.mean([x * x + y * y for x, y in pts]) == pytest.approx(2.0 ** 2 / 2)


# --- the edge effect: known values -------------------------------------------------------------
def test_flat_sheet_reads_the_distance():
    s = DistanceSensor(footprint_radius=3.0, surface=SHEET)
    assert s.read(0, 31.0, 30.0, 50.0, 0.0) == pytest.approx(1.0)
    assert s.covered == 1.0


def test_half_over_a_straight_edge_covers_half_and_reads_twice_the_distance():
    # centre exactly on the edge (along X and along Y): half the footprint is over the sheet
    s = DistanceSensor(footprint_radius=3.0, surface=SHEET)
    assert s.read(0, 31.0, 30.0, EDGE_X, 0.0) == pytest.approx(2.0)       # d / covered = 1 / 0.5
    assert s.covered == 0.5
    along_y = Surface(30.0, [Step(at=20.0, height=-40.0, axis="Y")])
    s = DistanceSensor(footprint_radius=1.0, surface=along_y)
    assert s.ideal(30.8, 30.0, 7.0, 20.0) == pytest.approx(1.6)
    assert s.covered == 0.5


def test_reported_distance_is_d_over_covered_and_covered_follows_the_disc_area():
    r = 3.0
    s = DistanceSensor(footprint_radius=r, surface=SHEET)
    errors = []
    for x in np.linspace(EDGE_X - r - 0.5, EDGE_X + 2.5, 60):
        d_seen = s.footprint_distance(31.0, 30.0, x, 0.0)
        f = s.covered
        assert f > 0
        assert d_seen == pytest.approx(1.0 / f)                                 # C ∝ covered / d
        assert s.ideal(31.0, 30.0, x, 0.0) == pytest.approx(min(1.0 / f, 10.0))  # saturated at range_max
        errors.append(f - disc_fraction_over_half_plane(EDGE_X - x, r))
    # 16 samples: the covered fraction is a staircase of 1/16 steps around the disc's true area fraction
    assert max(map(abs, errors)) < 0.1 and np.mean(np.abs(errors)) < 0.035


def test_no_sheet_in_reach_saturates_at_the_range_and_points_in_the_sheet_count_as_d_min():
    s = DistanceSensor(range_max=8.0, footprint_radius=2.0, surface=SHEET)
    assert s.read(0, 31.0, -10.0, EDGE_X + 10.0, 0.0) == 8.0 and s.covered == 0.0
    # nozzle in the sheet: 1/d stays finite (D_MIN), the reading clamps at 0
    assert s.footprint_distance(29.0, 30.0, 50.0, 0.0) == pytest.approx(D_MIN)
    assert s.read(1, 29.0, 30.0, 50.0, 0.0) == pytest.approx(D_MIN)
    assert math.isnan(s.read(2, math.nan, 30.0, 50.0, 0.0))


def test_a_lower_part_within_the_field_range_still_contributes():
    # a step down of 2 mm (not a hole): the lower half is 3 mm away and within reach
    srf = Surface(30.0, [Step(at=EDGE_X, height=-2.0)])
    s = DistanceSensor(footprint_radius=3.0, surface=srf)
    assert s.ideal(31.0, 30.0, EDGE_X, 0.0) == pytest.approx(16 / (8 / 1.0 + 8 / 3.0))   # harmonic mean 1.5
    assert s.covered == 1.0
    near = DistanceSensor(footprint_radius=3.0, surface=srf, field_range=2.5)       # reach 2.5 mm: a hole
    assert near.ideal(31.0, 30.0, EDGE_X, 0.0) == pytest.approx(2.0) and near.covered == 0.5


def test_characteristic_applies_to_what_the_electrode_sees():
    ch = [[0.0, 0.0], [1.0, 1.02], [3.0, 3.0], [10.0, 9.7]]
    s = DistanceSensor(footprint_radius=3.0, surface=SHEET, characteristic=ch)
    assert s.ideal(31.0, 30.0, 50.0, 0.0) == pytest.approx(1.02)              # characteristic point
    assert s.ideal(32.0, 30.0, 50.0, 0.0) == pytest.approx(2.01)              # between points
    assert s.ideal(30.5, 30.0, EDGE_X, 0.0) == pytest.approx(1.02)            # 0.5 mm seen as 1.0 mm
    assert s.ideal(34.0, 30.0, EDGE_X, 0.0) == pytest.approx(3.0 + 5.0 * 6.7 / 7.0)   # 8 mm seen


def test_without_footprint_the_sensor_is_the_point_sensor_bit_for_bit():
    plain = DistanceSensor(noise_std=0.01, seed=4, delay_cycles=2)
    fp0 = DistanceSensor(noise_std=0.01, seed=4, delay_cycles=2, footprint_radius=0.0, surface=SHEET)
    zs = 31.0 + 0.1 * np.sin(np.arange(500) / 30.0)
    a = [plain.read(k, z, 30.0) for k, z in enumerate(zs)]
    b = [fp0.read(k, z, 30.0, EDGE_X, 0.0) for k, z in enumerate(zs)]
    assert a == b


@pytest.mark.parametrize("points", [8, 16, 24, 32])
def test_fewer_or_more_points_keep_the_half_edge_exact_and_refine_the_staircase(points):
    s = DistanceSensor(footprint_radius=3.0, surface=SHEET, footprint_points=points)
    assert len(s.offsets) == points
    assert s.ideal(31.0, 30.0, EDGE_X, 0.0) == pytest.approx(2.0) and s.covered == 0.5
    errors = []
    for x in np.linspace(EDGE_X - 2.0, EDGE_X + 2.0, 81):
        s.footprint_distance(31.0, 30.0, x, 0.0)
        errors.append(abs(s.covered - disc_fraction_over_half_plane(EDGE_X - x, 3.0)))
    assert np.mean(errors) < {8: 0.08, 16: 0.03, 24: 0.03, 32: 0.02}[points]
    assert max(errors) < {8: 0.17, 16: 0.075, 24: 0.065, 32: 0.045}[points]


def test_footprint_needs_a_surface():
    with pytest.raises(ConfigError, match="DistanceSensor.surface"):
        DistanceSensor(footprint_radius=1.0)
    with pytest.raises(ConfigError, match="footprint_radius"):
        DistanceSensor(footprint_radius=-1.0, surface=SHEET)
    with pytest.raises(ConfigError, match="footprint_points"):
        DistanceSensor(footprint_radius=1.0, surface=SHEET, footprint_points=12)


# --- plume/spark bursts ------------------------------------------------------------------------
def _burst_samples(seed: int, n: int, bursts: Bursts, noise_std: float = 0.0):
    s = DistanceSensor(bursts=bursts, seed=seed, noise_std=noise_std)
    out = np.array([s.read(k, 32.0, 30.0) for k in range(n)]) - 2.0
    return s, out


def test_burst_statistics_rate_duration_amplitude_offset():
    b = Bursts(rate=5.0, duration=0.02, amplitude=0.1, offset=-0.05)
    n = 200_000                                                     # 200 s at 1 ms
    s, dev = _burst_samples(11, n, b)
    # starts: Poisson, 5/s over 200 s = 1000 +- 3 sigma (sqrt(1000) = 32)
    assert abs(s.burst_count - 1000) < 100
    active = dev != 0.0
    # P(in a burst) = 1 - exp(-rate * duration) for merged Poisson bursts = 0.0952
    assert active.mean() == pytest.approx(1 - math.exp(-5.0 * 0.02), abs=0.01)
    assert dev[active].mean() == pytest.approx(-0.05, abs=0.005)
    assert dev[active].std() == pytest.approx(0.1, rel=0.05)
    # bursts last whole multiples of 20 cycles (merged ones longer)
    edges = np.flatnonzero(np.diff(active.astype(int)))
    runs = np.diff(edges)[::2] if active[0] == 0 else np.diff(edges)[1::2]
    assert runs.min() >= 20


def test_bursts_are_reproducible_from_the_seed_and_leave_the_normal_noise_alone():
    b = Bursts(rate=3.0, duration=0.01, amplitude=0.2)
    _, a = _burst_samples(7, 20_000, b, noise_std=0.01)
    _, again = _burst_samples(7, 20_000, b, noise_std=0.01)
    _, other = _burst_samples(8, 20_000, b, noise_std=0.01)
    assert np.array_equal(a, again) and not np.array_equal(a, other)
    quiet = DistanceSensor(seed=7, noise_std=0.01)
    base = np.array([quiet.read(k, 32.0, 30.0) for k in range(20_000)]) - 2.0
    outside = np.abs(a - base) < 1e-12
    assert 0.9 < outside.mean() < 1.0                              # outside the bursts: the same noise


def test_bursts_with_rate_zero_never_happen_and_bad_values_are_refused():
    s, dev = _burst_samples(1, 5000, Bursts(rate=0.0, duration=0.01, amplitude=1.0))
    assert s.burst_count == 0 and not dev.any()
    with pytest.raises(ConfigError, match="Bursts.duration"):
        Bursts(rate=1.0, duration=0.0, amplitude=0.1)
    with pytest.raises(ConfigError, match="Bursts.amplitude"):
        Bursts(rate=1.0, duration=0.1, amplitude=-0.1)


def test_bursts_come_before_the_faults_and_the_dead_time():
    b = Bursts(rate=50.0, duration=0.005, amplitude=0.1, offset=0.3)
    plain = DistanceSensor(bursts=b, seed=2)
    late = DistanceSensor(bursts=b, seed=2, delay_cycles=3, faults=[Fault("freeze", start_cycle=400)])
    a = [plain.read(k, 32.0, 30.0) for k in range(500)]
    d = [late.read(k, 32.0, 30.0) for k in range(500)]
    assert any(v != 2.0 for v in a[:400])
    assert d[3:403] == a[:400]                                    # the bursts, 3 cycles late
    assert set(d[403:]) == {a[399]}                               # frozen from cycle 400 on


# --- the footprint's heights: shortcuts give the look-ups' values --------------------------------
def test_footprint_heights_equal_one_look_up_per_point_and_feature():
    from distctrl.sim.sensors import FootprintHeights
    from distctrl.sim.surface import Flat, HeightMap, Ramp, Sine, TiltedPlane
    srf = Surface(20.0, [Flat(), Sine(0.3, 40.0, phase=0.7), Sine(0.1, 7.0, axis="Y"),
                         Step(at=50.0, height=0.5), Step(at=60.0, height=-3.0, width=4.0, ramp_length=1.0),
                         Step(at=10.0, height=1.0, axis="Y", width=2.0), Ramp(70.0, 75.0, 2.0),
                         TiltedPlane(0.01, -0.02, 5.0, 3.0),
                         HeightMap([0.0, 50.0, 100.0], [0.0, 30.0], [[0.0, 0.2, 0.0], [0.1, 0.0, 0.3]])])
    for points in (8, 16, 32):
        offs = footprint_offsets(2.5, points // 8)
        fh = FootprintHeights(srf, offs)
        for x in np.linspace(40.0, 80.0, 161):
            for y in (0.0, 8.5, 9.9, 11.0, 12.3):
                got = fh.heights(x, y)
                want = [srf.height(x + dx, y + dy) for dx, dy in offs]
                assert np.max(np.abs(np.subtract(got, want))) < 1e-12, (x, y)


def test_footprint_heights_look_a_step_up_once_away_from_its_edges():
    from distctrl.sim.sensors import FootprintHeights
    calls = []

    class Counted(Step):
        def z(self, x, y):
            calls.append(x)
            return super().z(x, y)

    srf = Surface(0.0, [Step(at=100.0, height=1.0)])
    srf.features[0].__class__ = Counted                           # a subclass: not a Step, looked up per point
    fh = FootprintHeights(srf, footprint_offsets(3.0))
    fh.heights(50.0, 0.0)
    assert len(calls) == 16
    step = Step(at=100.0, height=1.0)
    fh = FootprintHeights(Surface(0.0, [step]), footprint_offsets(3.0))
    assert fh.edged and not fh.points
    calls.clear()
    step.z = lambda x, y: calls.append(x) or Step.z(step, x, y)   # count the step's own look-ups
    fh = FootprintHeights(Surface(0.0, [step]), footprint_offsets(3.0))
    fh.heights(50.0, 0.0)
    assert calls == [50.0]                                        # far from the edge: once, at the centre
    calls.clear()
    fh.heights(98.0, 0.0)
    assert len(calls) == 16                                       # the edge within reach: every point


def test_footprint_heights_over_holes_match_one_look_up_per_point():
    from distctrl.sim.sensors import FootprintHeights
    from distctrl.sim.surface import Holes, Sine
    holes = Holes([[50.0, 10.0], [58.0, 10.0], [70.0, 14.0]], diameter=6.0, height=-30.0)
    srf = Surface(20.0, [holes, Sine(0.3, 40.0), Step(at=65.0, height=-30.0, width=1.5)])
    offs = footprint_offsets(2.5)
    fh = FootprintHeights(srf, offs)
    assert fh.holes and not fh.points
    inside = 0
    for x in np.linspace(40.0, 80.0, 161):
        for y in (0.0, 6.0, 8.5, 10.0, 12.3, 17.5):
            got = fh.heights(x, y)
            want = [srf.height(x + dx, y + dy) for dx, dy in offs]
            inside += min(want) < 0.0
            assert np.max(np.abs(np.subtract(got, want))) < 1e-12, (x, y)
    assert inside > 50                                            # the sweep does cross the holes


def test_a_capacitive_sensor_over_a_hole_reads_too_far():
    from distctrl.sim.surface import Holes
    srf = Surface(30.0, [Holes([[100.0, 0.0]], diameter=10.0, height=-40.0)])
    s = DistanceSensor(footprint_radius=3.0, surface=srf, range_max=10.0)
    assert s.ideal(31.0, 30.0, 50.0, 0.0) == pytest.approx(1.0) and s.covered == 1.0
    edge = s.ideal(31.0, 30.0, 105.0, 0.0)                       # centre on the rim: about half covered
    assert s.covered == pytest.approx(0.5, abs=0.1) and edge == pytest.approx(1.0 / s.covered)
    assert s.ideal(31.0, -10.0, 100.0, 0.0) == 10.0 and s.covered == 0.0   # over the middle: no sheet
