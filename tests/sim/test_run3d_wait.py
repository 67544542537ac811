"""End to end, 3D distance control: deselection with and without WAIT, and FCT-M3 §12.4.2.1's listing.

* PROG #DIST CTRL, WAIT: "waits until distance control is completely activated/deactivated"; example
  2 (N120 ``#DIST CTRL WAIT OFF``) holds the next block until the deselection is complete.
* PROG #DIST CTRL example 1 (N900 ``#DIST CTRL OFF``): "Deactivate distance control with no wait Next
  block is executed immediately"; FCT-M3 §12.4.4: the offset values are then removed "on the fly".
* FCT-M3 §12.4.2.1 "Example: Inclination of tool via CA kinematic": the printed listing
  (DistCtrl-OnOff.nc, ``examples/scenarios/ca_kin98_12_4_2_1.nc``) run on the CA head.

The deselection runs use PROG #DIST CTRL example 1's scenario (``dist3d_1.toml``: MODE=ACS
DIRECTION=Z, the sheet 8.8 mm up) with its program completed so that the control is selected and has
an offset when it is deselected (SET_DIST=1 at Z10: the offset is about -0.2 mm).
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from distctrl.sim.runner import run
from distctrl.sim.scenario import load_scenario

from .test_run3d import L, expected_height

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
INACTIVE, TURNING_OFF, ACTIVE_CONST_DIST = 0, 3, 4


def deselect_run(off_block: str):
    program = "\n".join([
        "N010 G0 Z10",
        "N020 #DIST CTRL [SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]",
        "N030 #DIST CTRL WAIT ON [CONST_DIST SET_DIST=1 MODE=ACS DIRECTION=Z]",
        "N040 #TIME 0.5",
        f"N900 {off_block}",
        "N910 G0 Z20",
        "N920 #TIME 1",
        "N999 M30", ""])
    sc = dataclasses.replace(load_scenario(SCN / "dist3d_1.toml"), program_text=program, program_file=None)
    r = run(sc)
    assert r.completed and r.errors == [] and r.warnings == [] and r.final_state == "INACTIVE"
    lines = program.splitlines()
    off_line = 1 + next(i for i, text in enumerate(lines) if text.startswith("N900"))
    next_line = off_line + 1                                           # N910 G0 Z20
    tr = r.trace
    line = tr["line"]
    k_off = int(np.argmax(line == off_line))                           # the cycle the OFF block runs
    k_next = int(np.argmax(line == next_line))                         # the first cycle of N910
    assert 0 < k_off < k_next
    # before the deselection the control was tracking with an offset that has to run out
    assert tr["dc3d.state"][k_off - 1] == ACTIVE_CONST_DIST and abs(tr["dc3d.comp_z"][k_off - 1]) > 0.1
    return tr, k_off, k_next


def test_wait_off_holds_the_next_block_until_the_deselection_is_complete():
    """A32: ``#DIST CTRL WAIT OFF``: N910 starts only once the state is INACTIVE and the offset is 0;
    until then the OFF block is the running one and the programmed path does not move."""
    tr, k_off, k_next = deselect_run("#DIST CTRL WAIT OFF")
    state, comp = tr["dc3d.state"], tr["dc3d.comp_z"]
    assert tr["dc3d.state"][k_off] == TURNING_OFF
    running_out = slice(k_off, k_next)
    assert np.all(tr["line"][running_out] == tr["line"][k_off])       # the OFF block waits ...
    assert np.ptp(tr["Z.prog"][running_out]) == 0.0                    # ... and the path stands
    assert TURNING_OFF in state[running_out] and state[k_next - 1] == INACTIVE
    k_inactive = k_off + int(np.argmax(state[k_off:] == INACTIVE))
    assert k_inactive < k_next                                         # complete before N910
    assert np.all(state[k_next:] == INACTIVE) and np.all(comp[k_next:] == 0.0)
    assert k_next - k_off > 10                                         # the run-out took its time


def test_off_without_wait_runs_the_next_block_at_once_and_the_offset_runs_out_on_the_fly():
    """A33: ``#DIST CTRL OFF``: "Next block is executed immediately": N910 starts in the cycle after the
    OFF block, while the offset is still running out (TURNING_OFF); the offset then reaches 0 during
    N910's motion (FCT-M3 §12.4.4 "on the fly") and the control ends INACTIVE."""
    tr, k_off, k_next = deselect_run("#DIST CTRL OFF")
    state, comp = tr["dc3d.state"], tr["dc3d.comp_z"]
    assert k_next == k_off + 1                                         # the OFF block takes one cycle
    assert state[k_next] == TURNING_OFF and abs(comp[k_next]) > 0.1    # not waited for
    moving = np.flatnonzero(np.diff(tr["Z.prog"][k_next:]) != 0.0)
    assert len(moving) and state[k_next + int(moving[0])] == TURNING_OFF   # the path moves during the run-out
    k_inactive = k_next + int(np.argmax(state[k_next:] == INACTIVE))
    assert k_inactive > k_next and comp[k_inactive] == 0.0
    assert np.all(state[k_inactive:] == INACTIVE) and np.all(comp[k_inactive:] == 0.0)
    assert tr["Z.cmd"][-1] == tr["Z.prog"][-1] == pytest.approx(20.0)


# ---------------------------------------------------------------- FCT-M3 §12.4.2.1
HD2, HD3 = 50.0, 70.0            # PARAM[1] = 500000, PARAM[2] = 700000 (0.0001°); HD4 = 91°; L = 80


def clamping_point_height(theta_deg: float) -> float:
    """Height of the clamping point above the TCP (SPEC §11), the geometry of test_run3d."""
    return expected_height(theta_deg, HD2, HD3)


def test_fct_m3_12_4_2_1_ca_listing_runs_end_to_end():
    """A38: the printed listing (N210 three times, ``#TRAFO [ 9, 98]``, ``G01 A90``) runs to its end
    without an error (90° < HD4 = 91°): the TCP is kept, the clamping point follows L·cos θ up to HD2,
    stays at L·cos 50° = 51.42 mm above the TCP from HD2 to HD3 ("starting at the specified angle, the
    tool head is maintained at a constant height") and falls above HD3. The printed feed F10 would
    take 9 minutes; the run uses F1800 (30°/s)."""
    sc = load_scenario(SCN / "ca_kin98_12_4_2_1.toml")
    assert sc.program_text.count("N210 V.G.KIN_STEP[1].ID[98]") == 3 and "G01 A90 F10\n" in sc.program_text
    r = run(dataclasses.replace(sc, program_text=sc.program_text.replace("G01 A90 F10", "G01 A90 F1800"),
                                program_file=None))
    assert r.completed and r.errors == [] and r.warnings == []
    tr = r.trace
    a = tr["A.act"]
    assert a[-1] == pytest.approx(90.0, abs=1e-6)
    for c in ("tcp.x", "tcp.y", "tcp.z"):                              # the TCP is kept (RTCP)
        assert np.ptp(tr[c]) < 1e-3, c
    height = tr["true.clamp_z"] - tr["tcp.z"]
    # the plateau between HD2 and HD3
    plateau = (a > HD2 + 3.0) & (a <= HD3)            # after the transient of the drives at the kink
    assert plateau.sum() > 100
    assert np.all(np.abs(height[plateau] - L * math.cos(math.radians(HD2))) < 2e-3)
    assert L * math.cos(math.radians(HD2)) == pytest.approx(51.42, abs=5e-3)
    # below HD2 and above HD3 the height follows the curve (within the lag of the moving axes)
    for theta in (10.0, 30.0, 45.0, 75.0, 80.0, 85.0):
        k = int(np.argmin(np.abs(a - theta)))
        assert height[k] == pytest.approx(clamping_point_height(a[k]), abs=0.1), theta
    above = np.flatnonzero((a > HD3 + 1.0) & (a < 89.5))              # on the way (A overshoots 90° by 0.03°)
    assert len(above) > 100 and np.all(np.diff(above) == 1)
    assert np.all(np.diff(height[above]) < 0.0)                        # falls above HD3
    assert height[-1] == pytest.approx(0.0, abs=1e-3)                  # at 90°: L·cos 50°/cos 70°·cos 90°
    # the virtual tool length (PLC virt_tool_length_r) at 90°: L·cos HD2 / cos HD3 = 150.35 mm
    assert tr["dc3d.virt_tool_length"][-1] == pytest.approx(
        L * math.cos(math.radians(HD2)) / math.cos(math.radians(HD3)), abs=1e-6)
