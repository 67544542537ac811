"""distctrl's law as a LinuxCNC component (hal/distctrl_thc.comp): streamed through halrun in lock-step,
its outputs equal distctrl's cycle core's (AxisDistanceController, driven by distctrl.linuxcnc.thc.ThcCore
with the commands a PLC gives it) to the last bit: for every filter type through the HLI state transitions
INACTIVE -> ACTIVE_CONST_DIST -> FREEZE (void lock, corner lock) -> ACTIVE_CONST_DIST -> TURNING_OFF ->
INACTIVE -> ACTIVE_CONST_DIST, and on inputs that trigger each monitoring error (70329, 70330, 70576,
70331, 900001): ERROR -> TURNING_OFF -> INACTIVE -> ACTIVE_CONST_DIST. One halrun session runs all
instances, each group of instances on its own input stream."""
from __future__ import annotations

import math
import struct
import time

import numpy as np
import pytest

from distctrl.base.kinds import FilterType
from distctrl.control.filters import FilterConfig
from distctrl.linuxcnc.bench import release_gate
from distctrl.linuxcnc.hal_env import HalSession, LinuxCNCError, import_hal, install_component
from distctrl.linuxcnc.thc import ThcConfig, ThcCore

LAW = {
    "PASS (n 1)": ThcConfig(kp=0.6, filter=FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=1)),
    "DEFAULT": ThcConfig(kp=0.5, i_tn=0.05, filter=FilterConfig(FilterType.DEFAULT)),
    "MOVING_AVERAGE": ThcConfig(kp=0.4, d_tv=0.01, use_both_encoders=True, filter=FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=7)),
    "EXPO_MEAN": ThcConfig(kp=0.5, i_tn=0.1, d_tv=0.005, filter=FilterConfig(FilterType.EXPO_MEAN, n_cycles=9,
                                                                             smoothing_factor=0.3)),
    "LOWPASS": ThcConfig(kp=0.3, filter=FilterConfig(FilterType.LOWPASS, order=5, fg_f0=40.0)),
    "KALMAN_MA": ThcConfig(kp=0.5, use_both_encoders=True, filter=FilterConfig(FilterType.KALMAN_MA, n_cycles=20, kalman_sigma=1000.0)),
    "KALMAN_EXPO": ThcConfig(kp=0.5, filter=FilterConfig(FilterType.KALMAN_EXPO, n_cycles=30, smoothing_factor=0.2,
                                                         kalman_sigma=4.0)),
}
#: each trips its monitoring error on _error_inputs() (name: config, its error ID); the NaN there trips
#: 900001 in every instance that is running then
ERRORS = {
    "70329 sensor jump": (ThcConfig(kp=0.5, max_act_value_change=1000.0), 70329),
    "70576 run-out min": (ThcConfig(kp=0.5, min_pos=-6.0, tolerance=0.5), 70576),
    "70330 run-out max": (ThcConfig(kp=0.5, max_pos=2.0, tolerance=0.5), 70330),
    "70331 max deviation": (ThcConfig(kp=0.5, i_tn=0.05, max_deviation=1.0), 70331),
    "900001 not finite": (ThcConfig(kp=0.5, filter=FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=5)), 900001),
}
NAN_AT = 720
N = 900


def _row(v, enable, cl, vel, feed_upm, vl, zc, za, sd, dryrun=False, mode=0, sp=0.0):
    return (float(v), bool(enable), bool(cl), float(vel), float(feed_upm), bool(vl), float(zc), float(za), float(sd),
            bool(dryrun), int(mode), float(sp))


def _law_inputs():
    """Arc voltage with warp, ripple, noise, a void (fast rise and fall), a corner slow-down, the THC
    switched off (the offset runs out) and on again, the cut height changed."""
    rng = np.random.default_rng(29)
    rows = []
    for k in range(N):
        t = k * 0.001
        v = 104.0 + 3.0 * math.sin(2 * math.pi * 3 * t) + 2.0 * math.sin(2 * math.pi * 50 * t) + 0.3 * rng.standard_normal()
        if 300 <= k < 330:
            v += 45.0 * min(1.0, (k - 300) / 5.0)      # a hole: fast rise, then high
        enable = not (20 > k or 600 <= k < 680)      # INACTIVE, ACTIVE..., TURNING_OFF, INACTIVE, ACTIVE
        vel = 83.3 if not (450 <= k < 520) else 83.3 * (1.0 - min(1.0, (k - 450) / 20.0)) + 5.0
        zc = 40.0 - 0.01 * k + 0.5 * math.sin(2 * math.pi * 7 * t)       # programmed and actual Z (both encoders)
        za = zc - 0.2 * math.cos(2 * math.pi * 7 * t) - 0.001 * rng.standard_normal()
        rows.append(_row(v, enable, True, vel, 83.3 * 60.0, True, zc, za, 1.5 if k < 750 else 1.8))
    return rows


def _error_inputs():
    """No locks: a hole (70329 with a tight jump limit, 70576 with a narrow window, 70331 with a small
    bound), an arc-voltage dip (70330), a NaN (900001); the THC off and on again after each."""
    rng = np.random.default_rng(31)
    rows = []
    for k in range(N):
        t = k * 0.001
        v = 104.0 + 2.0 * math.sin(2 * math.pi * 50 * t) + 0.3 * rng.standard_normal()
        if 200 <= k < 260:
            v += 45.0 * min(1.0, (k - 200) / 5.0, (259 - k) / 5.0)      # a hole (in and out in 5 periods)
        if 480 <= k < 540:
            v -= 24.0 * min(1.0, (k - 480) / 20.0, (539 - k) / 20.0)     # a dip (distance below -1.5 mm)
        if k == NAN_AT:
            v = math.nan
        enable = not (k < 10 or 380 <= k < 440 or 600 <= k < 660 or 800 <= k < 860)
        zc = 30.0 - 0.005 * k
        rows.append(_row(v, enable, False, 80.0, 4800.0, False, zc, zc, 1.5))
    return rows


def _command_inputs():
    """The commands' edges: thc-enable coming on while plasmac's corner lock holds (ON_CONST_DIST and FREEZE
    in one period), once with a NaN cut height (ON refused: 900005, then FREEZE in ERROR: 900003)."""
    rows = []
    for k in range(400):
        v = 104.0 + 2.0 * math.sin(2 * math.pi * 50 * k * 0.001)
        slow = 95 <= k < 105 or 340 <= k < 360
        sd = math.nan if 90 <= k < 110 else 1.5
        rows.append(_row(v, 100 <= k < 300 or k >= 350, True, 50.0 if slow else 80.0, 4800.0, False, 30.0, 30.0, sd))
    return rows + rows[-1:] * (N - len(rows))


COMMANDS = {"ON refused, FREEZE at ON": ThcConfig(kp=0.5, i_tn=0.05, cornerlock_mode="plasmac")}


def _lock_inputs():
    """The locks' edges. The path accelerates after the THC came on (k 20..120: distctrl's corner lock is
    not armed before 95 % of the feed, plasmac's locks), slows to 87.5 % of the feed (a corner: both lock),
    comes back to 92.5 % (distctrl's holds: hysteresis; plasmac's holds below 99 %), to 96.25 % (distctrl's
    opens), to 100 % (plasmac's opens); a feed hold (feed-upm 0: distctrl's locks at once); the THC off and on
    at full speed (armed at once); the void lock switched off and on (reset); a void; a second one with a
    NaN sample (not stored by the void lock, 900001 for the core)."""
    rng = np.random.default_rng(37)
    rows = []
    F = 80.0                                          # mm/s: feed-upm 4800
    for k in range(N):
        t = k * 0.001
        v = 104.0 + 2.0 * math.sin(2 * math.pi * 50 * t) + 0.3 * rng.standard_normal()
        if 560 <= k < 600:
            v += 45.0 * min(1.0, (k - 560) / 5.0, (599 - k) / 5.0)     # a void (hole) in and out
        if 780 <= k < 820:
            v += 45.0 * min(1.0, (k - 780) / 5.0)
        if k == 790:
            v = math.nan
        feed = 0.0 if 400 <= k < 430 else F * 60.0
        if k < 20:
            vel = 0.0
        elif k < 120:
            vel = F * (k - 20) / 100.0
        elif 200 <= k < 230:
            vel = 0.875 * F
        elif 230 <= k < 280:
            vel = 0.925 * F
        elif 280 <= k < 330:
            vel = 0.9625 * F
        elif 400 <= k < 430:
            vel = F * (1.0 - (k - 400) / 30.0)
        elif 430 <= k < 480:
            vel = F * (k - 430) / 50.0
        else:
            vel = F
        enable = not (k < 20 or 500 <= k < 520 or k >= 860)
        vl = not (640 <= k < 660)
        rows.append(_row(v, enable, True, vel, feed, vl, 30.0, 30.0, 1.5))
    return rows


LOCKS = {
    "locks distctrl": ThcConfig(kp=0.5, i_tn=0.05),
    "locks plasmac": ThcConfig(kp=0.5, i_tn=0.05, cornerlock_mode="plasmac"),
    "locks distctrl 75 % no hysteresis": ThcConfig(kp=0.4, cornerlock_threshold=75.0, cornerlock_hysteresis=0.0,
                                                   voidlock_slope=300.0, voidlock_window=0.01, voidlock_on_cycles=2,
                                                   voidlock_off_cycles=10, voidlock_release_band=3.0),
}


def _limit_inputs():
    """The rest of the core's CONST_DIST cycle: first a DRYRUN from rest with a pulse (the offset stands),
    the THC off for one period and on (ACTIVE_CONST_DIST); arc-voltage pulses that lower (+12 V) and lift
    (-12 V) the torch for 40 periods each (the software limits, the lowering weights, the adaptive
    acceleration act), then the THC off for one period with dryrun on (TURNING_OFF runs the offset out; the DRYRUN selected
    right after, while the run-out's last step still moves, is the core's FREEZE until the offset stands,
    which the braking reaches within that period), a pulse in DRYRUN (computed, reported, not applied), the
    THC off (dryrun off), on again and a last pulse."""
    rng = np.random.default_rng(41)
    rows = []
    for k in range(N):
        t = k * 0.001
        v = 104.0 + 2.0 * math.sin(2 * math.pi * 3 * t) + 1.0 * math.sin(2 * math.pi * 50 * t) \
            + 0.2 * rng.standard_normal()
        for start, dv in ((15, 12.0), (100, 12.0), (200, -12.0), (600, 12.0), (720, 12.0)):
            if start <= k < start + 40:
                v += dv * min(1.0, (k - start) / 10.0, (start + 39 - k) / 10.0)
        enable = not (k < 10 or k == 60 or k == 400 or 650 <= k < 670)
        rows.append(_row(v, enable, False, 80.0, 4800.0, False, 30.0, 30.0, 1.5, k < 60 or 400 <= k < 650))
    return rows


LIMITS = {
    "plain": ThcConfig(kp=0.5),
    "software limit below (900002)": ThcConfig(kp=0.5, check_sw_limit_switch=True, sw_limit_min=29.0,
                                               sw_limit_max=31.0),
    "software limit above (900002)": ThcConfig(kp=0.5, check_sw_limit_switch=True, sw_limit_min=25.0,
                                               sw_limit_max=30.5),
    "lowering weights": ThcConfig(kp=0.5, v_weight_down=0.2, a_weight_down=0.25),
    "adaptive acceleration": ThcConfig(kp=0.5, use_adaptive_acceleration=True, a_min=300.0, dist_error_a_min=0.2,
                                       dist_error_a_max=1.5),
    "all, I and D, moving average": ThcConfig(kp=0.4, i_tn=0.08, d_tv=0.004, v_weight_down=0.5, a_weight_down=0.6,
                                              use_adaptive_acceleration=True, a_min=800.0, dist_error_a_min=0.1,
                                              dist_error_a_max=0.8, check_sw_limit_switch=True, sw_limit_min=20.0,
                                              sw_limit_max=40.0,
                                              filter=FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=4)),
}


def _setpos_inputs():
    """SET_POS (mode 1): the surface a - d held at set-pos. The head moves (a), the surface drops by 2 mm
    (+12 V) for 40 periods, set-pos changes while ACTIVE (the PLC's cyclic D_Position), a corner (FREEZE,
    released into SET_POS); the THC off, on in CONST_DIST (mode 0), off, on in DRYRUN SET_POS, off, on in
    SET_POS, off, on with a NaN set-pos (ON refused: 900005), off and on in SET_POS again."""
    rng = np.random.default_rng(43)
    rows = []
    for k in range(N):
        t = k * 0.001
        v = 104.0 + 1.0 * math.sin(2 * math.pi * 50 * t) + 0.2 * rng.standard_normal()
        if 100 <= k < 140 or 500 <= k < 540:
            v += 12.0 * min(1.0, (k - 100) % 400 / 10.0, (139 - k) % 400 / 10.0)
        za = 30.0 + 0.3 * math.sin(2 * math.pi * 5 * t)
        vel = 40.0 if 230 <= k < 260 else 80.0
        enable = not (k < 10 or 300 <= k < 310 or 400 <= k < 410 or 600 <= k < 610 or 700 <= k < 710
                      or 800 <= k < 810)
        mode = 0 if 300 <= k < 400 else 1
        sp = 28.5 if k < 200 else 28.2
        if 700 <= k < 790:
            sp = math.nan
        rows.append(_row(v, enable, True, vel, 4800.0, False, 30.0, za, 1.5, 400 <= k < 600, mode, sp))
    return rows


SETPOS = {
    "SET_POS PI": ThcConfig(kp=0.5, i_tn=0.05, mode="SET_POS", set_pos=28.5),
    "SET_POS PD moving average, adaptive, plasmac's corner lock": ThcConfig(
        kp=0.4, d_tv=0.005, filter=FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=5), use_adaptive_acceleration=True,
        a_min=400.0, cornerlock_mode="plasmac", mode="SET_POS", set_pos=28.5),
}
GROUPS = [(list(LAW), [LAW[n] for n in LAW], _law_inputs),
          (list(ERRORS), [c for c, _ in ERRORS.values()], _error_inputs),
          (list(COMMANDS), list(COMMANDS.values()), _command_inputs),
          (list(LOCKS), list(LOCKS.values()), _lock_inputs),
          (list(LIMITS), list(LIMITS.values()), _limit_inputs),
          (list(SETPOS), list(SETPOS.values()), _setpos_inputs)]
_IN = {"arc": ("arc-voltage-in", "f"), "enable": ("thc-enable", "b"), "cl-enable": ("cornerlock-enable", "b"),
       "vel": ("current-velocity", "f"), "feed-upm": ("feed-upm", "f"), "vl-enable": ("voidlock-enable", "b"),
       "zc": ("axis-z-command", "f"), "za": ("axis-z-position", "f"), "sd": ("set-dist", "f"),
       "dryrun": ("dryrun", "b"), "mode": ("mode", "s"), "sp": ("set-pos", "f")}
_OUT = {"offset": ("offset", "f"), "filtered": ("filtered", "f"), "velocity": ("velocity", "f"),
        "distance": ("distance", "f"), "counts": ("z-offset-counts", "s"), "state": ("state", "s"),
        "error_id": ("error-id", "s"), "cl": ("cornerlock-is-locked", "b"), "vl": ("voidlock-is-locked", "b"),
        "vl-rate": ("voidlock-rate", "f"), "vl-mean": ("voidlock-mean", "f"),
        "tdev": ("target-deviation", "f"), "step": ("wanted-step", "f")}


@pytest.fixture(scope="module")
def streamed():
    """All groups' instances in one halrun session, in lock-step; per group the rows and per period the
    outputs of each instance."""
    install_component("distctrl_lockstep")
    install_component("distctrl_thc")
    hal = import_hal()
    types = {"f": hal.HAL_FLOAT, "b": hal.HAL_BIT, "s": hal.HAL_S32}
    inst = []                                     # (group, index in group, instance name)
    for g, (names, cfgs, _) in enumerate(GROUPS):
        inst += [(g, i, f"distctrl-thc.{len(inst) + i}") for i in range(len(names))]
    rows = [make() for _, _, make in GROUPS]
    with HalSession() as hs:
        setp = [line for g, i, name in inst for line in GROUPS[g][1][i].setp_lines(0.001, name)]
        hs.cmd("loadrt threads name1=servo-thread period1=1000000", "loadrt distctrl_lockstep",
               f"loadrt distctrl_thc count={len(inst)}", "addf distctrl-lockstep.0.wait servo-thread",
               *[f"addf {name} servo-thread" for _, _, name in inst],
               "addf distctrl-lockstep.0.post servo-thread", "setp distctrl-lockstep.0.enable 1", *setp)
        comp = hal.component("thc-stream")
        for g in range(len(GROUPS)):
            for p, (_, t) in _IN.items():
                comp.newpin(f"g{g}-{p}", types[t], hal.HAL_OUT)
        for n, (g, i, _) in enumerate(inst):
            for p, (_, t) in _OUT.items():
                comp.newpin(f"{n}-{p}", types[t], hal.HAL_IN)
        comp.newpin("seq", hal.HAL_U32, hal.HAL_IN)
        comp.newpin("ack", hal.HAL_U32, hal.HAL_OUT)
        comp.ready()
        try:
            nets = [f"net ts-g{g}-{p} thc-stream.g{g}-{p} => " + " ".join(f"{name}.{q}" for gg, _, name in inst
                                                                         if gg == g)
                    for g in range(len(GROUPS)) for p, (q, _) in _IN.items()]
            nets += [f"net ts-{n}-{p} {name}.{q} => thc-stream.{n}-{p}" for n, (_, _, name) in enumerate(inst)
                     for p, (q, _) in _OUT.items()]
            nets += ["net ts-seq distctrl-lockstep.0.seq => thc-stream.seq",
                     "net ts-ack thc-stream.ack => distctrl-lockstep.0.ack", "start"]
            # period 1 runs on the pins' start values (all 0 but the set-dist setp): its outputs are skipped
            got = []
            k = 0
            deadline = time.monotonic() + 240.0
            hs.cmd(*nets)
            while len(got) <= N and time.monotonic() < deadline:
                s = comp["seq"]
                if s == k:
                    time.sleep(0.0001)
                    continue
                k = s
                got.append([{p: comp[f"{n}-{p}"] for p in _OUT} for n in range(len(inst))])
                if k - 1 < N:
                    for g in range(len(GROUPS)):
                        for p, value in zip(_IN, rows[g][k - 1]):
                            comp[f"g{g}-{p}"] = value
                comp["ack"] = k
            release_gate()
            missed = int(hs.getp("distctrl-lockstep.0.missed"), 0)
        finally:
            release_gate()
            try:
                hs.cmd("stop")
            except LinuxCNCError:
                pass
            comp.exit()
    got = got[1:N + 1]
    per = {}
    for n, (g, i, _) in enumerate(inst):
        per[GROUPS[g][0][i]] = (GROUPS[g][1][i], rows[g], [p[n] for p in got])
    return per, missed, len(got)


def _bits(x: float) -> bytes:
    return struct.pack("<d", x)


def _same(a: float, b: float) -> bool:
    """The same double to the last bit (any NaN equals any NaN: a NaN's payload is not the law's)."""
    return (math.isnan(a) and math.isnan(b)) or _bits(a) == _bits(b)


def _compare(cfg, rows, got, first_set_dist):
    """ThcCore on the rows against the component's outputs, every period; the HLI states seen."""
    ref = ThcCore(cfg)
    ref.step(0.0, False, set_dist=first_set_dist)      # period 1: the pins' start values (outputs skipped)
    states = []
    for k, row in enumerate(rows):
        v, en, cl, vel, feed, vl, zc, za, sd, dry, mode, sp = row
        r = ref.step(v, en, cl, vel, feed, vl, zc, za, sd, dry, mode, sp)
        g = got[k]
        states.append(r["state"])
        assert (g["state"], g["error_id"]) == (r["state"], r["error_id"]), (k, "state, error id")
        for key in ("offset", "velocity", "distance", "filtered"):
            assert _same(g[key], r[key]), (k, key, g[key], r[key])
        assert g["counts"] == r["counts"], (k, "counts")
        assert (bool(g["cl"]), bool(g["vl"])) == (r["cornerlock_is_locked"], r["voidlock_is_locked"]), (k, "locks")
        for key, ref_key in (("vl-rate", "voidlock_rate"), ("vl-mean", "voidlock_mean"),
                             ("tdev", "target_deviation"), ("step", "wanted_step")):
            assert _same(g[key], r[ref_key]), (k, key, g[key], r[ref_key])
    return states


def _changes(states):
    return [s for n, s in enumerate(states) if n == 0 or s != states[n - 1]]


def test_the_stream_ran_lock_step(streamed):
    _, missed, n = streamed
    assert missed == 0 and n == N


@pytest.mark.parametrize("name", list(LAW))
def test_the_component_equals_the_cycle_core_bit_for_bit_through_the_states(streamed, name):
    cfg, rows, got = streamed[0][name]
    states = _compare(cfg, rows, got, cfg.set_dist)
    # INACTIVE -> ACTIVE_CONST_DIST -> FREEZE (void) -> ... -> TURNING_OFF -> INACTIVE -> ACTIVE_CONST_DIST
    seq = _changes(states)
    assert seq[:4] == [0, 4, 2, 4] and seq[-3:] == [3, 0, 4], seq
    assert 2 in states[300:340] and 2 in states[460:520]          # void lock, corner lock
    assert states[600] == 3 and states[679] == 0 and got[679]["offset"] == 0.0 != got[590]["offset"]   # the run-out
    assert all(g["error_id"] == 0 for g in got)


@pytest.mark.parametrize("name", list(ERRORS))
def test_the_component_raises_the_cores_monitoring_errors_bit_for_bit(streamed, name):
    cfg, rows, got = streamed[0][name]
    states = _compare(cfg, rows, got, cfg.set_dist)
    error_id = ERRORS[name][1]
    before = {g["error_id"] for g in got[:NAN_AT]} - {0}
    assert before == ({error_id} if error_id != 900001 else set())
    assert got[NAN_AT]["error_id"] == 900001 and math.isnan(got[NAN_AT]["distance"])
    seq = _changes(states)
    i = seq.index(5)                                           # ERROR -> TURNING_OFF -> INACTIVE -> ACTIVE again
    assert seq[i:i + 4] == [5, 3, 0, 4], seq
    # in ERROR the offset is held: the velocity brakes to 0 and stays
    errs = [k for k, s in enumerate(states) if s == 5]
    assert got[errs[-1]]["velocity"] == 0.0


def test_the_component_answers_the_commands_edges_as_the_core(streamed):
    cfg, rows, got = streamed[0]["ON refused, FREEZE at ON"]
    states = _compare(cfg, rows, got, cfg.set_dist)
    assert states[99] == 0 and (states[100], got[100]["error_id"]) == (5, 900003)    # ON refused, FREEZE in ERROR
    assert states[299] == 5 and states[300] == 0             # OFF: nothing to run out, INACTIVE at once
    assert states[350] == 2 and states[360] == 4                 # ON and FREEZE in one period, then tracking


def test_thc_config_refuses_values_outside_the_documents_ranges():
    with pytest.raises(LinuxCNCError, match="kp = 2.5 out of range"):
        ThcConfig(kp=2.5).check(0.001)
    with pytest.raises(LinuxCNCError, match="P-AXIS-00765"):
        ThcConfig(d_tv=3.0).check(0.001)
    with pytest.raises(LinuxCNCError, match="P-AXIS-00413"):
        ThcConfig(filter=FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=100)).check(0.001)
    with pytest.raises(LinuxCNCError, match="P-AXIS-00508"):
        ThcConfig(filter=FilterConfig(FilterType.LOWPASS, order=2, fg_f0=600.0)).check(0.001)
    with pytest.raises(LinuxCNCError, match="window is empty"):
        ThcConfig(min_pos=1.0, max_pos=1.5, tolerance=0.5).check(0.001)


def test_the_components_locks_are_distctrls_process_functions_period_for_period(streamed):
    """The component's corner lock and void lock against ThcCore, whose locks are distctrl's CornerLock and
    VoidLock process functions themselves (ThcLocks steps them): locks, the void lock's rate and mean bit for
    bit, every period; and the edges the stream was made for happen."""
    cl, vl = {}, {}
    for name, cfg in LOCKS.items():
        _, rows, got = streamed[0][name]
        _compare(cfg, rows, got, cfg.set_dist)
        cl[name] = [bool(g["cl"]) for g in got]
        vl[name] = [bool(g["vl"]) for g in got]
    d, p, d75 = cl["locks distctrl"], cl["locks plasmac"], cl["locks distctrl 75 % no hysteresis"]
    assert not any(d[:200]) and all(p[25:100])           # arming: distctrl's waits for 95 % of the feed
    assert all(d[202:280]) and not any(d[282:400])       # 87.5 % locks, 92.5 % holds (hysteresis), 96.25 % opens
    assert all(p[202:330]) and not any(p[332:400])       # plasmac's opens above 99 % only
    assert not any(d75[200:330])                         # 75 %: the corner's 87.5 % is no corner
    assert all(d[401:430]) and all(d75[401:430])         # a feed hold (feed-upm 0) locks distctrl's
    assert not any(p[400:405])                           # plasmac's compares with 0 % of 0
    assert not any(d[500:521]) and d[540] is False       # THC off: disarmed; on at full speed: armed, open
    for name in LOCKS:
        assert any(vl[name][560:600]) and not any(vl[name][640:661]), name   # the void; the switch resets
    assert cl["locks distctrl"][0] is False


def test_thc_config_refuses_lock_settings_outside_the_process_functions_ranges():
    with pytest.raises(LinuxCNCError, match="cornerlock-threshold / 100: corner_lock.share"):
        ThcConfig(cornerlock_threshold=0.0).check(0.001)
    with pytest.raises(LinuxCNCError, match="corner_lock.hysteresis"):
        ThcConfig(cornerlock_threshold=97.0, cornerlock_hysteresis=5.0).check(0.001)
    with pytest.raises(LinuxCNCError, match="cornerlock-mode = 'vad' unknown"):
        ThcConfig(cornerlock_mode="vad").check(0.001)
    with pytest.raises(LinuxCNCError, match="voidlock-on-cycles: void_lock.on_cycles"):
        ThcConfig(voidlock_on_cycles=0).check(0.001)
    ThcConfig(cornerlock_mode="plasmac", cornerlock_threshold=0.0).check(0.001)   # plasmac: 0 % never locks
    with pytest.raises(LinuxCNCError, match="cornerlock-hysteresis = nan out of range"):
        ThcConfig(cornerlock_mode="plasmac", cornerlock_hysteresis=math.nan).check(0.001)   # a pin, even unused


@pytest.mark.parametrize("name", list(LIMITS))
def test_the_component_has_the_cores_limits_weights_adaptive_acceleration_and_dryrun_bit_for_bit(streamed, name):
    """Software limits (P-AXIS-00428/00177/00178), lowering weights (P-AXIS-00533/00534), adaptive
    acceleration (P-AXIS-00501..00505) and DRYRUN (HLI CONST_DIST) against AxisDistanceController, bit for
    bit; and each of them acts on the stream."""
    cfg, rows, got = streamed[0][name]
    states = _compare(cfg, rows, got, cfg.set_dist)
    seq = _changes(states)
    off = [g["offset"] for g in got]
    vel = [g["velocity"] for g in got]
    dry = [k for k, st in enumerate(states) if st == 6]
    if name.startswith("software limit below"):
        assert {g["error_id"] for g in got} - {0} == {900002} and min(off) >= -1.0 - 1e-9, (min(off), seq)
    elif name.startswith("software limit above"):
        assert {g["error_id"] for g in got} - {0} == {900002} and max(off) <= 0.5 + 1e-9, (max(off), seq)
    else:
        assert all(g["error_id"] == 0 for g in got), seq
    plain = streamed[0]["plain"][2]
    if name == "lowering weights":                   # lowers at most at 0.2 v-max (reached), lifts faster
        assert min(vel) >= -20.0 - 1e-9 and min(vel[100:200]) < -19.0 and max(vel) > 50.0
    if name == "adaptive acceleration":              # a_min near the target: a smaller first step
        assert abs(vel[101]) < 0.5 * abs(plain[101]["velocity"])
    # DRYRUN from rest: the cycle runs, the offset stands at 0, the law's step is reported
    assert set(states[10:60]) == {6} and all(g["offset"] == 0.0 for g in got[:61]), seq
    assert max(abs(g["step"]) for g in got[10:60]) > 0.2 and max(abs(g["tdev"]) for g in got[10:60]) > 1.0
    assert states[60] == 0 and states[61] == 4
    # DRYRUN right after a run-out: the core's FREEZE until the offset stands, then DRYRUN
    dry = [k for k in dry if k > 400]
    assert dry and set(states[dry[0]:650]) == {6}, seq
    assert 2 in states[401:dry[0]] or states[dry[0] - 1] == 0, seq
    assert len({off[k] for k in dry}) == 1                                      # the offset stands ...
    assert max(abs(got[k]["step"]) for k in dry) > 0.2                          # ... the law's step is reported
    assert max(abs(got[k]["tdev"]) for k in dry) > 1.0
    assert 4 in states[670:] and 6 not in states[670:]


def test_thc_config_refuses_limits_weights_and_adaptive_settings_outside_the_documents_ranges():
    with pytest.raises(LinuxCNCError, match="P-AXIS-00533"):
        ThcConfig(v_weight_down=2.5).check(0.001)
    with pytest.raises(LinuxCNCError, match="P-AXIS-00534"):
        ThcConfig(a_weight_down=-0.1).check(0.001)
    with pytest.raises(LinuxCNCError, match="P-AXIS-00502"):
        ThcConfig(use_adaptive_acceleration=True, a_min=0.0).check(0.001)
    with pytest.raises(LinuxCNCError, match="P-AXIS-00177/00178"):
        ThcConfig(check_sw_limit_switch=True, sw_limit_min=31.0, sw_limit_max=30.0).check(0.001)
    lines = ThcConfig(check_sw_limit_switch=True, sw_limit_max=12.5, dryrun=True).setp_lines(0.001)
    assert "setp distctrl-thc.0.sw-limit-max 12.5" in lines and "setp distctrl-thc.0.dryrun 1" in lines


@pytest.mark.parametrize("name", list(SETPOS))
def test_the_component_runs_the_cores_set_pos_cycle_bit_for_bit(streamed, name):
    """mode 1: ON (SET_POS) with set-pos, the surface a - d as the filter's input, the cyclic D_Position, a
    FREEZE released into SET_POS, DRYRUN_SETPOS, 900005 for a NaN set-pos; mode 0 between: CONST_DIST."""
    cfg, rows, got = streamed[0][name]
    states = _compare(cfg, rows, got, cfg.set_dist)
    seq = _changes(states)
    assert states[11] == 1 and 2 in states[230:262] and states[290] == 1, seq        # ACTIVE, FREEZE, ACTIVE
    assert 4 in states[300:400] and 7 in states[400:600] and 1 in states[610:700], seq   # CONST_DIST, DRYRUN
    assert {g["error_id"] for g in got[700:800]} == {0, 900005} and states[-1] == 1, seq   # NaN refused; SET_POS
    # SET_POS follows the surface: the offset goes to (the surface a - d, filtered) - set-pos; the 2 mm drop
    # moves it down
    assert min(g["offset"] for g in got[100:160]) < -1.0
    for k in (290, 690):                             # (the surface oscillates with a at 5 Hz: a lag remains)
        assert abs(got[k]["offset"] - (got[k]["filtered"] - 28.2)) < 0.35, (k, got[k])


def test_thc_config_refuses_an_unknown_mode():
    with pytest.raises(LinuxCNCError, match="mode = 'REF' unknown"):
        ThcConfig(mode="REF").check(0.001)
    assert "setp distctrl-thc.0.mode 1" in ThcConfig(mode="SET_POS").setp_lines(0.001)
