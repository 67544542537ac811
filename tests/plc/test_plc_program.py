"""A PLC program (Python) drives distance control through the HLI unit on the virtual machine."""
from __future__ import annotations

from pathlib import Path

import pytest

from distctrl.sim.runner import run
from distctrl.sim.scenario import scenario_from_dict

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def test_plc_program_references_selects_reads_state_and_switches_off():
    seen = []

    class Plc:
        step = 0

        def __call__(self, machine, cycle):
            unit = machine.hli["Z"]
            s = unit.state_r
            if self.step == 0 and unit.plc_command("REF", 40.0):    # REF_POS 40 mm (Z): "sensor zero"
                self.step = 1
            elif self.step == 1 and not unit.command_semaphore_rw and unit.plc_command("ON", 40.0):
                self.step = 2                        # sent when the CNC has consumed the REF
            elif self.step == 2 and s.actual_state == 1:
                seen.append(("active", cycle, s.command_source, s.actual_position))
                self.step = 3
            elif self.step == 3 and cycle >= 1500 and unit.plc_command(0):
                self.step = 4
            elif self.step == 4 and s.actual_state == 0:
                seen.append(("inactive", cycle, s.actual_offset))
                self.step = 5

    sc = scenario_from_dict({
        "program_text": "N10 G1 X100 F6000\nN20 #TIME 1\nN30 M30\n", "duration": 5.0,
        "axes": {"X": {}, "Z": {"params": str(SCN / "z_probe.lis"), "start": 40.0}},
        "surface": {"base": 39.0, "features": [{"type": "step", "axis": "X", "at": 50.0, "height": 0.5}]},
        "sensor": {"axis": "Z", "kind": "encoder", "range_min": -20.0, "range_max": 20.0}}, base_dir=SCN)
    r = run(sc, plc_program=Plc())
    assert r.completed and r.errors == []
    (a, c_on, source, surface_01um), (b, c_off, offset) = seen
    assert source == 1 and c_on <= 5                                # handshake takes a couple of cycles
    assert surface_01um == pytest.approx(400000, abs=2)              # referenced: surface at 40 mm
    assert c_off > 1500 and offset == 0
    tr = r.trace
    assert tr["Z.dc.offset"][1400] == pytest.approx(0.5, abs=1e-3)   # followed the 0.5 mm step
