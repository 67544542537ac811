"""Recordings made with ``distctrl run`` as the new-user audit made them (M2): distance control off, a
Z axis (kv 45, bus delay 3 cycles, 40 Hz ζ 0.05 resonance) moved by NC G0 blocks, so the NC's
interpolator shapes every step with the axis's v_max / a_max, and a distance sensor with a non-linear
characteristic. Steps of 0.2-0.5 mm 0.5 s apart plus one of 5 mm (docs/identify.md), and a slow ramp."""
from __future__ import annotations

from pathlib import Path

from distctrl.sim.runner import run

LIST = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "z_laser.lis"
SURFACE = 30.0
START = 31.5
CHAR = [[0.0, 0.0], [1.0, 1.02], [3.0, 3.05], [5.0, 5.02], [10.0, 9.9]]


def scenario_text(program: str, *, kv: float = 45.0, a_max: float = 5000.0, v_max: float = 80.0,
                  duration: float = 20.0) -> str:
    return f'''name = "identify recording"
cycle_time = 0.001
program = "{program}"
duration = {duration}

[axes.Z]
params = "{LIST}"
start = {START}
kv = {kv}
v_max = {v_max}
a_max = {a_max}
bus_delay_cycles = 3
resonance_hz = 40.0
damping = 0.05

[surface]
base = {SURFACE}

[sensor]
axis = "Z"
kind = "distance"
variable = "SENSOR"
range_max = 10.0
noise_std = 0.004
delay_cycles = 2
seed = 5
characteristic = {CHAR}
'''


#: distance control stays off: the program only selects the sensor variable (the Z.dc.sensor column)
SELECT_SENSOR = "N0 Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]"
STEPS = [0.3, -0.2, 0.5, -0.4, 0.2, 0.4, -0.5, -0.2, 0.3, -0.3, 0.25, 0.45, -0.45, -0.25, 0.35, -0.35]


def steps_program() -> str:
    lines = ["%STEPS", f"N1 G90 G0 Z{START}", SELECT_SENSOR, "N2 #TIME 0.5"]
    z, n = START, 10
    for s in STEPS:
        z = round(z + s, 4)
        lines += [f"N{n} G0 Z{z}", f"N{n + 1} #TIME 0.5"]
        n += 2
    lines += [f"N{n} G0 Z{START + 5.0}", f"N{n + 1} #TIME 0.5", f"N{n + 2} G0 Z{START}", f"N{n + 3} #TIME 0.5",
              f"N{n + 4} M30"]
    return "\n".join(lines) + "\n"


def ramp_program() -> str:
    return f"%RAMP\nN1 G90 G0 Z30.3\n{SELECT_SENSOR}\nN2 #TIME 1\nN3 G1 Z37.5 F24\nN4 #TIME 1\nN5 M30\n"  # 0.4 mm/s


def record(tmp: Path, kind: str = "steps", **plant) -> Path:
    """Run the recording scenario and return its trace CSV (columns Z.cmd, Z.act, Z.dc.sensor)."""
    tmp.mkdir(parents=True, exist_ok=True)
    tag = "_".join(f"{k}{v:g}" for k, v in sorted(plant.items()))
    prog = tmp / f"{kind}_{tag}.nc"
    prog.write_text(steps_program() if kind == "steps" else ramp_program(), encoding="utf-8")
    scn = tmp / f"{kind}_{tag}.toml"
    scn.write_text(scenario_text(prog.name, duration=40.0, **plant), encoding="utf-8")
    csv = tmp / f"{kind}_{tag}.csv"
    run(scn, trace=csv)
    return csv
