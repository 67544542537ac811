"""distctrl's law as a LinuxCNC component (hal/distctrl_thc.comp): streamed through halrun in lock-step,
its outputs equal the Python law's (distctrl.linuxcnc.thc.ThcReference, made of distctrl.control.law)
to the last bit, for every filter type, with the state transitions idle -> active -> locked (corner
lock, void lock) -> active -> idle -> active."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest

from distctrl.control.filters import FilterConfig
from distctrl.linuxcnc.bench import release_gate
from distctrl.linuxcnc.hal_env import HalSession, LinuxCNCError, import_hal, install_component
from distctrl.linuxcnc.thc import ThcConfig, ThcReference
from distctrl.base.kinds import FilterType

CONFIGS = {
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
N = 900


def _inputs():
    """Arc voltage with warp, ripple, noise, a void (fast rise and fall), a corner slow-down, and the THC
    switched off and on again."""
    rng = np.random.default_rng(29)
    rows = []
    for k in range(N):
        t = k * 0.001
        v = 104.0 + 3.0 * math.sin(2 * math.pi * 3 * t) + 2.0 * math.sin(2 * math.pi * 50 * t) + 0.3 * rng.standard_normal()
        if 300 <= k < 330:
            v += 45.0 * min(1.0, (k - 300) / 5.0)      # a hole: fast rise, then high
        enable = not (20 > k or 600 <= k < 640)      # idle, active, ..., idle, active
        vel = 83.3 if not (450 <= k < 520) else 83.3 * (1.0 - min(1.0, (k - 450) / 20.0)) + 5.0
        zc = 40.0 - 0.01 * k + 0.5 * math.sin(2 * math.pi * 7 * t)       # commanded and actual Z (both encoders)
        za = zc - 0.2 * math.cos(2 * math.pi * 7 * t) - 0.001 * rng.standard_normal()
        reset = 620 <= k < 625                          # while idle: the offset back to 0
        rows.append((float(v), enable, True, float(vel), 83.3, True, zc, za, reset))
    return rows


@pytest.fixture(scope="module")
def streamed():
    install_component("distctrl_lockstep")
    install_component("distctrl_thc")
    hal = import_hal()
    names = list(CONFIGS)
    with HalSession() as hs:
        hs.cmd("loadrt threads name1=servo-thread period1=1000000", "loadrt distctrl_lockstep",
               f"loadrt distctrl_thc count={len(names)}", "addf distctrl-lockstep.0.wait servo-thread",
               *[f"addf distctrl-thc.{i} servo-thread" for i in range(len(names))],
               "addf distctrl-lockstep.0.post servo-thread", "setp distctrl-lockstep.0.enable 1",
               *[line for i, n in enumerate(names) for line in CONFIGS[n].setp_lines(0.001, f"distctrl-thc.{i}")])
        comp = hal.component("thc-stream")
        ins = {"arc": hal.HAL_FLOAT, "enable": hal.HAL_BIT, "cl-enable": hal.HAL_BIT, "vel": hal.HAL_FLOAT,
               "req-vel": hal.HAL_FLOAT, "vl-enable": hal.HAL_BIT, "zc": hal.HAL_FLOAT, "za": hal.HAL_FLOAT,
               "reset": hal.HAL_BIT}
        for p, t in ins.items():
            comp.newpin(p, t, hal.HAL_OUT)
        outs = {"offset": hal.HAL_FLOAT, "filtered": hal.HAL_FLOAT, "velocity": hal.HAL_FLOAT, "distance": hal.HAL_FLOAT,
                "counts": hal.HAL_S32, "state": hal.HAL_S32, "cl": hal.HAL_BIT, "vl": hal.HAL_BIT}
        for i in range(len(names)):
            for p, t in outs.items():
                comp.newpin(f"{i}-{p}", t, hal.HAL_IN)
        comp.newpin("seq", hal.HAL_U32, hal.HAL_IN)
        comp.newpin("ack", hal.HAL_U32, hal.HAL_OUT)
        comp.ready()
        try:
            target = {"arc": "arc-voltage-in", "enable": "thc-enable", "cl-enable": "cornerlock-enable",
                      "vel": "current-velocity", "req-vel": "requested-velocity", "vl-enable": "voidlock-enable",
                      "zc": "axis-z-command", "za": "axis-z-position", "reset": "offset-reset"}
            src = {"offset": "offset", "filtered": "filtered", "velocity": "velocity", "distance": "distance",
                   "counts": "z-offset-counts", "state": "state-out", "cl": "cornerlock-is-locked",
                   "vl": "voidlock-is-locked"}
            nets = [f"net ts-{p} thc-stream.{p} => " + " ".join(f"distctrl-thc.{i}.{q}" for i in range(len(names)))
                    for p, q in target.items()]
            nets += [f"net ts-{i}-{p} distctrl-thc.{i}.{q} => thc-stream.{i}-{p}" for i in range(len(names))
                     for p, q in src.items()]
            nets += ["net ts-seq distctrl-lockstep.0.seq => thc-stream.seq",
                     "net ts-ack thc-stream.ack => distctrl-lockstep.0.ack", "start"]
            rows = _inputs()
            # period 1 runs on the pins' start values (all 0): its outputs are read and skipped
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
                got.append([{p: comp[f"{i}-{p}"] for p in outs} for i in range(len(names))])
                if k - 1 < N:
                    v, en, cl, vel, req, vl, zc, za, reset = rows[k - 1]
                    comp["reset"] = reset
                    comp["arc"], comp["enable"], comp["cl-enable"] = v, en, cl
                    comp["vel"], comp["req-vel"], comp["vl-enable"] = vel, req, vl
                    comp["zc"], comp["za"] = zc, za
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
    return names, rows, got[1:N + 1], missed


def test_the_stream_ran_lock_step(streamed):
    names, rows, got, missed = streamed
    assert missed == 0 and len(got) == N


@pytest.mark.parametrize("name", list(CONFIGS))
def test_the_component_equals_the_python_law_bit_for_bit(streamed, name):
    names, rows, got, _ = streamed
    i = names.index(name)
    ref = ThcReference(CONFIGS[name])
    ref.step(0.0, False)                     # period 1: the pins' start values (its outputs are skipped)
    states = []
    for k, (v, en, cl, vel, req, vl, zc, za, reset) in enumerate(rows):
        r = ref.step(v, en, cl, vel, req, vl, zc, za, reset)
        g = got[k][i]
        states.append(g["state"])
        assert g["distance"] == r["distance"], (k, "distance")
        assert g["state"] == r["state"], (k, "state")
        assert g["offset"] == r["offset"], (k, "offset", g["offset"], r["offset"])
        assert g["velocity"] == r["velocity"], (k, "velocity")
        assert bool(g["cl"]) == r["cornerlock_is_locked"] and bool(g["vl"]) == r["voidlock_is_locked"], k
        assert g["counts"] == r["counts"], (k, "counts")
        if r["state"]:
            assert g["filtered"] == r["filtered"], (k, "filtered")
    # the transitions happened: idle -> active -> locked -> active -> idle -> active
    seq = [s for n, s in enumerate(states) if n == 0 or s != states[n - 1]]
    assert seq[:3] == [0, 1, 2] and 0 in seq[3:] and seq[-1] == 1
    assert any(s == 2 for s in states[300:340]) and any(s == 2 for s in states[460:520])
    assert got[630][i]["offset"] == 0.0 and got[590][i]["offset"] != 0.0     # the reset while idle


def test_thc_config_refuses_values_outside_the_documents_ranges():
    with pytest.raises(LinuxCNCError, match="kp = 2.5 out of range"):
        ThcConfig(kp=2.5).check(0.001)
    with pytest.raises(LinuxCNCError, match="P-AXIS-00413"):
        ThcConfig(filter=FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=100)).check(0.001)
    with pytest.raises(LinuxCNCError, match="P-AXIS-00508"):
        ThcConfig(filter=FilterConfig(FilterType.LOWPASS, order=2, fg_f0=600.0)).check(0.001)
