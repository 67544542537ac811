"""Machine(controller_factory=...) builds each axis's controller with the given factory (issue 27: the
closed-loop kernel's recorder stands in for the sensor axis's controller without patching the machine's
internals)."""
from __future__ import annotations

from pathlib import Path

from distctrl.control.controller import AxisDistanceController
from distctrl.sim.machine import Machine
from distctrl.sim.runner import load_program
from distctrl.sim.scenario import load_scenario

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def test_the_factory_builds_every_axis_controller_and_the_cycle_uses_it():
    sc = load_scenario(SCN / "tune_sheet.toml")
    made = {}

    def factory(name, params, cycle_time):
        made[name] = AxisDistanceController(params, cycle_time)
        return made[name]

    m = Machine(sc, load_program(sc), controller_factory=factory)
    assert set(made) == set(sc.axes)
    assert all(m.controllers[n] is made[n] for n in made)
    assert [entry[3] for entry in m._axes] == [made[n] for n, *_ in m._axes]
    for _ in range(5):
        m.step()
    assert made[sc.sensor.axis].state.cycle == 5         # the distance-controlled axis's controller ran


def test_without_a_factory_each_axis_gets_an_axis_distance_controller():
    sc = load_scenario(SCN / "tune_sheet.toml")
    m = Machine(sc, load_program(sc))
    assert all(type(c) is AxisDistanceController for c in m.controllers.values())
