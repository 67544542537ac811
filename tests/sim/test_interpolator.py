"""Interpolator: exact landing, trapezoid against the closed form, G0 synchronisation, override,
dwell, and property tests on the axis limits."""
from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from distctrl.errors.config import ConfigError
from distctrl.sim.interpolator import AxisLimits, Interpolator, brake_velocity, trapezoid_time

T = 0.001


def run_block(ip: Interpolator, max_cycles: int = 10**6, on_cycle=None) -> list[dict[str, float]]:
    """Step until the block is done; returns the positions of every cycle (start state first)."""
    out = [dict(ip.position)]
    n = 0
    while not ip.done:
        if on_cycle is not None:
            on_cycle(ip, n)
        out.append(ip.step())
        n += 1
        assert n < max_cycles
    return out


def velocities(path: list[dict[str, float]], axis: str) -> list[float]:
    """Axis velocity per cycle (mm/s), with a rest cycle before and after the block."""
    p = [path[0][axis]] + [q[axis] for q in path] + [path[-1][axis]]
    return [(b - a) / T for a, b in zip(p, p[1:])]


def path_speed(path):
    return [math.sqrt(sum((b[k] - a[k]) ** 2 for k in a)) / T for a, b in zip(path, path[1:])]


XYZ = {"X": AxisLimits(200.0, 2000.0, v_rapid=500.0, a_rapid=5000.0),
       "Y": AxisLimits(200.0, 2000.0, v_rapid=500.0, a_rapid=5000.0),
       "Z": AxisLimits(100.0, 1000.0, v_rapid=100.0, a_rapid=1000.0)}


def test_lands_exactly_on_target():
    ip = Interpolator(T, XYZ, start={"X": 0.1, "Y": -3.3, "Z": 7.7})
    for target, feed in [({"X": 123.456789, "Y": 1 / 3}, 3000.0), ({"Z": -0.1}, None),
                         ({"X": 0.3, "Y": 0.1 + 0.2, "Z": math.pi}, 777.0)]:
        ip.start_linear(target, feed)
        path = run_block(ip)
        for k, v in target.items():
            assert path[-1][k] == v  # exact, not approx
        assert ip.path_position == ip.path_length


@pytest.mark.parametrize("length, feed", [(100.0, 6000.0), (100.0, 600.0), (1.0, 6000.0), (0.01, 6000.0),
                                          (37.3, 2345.0)])
def test_trapezoid_time_and_peak_velocity(length, feed):
    ip = Interpolator(T, XYZ)
    ip.start_linear({"X": length}, feed)
    path = run_block(ip)
    cycles = len(path) - 1
    V, A = feed / 60.0, 2000.0
    assert cycles * T == pytest.approx(trapezoid_time(length, V, A), abs=2 * T)
    peak = max(path_speed(path))
    reachable = math.sqrt(length * A)  # triangle peak
    assert peak <= min(V, reachable) * (1 + 1e-9)
    assert peak >= min(V, reachable) - A * T * 1.01


def test_trapezoid_formula():
    assert trapezoid_time(100.0, 100.0, 2000.0) == pytest.approx(1.05)
    assert trapezoid_time(1.0, 100.0, 2000.0) == pytest.approx(2 * math.sqrt(1 / 2000))
    assert trapezoid_time(0.0, 1.0, 1.0) == 0.0


def test_brake_velocity_is_exact_discrete_stopping_velocity():
    dv = 2.0  # mm/s per cycle
    for r in (0.0001, 0.002, 0.0031, 0.05, 1.0, 12.345):
        v = brake_velocity(r, dv, T)
        dist, u = 0.0, v
        while u > 0:
            dist += u * T
            u -= dv
        assert dist == pytest.approx(r, rel=1e-9)


def test_diagonal_feed_is_path_velocity():
    ip = Interpolator(T, XYZ)
    ip.start_linear({"X": 300.0, "Y": 400.0}, 6000.0)  # 100 mm/s along the 3-4-5 diagonal
    path = run_block(ip)
    assert max(path_speed(path)) == pytest.approx(100.0, rel=1e-9)
    assert max(velocities(path, "X")) == pytest.approx(60.0, rel=1e-9)
    assert max(velocities(path, "Y")) == pytest.approx(80.0, rel=1e-9)


def test_feed_above_axis_limit_is_capped():
    ip = Interpolator(T, XYZ)
    ip.start_linear({"Z": 50.0}, 60000.0)  # 1000 mm/s wanted, Z allows 100
    path = run_block(ip)
    assert max(velocities(path, "Z")) == pytest.approx(100.0, rel=1e-9)


def test_rapid_slowest_axis_dominates_and_axes_arrive_together():
    ip = Interpolator(T, XYZ)
    ip.start_linear({"X": 100.0, "Z": 100.0}, None)
    path = run_block(ip)
    vx, vz = velocities(path, "X"), velocities(path, "Z")
    assert max(vz) == pytest.approx(100.0, rel=1e-9)  # Z at its rapid velocity
    assert max(vx) == pytest.approx(100.0, rel=1e-9)  # X slowed down to stay on the line
    assert vx == pytest.approx(vz, abs=1e-6)         # same profile: they arrive together
    L = 100.0 * math.sqrt(2)
    t_closed = trapezoid_time(L, 100 * math.sqrt(2), 1000 * math.sqrt(2))
    assert (len(path) - 1) * T == pytest.approx(t_closed, abs=2 * T)
    # a single-axis rapid of X alone uses the X rapid limits
    ip.start_linear({"X": 0.0}, None)
    assert max(-v for v in velocities(run_block(ip), "X")) == pytest.approx(500.0, rel=1e-9)


def test_override_zero_decelerates_within_a_max_and_holds():
    ip = Interpolator(T, XYZ)
    ip.start_linear({"X": 100.0}, 6000.0)
    speeds = []

    def hold_then_resume(ip, n):
        if n == 300:
            ip.feed_override = 0.0
        if n == 700:
            ip.feed_override = 1.0
        speeds.append(ip.path_velocity)

    path = run_block(ip, on_cycle=hold_then_resume)
    v = velocities(path, "X")
    assert all(abs(b - a) <= 2000.0 * T * (1 + 1e-9) + 1e-6 for a, b in zip(v, v[1:]))
    # fully stopped and holding position before the resume
    assert v[600] == 0.0 and path[650]["X"] == path[700]["X"]
    assert 0.0 < path[700]["X"] < 100.0
    assert path[-1]["X"] == 100.0
    # braking from 100 mm/s at 2000 mm/s^2 takes 50 cycles, not one
    assert v[301] > 90.0 and v[340] > 0.0 and v[352] == 0.0


def test_override_scales_path_velocity():
    ip = Interpolator(T, XYZ)
    ip.feed_override = 0.5
    ip.start_linear({"X": 100.0}, 6000.0)
    assert max(velocities(run_block(ip), "X")) == pytest.approx(50.0, rel=1e-9)
    ip.feed_override = 10.0  # capped by the axis limit
    ip.start_linear({"X": 0.0}, 6000.0)
    assert max(-v for v in velocities(run_block(ip), "X")) == pytest.approx(200.0, rel=1e-9)


def test_dwell_holds_positions_for_whole_cycles():
    ip = Interpolator(T, XYZ, start={"X": 5.0})
    ip.start_dwell(0.0105)
    path = run_block(ip)
    assert len(path) - 1 == 11
    assert all(p == path[0] for p in path)
    ip.start_dwell(0.010)
    assert len(run_block(ip)) - 1 == 10
    ip.start_dwell(0.0)
    assert ip.done


def test_zero_length_move_and_errors():
    ip = Interpolator(T, XYZ)
    ip.start_linear({"X": 0.0}, 1000.0)
    assert ip.done
    ip.start_linear({"X": 1.0}, 1000.0)
    with pytest.raises(RuntimeError):
        ip.start_linear({"X": 2.0}, 1000.0)
    with pytest.raises(RuntimeError):
        ip.start_dwell(1.0)
    run_block(ip)
    with pytest.raises(ConfigError, match="start_linear.target"):
        ip.start_linear({"Q": 1.0}, 1000.0)
    with pytest.raises(ConfigError, match="start_linear.feed_mm_min"):
        ip.start_linear({"X": 1.0}, 0.0)
    with pytest.raises(ConfigError, match="AxisLimits.a_max"):
        AxisLimits(100.0, 0.0)
    assert ip.step() == ip.position  # idle: positions stay


@settings(max_examples=80, deadline=None)
@given(
    limits=st.lists(st.tuples(st.floats(20.0, 500.0), st.floats(10.0, 10000.0),
                              st.floats(20.0, 1000.0), st.floats(10.0, 20000.0)), min_size=3, max_size=3),
    moves=st.lists(st.tuples(st.lists(st.floats(-50.0, 50.0), min_size=3, max_size=3),
                             st.one_of(st.none(), st.floats(1200.0, 30000.0)),
                             st.lists(st.tuples(st.integers(0, 400),
                                                st.one_of(st.just(0.0), st.floats(0.2, 1.5))), max_size=3)),
                   min_size=1, max_size=3),
    cycle_time=st.sampled_from([0.001, 0.0005, 0.002]),
)
def test_never_exceeds_axis_limits_and_always_lands(limits, moves, cycle_time):
    names = ("X", "Y", "Z")
    axes = {n: AxisLimits(*lim) for n, lim in zip(names, limits)}
    ip = Interpolator(cycle_time, axes)
    for target_values, feed, override_changes in moves:
        target = dict(zip(names, target_values))
        start = dict(ip.position)
        ip.feed_override = 1.0
        ip.start_linear(target, feed)
        changes = dict(override_changes)
        prev_p, prev_v, n = dict(start), {k: 0.0 for k in names}, 0
        while True:
            if n in changes:
                ip.feed_override = changes[n]
            if n > 1000 and ip.feed_override == 0.0:
                ip.feed_override = 1.0  # do not hold forever
            p = ip.step() if not ip.done else dict(ip.position)
            for k in names:
                lim = axes[k]
                v_lim = lim.rapid_velocity if feed is None else lim.v_max
                a_lim = lim.rapid_acceleration if feed is None else lim.a_max
                v = (p[k] - prev_p[k]) / cycle_time
                assert abs(v) <= v_lim * (1 + 1e-9) + 1e-6
                assert abs(v - prev_v[k]) <= a_lim * cycle_time * (1 + 1e-9) + 1e-6
                # never beyond the segment between start and target (no overshoot)
                lo, hi = min(start[k], target[k]), max(start[k], target[k])
                assert lo <= p[k] <= hi
                prev_v[k] = v
            prev_p = p
            if ip.done and all(v == 0.0 for v in prev_v.values()):
                break
            n += 1
            assert n < 200_000
        assert ip.position == target


# ------------------------------------------------------------------ look-ahead (issue 28)
def _chain(interp, steps, feeds, use_ahead=True, stop_after=None):
    """Start the blocks one after the other, each when the interpolator is idle (as the machine does), with
    the following ones as ``ahead``; the Z position of every cycle."""
    z, pos, i = [], 0.0, 0
    while i < len(steps) or not interp.done:
        if interp.done and i < len(steps) and (stop_after is None or i < stop_after):
            pos += steps[i]
            ahead = tuple((s, f) for s, f in zip(steps[i + 1:i + 17], feeds[i + 1:i + 17])) if use_ahead else ()
            interp.start_linear({"Z": pos}, feeds[i], ahead=ahead)
            i += 1
        elif interp.done and stop_after is not None and i >= stop_after:
            z.append(interp.step()["Z"])
            if interp.done and interp.path_velocity == 0.0 or len(z) > 10_000:
                break
            continue
        z.append(interp.step()["Z"])
    return z


def test_a_chain_of_short_blocks_runs_one_block_per_cycle_within_a_max():
    T, A = 0.001, 20000.0
    steps = [0.002 * k for k in range(1, 16)] + [0.03] * 10 + [0.002 * k for k in range(15, 0, -1)]
    feeds = [s / T * 60.0 for s in steps]                 # each block's feed covers it in one cycle
    z = _chain(Interpolator(T, {"Z": AxisLimits(v_max=300.0, a_max=A)}), steps, feeds)
    assert len(z) == len(steps)                           # one block per cycle
    assert z[-1] == pytest.approx(sum(steps))
    v = [0.0] + [(b - a) / T for a, b in zip([0.0] + z[:-1], z)]
    assert max(abs(b - a) for a, b in zip(v, v[1:])) <= A * T + 1e-6
    # without look-ahead every block starts and ends at rest: more than one cycle per block
    z0 = _chain(Interpolator(T, {"Z": AxisLimits(v_max=300.0, a_max=A)}), steps, feeds, use_ahead=False)
    assert len(z0) > 1.3 * len(steps)


def test_long_blocks_ignore_the_look_ahead():
    """Blocks longer than SHORT_BLOCK_CYCLES cycles at their feed start and end at rest as before."""
    T = 0.001
    lim = {"Z": AxisLimits(v_max=300.0, a_max=5000.0)}
    steps, feeds = [10.0, 10.0, 10.0], [6000.0] * 3
    assert _chain(Interpolator(T, lim), steps, feeds) == _chain(Interpolator(T, lim), steps, feeds, use_ahead=False)


def test_a_chain_whose_next_block_does_not_come_runs_out_braking_at_a_max():
    T, A = 0.001, 5000.0
    steps = [0.004 * k for k in range(1, 6)] + [0.02] * 40           # up to 20 mm/s, 4 mm/s per cycle
    feeds = [s / T * 60.0 for s in steps]
    z = _chain(Interpolator(T, {"Z": AxisLimits(v_max=300.0, a_max=A)}), steps, feeds, stop_after=20)
    v = [(b - a) / T for a, b in zip(z, z[1:])]
    assert max(abs(b - a) for a, b in zip(v, v[1:])) <= A * T + 1e-6   # no velocity step at the stop
    assert z[-1] <= sum(steps)                                         # within the prepared blocks
