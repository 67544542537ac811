"""3D distance control across program end, reset and a new CNC start (scenario ``start`` events).

FCT-M3 §12.4.4 (reset and program end keep the offset; "a new set position must be specified
before distance control is reactivated", PROG #DIST CTRL SET_POS / SET_DIST), P-CHAN-00802/00803
(the compensation moves within v_max and a_max). Audit 3d-hli-2026-11-27 W2 at the run level;
docs/run-3d.md and docs/scenarios.md (``start``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from distctrl.sim.runner import run
from distctrl.sim.scenario import ScenarioError, scenario_from_dict

ROOT = Path(__file__).resolve().parents[2]
SCN = ROOT / "examples" / "scenarios"
V_MAX, A_MAX, T = 10.0, 100.0, 0.001     # FCT-M3 §12.8.3's channel list: 10000 µm/s, 100 mm/s²

SENSOR = "#DIST CTRL [SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]\n"


def scenario(program_text: str, events, *, duration=8.0):
    """PROG #DIST CTRL example 1's machine (ACS on Z, no kinematics): the sheet at 8.8 mm, 0.3 mm
    higher from X = 50 on."""
    data = {"name": "restart", "program_text": program_text, "duration": duration,
            "external_variables": "../external_variables_12_8_4.lis",
            "channel": {"params": "../channel_3d_12_8_3.lis", "kinematics": "none"},
            "axes": {"X": {}, "Y": {}, "Z": {"start": 10.0, "kv": 50.0, "feedforward": 1.0}},
            "surface": {"base": 8.8, "features": [{"type": "step", "at": 50.0, "height": 0.3}]},
            "sensor": {"kind": "distance", "mode": "orthogonal_clamping_point", "variable": "SENSOR",
                       "range_max": 150.0},
            "events": list(events)}
    return scenario_from_dict(data, base_dir=SCN)


def within_limits(comp: np.ndarray) -> None:
    v = np.diff(comp) / T
    assert np.max(np.abs(v)) <= V_MAX * (1 + 1e-9) + 1e-6
    assert np.max(np.abs(np.diff(v))) <= A_MAX * T * (1 + 1e-9) + 1e-6


def test_a_select_after_program_end_tracks_again():
    """Program 1 ends with the control selected (310021, offset held); program 2 (a start event)
    selects again with a new SET_DIST and tracks the 0.3 mm step under X = 60."""
    first = "G0 Z10\n" + SENSOR + "#DIST CTRL WAIT ON [CONST_DIST SET_DIST=1 MODE=ACS DIRECTION=Z]\n#TIME 0.3\nM30\n"
    second = "#DIST CTRL WAIT ON [CONST_DIST SET_DIST=1]\nG1 X60 F1200\n#TIME 0.5\nM30\n"
    r = run(scenario(first, [{"t": 1.0, "start": {"program_text": second}}]))
    assert r.completed and r.errors == [] and r.final_state == "ACTIVE_CONST_DIST"
    assert [w["id"] for w in r.warnings] == [310021, 310021]         # both programs end while active
    tr = r.trace
    assert np.array_equal(tr["dc3d.offset"], tr["dc3d.comp_z"])     # reported = applied
    held = (tr["t"] > 0.5) & (tr["t"] < 1.0)
    comp_held = tr["dc3d.comp_z"][held][0]
    assert np.ptp(tr["dc3d.comp_z"][held]) == 0.0 and comp_held == pytest.approx(-0.2, abs=0.02)
    assert tr["X.act"][-1] == pytest.approx(60.0)
    assert tr["dc3d.comp_z"][-1] - comp_held == pytest.approx(0.3, abs=0.03)   # followed the step
    assert tr["true.distance_orth"][-1] == pytest.approx(1.0, abs=0.02)
    within_limits(tr["dc3d.comp_z"])


def test_a_select_after_reset_takes_the_kept_offset_over():
    """A reset stops program 1 while X moves over the step; the offset stops within the limits and
    is kept (INACTIVE). Program 2 selects: the compensation goes on from the kept offset (no drop),
    within v_max and a_max; its WAIT OFF runs it out to zero."""
    first = ("G0 Z10\n" + SENSOR + "#DIST CTRL WAIT ON [CONST_DIST SET_DIST=1 MODE=ACS DIRECTION=Z]\n"
             "G1 X100 F1200\nM30\n")
    second = "#DIST CTRL WAIT ON [CONST_DIST SET_DIST=1]\n#TIME 0.3\n#DIST CTRL WAIT OFF\nG0 Z20\nM30\n"
    r = run(scenario(first, [{"t": 3.5, "reset": {}}, {"t": 4.0, "start": {"program_text": second}}]))
    assert r.completed and r.errors == [] and r.warnings == [] and r.final_state == "INACTIVE"
    tr = r.trace
    comp = tr["dc3d.comp_z"]
    assert np.array_equal(tr["dc3d.offset"], comp)
    kept = (tr["t"] > 3.7) & (tr["t"] < 3.9995)
    assert np.all(tr["dc3d.state"][kept] == 0) and np.ptp(comp[kept]) == 0.0
    assert comp[kept][0] == pytest.approx(0.1, abs=0.02)              # over the step: kept
    k_on = int(np.argmax((tr["t"] > 3.7) & (tr["dc3d.state"] == 4)))   # program 2's select
    assert tr["t"][k_on] == pytest.approx(4.0)
    assert comp[k_on] == comp[kept][0] and np.min(comp[k_on:k_on + 200]) > 0.05   # taken over, not dropped
    x_stop = tr["X.prog"][kept][0]
    assert 50.0 < x_stop < 100.0 and tr["X.prog"][-1] == x_stop      # program 2 starts where it stood
    within_limits(comp)
    assert comp[-1] == 0.0 and tr["Z.cmd"][-1] == 20.0


def test_a_start_waits_for_the_running_program():
    """A start while a program runs waits for its end (then the next program begins)."""
    first = "G0 Z10\nG1 X20 F600\nM30\n"                            # runs until ~2 s
    r = run(scenario(first, [{"t": 0.5, "start": {"program_text": "G0 Z30\nM30\n"}}]))
    assert r.completed and r.errors == []
    tr = r.trace
    assert tr["X.prog"][-1] == 20.0 and tr["Z.prog"][-1] == 30.0
    z_starts = tr["t"][np.argmax(tr["Z.prog"] > 10.0)]
    x_done = tr["t"][np.argmax(tr["X.prog"] == 20.0)]
    assert z_starts > x_done


def test_start_without_a_program_restarts_the_scenarios_own():
    r = run(scenario("G91 G0 Z1\nM30\n", [{"t": 1.0, "start": {}}]))
    assert r.completed and r.trace["Z.prog"][-1] == pytest.approx(12.0)


def test_start_event_errors_name_the_key(tmp_path):
    with pytest.raises(ScenarioError, match=r"events\[0\]\.start\.program: .*file not found"):
        scenario("M30\n", [{"t": 1.0, "start": {"program": "nowhere.nc"}}])
    with pytest.raises(ScenarioError, match=r"events\[0\]\.start\.program_text"):
        scenario("M30\n", [{"t": 1.0, "start": {"program": "../dist3d_1.nc", "program_text": "M30"}}])
    with pytest.raises(ScenarioError, match=r"events\[0\]\.start\.file: unknown key"):
        scenario("M30\n", [{"t": 1.0, "start": {"file": "x.nc"}}])


def test_a_syntax_error_in_a_start_program_is_reported_before_the_run():
    from distctrl.errors import DistCtrlError
    with pytest.raises(DistCtrlError, match=r"events\[0\]\.start\.program_text:2"):
        run(scenario("M30\n", [{"t": 1.0, "start": {"program_text": "G0 Z1\nG0 Z=\n"}}]))
