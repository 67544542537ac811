"""Recordings of KNOWN plants for the identify tests and the benchmark: an independent generator.

The continuous model, simulated with scipy and a fine time step (T/20), sampled at the cycle T:

* the command is held over each cycle and delayed by ``dead_time``;
* motor: P position loop ``v = kv (c - x)``, |v| <= v_max, |dv/dt| <= a_max (integrated at T/20);
* nozzle = motor + e, ``e'' + 2 zeta w0 e' + w0^2 e = -x''`` (scipy.signal: the transfer
  -s / (s^2 + 2 zeta w0 s + w0^2) from the motor velocity, zero-order hold at T/20, lfilter);
* sensor = characteristic(nozzle(t - delay) - surface) + noise (Gaussian, added to the distance);
* the actual column is the motor at the row's time (TwinCAT's input mapping), quantised to 0.1 um.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Plant:
    kv: float = 40.0
    dead_time: float = 0.003
    v_max: float = 60.0
    a_max: float = 5000.0
    resonance_hz: float = 40.0
    damping: float = 0.05
    delay: float = 0.002
    noise_std: float = 0.004
    surface: float = 10.0
    resolution: float = 1e-4

    def characteristic(self, d):
        d = np.asarray(d, float)
        return 1.02 * d + 0.004 * d * d - 0.01


def simulate(plant: Plant, command: np.ndarray, T: float = 0.001, seed: int = 0, sub: int = 20):
    """(t, command, actual, sensor) rows at the cycle T."""
    from scipy.signal import cont2discrete, lfilter

    n = command.size
    dt = T / sub
    m = n * sub
    ts = np.arange(m) * dt
    idx = np.clip(np.floor((ts - plant.dead_time) / T + 1e-9).astype(np.int64), 0, n - 1)
    c = command[idx].tolist()
    x = float(command[0])
    v = 0.0
    xs = np.empty(m + 1)
    vs = np.empty(m)
    xs[0] = x
    kv, vm, dvm = plant.kv, plant.v_max, plant.a_max * dt
    for j in range(m):
        vn = kv * (c[j] - x)
        vn = vm if vn > vm else (-vm if vn < -vm else vn)
        vn = v + dvm if vn > v + dvm else (v - dvm if vn < v - dvm else vn)
        v = vn
        x += v * dt
        vs[j] = v
        xs[j + 1] = x
    if plant.resonance_hz:
        w0 = 2 * math.pi * plant.resonance_hz
        b, a, _ = cont2discrete(([-1.0, 0.0], [1.0, 2 * plant.damping * w0, w0 * w0]), dt, method="zoh")
        e = np.concatenate([[0.0], lfilter(np.ravel(b), a, vs)])   # e at the sub-step boundaries
    else:
        e = np.zeros(m + 1)
    nozzle = xs + e
    rows = np.arange(n)
    t = rows * T
    actual = xs[rows * sub]
    actual = np.round(actual / plant.resolution) * plant.resolution
    tn = np.arange(m + 1) * dt
    nd = np.interp(t - plant.delay, tn, nozzle, left=nozzle[0])
    rng = np.random.default_rng(seed)
    d = nd - plant.surface + plant.noise_std * rng.standard_normal(n)
    sensor = plant.characteristic(d)
    return t, command.copy(), actual, sensor


def steps_command(T=0.001, seconds=12.0, z0=11.0, step=0.3, period=0.5, large=4.0):
    n = int(round(seconds / T))
    t = np.arange(n) * T
    c = np.full(n, z0)
    k = (t // period).astype(int)
    c += np.where(k % 2 == 1, step, 0.0)
    # two large steps (the velocity limit) in the last quarter
    big = t >= 0.75 * seconds
    c[big] = z0 + np.where(t[big] < 0.875 * seconds, large, 0.0)
    c[t < period] = z0
    return c


def chirp_command(T=0.001, seconds=20.0, z0=11.0, amp=0.05, f1=1.0, f2=150.0):
    from scipy.signal import chirp

    n = int(round(seconds / T))
    t = np.arange(n) * T
    c = np.full(n, z0)
    on = (t >= 0.5) & (t < seconds - 0.5)
    tt = t[on] - 0.5
    c[on] += amp * chirp(tt, f1, tt[-1], f2, method="linear", phi=-90)
    return c


def ramp_command(T=0.001, seconds=20.0, d_from=0.3, d_to=7.6, surface=10.0):
    n = int(round(seconds / T))
    t = np.arange(n) * T
    t0, t1 = 1.0, seconds - 1.0
    frac = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    return surface + d_from + (d_to - d_from) * frac


def write_csv(path, t, command, actual, sensor, names=("time", "set_pos", "act_pos", "sensor"), sep=",",
              decimal="."):
    with open(path, "w", encoding="utf-8") as f:
        f.write(sep.join(names) + "\n")
        for row in zip(t, command, actual, sensor):
            line = sep.join(f"{v:.9f}" for v in row)
            if decimal == ",":
                line = line.replace(".", ",")
            f.write(line + "\n")


def write_scope_csv(path, t, command, actual, sensor, sep="\t", decimal=",",
                    names=("MAIN.fSetPos", "MAIN.fActPos", "MAIN.fDistance")):
    """A TwinCAT Scope CSV export: project rows, the channel blocks side by side (one time column
    per channel: Timelines "All"), then the data in ms since the start."""
    def num(v, fmt="{:.9f}"):
        s = fmt.format(v)
        return s.replace(".", ",") if decimal == "," else s
    chans = list(zip(names, (command, actual, sensor)))
    lines = [sep.join(["Name", "Identify Scope Project"]), sep.join(["File", "C:\\\\rec\\\\z_axis.svdx"]),
             sep.join(["StartTime", "133512345678900000", "Montag, 1. Januar 2024"]),
             sep.join(["EndTime", "133512347678900000", "Montag, 1. Januar 2024"]), ""]
    meta = [("Name", lambda nm: nm.split(".")[-1]), ("SymbolComment", lambda nm: ""),
            ("Data-Type", lambda nm: "REAL64"), ("SampleTime[ms]", lambda nm: "1"), ("VariableSize", lambda nm: "8"),
            ("SymbolBased", lambda nm: "True"), ("IndexGroup", lambda nm: "16448"), ("IndexOffset", lambda nm: "0"),
            ("SymbolName", lambda nm: nm), ("NetId", lambda nm: "5.23.18.40.1.1"), ("Port", lambda nm: "851"),
            ("Offset", lambda nm: "0"), ("ScaleFactor", lambda nm: "1"), ("BitMask", lambda nm: "0xFFFFFFFFFFFFFFFF"),
            ("Unit", lambda nm: "")]
    for key, val in meta:
        lines.append(sep.join(sep.join([key, val(nm)]) for nm, _ in chans))
    lines.append("")
    ms = t * 1e3
    for i in range(t.size):
        lines.append(sep.join(sep.join([num(ms[i], "{:.3f}"), num(vals[i])]) for _, vals in chans))
    lines.append("EOF")
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")
