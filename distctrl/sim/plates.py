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

__all__ = ["PLATES", "EXAMPLES", "plate_figures", "compare", "TARGET_MIN_SHARE", "TARGET_LIFT_INCREASE"]

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
#: the two plates of issue 16 (scenario file stems in examples/scenarios/)
PLATES = ("plasma_plate", "laser_sheet")
#: issue 16's target: with the functions the head never comes closer than 30 % of the set distance
TARGET_MIN_SHARE = 0.3
#: issue 16's target: the lift adds at most 5 % to the path time against no lift
TARGET_LIFT_INCREASE = 0.05
_RUNNING = (1, 2, 4)            # ACTIVE, FREEZE, ACTIVE_CONST_DIST (HLI state)


def plate_figures(scenario, functions: bool = True, drop: tuple = ()) -> dict:
    """Run ``scenario`` (a path or a Scenario) with its ``[[process]]`` tables (but those whose function
    is in ``drop``), or without any, and return the figures (module docstring) plus ``completed``,
    ``errors``, ``functions`` (names) and ``lifts`` (rapids the lift function lifted)."""
    import numpy as np

    from . import run
    from .scenario import Scenario, load_scenario

    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    keep = tuple(p for p in sc.processes if functions and p.function not in drop)
    sc = dataclasses.replace(sc, processes=keep)
    if "IHS" in sc.variables and not any(p.function == "touch_off" for p in keep):
        # the plates' programs ask for the touch-off when IHS = 1 and wait for the PLC's answer: without
        # the function the machine's initial height sense is off (distance control's select comes down)
        sc = dataclasses.replace(sc, variables={**sc.variables, "IHS": 0.0})
    ended = {"cycle": None, "lifts": 0, "up": False, "cut_min": math.inf}

    def watch(machine, cycle):          # a PLC program that only reads: the cycle the program ran last
        nc = machine.nc
        if nc is not None and nc.running:
            ended["cycle"] = cycle
        if machine.channel_path.motion_type == 2 and machine.true_distance < ended["cut_min"]:
            ended["cut_min"] = machine.true_distance       # the cuts (G1) only: no touch-off, no rapid
        up = any(lm.lift_active for lm in machine.lift_motions)
        if up and not ended["up"]:
            ended["lifts"] += 1
        ended["up"] = up

    r = run(sc, plc_program=watch)
    tr = r.trace
    col = tr.columns.index
    axis = sc.sensor.axis if sc.sensor is not None and sc.sensor.axis else "Z"
    d = tr.data[:, col("true.distance")]
    state = tr.data[:, col(f"{axis}.dc.state")]
    set_dist = tr.data[:, col(f"{axis}.dc.set_dist")]
    on = np.isin(state, _RUNNING)
    # the cut's set distance: the one in force for most of the time distance control ran (a touch-off's
    # SET_DIST = 0 probe and its pierce height are brief)
    set_cut = float(np.median(set_dist[on])) if on.any() else float("nan")
    below = int(np.count_nonzero(on & (d < 0.5 * set_dist)))
    m = r.metrics
    path = None if ended["cycle"] is None else (ended["cycle"] + 1) * sc.cycle_time
    cut_min = ended["cut_min"] if math.isfinite(ended["cut_min"]) else None
    return {"min_distance_mm": m["min_distance_mm"], "min_cut_distance_mm": cut_min, "time_below_half_s": below * sc.cycle_time,
            "collisions": m["collisions"], "path_time_s": path, "set_distance_mm": set_cut,
            "min_share": (m["min_distance_mm"] / set_cut) if m["min_distance_mm"] is not None else None,
            "completed": r.completed, "errors": [e["id"] for e in r.errors],
            "functions": [p.function for p in sc.processes], "lifts": ended["lifts"]}


def compare(scenario) -> dict:
    """``{"with": plate_figures(sc), "without": plate_figures(sc, functions=False)}``, and with a
    ``lift`` table ``"no_lift"`` (the functions but the lift) and ``lift_path_time_increase`` (the
    path time with the lift over that without it, minus 1; issue 16's target: at most 5 %)."""
    from .scenario import Scenario, load_scenario

    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    out = {"with": plate_figures(sc), "without": plate_figures(sc, functions=False)}
    if any(p.function == "lift" for p in sc.processes):
        out["no_lift"] = nl = plate_figures(sc, drop=("lift",))
        w = out["with"]["path_time_s"]
        out["lift_path_time_increase"] = None if w is None or not nl["path_time_s"] else w / nl["path_time_s"] - 1.0
    return out
