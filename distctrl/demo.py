"""The demo job: distance control over a real, uneven sheet, run through the cycle core.

Two runs on a simulated Z axis (first-order drive, probe on encoder 2 with noise):
 * CONST_DIST: a laser head keeps 1 mm above a sheet with waviness, a thickness step and the
   2.8 mm obstacle of seeds/000 §4 while X moves at 6 m/min (plain, and with both encoders);
 * SET_POS: the programmed surface Z = 30 mm, the real sheet is 0.4 mm thinner and wavy.
Prints a summary table and returns the metrics.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .control import Action, AxisDistanceController, Command, CycleInput, CycleOutput, FilterType, HliState
from .params import AxisParameters

T = 0.001


def sheet(x: float) -> float:
    """Surface height (mm) under the tool at X (mm): waviness, a 0.5 mm step, the 2.8 mm obstacle."""
    z = 30.0 + 0.3 * math.sin(2 * math.pi * x / 120.0)
    if x >= 150.0:
        z += 0.5
    if 250.0 <= x < 280.0:
        z += 2.8
    return z


@dataclass
class DemoResult:
    name: str
    cycles: int
    distance_error_rms: float
    distance_error_max: float
    max_offset: float
    errors: list


def run_case(name: str, mode: str, params: AxisParameters, seed: int = 1) -> DemoResult:
    ctrl = AxisDistanceController(params, T)
    rng = np.random.default_rng(seed)
    noise = rng.normal(0.0, 0.002, 200_000)
    inp, out = CycleInput(), CycleOutput()
    feed = 100.0                                   # mm/s (6 m/min)
    z_prog = 31.0 if mode == "const" else 30.0 + 1.0   # SET_POS: programmed 1 mm above the ideal surface
    actual = z_prog
    commands = {0: Command(Action.ON, const_dist=True, set_dist=1.0) if mode == "const"
                else Command(Action.ON, set_pos=30.0)}
    errors, dist_err = [], []
    n = int(400.0 / feed / T)
    max_offset = 0.0
    for k in range(n):
        x = feed * k * T
        surface = sheet(x) - (0.4 if mode == "setpos" else 0.0)
        inp.programmed_position = z_prog
        inp.actual_position = actual
        inp.sensor_increments = (surface - actual + noise[k]) / params.sensor_mm_per_increment
        if k in commands:
            inp.commands.append(commands[k])
        ctrl.update(inp, out)
        errors.extend(out.events)
        actual += (out.command_position - actual) * (T / 0.004)      # drive: 4 ms time constant
        max_offset = max(max_offset, abs(out.offset))
        if out.hli_state in (HliState.ACTIVE, HliState.ACTIVE_CONST_DIST) and k > 200:
            want = 1.0 if mode == "const" else z_prog - 30.0
            dist_err.append((actual - surface) - want)
    e = np.asarray(dist_err)
    return DemoResult(name, n, float(np.sqrt(np.mean(e**2))), float(np.max(np.abs(e))), max_offset, errors)


def demo_params() -> AxisParameters:
    return AxisParameters(enabled=True, v_max=200.0, a_max=20000.0, max_act_value_change=1e6, max_pos=10.0,
                          min_pos=-10.0, max_deviation=8.0, optimized_scheduling=True,
                          filter_type=FilterType.MOVING_AVERAGE, n_cycles=4, kp=0.5, d_tv=0.002)


def main() -> list[DemoResult]:
    from rich.console import Console
    from rich.table import Table

    p = demo_params()
    results = [run_case("CONST_DIST 1 mm", "const", p),
               run_case("CONST_DIST 1 mm, both encoders", "const", p.replace(use_both_encoders=True)),
               run_case("SET_POS 30 mm", "setpos", p)]
    table = Table(title="distctrl demo — axis distance control through the cycle core")
    for col in ("run", "cycles", "distance error RMS [mm]", "max |error| [mm]", "max |offset| [mm]", "errors"):
        table.add_column(col)
    for r in results:
        table.add_row(r.name, str(r.cycles), f"{r.distance_error_rms:.4f}", f"{r.distance_error_max:.3f}",
                      f"{r.max_offset:.3f}", ", ".join(str(e.id) for e in r.errors) or "none")
    console = Console()
    console.print(table)
    console.print("Sheet: waviness 0.3 mm / 120 mm, a 0.5 mm thickness step at X150, the 2.8 mm obstacle of "
                  "seeds/000 §4 at X250-280; X at 6 m/min. The max error is the obstacle edge itself; "
                  "P-AXIS-00500 (both encoders) removes the overshoot of the plain CONST_DIST loop.")
    return results
