"""Issue 16's plates: a plate run with and without its cutting-process functions, and the figures.

``plate_figures(scenario, functions=True)`` runs a scenario (its ``[[process]]`` tables, or none of
them with ``functions=False``) and measures, as docs/process.md "The two plates" defines them:

* ``min_distance_mm`` - the minimum true distance of the nozzle over the whole run (mm; negative:
  into the plate), a touch-off's probe included; ``min_cut_distance_mm`` the same while a G1 block
  runs (the cuts);
* ``time_below_half_s`` - how long the true distance was below half the set distance in force while
  distance control ran (ACTIVE, ACTIVE_CONST_DIST or FREEZE; s);
* ``collisions`` - contacts with the plate (warning 900030, docs/run.md "Collisions");
* ``path_time_s`` - from the start until the NC program ended (s);
* ``set_distance_mm`` - the cut's set distance: the median of the set distance in force while
  distance control ran (mm; a touch-off's probe and pierce height are brief), and
  ``min_share`` = min_distance_mm / set_distance_mm.

``compare(scenario)`` gives both (``{"with": ..., "without": ...}``), and with a ``lift`` table the
run without the lift alone (``"no_lift"``) and the lift's share of the path time. The plates themselves are
examples/scenarios/plasma_plate.toml and laser_sheet.toml (tools/make_plates.py writes them).
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from .runner import run
from .scenario import Scenario, load_scenario

__all__ = ["PLATES", "EXAMPLES", "plate_figures", "compare", "select_functions", "CutWatch", "TARGET_MIN_SHARE",
           "TARGET_LIFT_INCREASE"]

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
#: the two plates of issue 16 (scenario file stems in examples/scenarios/)
PLATES = ("plasma_plate", "laser_sheet")
#: issue 16's target: with the functions the head never comes closer than 30 % of the set distance
TARGET_MIN_SHARE = 0.3
#: issue 16's target: the lift adds at most 5 % to the path time against no lift
TARGET_LIFT_INCREASE = 0.05
_RUNNING = (1, 2, 4)            # ACTIVE, FREEZE, ACTIVE_CONST_DIST (HLI state)


def select_functions(sc, functions: bool = True, drop: tuple = (), only: tuple | None = None):
    """``sc`` with its ``[[process]]`` tables (``functions=False``: none; ``only``: just the functions
    named; ``drop``: all but those), as ``distctrl run --no-process`` / ``--process`` and the plates'
    comparison run it. A plate program that asks for the touch-off (variable ``IHS``) runs with
    ``IHS = 0`` when the touch-off is not among them: it would wait for the PLC's answer for ever."""
    keep = tuple(p for p in sc.processes if functions and p.function not in drop
                 and (only is None or p.function in only))
    sc = dataclasses.replace(sc, processes=keep)
    if "IHS" in sc.variables and not any(p.function == "touch_off" for p in keep):
        # the plates' programs ask for the touch-off when IHS = 1 and wait for the PLC's answer: without
        # the function the machine's initial height sense is off (distance control's select comes down)
        sc = dataclasses.replace(sc, variables={**sc.variables, "IHS": 0.0})
    return sc


class CutWatch:
    """A PLC program that only reads (``run(sc, plc_program=CutWatch(axis))``): the figures of the
    module docstring for any run, without keeping its trace. Called at the start of cycle k it sees the
    machine as cycle k-1 left it (the trace's row k-1); :meth:`finish` takes the last cycle's row.

    ``figures(result, cycle_time)``: ``min_cut_distance_mm``, ``time_below_half_s``, ``path_time_s``,
    ``set_distance_mm``, ``lifts``."""

    def __init__(self, axis: str):
        self.axis = axis
        self.machine = None
        self.ended_cycle: int | None = None
        self.lifts = 0
        self._up = False
        self.cut_min = math.inf
        self.below = 0
        self.set_counts: dict[float, int] = {}

    #: False for a run the figures do not apply to (3D distance control, no such axis)
    applies = True

    def __call__(self, machine, cycle: int) -> None:
        if cycle == 0:
            self.applies = machine.ch3d is None and self.axis in machine.dc_axes
        if not self.applies:
            return
        self.machine = machine
        nc = machine.nc
        if nc is not None and nc.running:
            self.ended_cycle = cycle                       # the cycle the program ran last
        if machine.channel_path.motion_type == 2 and machine.true_distance < self.cut_min:
            self.cut_min = machine.true_distance           # the cuts (G1) only: no touch-off, no rapid
        up = any(lm.lift_active for lm in machine.lift_motions)
        if up and not self._up:
            self.lifts += 1
        self._up = up
        if cycle > 0:
            self._row(machine)

    def _row(self, machine) -> None:
        out = machine.outputs[self.axis]
        if out.hli_state in _RUNNING:
            sd = float(out.set_distance)
            self.set_counts[sd] = self.set_counts.get(sd, 0) + 1
            if machine.true_distance < 0.5 * sd:
                self.below += 1

    def finish(self) -> None:
        """The last cycle's row (no cycle start follows it)."""
        if self.machine is not None:
            self._row(self.machine)
            self.machine = None

    def _set_median(self) -> float:
        """The median of the set distance over the cycles distance control ran (as numpy's median)."""
        n = sum(self.set_counts.values())
        if n == 0:
            return float("nan")
        picks, seen, out = sorted({(n - 1) // 2, n // 2}), 0, []
        for value in sorted(self.set_counts):
            seen += self.set_counts[value]
            while picks and picks[0] < seen:
                out.append(value)
                picks.pop(0)
        return float(out[0]) if len(out) == 1 else float((out[0] + out[1]) / 2.0)

    def figures(self, cycle_time: float) -> dict:
        self.finish()
        return {"min_cut_distance_mm": self.cut_min if math.isfinite(self.cut_min) else None,
                "time_below_half_s": self.below * cycle_time,
                "path_time_s": None if self.ended_cycle is None else (self.ended_cycle + 1) * cycle_time,
                "set_distance_mm": self._set_median(), "lifts": self.lifts}


def plate_figures(scenario, functions: bool = True, drop: tuple = ()) -> dict:
    """Run ``scenario`` (a path or a Scenario) with its ``[[process]]`` tables (but those whose function
    is in ``drop``), or without any, and return the figures (module docstring) plus ``completed``,
    ``errors``, ``functions`` (names) and ``lifts`` (rapids the lift function lifted)."""

    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    sc = select_functions(sc, functions, drop)
    axis = sc.sensor.axis if sc.sensor is not None and sc.sensor.axis else "Z"
    watch = CutWatch(axis)
    r = run(sc, plc_program=watch, keep_trace=False)
    m = r.metrics
    f = watch.figures(sc.cycle_time)
    set_cut = f["set_distance_mm"]
    return {"min_distance_mm": m["min_distance_mm"], "min_cut_distance_mm": f["min_cut_distance_mm"],
            "time_below_half_s": f["time_below_half_s"], "collisions": m["collisions"],
            "path_time_s": f["path_time_s"], "set_distance_mm": set_cut,
            "min_share": (m["min_distance_mm"] / set_cut) if m["min_distance_mm"] is not None else None,
            "completed": r.completed, "errors": [e["id"] for e in r.errors],
            "functions": [p.function for p in sc.processes], "lifts": f["lifts"]}


def compare(scenario) -> dict:
    """``{"with": plate_figures(sc), "without": plate_figures(sc, functions=False)}``, and with a
    ``lift`` table ``"no_lift"`` (the functions but the lift) and ``lift_path_time_increase`` (the
    path time with the lift over that without it, minus 1; issue 16's target: at most 5 %)."""

    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    out = {"with": plate_figures(sc), "without": plate_figures(sc, functions=False)}
    if any(p.function == "lift" for p in sc.processes):
        out["no_lift"] = nl = plate_figures(sc, drop=("lift",))
        w = out["with"]["path_time_s"]
        out["lift_path_time_increase"] = None if w is None or not nl["path_time_s"] else w / nl["path_time_s"] - 1.0
    return out
