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


# R18 (new-user audit): the console said nothing about CNC-object writes, the page's sensor faults,
# Reset, Feed hold and process-function switches; each is one line with the machine time now.

def test_cnc_object_writes_over_ads_are_logged_pending_then_adopted(caplog):
    import struct

    from distctrl.ads.devices import serve_over_ads

    s = serve_over_ads(load_scenario(SCN / "serve_z.toml"), port=0, discovery_port=None)   # not started
    old = s.machine.controllers["Z"].tuning.kp
    with caplog.at_level(logging.INFO, logger="distctrl.serve"):
        # DIST_CTRL::kp of Z, as an ADS client writes it
        s.services["ads"].cnc.write(0x120300, (2 << 16) | 0x3106, struct.pack("<d", 0.3))
        for _ in range(3):
            s.step()
        written = [r.getMessage() for r in caplog.records if "DIST_CTRL::kp" in r.getMessage()]
        assert written == [f"t=0.001 s axis Z: DIST_CTRL::kp {old:g} -> 0.3 pending "
                           "(adopted on the next INACTIVE->active or FREEZE->active)"], written
        s.machine.hli["Z"].plc_command("ON_CONST_DIST", 1.0)
        for _ in range(5):
            s.step()
    lines = [r.getMessage() for r in caplog.records if "DIST_CTRL::kp" in r.getMessage()]
    assert len(lines) == 2 and lines[1].startswith("t=0.00") and lines[1].endswith(
        f"axis Z: DIST_CTRL::kp 0.3 adopted (was {old:g})"), lines


def test_a_process_function_switched_over_ads_or_the_page_is_logged(caplog):
    s = ServedMachine(load_scenario(SCN / "process_corner.toml"))
    with caplog.at_level(logging.INFO, logger="distctrl.serve"):
        s.step()
        s.machine.process_program.set_enabled("corner_lock", "Z", False)
        s.step()
        s.machine.process_program.set_enabled("corner_lock", "Z", True)
        s.step()
    lines = [r.getMessage() for r in caplog.records if "corner_lock" in r.getMessage()]
    assert lines == ["t=0.002 s process function corner_lock on Z switched off",
                     "t=0.003 s process function corner_lock on Z switched on"], lines
