"""The run's observers (distctrl/sim/observers.py): what ``run`` learns besides the trace comes from
them, through one small protocol, and they watch only what the run has."""
from __future__ import annotations

from pathlib import Path

import pytest

from distctrl.sim.machine import Machine
from distctrl.sim.observers import ContactObserver, ProgressObserver, TrackingObserver
from distctrl.sim.runner import load_program, run
from distctrl.sim.scenario import load_scenario, scenario_from_dict

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
PROTOCOL = ("after_cycle", "finish", "errors", "warnings", "metrics", "notes")


def _machine(sc):
    return Machine(sc, load_program(sc))


@pytest.mark.parametrize("name", ["const_dist_sheet", "app_90"])
def test_observers_stepped_by_hand_give_the_metrics_of_run(name):
    sc = load_scenario(SCN / f"{name}.toml")
    m = _machine(sc)
    dc_axis = sc.sensor.axis if sc.sensor is not None and sc.sensor.axis in m.dc_axes else (
        m.dc_axes[0] if m.dc_axes else None)
    observers = [TrackingObserver(m, sc, dc_axis), ContactObserver(m, sc)]
    for o in observers:
        assert all(hasattr(o, p) for p in PROTOCOL)
    after = [o.after_cycle for o in observers if o.after_cycle is not None]
    assert len(after) == 2
    result = run(sc, keep_trace=False)
    for k in range(result.cycles):
        m.step()
        line = m.nc.line if m.nc is not None else None
        for f in after:
            assert not f(k, line)
    metrics = {}
    for o in observers:
        o.finish()
        metrics.update(o.metrics())
    assert metrics == result.metrics


def test_without_a_sensor_nothing_is_watched_for_contact():
    sc = scenario_from_dict({"program_text": "G0 Z1\nM30\n", "axes": {"Z": {}}})
    m = _machine(sc)
    contact = ContactObserver(m, sc)
    assert contact.after_cycle is None and contact.metrics()["min_distance_mm"] is None
    assert TrackingObserver(m, sc, None).after_cycle is None
    assert ProgressObserver(10, sc.cycle_time).after_cycle is None       # not a terminal under pytest


def test_a_collision_ends_the_run_only_with_stop_on_collision():
    sc = load_scenario(SCN / "const_dist_sheet.toml")
    m = _machine(sc)
    m.true_distance = -1.0                      # the tool 1 mm inside the surface
    watch, stop = ContactObserver(m, sc), ContactObserver(m, sc, stop_on_collision=True)
    assert watch.after_cycle(0, 10) is False and stop.after_cycle(0, 10) is True
    watch.finish()
    stop.finish()
    assert [w["id"] for w in watch.warnings()] == [900030] and watch.errors() == []
    assert [e["id"] for e in stop.errors()] == [900030] and stop.warnings() == []
    assert "severity" not in stop.errors()[0]
