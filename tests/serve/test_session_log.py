"""`distctrl serve` says what happens: axis map at start, PLC commands, state changes, errors such as
70336 for a PLC command to an axis without distance control (issue 13; audit item 12)."""
from __future__ import annotations

import logging
from pathlib import Path

from distctrl.serve.machine import ServedMachine
from distctrl.sim.scenario import load_scenario

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def _served():
    # not started: the cycle is stepped by hand
    return ServedMachine(load_scenario(SCN / "serve_z.toml"))


def test_the_axis_map_names_the_axis_without_distance_control():
    lines = _served().session.axis_lines()
    assert lines[0].startswith("axis 1 = X (no distance control, P-AXIS-00328 = 0") and "70336" in lines[0]
    assert lines[1] == "axis 2 = Z (distance control)"


def test_a_plc_command_to_an_axis_without_distance_control_is_logged_as_70336(caplog):
    s = _served()
    s.machine.hli["X"].plc_command("ON", 40.0)
    with caplog.at_level(logging.INFO, logger="distctrl.serve"):
        for _ in range(5):
            s.step()
    text = caplog.text
    assert "axis X (gpAx[1]): PLC command transition" in text
    errors = [r for r in caplog.records if r.levelno == logging.ERROR]
    assert errors and "70336" in errors[0].getMessage() and "P-AXIS-00328" in errors[0].getMessage()


def test_state_changes_of_the_distance_controlled_axis_are_logged(caplog):
    s = _served()
    s.machine.hli["Z"].plc_command("ON_CONST_DIST", 1.0)
    with caplog.at_level(logging.INFO, logger="distctrl.serve"):
        for _ in range(20):
            s.step()
    assert "axis Z: distance control INACTIVE -> ACTIVE_CONST_DIST" in caplog.text
