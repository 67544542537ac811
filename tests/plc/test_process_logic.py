"""Unit tests of the process functions' logic (issue 16) on a fake machine: only the HLI control unit,
V.E. variables, the channel path status and the CNC objects, as a PLC sees them."""
import math

import numpy as np
import pytest

from distctrl.control import CycleOutput
from distctrl.base.states import HliState, HliTransition
from distctrl.plc import DistanceControlUnit
from distctrl.plc.process import (AutoSetValue, CornerLock, ProcessProgram, VoidLock)
from distctrl.plc.process.channel import ChannelPathStatus
from distctrl.errors.config import ConfigError

ACTIVE_CD = int(HliState.ACTIVE_CONST_DIST)
FREEZE = int(HliState.FREEZE)


class FakePath:
    def __init__(self):
        self.D_CommandFeed = 50_000      # µm/s = 3 m/min
        self.D_ActiveFeed = 0
        self.override = 1.0


class FakeMachine:
    """A PLC's view: one axis Z with its control unit; a CNC that takes commands as the states table says."""

    def __init__(self, state=ACTIVE_CD, set_distance=1.5):
        self.hli = {"Z": DistanceControlUnit(1)}
        self.hli["Z"].state_r.actual_state = state
        self.outputs = {"Z": CycleOutput()}
        self.outputs["Z"].set_distance = set_distance
        self.controllers = {"Z": None}
        self.variables = {}
        self.channel_path = FakePath()
        self.T = 0.001
        self.taken = []                  # (transition, position mm) the CNC took

    def cnc(self):
        unit = self.hli["Z"]
        if unit.command_semaphore_rw:
            t, pos = unit.command_w.transition, unit.command_w.position * 1e-4
            unit.command_semaphore_rw = False
            self.taken.append((t, round(pos, 4)))
            if t == HliTransition.FREEZE and unit.state_r.actual_state in (1, 4):
                unit.state_r.actual_state = FREEZE
            elif t == HliTransition.ON_CONST_DIST:
                unit.state_r.actual_state = ACTIVE_CD
                self.outputs["Z"].set_distance = pos
            elif t == HliTransition.ON:
                unit.state_r.actual_state = int(HliState.ACTIVE)
            elif t == HliTransition.OFF:
                unit.state_r.actual_state = int(HliState.INACTIVE)


def run_cycles(m, program, n, before=None, start=0):
    for k in range(start, start + n):
        if before is not None:
            before(m, k)
        program(m, k)
        m.cnc()
    return start + n


# ------------------------------------------------------------------ corner lock
def corner(m, **kw):
    f = CornerLock("Z", **kw)
    return f, ProcessProgram([f])


def test_corner_lock_arms_at_speed_then_freezes_below_share_and_releases_with_hysteresis():
    m = FakeMachine()
    f, prog = corner(m)
    p = m.channel_path
    p.D_ActiveFeed = 0                     # at rest after the select: not armed, no FREEZE
    k = run_cycles(m, prog, 5)
    assert not f.armed and m.taken == []
    p.D_ActiveFeed = 48_000                # 96 % >= 95 %: armed
    k = run_cycles(m, prog, 2, start=k)
    assert f.armed and m.taken == []
    p.D_ActiveFeed = 45_500                # 91 %: still above 90 %
    k = run_cycles(m, prog, 2, start=k)
    assert m.taken == []
    p.D_ActiveFeed = 44_900                # 89.8 % < 90 %: FREEZE
    k = run_cycles(m, prog, 1, start=k)
    assert m.taken == [(int(HliTransition.FREEZE), 0.0)]
    assert m.hli["Z"].state_r.actual_state == FREEZE
    p.D_ActiveFeed = 46_000                # 92 %: inside the hysteresis band, stays frozen
    k = run_cycles(m, prog, 5, start=k)
    assert len(m.taken) == 1
    p.D_ActiveFeed = 47_500                # 95 %: back -> ON_CONST_DIST with the set distance in force
    k = run_cycles(m, prog, 2, start=k)
    assert m.taken[1] == (int(HliTransition.ON_CONST_DIST), 1.5)
    assert m.hli["Z"].state_r.actual_state == ACTIVE_CD


def test_corner_lock_reference_is_feed_times_override():
    m = FakeMachine()
    f, prog = corner(m)
    m.channel_path.override = 0.5
    m.channel_path.D_ActiveFeed = 25_000   # 100 % of F x override: armed, not slow
    run_cycles(m, prog, 10)
    assert f.armed and m.taken == []


def test_corner_lock_never_releases_a_freeze_the_nc_commanded():
    m = FakeMachine(state=FREEZE)          # Z[DIST_CTRL FREEZE] from the program
    f, prog = corner(m)
    m.channel_path.D_ActiveFeed = 50_000
    run_cycles(m, prog, 10)
    assert m.taken == []


def test_corner_lock_forgets_its_hold_when_the_nc_switches_off():
    m = FakeMachine()
    f, prog = corner(m)
    m.channel_path.D_ActiveFeed = 50_000
    k = run_cycles(m, prog, 2)
    m.channel_path.D_ActiveFeed = 0
    k = run_cycles(m, prog, 2, start=k)
    assert m.hli["Z"].state_r.actual_state == FREEZE
    m.hli["Z"].state_r.actual_state = int(HliState.INACTIVE)   # NC: OFF
    m.channel_path.D_ActiveFeed = 50_000
    run_cycles(m, prog, 5, start=k)
    assert [t for t, _ in m.taken] == [int(HliTransition.FREEZE)]
    assert prog.holds["Z"].phase == "IDLE"


def test_hold_waits_for_the_semaphore():
    m = FakeMachine()
    f, prog = corner(m)
    m.channel_path.D_ActiveFeed = 50_000
    k = run_cycles(m, prog, 2)
    m.hli["Z"].command_semaphore_rw = True    # another command is still waiting for the CNC
    m.hli["Z"].command_w.transition = 99
    m.channel_path.D_ActiveFeed = 0
    prog(m, k)
    assert m.hli["Z"].command_w.transition == 99      # not overwritten
    m.cnc()                                           # the CNC takes the other one
    prog(m, k + 1)
    assert m.hli["Z"].command_w.transition == int(HliTransition.FREEZE)


@pytest.mark.parametrize("kw", [{"share": 0.0}, {"share": 1.2}, {"hysteresis": -0.1}, {"share": 0.98, "hysteresis": 0.05}])
def test_corner_lock_refuses_bad_parameters(kw):
    with pytest.raises(ConfigError):
        CornerLock("Z", **kw)


# ------------------------------------------------------------------ void lock
def void(m, **kw):
    kw.setdefault("variable", "ARC_VOLTAGE")
    f = VoidLock("Z", m.T, kw.pop("threshold", 500.0), **kw)
    return f, ProcessProgram([f])


def feed_signal(values):
    it = iter(values)

    def before(m, k):
        m.variables["V.E.ARC_VOLTAGE"] = next(it)
    return before


def test_void_lock_counts_on_cycles_before_freezing():
    m = FakeMachine()
    f, prog = void(m, window=0.005, on_cycles=3, off_cycles=4)
    # 5-cycle window; a steady 110 V, then a ramp of 5 V per cycle = 5000 V/s (rate over the window too)
    k = run_cycles(m, prog, 10, feed_signal([110.0] * 10))
    assert m.taken == []
    k = run_cycles(m, prog, 2, feed_signal([115.0, 120.0]), start=k)
    assert m.taken == [] and f.on_count == 2             # 2 cycles above: not yet
    k = run_cycles(m, prog, 1, feed_signal([125.0]), start=k)
    assert m.taken == [(int(HliTransition.FREEZE), 0.0)] and f.locked
    assert f.level == 110.0                                # the level before the void


def test_void_lock_single_spike_below_on_cycles_does_not_freeze():
    m = FakeMachine()
    f, prog = void(m, window=0.001, on_cycles=3)
    run_cycles(m, prog, 20, feed_signal([110.0] * 5 + [140.0] + [110.0] * 14))
    assert m.taken == []


def test_void_lock_releases_after_off_cycles_of_steady_signal_back_at_its_level():
    m = FakeMachine()
    f, prog = void(m, window=0.002, on_cycles=1, off_cycles=5, release_band=3.0)
    k = run_cycles(m, prog, 5, feed_signal([110.0] * 5))
    k = run_cycles(m, prog, 1, feed_signal([140.0]), start=k)         # the kerf
    assert f.locked
    k = run_cycles(m, prog, 10, feed_signal([140.0] * 10), start=k)   # steady, but 30 V above: held
    assert f.locked and len(m.taken) == 1
    k = run_cycles(m, prog, 1, feed_signal([110.0]), start=k)         # back (a fast change: unsteady)
    # the window (2 cycles) still sees 140 V for one more cycle; then 5 steady cycles release
    k = run_cycles(m, prog, 5, feed_signal([111.0] * 5), start=k)
    assert f.locked
    k = run_cycles(m, prog, 2, feed_signal([111.0] * 2), start=k)
    assert not f.locked
    assert m.taken[-1] == (int(HliTransition.ON_CONST_DIST), 1.5)


def test_void_lock_ripple_of_a_whole_period_is_cancelled_by_the_default_window():
    m = FakeMachine()
    f, prog = void(m)                                     # 20 ms window, 500 V/s
    sig = [110.0 + 4.0 * math.sin(2 * math.pi * 50 * k * 0.001) for k in range(200)]
    run_cycles(m, prog, 200, feed_signal(sig))
    assert m.taken == [] and abs(f.rate) < 1.0


def test_void_lock_reads_state_r_actual_distance_without_a_variable():
    m = FakeMachine()
    f = VoidLock("Z", m.T, 80.0, variable=None, window=0.001, on_cycles=1)
    prog = ProcessProgram([f])

    def before(m, k):
        m.hli["Z"].state_r.actual_distance = 15000 if k < 5 else 25000   # 1.5 mm, then 2.5 mm
    run_cycles(m, prog, 6, before)
    assert f.locked


def test_void_lock_releases_after_a_kerf_with_mains_ripple_on_the_voltage():
    # 104 V with a 2 V, 50 Hz ripple; a 30 V kerf for 15 ms; after it the voltage is back where it was
    # (the head held): the lock must release although single samples differ by up to 4 V + noise
    m = FakeMachine()
    f, prog = void(m)                                     # the defaults: 20 ms, 500 V/s, band 5 V
    rng = np.random.default_rng(1)

    def volts(k):
        kerf = 30.0 if 300 <= k < 315 else 0.0
        return 104.0 + 2.0 * math.sin(2 * math.pi * 50 * k * 0.001 + 1.3) + 0.3 * rng.standard_normal() + kerf
    k = run_cycles(m, prog, 320, feed_signal([volts(k) for k in range(320)]))
    assert f.locked and m.taken == [(int(HliTransition.FREEZE), 0.0)]
    assert abs(f.level - 104.0) < 0.5                       # the level before the kerf, the ripple averaged out
    run_cycles(m, prog, 200, feed_signal([volts(k) for k in range(320, 520)]), start=k)
    assert not f.locked and m.taken[-1] == (int(HliTransition.ON_CONST_DIST), 1.5)


def test_void_lock_releases_when_the_signal_comes_back_below_its_level():
    # the torch dived before the lock caught the void: past it the voltage is 10 V below the level
    # (the torch 1.7 mm closer); re-activating moves it away from the sheet, so the lock releases.
    # Back above the level by more than the band (the plate lower beyond a kerf) it keeps holding.
    for after, released in ((100.0, True), (120.0, False)):
        m = FakeMachine()
        f, prog = void(m, window=0.002, on_cycles=1, off_cycles=5, release_band=3.0)
        k = run_cycles(m, prog, 5, feed_signal([110.0] * 5))
        k = run_cycles(m, prog, 3, feed_signal([140.0] * 3), start=k)
        assert f.locked
        run_cycles(m, prog, 20, feed_signal([after] * 20), start=k)
        assert f.locked is not released, after


def test_void_lock_window_starts_at_the_select_not_before_it():
    # the head comes down to the cut height with distance control off (the arc voltage falls from
    # 150 V to 104 V), then the NC selects: the window must not compare against the descent
    m = FakeMachine(state=0)                               # INACTIVE
    f, prog = void(m, window=0.005, on_cycles=1)
    descent = [150.0 - 46.0 * min(k, 10) / 10 for k in range(12)]
    k = run_cycles(m, prog, 12, feed_signal(descent))
    m.hli["Z"].state_r.actual_state = ACTIVE_CD            # the select, at rest at the cut height
    k = run_cycles(m, prog, 20, feed_signal([104.0] * 20), start=k)
    assert m.taken == [] and not f.locked


# ------------------------------------------------------------------ automatic set value
def test_auto_set_value_samples_after_the_select_and_commands_the_mean():
    m = FakeMachine(state=int(HliState.INACTIVE), set_distance=1.0)
    f = AutoSetValue("Z", m.T, delay=0.003, sample_time=0.004)
    prog = ProcessProgram([f])
    run_cycles(m, prog, 3)
    assert m.taken == [] and f.phase == "DONE"
    m.hli["Z"].state_r.actual_state = ACTIVE_CD            # the cut starts (NC select)
    samples = iter([99999] * 3 + [19000, 21000, 20000, 20000] + [99999] * 20)

    def before(m, k):
        m.hli["Z"].state_r.actual_distance = next(samples)
    k = run_cycles(m, prog, 3, before, start=3)            # FREEZE at once, then 3 cycles of delay
    assert m.taken == [(int(HliTransition.FREEZE), 0.0)] and f.phase == "WAITING"
    k = run_cycles(m, prog, 3, before, start=k)
    assert f.phase == "SAMPLING" and len(m.taken) == 1
    k = run_cycles(m, prog, 1, before, start=k)
    assert f.result == pytest.approx(2.0)                  # mean of 1.9, 2.1, 2.0, 2.0 mm
    assert m.taken[-1] == (int(HliTransition.ON_CONST_DIST), 2.0)
    run_cycles(m, prog, 10, before, start=k)               # FREEZE -> ON is not a new cut
    assert len(m.taken) == 2 and f.log == [(k - 1, pytest.approx(2.0))]


def test_auto_set_value_waits_for_other_locks_before_releasing():
    m = FakeMachine(state=int(HliState.INACTIVE))
    a = AutoSetValue("Z", m.T, delay=0.0, sample_time=0.004)
    c = CornerLock("Z")
    prog = ProcessProgram([a, c])
    m.hli["Z"].state_r.actual_state = ACTIVE_CD
    m.hli["Z"].state_r.actual_distance = 17000
    m.channel_path.D_ActiveFeed = 50_000
    k = run_cycles(m, prog, 2)                             # corner lock arms, auto freezes
    m.channel_path.D_ActiveFeed = 10_000                  # slow: corner lock requests the hold too
    k = run_cycles(m, prog, 5, start=k)
    assert a.phase == "DONE" and [t for t, _ in m.taken] == [int(HliTransition.FREEZE)]
    m.channel_path.D_ActiveFeed = 50_000
    run_cycles(m, prog, 2, start=k)
    assert m.taken[-1] == (int(HliTransition.ON_CONST_DIST), 1.7)


def test_auto_set_value_stops_when_distance_control_is_switched_off():
    m = FakeMachine(state=int(HliState.INACTIVE))
    f = AutoSetValue("Z", m.T, delay=0.0, sample_time=0.01)
    prog = ProcessProgram([f])
    m.hli["Z"].state_r.actual_state = ACTIVE_CD
    k = run_cycles(m, prog, 3)
    m.hli["Z"].state_r.actual_state = int(HliState.INACTIVE)
    run_cycles(m, prog, 20, start=k)
    assert f.phase == "DONE" and math.isnan(f.result)
    assert [t for t, _ in m.taken] == [int(HliTransition.FREEZE)]


# ------------------------------------------------------------------ channel path status
class _Interp:
    block = "linear"
    path_velocity = 41.6667


class _Nc:
    feed = 3000.0


class _M:
    interp = _Interp()
    nc = _Nc()
    channel_override = 0.8


def test_channel_path_status_units():
    s = ChannelPathStatus(_M())
    assert s.D_CommandFeed == 50_000 and s.D_ActiveFeed == 41_667 and s.override == 0.8
    _M.interp.block = "idle"
    assert s.D_ActiveFeed == 0


# ------------------------------------------------------------------ switching at run time
def test_set_enabled_off_releases_the_freeze_a_function_holds_and_on_again_starts_afresh():
    m = FakeMachine()
    f, prog = corner(m)
    m.channel_path.D_ActiveFeed = 50_000
    k = run_cycles(m, prog, 2)                             # armed
    m.channel_path.D_ActiveFeed = 0                        # slow: FREEZE
    k = run_cycles(m, prog, 3, start=k)
    assert m.hli["Z"].state_r.actual_state == FREEZE and f.requesting_hold
    assert f.status() == {"name": "corner_lock", "axis": "Z", "enabled": True, "requesting_hold": True}
    prog.set_enabled("corner_lock", "Z", False)            # still slow, but the lock is off
    assert not f.requesting_hold and not f.armed and not f.locked
    k = run_cycles(m, prog, 3, start=k)
    assert m.taken == [(int(HliTransition.FREEZE), 0.0), (int(HliTransition.ON_CONST_DIST), 1.5)]
    assert m.hli["Z"].state_r.actual_state == ACTIVE_CD and prog.holds["Z"].phase == "IDLE"
    assert f.status()["enabled"] is False and not f.armed  # a disabled function is not stepped
    prog.set_enabled("corner_lock", "Z", True)             # on again while slow: not armed, no FREEZE
    k = run_cycles(m, prog, 5, start=k)
    assert len(m.taken) == 2 and not f.armed
    m.channel_path.D_ActiveFeed = 50_000                   # back at speed: armed; then slow: FREEZE again
    k = run_cycles(m, prog, 2, start=k)
    m.channel_path.D_ActiveFeed = 0
    run_cycles(m, prog, 2, start=k)
    assert [t for t, _ in m.taken] == [2, 4, 2]


def test_set_enabled_off_keeps_the_hold_while_another_function_requests_it():
    m = FakeMachine()
    c = CornerLock("Z")
    v = VoidLock("Z", m.T, 80.0, variable="SENSOR", window=0.002, on_cycles=1)
    prog = ProcessProgram([c, v])
    m.variables["V.E.SENSOR"] = 1.5
    m.channel_path.D_ActiveFeed = 50_000
    k = run_cycles(m, prog, 4)
    m.channel_path.D_ActiveFeed = 0                        # corner lock freezes
    m.variables["V.E.SENSOR"] = 4.0                        # and a void: the void lock too
    k = run_cycles(m, prog, 3, start=k)
    assert c.requesting_hold and v.requesting_hold and m.hli["Z"].state_r.actual_state == FREEZE
    prog.set_enabled("corner_lock", "Z", False)
    run_cycles(m, prog, 3, start=k)
    assert [t for t, _ in m.taken] == [2]                  # the void lock still holds
    assert prog.status() == [{"name": "corner_lock", "axis": "Z", "enabled": False, "requesting_hold": False},
                             {"name": "void_lock", "axis": "Z", "enabled": True, "requesting_hold": True}]


def test_auto_set_value_switched_on_during_a_cut_waits_for_the_next_cut():
    m = FakeMachine(state=int(HliState.INACTIVE))
    a = AutoSetValue("Z", m.T, delay=0.0, sample_time=0.002, enabled=False)
    prog = ProcessProgram([a])
    m.hli["Z"].state_r.actual_state = ACTIVE_CD            # the cut runs while the function is off
    k = run_cycles(m, prog, 3)
    prog.set_enabled("auto_set_value", "Z", True)
    k = run_cycles(m, prog, 5, start=k)
    assert m.taken == [] and a.phase == "DONE"
    m.hli["Z"].state_r.actual_state = int(HliState.INACTIVE)
    k = run_cycles(m, prog, 1, start=k)
    m.hli["Z"].state_r.actual_state = ACTIVE_CD            # the next cut: sampled
    run_cycles(m, prog, 1, start=k)
    assert a.phase != "DONE" and m.taken == [(int(HliTransition.FREEZE), 0.0)]


def test_set_enabled_names_unknown_functions_and_reset_returns_to_the_initial_state():
    m = FakeMachine()
    f, prog = corner(m)
    with pytest.raises(KeyError, match="corner_lock@Z"):
        prog.set_enabled("void_lock", "Z", False)
    m.channel_path.D_ActiveFeed = 50_000
    k = run_cycles(m, prog, 2)
    m.channel_path.D_ActiveFeed = 0
    run_cycles(m, prog, 2, start=k)
    assert f.locked and prog.holds["Z"].phase == "FROZEN"
    prog.reset()
    assert not f.armed and not f.locked and prog.holds["Z"].phase == "IDLE" and not prog.holds["Z"].requested
    assert f.enabled and prog.holds["Z"].log                 # reset keeps the switch and the log


@pytest.mark.parametrize("value", ["no", 0, 1])
def test_enabled_must_be_a_boolean(value):
    with pytest.raises(ConfigError, match="corner_lock.enabled"):
        CornerLock("Z", enabled=value)
