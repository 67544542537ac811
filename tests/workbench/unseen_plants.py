"""Random plants that ``distctrl identify`` was NOT designed around (issue 26): a generator with its own
assumptions, deliberately different from the fit's model and from tests/workbench/identify_plants.py.

* Setpoint delay in **whole cycles** (the NC's bus), the command held over each cycle.
* Drive: a continuous P position loop ``v = kv (c - x)`` with |v| <= v_max and |dv/dt| <= a_max,
  integrated at ``sub`` steps per cycle (the limits act within the cycle), the motor exactly linear
  within each sub-step.
* Mode motor -> nozzle, ``n'' = -w0^2 (n - x) - 2 zeta w0 (n' - x')``, discretised **exactly** for a
  motor that is piecewise linear in time (first-order hold, matrix exponential; scipy.signal.lsim),
  not by the fit's nor by identify_plants' ZOH filter.
* Sensor: the nozzle at ``t - delay`` (continuous delay 0-4 ms, interpolated on the sub-step grid),
  white noise on the distance, a non-linear characteristic of one of several shapes (polynomial,
  saturating exponential, piecewise linear with kinks, square-root-like), the reading **quantised**
  to the sensor's resolution (1 um).
* Encoder (actual column) quantised to 0.1 um, sampled at the start of the row (TwinCAT).

Recordings: raw set-position steps of 0.2-0.5 mm every 0.5 s plus one large step of several mm, a
chirp 1-150 Hz of 0.05 mm, a slow ramp over the sensor's range; 10-20 s each, 1 ms cycle. Written as
plain CSV (``time,set_pos,act_pos,sensor``), the format ``distctrl identify`` reads.

Not imported by distctrl; used by tests/workbench/test_identify_unseen.py and
bench/bench_identify_unseen.py.
"""
from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass

from pathlib import Path

import numpy as np

T = 0.001
#: tolerances of issue 26
TOL = {"kv": 0.10, "dead_time": 0.001, "resonance_hz": 0.10, "damping": (0.50, 0.03), "delay": 0.001,
       "noise_std": 0.30, "characteristic": 0.020}
SHAPES = ("poly", "exp", "kinks", "sqrt")


@dataclass(frozen=True)
class UnseenPlant:
    kv: float
    dead_cycles: int
    v_max: float
    a_max: float
    resonance_hz: float
    damping: float
    delay: float
    noise_std: float
    shape: str
    shape_params: tuple
    surface: float = 10.0
    sensor_resolution: float = 1e-3
    encoder_resolution: float = 1e-4

    @property
    def dead_time(self) -> float:
        return self.dead_cycles * T

    def characteristic(self, d):
        """Reported distance (mm) at the true distance d (mm); monotonic over 0-9 mm."""
        d = np.asarray(d, float)
        p = self.shape_params
        if self.shape == "poly":          # gain, offset, quadratic, cubic
            g, o, q, c = p
            return o + g * d + q * d * d + c * d ** 3
        if self.shape == "exp":           # saturating: d + a (1 - exp(-d / L)) ...
            g, o, a, L = p
            return o + g * d + a * (1.0 - np.exp(-d / L))
        if self.shape == "kinks":         # piecewise linear through random slopes at 1.5, 3.5, 5.5 mm
            o, s0, s1, s2, s3 = p
            knots = np.array([-5.0, 1.5, 3.5, 5.5, 20.0])
            slopes = np.array([s0, s1, s2, s3])
            vals = np.concatenate([[0.0], np.cumsum(slopes * np.diff(knots))])
            return o + np.interp(d, knots, vals) - 5.0 * s0
        if self.shape == "sqrt":          # compressive: g d + a (sqrt(d + 1) - 1)
            g, o, a = p
            return o + g * d + a * (np.sqrt(np.maximum(d, -0.99) + 1.0) - 1.0)
        raise ValueError(self.shape)

    def describe(self) -> dict:
        out = asdict(self)
        out["dead_time"] = self.dead_time
        return out


def random_plant(seed: int) -> UnseenPlant:
    rng = np.random.default_rng(10_000 + seed)
    shape = SHAPES[seed % len(SHAPES)]
    if shape == "poly":
        params = (rng.uniform(0.9, 1.1), rng.uniform(-0.05, 0.05), rng.uniform(-0.01, 0.01), rng.uniform(-5e-4, 5e-4))
    elif shape == "exp":
        params = (rng.uniform(0.8, 1.0), rng.uniform(-0.05, 0.05), rng.uniform(0.1, 0.4), rng.uniform(0.5, 3.0))
    elif shape == "kinks":
        params = (rng.uniform(-0.05, 0.05),) + tuple(rng.uniform(0.85, 1.15, 4))
    else:
        params = (rng.uniform(0.8, 1.0), rng.uniform(-0.05, 0.05), rng.uniform(0.1, 0.5))
    return UnseenPlant(
        kv=float(rng.uniform(20.0, 80.0)), dead_cycles=int(rng.integers(0, 6)),
        v_max=float(rng.uniform(40.0, 120.0)), a_max=float(rng.uniform(2000.0, 10000.0)),
        resonance_hz=float(math.exp(rng.uniform(math.log(10.0), math.log(120.0)))),
        damping=float(math.exp(rng.uniform(math.log(0.01), math.log(0.2)))),
        delay=float(rng.uniform(0.0, 0.004)),
        noise_std=float(rng.uniform(0.001, 0.010)), shape=shape, shape_params=tuple(float(v) for v in params))


# ---------------------------------------------------------------- commands (set position per cycle)

def steps_command(rng, seconds: float, z0: float) -> np.ndarray:
    n = int(round(seconds / T))
    t = np.arange(n) * T
    step = rng.uniform(0.2, 0.5)
    k = (t // 0.5).astype(int)
    c = z0 + np.where(k % 2 == 1, step, 0.0)
    large = rng.uniform(3.0, 5.0)
    big = (t >= 0.7 * seconds) & (t < 0.85 * seconds)
    c[big] = z0 + large
    c[t >= 0.85 * seconds] = z0
    c[t < 0.5] = z0
    return c


def chirp_command(rng, seconds: float, z0: float, amp: float = 0.05) -> np.ndarray:
    n = int(round(seconds / T))
    t = np.arange(n) * T
    c = np.full(n, z0)
    on = (t >= 0.5) & (t < seconds - 0.5)
    tt = t[on] - 0.5
    dur = tt[-1]
    f1, f2 = 1.0, 150.0
    phase = 2 * np.pi * (f1 * tt + 0.5 * (f2 - f1) / dur * tt * tt)   # linear sweep, starts at zero
    c[on] += amp * np.sin(phase)
    return c


def ramp_command(rng, seconds: float, surface: float) -> np.ndarray:
    n = int(round(seconds / T))
    t = np.arange(n) * T
    t0, t1 = 0.5, seconds - 1.0
    d0, d1 = 0.3, 7.5
    frac = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    return surface + d0 + (d1 - d0) * frac


# ---------------------------------------------------------------- simulation

def simulate(plant: UnseenPlant, command: np.ndarray, seed: int, sub: int = 8):
    """(t, command, actual, sensor) rows at the cycle T."""
    from scipy.signal import lsim

    n = command.size
    dt = T / sub
    # setpoint delay in whole cycles, held over each cycle, seen at every sub-step
    cd = np.concatenate([np.full(plant.dead_cycles, command[0]), command])[:n]
    c = np.repeat(cd, sub).tolist()
    m = n * sub
    xs = np.empty(m + 1)
    x = float(command[0])
    v = 0.0
    xs[0] = x
    kv, vm, dvm = plant.kv, plant.v_max, plant.a_max * dt
    for j in range(m):
        # P loop on the position at the start of the sub-step, limited; v constant over the sub-step
        vn = kv * (c[j] - x)
        if vn > vm:
            vn = vm
        elif vn < -vm:
            vn = -vm
        if vn > v + dvm:
            vn = v + dvm
        elif vn < v - dvm:
            vn = v - dvm
        v = vn
        x += v * dt
        xs[j + 1] = x
    tf = np.arange(m + 1) * dt
    w0 = 2 * math.pi * plant.resonance_hz
    z = plant.damping
    x0 = xs[0]
    # nozzle - x0 from motor - x0 (piecewise linear): exact first-order-hold discretisation
    _, nz, _ = lsim(([2 * z * w0, w0 * w0], [1.0, 2 * z * w0, w0 * w0]), xs - x0, tf, interp=True)
    nozzle = nz + x0
    rows = np.arange(n)
    t = rows * T
    rng = np.random.default_rng(seed)
    actual = np.round(xs[rows * sub] / plant.encoder_resolution) * plant.encoder_resolution
    nd = np.interp(t - plant.delay, tf, nozzle, left=nozzle[0])
    d = nd - plant.surface + plant.noise_std * rng.standard_normal(n)
    sensor = np.round(plant.characteristic(d) / plant.sensor_resolution) * plant.sensor_resolution
    return t, command.copy(), actual, sensor


def recordings(plant: UnseenPlant, seed: int) -> dict:
    """Steps, chirp and ramp of 10-20 s each: {name: (t, command, actual, sensor)}."""
    rng = np.random.default_rng(20_000 + seed)
    z_chirp = plant.surface + rng.uniform(1.0, 2.0)
    z_steps = plant.surface + rng.uniform(1.0, 1.5)
    cmds = {"steps": steps_command(rng, rng.uniform(10.0, 20.0), z_steps),
            "chirp": chirp_command(rng, rng.uniform(15.0, 20.0), z_chirp),
            "ramp": ramp_command(rng, rng.uniform(15.0, 20.0), plant.surface)}
    return {k: simulate(plant, c, seed=1000 * seed + i) for i, (k, c) in enumerate(cmds.items())}


def write_csv(path, t, command, actual, sensor) -> None:
    data = np.column_stack([t, command, actual, sensor])
    np.savetxt(path, data, delimiter=",", fmt="%.9f", header="time,set_pos,act_pos,sensor", comments="")


def write_recordings(plant: UnseenPlant, seed: int, folder, prefix: str = "") -> list:
    """The plant's recordings (:func:`recordings`) as CSV files ``<folder>/<prefix><name>.csv``; their paths."""
    paths = []
    for name, rows in recordings(plant, seed).items():
        path = Path(folder) / f"{prefix}{name}.csv"
        write_csv(path, *rows)
        paths.append(path)
    return paths


# ---------------------------------------------------------------- the true plant as a scenario

def _set_key(text: str, section: str, key: str, value: str) -> str:
    """Replace ``key = ...`` inside ``[section]`` (up to the next table header); add it if it is not there."""
    head = text.index(f"[{section}]")
    end = text.find("\n[", head + 1)
    end = len(text) if end < 0 else end
    body, n = re.subn(rf"(?m)^{re.escape(key)} = .*$", f"{key} = {value}", text[head:end], count=1)
    if n != 1:
        line = text.index("\n", head)
        return text[:line + 1] + f"{key} = {value}\n" + text[line + 1:]
    return text[:head] + body + text[end:]


def true_scenario_text(plant: UnseenPlant, fitted: str) -> str:
    """The scenario ``distctrl identify --out`` wrote (``fitted``, its text) with the generator's own figures
    put in: kv (the same pole per cycle), dead time, v_max, a_max, the mode, the sensor delay (whole
    cycles), noise and characteristic. The true plant, as far as the simulator can represent it."""
    text = fitted
    z = {"kv": repr(-math.expm1(-plant.kv * T) / T), "bus_delay_cycles": str(plant.dead_cycles),
         "v_max": repr(plant.v_max), "a_max": repr(plant.a_max), "resonance_hz": repr(plant.resonance_hz),
         "damping": repr(plant.damping)}
    for k, v in z.items():
        text = _set_key(text, "axes.Z", k, v)
    d = np.round(np.arange(0.0, 10.0001, 0.1), 6)
    table = "[" + ", ".join(f"[{a:.6g}, {b:.6f}]" for a, b in zip(d, plant.characteristic(d))) + "]"
    for k, v in {"delay_cycles": str(int(round(plant.delay / T))), "noise_std": repr(plant.noise_std),
                 "characteristic": table}.items():
        text = _set_key(text, "sensor", k, v)
    return text


# ---------------------------------------------------------------- scoring

def score(plant: UnseenPlant, drive: dict, sensor: dict) -> dict:
    """Per quantity: True (within the tolerance of issue 26), False (outside or not identified)."""
    def rel(v, truth, tol):
        return v is not None and abs(v / truth - 1.0) <= tol

    out = {"kv": rel(drive.get("kv"), plant.kv, TOL["kv"]),
           "dead_time": drive.get("dead_time") is not None and abs(drive["dead_time"] - plant.dead_time) <= TOL["dead_time"],
           "resonance_hz": rel(drive.get("resonance_hz"), plant.resonance_hz, TOL["resonance_hz"])}
    zt = drive.get("damping")
    out["damping"] = zt is not None and (abs(zt / plant.damping - 1) <= TOL["damping"][0]
                                         or abs(zt - plant.damping) <= TOL["damping"][1])
    out["delay"] = sensor.get("delay") is not None and abs(sensor["delay"] - plant.delay) <= TOL["delay"]
    out["noise_std"] = rel(sensor.get("noise_std"), plant.noise_std, TOL["noise_std"])
    ch = sensor.get("characteristic")
    if ch:
        ch = np.asarray(ch, float)
        d = np.linspace(0.5, 7.0, 300)
        err = float(np.max(np.abs(np.interp(d, ch[:, 0], ch[:, 1]) - plant.characteristic(d))))
        out["characteristic"] = err <= TOL["characteristic"]
    else:
        out["characteristic"] = False
    return out
