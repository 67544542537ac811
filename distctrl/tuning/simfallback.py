"""tune on what the closed-loop kernel does not model exactly: the scalar simulation for the sets it reports.

The kernel (:mod:`distctrl.batch.closed_loop`) reads the surface under the tool's centre once per cycle.
A capacitive sensor with a footprint (``footprint_radius > 0``: the edge effect) sees the distance averaged
over its electrode, ``1 / mean(1 / d_i)`` over the footprint's points, which depends on the Z position
itself: the kernel cannot precompute it, so it does not model it (nor the plume bursts of such a sensor).

``distctrl tune`` then searches on the kernel with the same plant and a point sensor (the footprint and
the bursts left out: :func:`kernel_proxy`), and runs the sets it chooses between at the end (the best sets
of the search, the scenario's own) on the scalar simulation of the real scenario, footprint and all
(:func:`sim_evaluate`: :func:`distctrl.sim.runner.run`, the engine of ``distctrl run``); the figures it
reports and the choice come from those runs (docs/tuning.md "Sensors the kernel does not model").
"""
from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["kernel_proxy", "sim_traces", "sim_evaluate", "FINALISTS"]

#: how many of the search's best distinct sets are run on the scalar simulation at the end
FINALISTS = 6


def kernel_proxy(scenario) -> tuple[object, str | None]:
    """(the scenario the kernel runs, a note saying what it leaves out; None when it is the scenario)."""
    s = scenario.sensor
    if s is None or s.kind != "distance" or not s.footprint_radius > 0.0:
        return scenario, None
    proxy = dataclasses.replace(scenario, sensor=dataclasses.replace(s, footprint_radius=0.0, bursts=None))
    left = "footprint_radius" + (" and bursts" if s.bursts is not None else "")
    note = (f"the sensor's footprint ([sensor] footprint_radius = {s.footprint_radius:g} mm, the capacitive "
            "edge effect) is not modelled by the closed-loop kernel: the search ran on the kernel with a point "
            f"sensor (without {left}), and the scenario's set and the search's {FINALISTS} best sets were run "
            "again on the scalar simulation of the scenario as it is (distctrl run's engine); the figures "
            "reported and the choice are the simulation's (sweep.csv, the robustness runs and "
            "before_after.png: the kernel's)")
    return proxy, note


def sim_traces(scenario, axis: str, params, n_cycles: int) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """(offset, true distance, (error cycle, error id)) of ``scenario`` run on the scalar simulation with the
    axis list ``params``, the first ``n_cycles`` cycles; NaN from a controller error's cycle on (as the kernel
    does: the program would stop there), (-1, 0) without one."""
    from ..sim.runner import run            # the scalar machine: only on this path

    axes = dict(scenario.axes)
    axes[axis] = dataclasses.replace(axes[axis], params=params)
    r = run(dataclasses.replace(scenario, axes=axes))
    off = np.full(n_cycles, np.nan)
    dist = np.full(n_cycles, np.nan)
    o = np.asarray(r.trace[f"{axis}.dc.offset"], dtype=float)[:n_cycles]
    d = np.asarray(r.trace["true.distance"], dtype=float)[:n_cycles]
    off[:len(o)], dist[:len(d)] = o, d
    err = (-1, 0)
    if r.errors:
        k = int(round(float(r.errors[0]["t"]) / scenario.cycle_time))
        if k < n_cycles:
            off[k:], dist[k:] = np.nan, np.nan
            err = (k, int(r.errors[0]["id"]))
    return off, dist, err


def sim_evaluate(ev, scenario, inputs, sets: list, points: list, description: str = "simulation"):
    """The table :meth:`Evaluator.evaluate <distctrl.tuning.runner.Evaluator.evaluate>` makes of ``sets``,
    with each set run on the scalar simulation of ``scenario`` instead of the kernel (``inputs``: the
    kernel's recording of the proxy, for the cycles replayed, the select's cycle and the wanted distance)."""
    from ..batch.closed_loop import pack_sets           # numba: loaded only when a batch runs
    from .metrics import compute_metrics, limits_from_packed, wanted_distance
    from .runner import SweepResult

    n = ev.n_cycles
    offs, dists, errs = [], [], []
    for p in sets:
        o, d, e = sim_traces(scenario, inputs.axis, p, n)
        offs.append(o)
        dists.append(d)
        errs.append(e)
    m = compute_metrics(np.vstack(offs), np.vstack(dists), wanted_distance(inputs, n), inputs.cycle_time,
                        inputs.k_on, limits_from_packed(pack_sets(inputs, sets)))
    m["error_cycle"] = np.array([e[0] for e in errs], dtype=np.int64)
    m["error_id"] = np.array([e[1] for e in errs], dtype=np.int64)
    m["failed"] = np.asarray(m["failed"]) | (m["error_cycle"] >= 0)
    return SweepResult(ev._table(list(sets), points, m), params=list(sets), info={"description": description})
