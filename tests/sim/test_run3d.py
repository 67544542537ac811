"""End to end: 3D (channel-specific) distance control on the virtual machine with the CA head.

FCT-M3 ch. 12 (§12.4.2 kinematic 98, §12.4.3 compensation, §12.4.4 reset / program end, §12.4.5
channel re-initialisation, §12.7 errors, §12.9 application examples), PROG #DIST CTRL's two programs,
SPEC §11. docs/run-3d.md describes the machine and the scenarios.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from distctrl.errors import ParameterError
from distctrl.sim.machine import Machine
from distctrl.sim.runner import load_program, run, trace_columns
from distctrl.sim.scenario import ScenarioError, load_scenario, scenario_from_dict

ROOT = Path(__file__).resolve().parents[2]
SCN = ROOT / "examples" / "scenarios"
CHANNEL_LIST = SCN / "channel_3d.lis"
L = 80.0             # tool length of the examples (PROG #DIST CTRL)
HEIGHT_TOL = 2e-3    # mm: clamping-point height at rest against the geometry (drive encoders: 0.1 µm)


# ---------------------------------------------------------------- helpers
def expected_height(theta_deg: float, hd2_deg: float, hd3_deg: float) -> float:
    """Height of the clamping point above the surface with the TCP on it: Lv(θ)·cos θ (SPEC §11):
    L·cos θ below HD2, L·cos HD2 from HD2 to HD3 (kept constant), L·cos HD2/cos HD3·cos θ above."""
    th, a, b = (math.radians(v) for v in (theta_deg, hd2_deg, hd3_deg))
    if th < a:
        return L * math.cos(th)
    if th <= b:
        return L * math.cos(a)
    return L * math.cos(a) / math.cos(b) * math.cos(th)


def expected_lv(theta_deg: float, hd2_deg: float, hd3_deg: float) -> float:
    th, a, b = (math.radians(v) for v in (theta_deg, hd2_deg, hd3_deg))
    if hd2_deg == hd3_deg or th <= a:
        return L
    return L * math.cos(a) / math.cos(min(th, b))


def rest_index(tr, angle: float) -> int:
    """The last cycle at which the head stands at ``angle`` while distance control tracks (at 90°:
    frozen, the application examples FREEZE for the last step, see app_*.nc)."""
    state = 2 if angle == 90 else 4
    idx = np.where((np.abs(tr["A.act"] - angle) < 1e-9) & (tr["dc3d.state"] == state))[0]
    assert len(idx) > 100, f"the head never rested at A={angle} in state {state}"
    return int(idx[-1])


def tool_direction(tr, k: int) -> np.ndarray:
    a, c = math.radians(tr["A.act"][k]), math.radians(tr["C.act"][k])
    return np.array([math.sin(c) * math.sin(a), -math.cos(c) * math.sin(a), math.cos(a)])


def vec(tr, prefix: str, k=slice(None)) -> np.ndarray:
    names = ("comp_x", "comp_y", "comp_z") if prefix == "dc3d" else ("x", "y", "z")
    return np.stack([tr[f"{prefix}.{n}"][k] for n in names], axis=-1)


def with_program(path: Path, edit) -> object:
    sc = load_scenario(path)
    return dataclasses.replace(sc, program_text=edit(sc.program_text), program_file=None)


KIN98 = """V.G.KIN_STEP[1].ID[98].PARAM[0] = 1000000
V.G.KIN_STEP[1].ID[98].PARAM[1] = 300000
V.G.KIN_STEP[1].ID[98].PARAM[2] = 600000
V.G.KIN_STEP[1].ID[98].PARAM[3] = 910000
V.G.WZ_AKT.L = 80
"""
SELECT = "#DIST CTRL WAIT ON [CONST_DIST SET_DIST=80 MODE=MCS SENSOR_VAR=V.E.SENSOR]\n"


def head_scenario(program_text: str, *, channel=CHANNEL_LIST, surface=-1.0, duration=10.0, channel_table=True,
                  events=(), settle_time=0.5):
    """The CA head of the application examples (pivot 180 mm up: TCP at 0 after #TRAFO ON)."""
    axes = {n: {"feedforward": 1.0} for n in ("X", "Y", "Z")}
    axes["Z"]["start"] = 180.0
    for n in ("A", "C"):
        axes[n] = {"v_max": 90.0, "a_max": 900.0, "feedforward": 1.0}
    data = {"name": "test3d", "program_text": program_text, "duration": duration, "axes": axes,
            "surface": {"base": surface}, "events": list(events), "settle_time": settle_time}
    if channel_table:
        data["channel"] = {"params": str(channel)}
        data["sensor"] = {"kind": "distance", "variable": "SENSOR", "range_max": 200.0}
    return scenario_from_dict(data, base_dir=SCN)


def channel_list(tmp_path, **changes) -> Path:
    """channel_3d.lis with some keys replaced (list units)."""
    lines = []
    for line in CHANNEL_LIST.read_text().splitlines():
        key = line.split()[0] if line.strip() and not line.startswith("#") else None
        if key is not None and key.split(".")[-1] in changes:
            line = f"{key} {changes.pop(key.split('.')[-1])}"
        lines.append(line)
    lines += [f"dist_ctrl[0].{k} {v}" for k, v in changes.items()]
    path = tmp_path / "channel.lis"
    path.write_text("\n".join(lines) + "\n")
    return path


def only_error(result) -> dict:
    assert not result.completed and result.aborted
    assert len(result.errors) == 1, result.errors
    return result.errors[0]


# ---------------------------------------------------------------- PROG #DIST CTRL's programs
def test_prog_dist_ctrl_example_1_runs_acs_on_the_z_axis():
    r = run(SCN / "dist3d_1.toml")
    assert r.completed and r.errors == [] and r.final_state == "INACTIVE"
    # the printed N910 G0 Z0 goes 8.8 mm into this scenario's sheet: one collision, reported
    assert [(w["id"], w["line"]) for w in r.warnings] == [(900030, 11)] and r.metrics["collisions"] == 1
    assert r.metrics["min_distance_mm"] < -8.8
    tr = r.trace
    assert {0, 4}.issubset(set(np.unique(tr["dc3d.state"]).astype(int)))         # it was selected
    active = tr["dc3d.state"] != 0
    # ACS, DIRECTION=Z: the compensation is on the Z axis only, the axes are machine axes (no trafo)
    assert np.all(vec(tr, "dc3d")[active][:, :2] == 0.0)
    assert np.allclose(tr["Z.cmd"][active], tr["Z.prog"][active] + tr["dc3d.comp_z"][active])
    assert tr["Z.act"][-1] == pytest.approx(0.0, abs=2e-4)                         # N910 G0 Z0
    assert tr["dc3d.offset"][-1] == 0.0


def test_prog_dist_ctrl_example_2_inclines_with_kinematic_98_and_selects_ecs():
    r = run(SCN / "dist3d_2.toml")
    assert r.completed and r.errors == [] and r.warnings == [] and r.final_state == "INACTIVE"
    tr = r.trace
    # N110 ON [SURFACE SET_POS=1 MODE=ECS]: selected (ACTIVE) and deselected by N120 WAIT OFF
    assert 1 in set(np.unique(tr["dc3d.state"]).astype(int))
    # A=-45: inclination 45°, kinematic 98 [30°; 60°] extends the tool to 80·cos30°/cos45°
    k = len(tr["t"]) - 1
    assert tr["dc3d.inclination"][k] == pytest.approx(45.0, abs=1e-3)
    lv = 80 * math.cos(math.radians(30)) / math.cos(math.radians(45))
    assert tr["dc3d.virt_tool_length"][k] == pytest.approx(lv, abs=1e-3)
    # RTCP: the TCP stays where it was programmed (N130 G0 Z0); the pivot carries HD1 + Lv along u
    u = tool_direction(tr, k)
    pivot = np.array([tr["X.act"][k], tr["Y.act"][k], tr["Z.act"][k]])
    tcp = pivot - (tr["dc3d.virt_tool_length"][k] + 100.0) * u
    assert tcp == pytest.approx([0.0, 0.0, 0.0], abs=1e-3)
    clamp = np.array([tr["true.clamp_x"][k], tr["true.clamp_y"][k], tr["true.clamp_z"][k]])
    assert clamp == pytest.approx(pivot - 100.0 * u, abs=1e-3)


def test_prog_dist_ctrl_example_2_tcp_is_kept_while_the_head_inclines():
    tr = run(SCN / "dist3d_2.toml").trace
    rotating = np.where(np.diff(tr["A.prog"]) != 0)[0]
    assert len(rotating) > 100
    # the commanded TCP never moves while A turns (pivot = TCP + (Lv + HD1)·u, programmed)
    assert np.ptp(vec(tr, "tcp", rotating), axis=0) == pytest.approx([0, 0, 0], abs=1e-9)
    assert np.ptp(tr["Y.cmd"][rotating]) > 100.0                     # ... while the pivot swings


# ---------------------------------------------------------------- §12.9 application examples
APPS = [("app_90", 90.0, 90.0), ("app_0", 0.0, 80.0), ("app_30_60", 30.0, 60.0), ("app_10_31", 10.0, 31.0)]


@pytest.mark.parametrize("name,hd2,hd3", APPS)
def test_application_example_keeps_the_clamping_point_height(name, hd2, hd3):
    r = run(SCN / f"{name}.toml")
    assert r.completed and r.errors == [] and r.warnings == [] and r.final_state == "INACTIVE"
    tr = r.trace
    heights = {}
    for angle in range(0, 100, 10):
        k = rest_index(tr, angle)
        # orthogonal distance of the clamping point from the real sheet (1 mm below nominal)
        h = tr["true.distance_orth"][k]
        assert h == pytest.approx(expected_height(angle, hd2, hd3), abs=HEIGHT_TOL), angle
        assert tr["true.clamp_z"][k] - tr["true.surface"][k] == pytest.approx(h, abs=1e-9)   # flat sheet
        assert tr["dc3d.virt_tool_length"][k] == pytest.approx(expected_lv(angle, hd2, hd3), rel=1e-5)
        assert tr["dc3d.inclination"][k] == pytest.approx(angle, abs=1e-3)
        assert tr["dc3d.offset"][k] == pytest.approx(-1.0, abs=HEIGHT_TOL)     # the sheet's offset
        heights[angle] = h
    # the phases of kinematic 98 (FCT-M3 §12.4.2): L·cos θ below HD2, constant from HD2 to HD3,
    # never below the unmonitored L·cos θ
    for angle, h in heights.items():
        if angle < hd2:
            assert h == pytest.approx(L * math.cos(math.radians(angle)), abs=HEIGHT_TOL)
        elif angle <= hd3:
            assert h == pytest.approx(L * math.cos(math.radians(hd2)), abs=HEIGHT_TOL)
        assert h >= L * math.cos(math.radians(angle)) - HEIGHT_TOL
    kept = [h for a, h in heights.items() if hd2 <= a <= hd3]
    if len(kept) > 1:
        assert np.ptp(kept) < HEIGHT_TOL
    # the distance error while tracking (initial sheet offset of 1 mm aside)
    assert r.metrics["distance_error_rms"] < 0.05 and r.metrics["settle_time"] is not None   # settled after the last step


@pytest.mark.parametrize("name,hd2,hd3", APPS)
def test_application_example_mcs_keeps_the_xy_projection(name, hd2, hd3):
    tr = run(SCN / f"{name}.toml").trace
    active = tr["dc3d.state"] != 0
    assert active.sum() > 20000
    # MCS: the compensation is along machine Z only; x, y of the TCP are the programmed ones
    assert np.all(tr["dc3d.comp_x"][active] == 0.0) and np.all(tr["dc3d.comp_y"][active] == 0.0)
    assert np.array_equal(tr["tcp.x"], tr["X.prog"]) and np.array_equal(tr["tcp.y"], tr["Y.prog"])
    assert np.allclose(tr["tcp.z"][active], tr["Z.prog"][active] + tr["dc3d.comp_z"][active])


def test_application_example_with_ecs_keeps_the_cut_orientation():
    """Compensation in tool direction (MODE=ECS): the compensation is parallel to u, so the TCP moves
    along the tool axis (§12.4.3.1); up to 80° (at 90° a shift along u cannot change the height)."""
    last_step = "#DIST CTRL FREEZE\nG1 A90 F180\n#TIME 1\n"
    sc = with_program(SCN / "app_30_60.toml",
                      lambda t: t.replace("MODE=MCS", "MODE=ECS").replace(last_step, ""))
    r = run(sc)
    assert r.completed and r.errors == []
    tr = r.trace
    for angle in range(0, 90, 10):
        k = rest_index(tr, angle)
        assert tr["true.distance_orth"][k] == pytest.approx(expected_height(angle, 30, 60), abs=HEIGHT_TOL)
        u = tool_direction(tr, k)
        comp = vec(tr, "dc3d", k)
        assert np.linalg.norm(np.cross(comp, u)) < 1e-5 * max(1.0, np.linalg.norm(comp))   # comp ∥ u
        assert comp @ u == pytest.approx(-1.0 / math.cos(math.radians(angle)), abs=5e-3)  # δ·cos θ = o
        # the TCP left the programmed point along the tool axis only
        shift = vec(tr, "tcp", k) - np.array([tr["X.prog"][k], tr["Y.prog"][k], tr["Z.prog"][k]])
        assert np.linalg.norm(np.cross(shift, u)) < 1e-5 * max(1.0, np.linalg.norm(shift))
    active = tr["dc3d.state"] != 0
    comps = vec(tr, "dc3d", active)
    a, c = np.radians(tr["A.act"][active]), np.radians(tr["C.act"][active])
    u = np.stack([np.sin(c) * np.sin(a), -np.cos(c) * np.sin(a), np.cos(a)], axis=-1)
    assert np.max(np.linalg.norm(np.cross(comps, u), axis=-1)) < 1e-3          # every cycle (quantised A.act)


def test_application_example_without_superposition_shows_the_original_path():
    """MODE=OFF: the offset is computed (the sheet's -1 mm) but not superimposed; the clamping point
    follows the ideal geometry above the nominal surface (the path "with original contour", §12.9)."""
    sc = with_program(SCN / "app_10_31.toml", lambda t: t.replace("MODE=MCS", "MODE=OFF"))
    r = run(sc)
    assert r.completed and r.errors == []
    assert [w["id"] for w in r.warnings] == [900023]                 # SPEC §12: warn on ON with MODE=OFF
    tr = r.trace
    assert np.all(vec(tr, "dc3d") == 0.0)
    for angle in range(0, 100, 10):
        k = rest_index(tr, angle)
        assert tr["true.clamp_z"][k] == pytest.approx(expected_height(angle, 10, 31), abs=HEIGHT_TOL)
        nominal = expected_height(angle, 10, 31)
        assert tr["true.distance_orth"][k] == pytest.approx(nominal + 1.0, abs=HEIGHT_TOL)
        assert tr["dc3d.offset"][k] == pytest.approx(-1.0, abs=HEIGHT_TOL)


def test_plc_status_virtual_tool_length_and_inclination():
    sc = load_scenario(SCN / "app_30_60.toml")
    m = Machine(sc, load_program(sc))
    while m.interp.position["A"] != 40.0:
        m.step()
    for _ in range(500):                                # the dwell at A=40°
        m.step()
    st = m.channel_status
    assert st.inclination_r == pytest.approx(400000, abs=1)                      # 0.0001°
    lv = expected_lv(40.0, 30.0, 60.0)
    assert st.virt_tool_length_r == pytest.approx(round(lv * 1e4), abs=2)       # 0.1 µm


# ---------------------------------------------------------------- §12.4.3.3 robot example
def test_robot_example_on_the_30_degree_workpiece_in_pcs_ecs_and_mcs():
    r = run(SCN / "robot_30.toml")
    assert r.completed and r.errors == [] and r.warnings == []
    tr = r.trace
    err = tr["true.distance_orth"] - tr["dc3d.set_dist_orth"]
    n = np.array([0.0, -0.5, math.sqrt(3) / 2])          # the #CS's Z = the workpiece normal
    for mode in (1, 3, 2):                               # PCS, ECS, MCS (CompensationMode)
        sel = (tr["dc3d.state"] == 4) & (tr["dc3d.mode"] == mode)
        assert sel.sum() > 3000
        # the tool stands normal to the workpiece: set distance = SET_DIST (angle to the normal 0)
        assert tr["dc3d.set_dist_orth"][sel] == pytest.approx(80.0, abs=1e-4)
        assert tr["dc3d.inclination"][sel] == pytest.approx(30.0, abs=1e-3)
        assert np.sqrt(np.mean(err[sel] ** 2)) < 0.02 and np.abs(err[sel]).max() < 0.1
        comp = vec(tr, "dc3d", sel)
        assert np.abs(comp).max() > 0.1                                          # it compensated
        e = np.array([0.0, 0.0, 1.0]) if mode == 2 else n
        assert np.max(np.linalg.norm(np.cross(comp, e), axis=-1)) < 1e-4
        if mode == 2:   # MCS: along machine Z, δ = o / cos 30° (the orthogonal change is δ·cos 30°)
            assert np.allclose(tr["dc3d.delta"][sel] * math.cos(math.radians(30)), tr["dc3d.offset"][sel])
            assert np.all(tr["dc3d.comp_x"][sel] == 0.0) and np.all(tr["dc3d.comp_y"][sel] == 0.0)
        else:           # PCS / ECS: along the workpiece normal, δ = o
            assert np.allclose(tr["dc3d.delta"][sel], tr["dc3d.offset"][sel])


def test_cs_frame_maps_the_programmed_circle_onto_the_inclined_plane():
    tr = run(SCN / "robot_30.toml").trace
    sel = tr["dc3d.state"] == 4
    # the circle is programmed in the #CS (z = 0 there): the programmed TCP lies in the workpiece plane
    tcp = vec(tr, "tcp", sel) - vec(tr, "dc3d", sel)
    assert np.abs(tcp[:, 2] - math.tan(math.radians(30)) * tcp[:, 1]).max() < 1e-9
    radius = np.hypot(tr["X.prog"][sel], tr["Y.prog"][sel])
    assert radius.max() == pytest.approx(20.0, abs=1e-4)          # the NC writes 4 decimals


# ---------------------------------------------------------------- channel behaviour
def test_trafo_and_cs_reinitialise_the_channel_without_moving_the_axes():
    prog = KIN98 + "#KIN ID[9.98]\n#TRAFO ON\n#CS ON [5, 0, 0, 0, 0, 20]\nG1 A20 F1200\n#CS OFF\n" \
        "#TRAFO OFF\nM30\n"
    r = run(head_scenario(prog, channel_table=False))
    assert r.completed and r.errors == []
    tr = r.trace
    for ax in ("X", "Y", "Z"):
        assert np.abs(np.diff(tr[f"{ax}.cmd"])).max() < 0.5       # no jump at any #TRAFO / #CS
    # after #TRAFO ON the programmed Z is the TCP (180 - L - HD1 = 0); after #TRAFO OFF the pivot again
    k_on = int(np.argmax(tr["Z.prog"] == 0.0))
    assert tr["Z.cmd"][k_on] == pytest.approx(180.0)
    assert tr["Z.prog"][-1] == pytest.approx(tr["Z.cmd"][-1])


def test_wait_on_holds_the_next_block_until_the_target_is_reached():
    tr = run(SCN / "app_10_31.toml").trace
    first_move = int(np.argmax(np.diff(tr["A.prog"]) != 0))
    assert tr["dc3d.state"][first_move] == 4
    assert abs(tr["true.distance_orth"][first_move] - tr["dc3d.set_dist_orth"][first_move]) < 2e-3


def test_off_no_move_hands_the_compensation_to_the_channel():
    prog = KIN98 + "#KIN ID[9.98]\n#TRAFO ON\n" + SELECT + "G1 A20 F1200\n#TIME 0.5\n" \
        "#DIST CTRL WAIT OFF [NO_MOVE]\n#TIME 0.2\nG1 X10 F600\nM30\n"
    r = run(head_scenario(prog))
    assert r.completed and r.errors == []
    tr = r.trace
    k = int(np.argmax((tr["dc3d.state"][:-1] == 4) & (tr["dc3d.state"][1:] == 0))) + 1
    for ax in ("X", "Y", "Z"):
        assert abs(tr[f"{ax}.cmd"][k] - tr[f"{ax}.cmd"][k - 1]) < 1e-3          # no jump
    assert tr["dc3d.comp_z"][k] == 0.0 and tr["tcp.z"][k] == pytest.approx(-1.0, abs=2e-3)
    assert tr["Z.prog"][-1] == pytest.approx(-1.0, abs=2e-3)       # the next move took the offset over
    assert tr["true.distance_orth"][-1] == pytest.approx(expected_height(20, 30, 60), abs=2e-3)


def test_reset_keeps_the_3d_offset_as_a_static_offset():
    prog = KIN98 + "#KIN ID[9.98]\n#TRAFO ON\n" + SELECT + "G1 A20 F600\nG1 A0\nM30\n"
    r = run(head_scenario(prog, surface=-1.5, events=[{"t": 1.0, "reset": {}}]))
    assert r.aborted and r.errors == []
    tr = r.trace
    after = tr["t"] > 1.01
    assert np.all(tr["dc3d.state"][after] == 0)
    assert np.ptp(tr["dc3d.comp_z"][after]) == 0.0 and tr["dc3d.comp_z"][-1] == pytest.approx(-1.5, abs=0.01)
    assert tr["true.distance_orth"][-1] > 0        # the head stopped above the sheet, the offset kept


def test_program_end_while_active_warns_310021_and_holds_the_offset():
    prog = KIN98 + "#KIN ID[9.98]\n#TRAFO ON\n" + SELECT + "G1 A20 F1200\n#TIME 0.5\nM30\n"
    # a 2 mm sensor jump after the program end (at ~1.7 s) must not move the head
    jump = {"t": 2.5, "sensor_fault": {"kind": "jump", "value": 2.0}}
    r = run(head_scenario(prog, settle_time=2.0, events=[jump]))
    assert r.completed and r.errors == []
    assert [w["id"] for w in r.warnings] == [310021]
    tr = r.trace
    assert tr["t"][-1] > 3.0 and tr["dc3d.sensor"][-1] == pytest.approx(tr["true.distance_orth"][-1] + 2.0)
    end = int(np.argmax(tr["line"] == tr["line"][-1]))
    held = tr["dc3d.comp_z"][end + 5:]
    assert np.ptp(held) == 0.0 and held[0] == pytest.approx(-1.0, abs=2e-3)   # sensor changes no longer act
    assert tr["dc3d.state"][-1] == 4                                           # still active (static)


def test_off_then_program_end_during_the_run_out_runs_it_out_to_zero():
    """Audit W1 (FCT-M3 §12.4.4, PROG #DIST CTRL example 1 "Deactivate distance control with no wait"):
    OFF without WAIT, then M30 while the offset still runs out. The run-out completes to zero and
    the state reaches INACTIVE; the offset reported (dc3d.offset, DIST_CTRL[0]::m_actual_offset) is the
    one applied (dc3d.comp_z, on the Z axis with MODE=ACS) in every cycle."""
    prog = ("N010 G0 Z10\nN020 #DIST CTRL [SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]\n"
            "N030 #DIST CTRL WAIT ON [CONST_DIST SET_DIST=1 MODE=ACS DIRECTION=Z]\nN040 #TIME 0.5\n"
            "N900 #DIST CTRL OFF\nN910 G0 Z20\nN999 M30\n")
    r = run(with_program(SCN / "dist3d_1.toml", lambda _: prog))
    assert r.completed and r.errors == [] and r.warnings == [] and r.final_state == "INACTIVE"
    tr = r.trace
    end = int(np.argmax(tr["line"] == 7))                     # M30 (line 7) reached
    assert tr["dc3d.state"][end] == 3 and tr["dc3d.comp_z"][end] != 0.0   # still running out at M30
    assert np.array_equal(tr["dc3d.offset"], tr["dc3d.comp_z"])          # reported = applied, always
    assert tr["dc3d.state"][-1] == 0 and tr["dc3d.comp_z"][-1] == 0.0
    assert tr["Z.cmd"][-1] == tr["Z.prog"][-1] == 20.0


def test_axis_variant_machine_is_unchanged_without_3d():
    sc = load_scenario(SCN / "dist_1.toml")
    m = Machine(sc, load_program(sc))
    assert m.ch3d is None and not m.kinematic_path and m.step == m._step_axes
    cols, _ = trace_columns(m)
    assert not any(c.startswith(("dc3d.", "tcp.")) for c in cols)
    assert cols[-2:] == ["true.surface", "true.distance"]


# ---------------------------------------------------------------- every 3D error
def test_20209_dist_ctrl_without_fct_3d_dist_ctrl():
    prog = "G0 Z170\n#DIST CTRL ON [CONST_DIST SET_DIST=1]\nG0 Z160\nM30\n"
    r = run(head_scenario(prog, channel_table=False))
    err = only_error(r)
    assert err["id"] == 20209 and err["line"] == 2
    assert r.trace["Z.prog"][-1] == pytest.approx(170.0)               # stopped before N3


def test_20209_also_with_a_channel_list_without_the_function(tmp_path):
    lis = tmp_path / "no3d.lis"
    lis.write_text(CHANNEL_LIST.read_text().replace("FCT_3D_DIST_CTRL", "FCT_USE_CACHED_FILES"))
    data = {"program_text": "#DIST CTRL [MODE=MCS]\nM30\n", "axes": {"Z": {}},
            "channel": {"params": str(lis)}}
    r = run(scenario_from_dict(data, base_dir=SCN))
    assert only_error(r)["id"] == 20209


@pytest.mark.parametrize("command", ["#CS ON [0, 0, 0, 10, 0, 0]", "#TRAFO OFF", "#TRAFO [9, 98]",
                                     "#CHANNEL INIT"])
def test_51062_channel_position_reinitialised_while_active(command):
    prog = KIN98 + "#KIN ID[9.98]\n#TRAFO ON\n" + SELECT + f"{command}\nG1 A20 F600\nM30\n"
    r = run(head_scenario(prog))
    err = only_error(r)
    assert err["id"] == 51062 and err["line"] == 9
    assert np.all(r.trace["A.prog"] == 0.0)                            # aborted before the move


def test_51064_mode_changed_while_active():
    prog = KIN98 + "#KIN ID[9.98]\n#TRAFO ON\n" + SELECT + "#DIST CTRL [MODE=ECS]\nG1 A20 F600\nM30\n"
    err = only_error(run(head_scenario(prog)))
    assert err["id"] == 51064 and err["line"] == 9


def test_315001_a_max_zero_in_the_channel_list(tmp_path):
    prog = KIN98 + "#KIN ID[9.98]\n#TRAFO ON\n" + SELECT + "M30\n"
    err = only_error(run(head_scenario(prog, channel=channel_list(tmp_path, a_max=0))))
    assert err["id"] == 315001 and err["line"] == 8


@pytest.mark.parametrize("kin", ["#KIN ID[9]\n#TRAFO ON\n", ""])
def test_310015_ecs_without_kinematic_98(kin):
    prog = KIN98 + kin + "#DIST CTRL WAIT ON [CONST_DIST SET_DIST=80 MODE=ECS]\nM30\n"
    r = run(head_scenario(prog))
    err = only_error(r)
    assert err["id"] == 310015 and "kinematic 98" in err["message"]
    assert np.all(r.trace["dc3d.state"] == 0)


def test_900020_inclination_above_hd4():
    prog = KIN98 + "#KIN ID[9.98]\n#TRAFO ON\nG1 A60 F3000\nG1 A95\nM30\n"
    r = run(head_scenario(prog, channel_table=False))
    err = only_error(r)
    assert err["id"] == 900020 and err["line"] == 9 and "HD4" in err["message"]
    assert r.trace["A.act"].max() <= 91.0                               # never beyond HD4
    assert r.trace["A.prog"][-1] == pytest.approx(60.0)


def test_900020_at_trafo_on_with_the_head_beyond_hd4():
    prog = "V.G.KIN_STEP[1].ID[98].PARAM[0] = 0\nV.G.KIN_STEP[1].ID[98].PARAM[1] = 0\n" \
           "V.G.KIN_STEP[1].ID[98].PARAM[2] = 0\nV.G.KIN_STEP[1].ID[98].PARAM[3] = 100000\n" \
           "G1 A20 F1200\n#TRAFO [9, 98]\nM30\n"
    err = only_error(run(head_scenario(prog, channel_table=False)))
    assert err["id"] == 900020 and err["line"] == 6


def test_310017_max_deviation(tmp_path):
    prog = KIN98 + "#KIN ID[9.98]\n#TRAFO ON\n" + SELECT + "M30\n"
    r = run(head_scenario(prog, surface=-2.0, channel=channel_list(tmp_path, max_deviation=5000)))   # 0.5 mm
    err = only_error(r)
    assert err["id"] == 310017
    assert r.final_state == "ERROR" and np.abs(r.trace["dc3d.offset"]).max() <= 0.5 + 1e-12


def test_310026_select_without_set_dist():
    prog = KIN98 + "#KIN ID[9.98]\n#TRAFO ON\n#DIST CTRL WAIT ON [CONST_DIST MODE=MCS]\nM30\n"
    err = only_error(run(head_scenario(prog)))
    assert err["id"] == 310026 and err["line"] == 8


def test_310027_select_without_a_valid_sensor_variable():
    prog = KIN98 + "#KIN ID[9.98]\n#TRAFO ON\n" \
        "#DIST CTRL ON [CONST_DIST SET_DIST=80 SENSOR_VAR=V.E.NOPE]\nM30\n"
    err = only_error(run(head_scenario(prog)))
    assert err["id"] == 310027 and err["line"] == 8 and "V.E.NOPE" in err["message"]


def test_kinematics_errors_are_nc_runtime_errors():
    r = run(head_scenario("#KIN ID[9.45]\nM30\n", channel_table=False))
    assert only_error(r)["id"] == 900010
    r = run(head_scenario("#TRAFO [9, 98]\nM30\n", channel_table=False))     # PARAM[0..3] not assigned
    err = only_error(r)
    assert err["id"] == 900010 and "PARAM[0]" in err["message"]
    bad = KIN98.replace("PARAM[2] = 600000", "PARAM[2] = 950000")          # HD3 95°: infinite extension
    err = only_error(run(head_scenario(bad + "#TRAFO [9, 98]\nM30\n", channel_table=False)))
    assert err["id"] == 900010 and "PARAM[2]" in err["message"]


# ---------------------------------------------------------------- scenario keys
def _sc(**over):
    data = {"program_text": "M30\n", "axes": {n: {} for n in ("X", "Y", "Z", "A", "C")},
            "channel": {"params": str(CHANNEL_LIST)},
            "sensor": {"kind": "distance", "range_max": 200.0}}
    for k, v in over.items():
        if v is None:
            data.pop(k)
        else:
            data[k] = v
    return scenario_from_dict(data, base_dir=SCN)


def test_scenario_channel_keys_and_defaults():
    sc = _sc()
    assert sc.has_3d and sc.kinematics == "CA" and sc.channel_params.kp == 0.1
    assert sc.sensor.mode == "orthogonal_clamping_point" and sc.sensor.axis is None
    assert _sc(channel={"kinematics": "none"}, sensor=None).kinematics is None
    assert not _sc(channel={"kinematics": "none"}, sensor=None).has_3d
    axis_sensor = _sc(sensor={"axis": "Z", "kind": "distance", "mode": "axis"}).sensor
    assert axis_sensor.mode == "axis" and axis_sensor.axis == "Z"
    sc = _sc(axes={"Z": {"feedforward": 0.5}}, channel={"params": str(CHANNEL_LIST)})
    assert sc.axes["Z"].feedforward == 0.5


@pytest.mark.parametrize("over,key,words", [
    ({"channel": {"params": str(CHANNEL_LIST), "kinematics": "AC"}}, "channel.kinematics",
     ["'CA'", "'none'"]),
    ({"channel": {"kinematics": "CA"}, "axes": {"Z": {}, "A": {}, "C": {}}, "sensor": None},
     "channel.kinematics", ["missing: X, Y"]),
    ({"channel": {"params": "nope.lis"}}, "channel.params", ["file not found"]),
    ({"channel": {"param": "x"}}, "channel.param", ["unknown key", "kinematics"]),
    ({"sensor": {"kind": "distance", "mode": "normal"}}, "sensor.mode", ["orthogonal_clamping_point"]),
    ({"sensor": {"kind": "encoder", "mode": "orthogonal_clamping_point", "axis": "Z"}}, "sensor.mode",
     ["kind = 'distance'"]),
    ({"channel": {"kinematics": "none"}, "sensor": {"kind": "distance", "mode": "orthogonal_clamping_point"}},
     "sensor.mode", ["FCT_3D_DIST_CTRL"]),
    ({"sensor": {"kind": "distance", "mode": "axis"}}, "sensor.axis", ["missing"]),
    ({"axes": {"Z": {"feedforward": 1.5}}, "channel": {"kinematics": "none"}, "sensor": None},
     "axes.Z.feedforward", ["out of range"]),
])
def test_scenario_new_keys_are_validated(over, key, words):
    with pytest.raises(ScenarioError) as exc:
        _sc(**over)
    assert exc.value.key == key
    for w in words:
        assert w in str(exc.value)


def test_channel_list_errors_keep_file_and_line(tmp_path):
    lis = tmp_path / "bad.lis"
    lis.write_text("configuration.decoder.function FCT_3D_DIST_CTRL\ndist_ctrl[0].kp 3.5\n")
    with pytest.raises(ParameterError) as exc:
        _sc(channel={"params": str(lis)})
    assert f"{lis}:2" in str(exc.value) and "channel.params" in str(exc.value)
