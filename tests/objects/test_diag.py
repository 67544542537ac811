"""The diagnosis dump (FCT-M3 §12.10, Fig. 56 layout) for the axis and the 3D variant."""
from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from distctrl.control import Action, AxisDistanceController, Command, CycleInput, CycleOutput, ObjectWrite
from distctrl.objects.diag import format_diag_3d, format_diag_axis
from distctrl.errors.three_d import make_event_3d
from distctrl.objects.channel3d import Channel3DValues
from distctrl.params import AxisParameters
from distctrl.params.channel import ChannelParameters

# Fig. 56, in the figure's order
FIG56_DISTANCE_CONTROL = ["zstd", "tast_offset", "referenzwert", "sollw", "sollw_prog", "kp", "i_tn", "d_tv",
                          "filter_type", "n_cycles", "smooth_fact", "sigma", "max_dist_change", "fg_f0", "order",
                          "v_max", "a_max"]
FIG56_INTERFACE = ["cmd_offset", "cmd_offset_frozen", "act_offset", "delta_tool_length", "f_freeze",
                   "f_wait_for_finished", "f_use_weighting", "active_mode", "new_mode", "active_ax_idx",
                   "new_ax_idx"]

LINE = re.compile(r"^([A-Za-z_.0-9]+): (.*) \[([^\]]+)\]$")


class Loop:
    """An axis with a probe: s = surface - actual (mm) as encoder-2 increments; the drive follows the
    command one cycle late."""

    def __init__(self, p: float = 40.0, surface: float = 40.0, **changes):
        kw = dict(enabled=True, v_max=20.0, a_max=2000.0, max_act_value_change=1e5, max_pos=5.0, min_pos=-5.0,
                  kp=0.8, i_tn=0.02, d_tv=0.001, filter_type="MOVING_AVERAGE", n_cycles=6)
        kw.update(changes)
        self.params = AxisParameters(**kw)
        self.ctrl = AxisDistanceController(self.params, 0.001)
        self.p, self.surface, self.actual = p, surface, p
        self.inp, self.out = CycleInput(), CycleOutput()

    def cycle(self, *commands, n: int = 1, line: int | None = None) -> CycleOutput:
        for k in range(n):
            inp = self.inp
            inp.programmed_position, inp.actual_position = self.p, self.actual
            inp.sensor_increments = (self.surface - self.actual) / self.params.sensor_mm_per_increment
            inp.nc_line = line
            if k == 0:
                inp.commands.extend(commands)
            self.ctrl.update(inp, self.out)
            self.actual = self.out.command_position
        return self.out


def sections(text: str) -> dict[str, list[str]]:
    """Section title -> its lines (the header block is under '')."""
    result: dict[str, list[str]] = {"": []}
    current = ""
    for ln in text.splitlines()[1:]:
        if not ln:
            continue
        if ln.endswith(":") and " " not in ln.rstrip(":").replace("Dist-Ctrl Interface", "X").replace(
                "Distance Control", "X").replace("logged events", "X"):
            current = ln[:-1]
            result[current] = []
        else:
            result[current].append(ln)
    return result


def fields(lines: list[str]) -> dict[str, tuple[str, str]]:
    out = {}
    for ln in lines:
        m = LINE.match(ln)
        assert m, f"line without 'name: value [unit]': {ln!r}"
        out[m.group(1)] = (m.group(2), m.group(3))
    return out


def test_axis_diag_after_an_active_set_pos_select():
    loop = Loop()
    loop.cycle(Command(Action.ON, set_pos=40.0, line=20), line=20)
    loop.surface = 40.25                                    # the surface rises: the offset runs after it
    out = loop.cycle(n=10, line=30)
    assert 0 < out.offset < 0.25 and not out.target_reached
    text = format_diag_axis(loop.ctrl, out, "Z", axis_index=2)
    assert text.startswith("DiagData distance control: axis Z\n")
    sec = sections(text)
    # the figure's sections and fields, in its order
    assert list(sec)[1:4] == ["Distance Control", "logged events", "Dist-Ctrl Interface"]
    assert [ln.split(":")[0] for ln in sec["Distance Control"]] == FIG56_DISTANCE_CONTROL
    assert [ln.split(":")[0] for ln in sec["Dist-Ctrl Interface"]] == FIG56_INTERFACE
    # units in every line
    for name, lines in sec.items():
        if name != "logged events":
            fields(lines)
    dc = fields(sec["Distance Control"])
    assert dc["zstd"] == ("ACTIVE (2)", "-")
    assert dc["kp"] == ("0.800000", "-")
    assert dc["i_tn"] == ("0.020000", "s") and dc["d_tv"] == ("0.001000", "s")
    assert dc["filter_type"] == ("MOVING_AVERAGE", "-") and dc["n_cycles"] == ("6", "-")
    assert dc["sollw"] == ("40.000000", "mm") and dc["sollw_prog"] == ("40.000000", "mm")
    assert dc["v_max"] == ("20.000000", "mm/s") and dc["a_max"] == ("2000.000000", "mm/s²")
    ifc = fields(sec["Dist-Ctrl Interface"])
    assert ifc["act_offset"] == (f"{out.offset:.6f}", "mm")
    assert ifc["cmd_offset"] == (f"{out.m_actual_offset:.6f}", "mm")
    assert ifc["f_freeze"] == ("0", "-") and ifc["cmd_offset_frozen"] == ("0.000000", "mm")
    assert ifc["active_ax_idx"] == ("2", "-") and ifc["active_mode"] == ("ACS (4)", "-")
    assert ifc["f_wait_for_finished"] == ("1", "-")          # still running after the surface
    st = fields(sec["State"])
    assert st["hli_state"] == ("ACTIVE (1)", "-") and st["dist_ctrl_state"] == ("ACTIVE (2)", "-")
    assert st["mode"] == ("SET_POS (0)", "-") and st["last_error"] == ("none", "-")
    vals = fields(sec["Values"])
    assert vals["offset"] == (f"{out.offset:.6f}", "mm")
    assert vals["target_deviation"] == (f"{out.target_deviation:.6f}", "mm")
    assert vals["filtered_feedback"] == (f"{out.filtered_feedback:.6f}", "mm")
    assert vals["surface_position"] == (f"{out.surface_position:.6f}", "mm")
    lim = fields(sec["Limits"])
    assert lim["max_deviation"][1] == "mm" and lim["max_pos"] == ("5.000000", "mm")
    assert lim["v_max_int"] == (f"{out.v_max_int:.6f}", "mm/s")
    assert sec["logged events"] == ["(none)"]


def test_axis_diag_in_freeze_and_with_a_pending_write():
    loop = Loop()
    loop.cycle(Command(Action.ON, set_pos=40.0))
    loop.surface = 40.1
    loop.cycle(n=300)
    out = loop.cycle(Command(Action.FREEZE), ObjectWrite("kp", 0.5), n=50)
    sec = sections(format_diag_axis(loop.ctrl, out, "Z"))
    ifc = fields(sec["Dist-Ctrl Interface"])
    assert ifc["f_freeze"] == ("1", "-") and ifc["cmd_offset_frozen"] == (f"{out.offset:.6f}", "mm")
    assert fields(sec["Distance Control"])["zstd"] == ("FREEZE (3)", "-")
    assert fields(sec["State"])["pending_writes"] == ("kp=0.5", "internal units")
    assert fields(sec["Distance Control"])["kp"] == ("0.800000", "-")     # working value until adopted


def test_axis_diag_after_an_error_shows_id_cycle_and_line():
    loop = Loop()
    loop.cycle(Command(Action.ON, set_pos=40.0, line=20), line=20)
    loop.cycle(n=5, line=25)
    loop.surface = loop.actual + 7.0                         # the probe runs out (s > max_pos - tolerance)
    for _ in range(3):                                       # the reading arrives one cycle late
        out = loop.cycle(line=31)
        if out.events:
            break
    assert out.events and out.events[0].id == 70330
    cycle = out.events[0].cycle
    text = format_diag_axis(loop.ctrl, out, "Z")
    sec = sections(text)
    st = fields(sec["State"])
    assert st["hli_state"] == ("ERROR (5)", "-")
    assert st["last_error"] == ("70330", "-")
    assert st["last_error_cycle"] == (str(cycle), "cycles") and st["last_error_line"] == ("31", "NC line")
    assert fields(sec["Distance Control"])["zstd"] == ("ERROR_SENSOR_MAX (7)", "-")
    assert len(sec["logged events"]) == 1
    want = f"error ID 70330, cycle {cycle}, NC line 31: Sensor completely run out"
    assert sec["logged events"][0].startswith(want)
    # the error stays in the dump while the controller is in ERROR (the next cycle has no new event)
    out = loop.cycle(line=32)
    assert not out.events
    assert "error ID 70330" in format_diag_axis(loop.ctrl, out, "Z")


def test_axis_diag_before_the_first_cycle():
    ctrl = AxisDistanceController(AxisParameters(enabled=True, kp=0.4))
    sec = sections(format_diag_axis(ctrl, None, "X"))
    dc = fields(sec["Distance Control"])
    assert dc["zstd"] == ("IDLE (0)", "-") and dc["kp"] == ("0.400000", "-") and dc["sollw_prog"] == ("-", "mm")
    assert fields(sec["State"])["hli_state"] == ("INACTIVE (0)", "-")


def test_3d_diag_formats_fake_values():
    err = make_event_3d(310017, 512, 140, "offset at max_deviation")
    values = Channel3DValues(
        offset=0.4, m_actual_offset=0.45, cmd_offset=0.45, set_pos=1.0, set_distance=2.0, control_mode=1,
        programmed_set_dist=2.0, state=9, hli_state=5, kp=0.3, i_tn=0.0, d_tv=0.01, filter_type="MOVING_AVERAGE",
        n_cycles=20, smoothing_fact=0.05, kalman_sigma=2000.0, v_max_param=100.0, a_max_param=100.0,
        compensation_mode=3, new_compensation_mode=2, direction="Z", active_axis_index=2, new_axis_index=2,
        inclination_rad=math.radians(45.0), tool_length=10.0, virtual_tool_length=12.5,
        orthogonal_set_distance=2.0 * math.cos(math.radians(45.0)), compensation_x=0.1, compensation_y=-0.2,
        compensation_z=0.3, delta_tool_length=0.45, wait_for_finished=True, filter_time=50,
        sensor_var="V.E.SENSOR", error=err, cycle=600)
    params = ChannelParameters(fct_3d_dist_ctrl=True, low_pass_filter_order=3, low_pass_filter_fg_f0=50.0,
                               a_max=100.0, v_weight_down=0.5)
    text = format_diag_3d(values, params, channel=1)
    assert text.startswith("DiagData 3D distance control: Kanal 1\n")
    sec = sections(text)
    assert list(sec)[1:5] == ["Configuration", "Distance Control", "logged events", "Dist-Ctrl Interface"]
    assert [ln.split(":")[0] for ln in sec["Distance Control"]] == FIG56_DISTANCE_CONTROL
    assert [ln.split(":")[0] for ln in sec["Dist-Ctrl Interface"]] == FIG56_INTERFACE
    for name, lines in sec.items():
        if name != "logged events":
            fields(lines)
    cfg = fields(sec["Configuration"])
    assert cfg["configuration.decoder.function"] == ("FCT_3D_DIST_CTRL", "-")
    dc = fields(sec["Distance Control"])
    # the values of Fig. 56's example where they are the same quantity
    assert dc["kp"] == ("0.300000", "-") and dc["d_tv"] == ("0.010000", "s")
    assert dc["filter_type"] == ("MOVING_AVERAGE", "-") and dc["n_cycles"] == ("20", "-")
    assert dc["smooth_fact"] == ("0.050000", "-") and dc["sigma"] == ("2000.000000", "-")
    assert dc["fg_f0"] == ("50.000000", "Hz") and dc["order"] == ("3", "-")          # from the parameters
    assert dc["v_max"] == ("100.000000", "mm/s") and dc["a_max"] == ("100.000000", "mm/s²")
    assert dc["zstd"] == ("ERROR_MAX_DEVIATION (9)", "-")
    assert dc["sollw"] == ("2.000000", "mm") and dc["sollw_prog"] == ("2.000000", "mm")      # CONST_DIST
    ifc = fields(sec["Dist-Ctrl Interface"])
    assert ifc["active_mode"] == ("ECS (3)", "-") and ifc["new_mode"] == ("MCS (2)", "-")
    assert ifc["act_offset"] == ("0.400000", "mm") and ifc["cmd_offset"] == ("0.450000", "mm")
    assert ifc["delta_tool_length"] == ("0.450000", "mm")
    assert ifc["f_wait_for_finished"] == ("1", "-") and ifc["f_use_weighting"] == ("1", "-")
    assert ifc["active_ax_idx"] == ("2", "-")
    three = fields(sec["3D"])
    assert three["inclination"] == ("45.0000", "°")
    assert three["virtual_tool_length"] == ("12.500000", "mm")
    assert three["virt_tool_length_r"] == ("125000", "0.1 µm")
    assert three["inclination_r"] == ("450000", "0.0001°")
    assert three["compensation_y"] == ("-0.200000", "mm") and three["filter_time"] == ("50", "cycles")
    assert fields(sec["Values"])["orthogonal_set_distance"] == ("1.414214", "mm")
    st = fields(sec["State"])
    assert st["hli_state"] == ("ERROR (5)", "-") and st["mode"] == ("CONST_DIST (1)", "-")
    assert st["last_error"] == ("310017", "-") and st["last_error_line"] == ("140", "NC line")
    assert sec["logged events"] == ["error ID 310017, cycle 512, NC line 140: Excessive sensing deviation: "
                                    "offset at max_deviation"]


def test_3d_diag_without_parameters_and_defaults():
    text = format_diag_3d(Channel3DValues(), None, channel=2)
    sec = sections(text)
    assert fields(sec["Configuration"])["configuration.decoder.function"] == ("-", "-")
    dc = fields(sec["Distance Control"])
    assert dc["zstd"] == ("IDLE (0)", "-") and dc["fg_f0"] == ("-", "Hz") and dc["tast_offset"] == ("-", "mm")
    assert fields(sec["Dist-Ctrl Interface"])["active_mode"] == ("OFF (0)", "-")
    assert fields(sec[""])["channel"] == ("Kanal 2", "-")


@pytest.mark.parametrize("bad_state", [1, 99])
def test_unknown_state_codes_are_named(bad_state):
    text = format_diag_3d(Channel3DValues(state=bad_state), None)
    assert f"zstd: UNKNOWN ({bad_state}) [-]" in text


def test_docs_diag_md_explains_every_field_of_fig_56():
    from pathlib import Path
    doc = (Path(__file__).resolve().parents[2] / "docs" / "diag.md").read_text(encoding="utf-8")
    for name in FIG56_DISTANCE_CONTROL + FIG56_INTERFACE:
        assert f"`{name}`" in doc, name


def test_diagnosis_shows_the_n_the_filter_uses_under_default():
    """The diagnosis block's n_cycles (FCT-M3 Fig. 56) is the n in use: 4 under FILTER_TYPE DEFAULT."""
    loop = Loop(filter_type="DEFAULT", n_cycles=20)
    loop.cycle()
    dc = fields(sections(format_diag_axis(loop.ctrl, loop.out, "Z"))["Distance Control"])
    assert dc["n_cycles"] == ("4", "-") and dc["filter_type"] == ("DEFAULT", "-")


# ----------------------------------------------------------------------------- 3D on a running machine
ROOT = Path(__file__).resolve().parents[2]
SCN = ROOT / "examples" / "scenarios"

#: PROG #DIST CTRL example 1's machine (ACS on Z, the sheet 1.2 mm below Z10), through every state
STATES_PROGRAM = """G0 Z10
#DIST CTRL [SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]
#DIST CTRL [MODE=ACS DIRECTION=Z]
#TIME 0.2
#DIST CTRL DRYRUN [CONST_DIST SET_DIST=1.5]
#TIME 0.2
#DIST CTRL WAIT OFF
#DIST CTRL WAIT ON [SURFACE SET_POS=8.6]
#TIME 0.3
#DIST CTRL FREEZE
#TIME 0.3
#DIST CTRL WAIT OFF
#DIST CTRL WAIT ON [CONST_DIST SET_DIST=1.5]
#TIME 0.3
#DIST CTRL OFF
#TIME 0.5
#DIST CTRL WAIT ON [CONST_DIST SET_DIST=1.5]
#TIME 2
M30
"""


def _states_machine(events=()):
    from distctrl.sim.machine import Machine
    from distctrl.sim.runner import load_program
    from distctrl.sim.scenario import scenario_from_dict
    data = {"name": "diag3d", "program_text": STATES_PROGRAM, "duration": 10.0,
            "external_variables": "../external_variables_12_8_4.lis",
            "channel": {"params": "../channel_3d_12_8_3.lis", "kinematics": "none"},
            "axes": {"X": {}, "Y": {}, "Z": {"start": 10.0, "kv": 50.0, "feedforward": 1.0}},
            "surface": {"base": 8.8},
            "sensor": {"kind": "distance", "mode": "orthogonal_clamping_point", "variable": "SENSOR",
                       "range_max": 150.0},
            "events": list(events)}
    sc = scenario_from_dict(data, base_dir=SCN)
    return sc, Machine(sc, load_program(sc))


def _diag_at(machine, sc, line: int, extra_cycles: int) -> dict:
    """The 3D diagnosis block (as --json gives it) ``extra_cycles`` after NC line ``line`` began."""
    from distctrl.objects.diag import diag_3d
    for _ in range(20000):
        if machine.nc.line == line:
            break
        machine.step()
    else:
        raise AssertionError(f"line {line} never reached")
    for _ in range(extra_cycles):
        machine.step()
    d = diag_3d(machine.channel3d_values(), sc.channel_params, channel=1,
                events=[ev for _, ev in machine.events]).to_dict()
    flat = {}
    for sec in d["sections"].values():
        flat.update({k: v["value"] for k, v in sec.items()})
    flat["logged_events"] = d["logged_events"]
    return flat


def test_3d_diag_on_a_running_machine_in_every_state():
    """Audit W3 (FCT-M3 §12.10 Fig. 56, docs/diag.md): on a running machine the 3D block shows the
    select's mode and set values, the sensor variable, the FREEZE flag and frozen offset, the MODE
    programmed for the next select and the MODE in effect, in every state."""
    sc, m = _states_machine()
    d = _diag_at(m, sc, 4, 100)                                  # INACTIVE, MODE=ACS programmed
    assert (d["hli_state"], d["zstd"]) == ("INACTIVE (0)", "IDLE (0)")
    assert d["active_mode"] == "OFF (0)" and d["new_mode"] == "ACS (4)"
    assert d["active_ax_idx"] == 2 and d["new_ax_idx"] == 2          # DIRECTION=Z: channel axis 2 (X, Y, Z)
    assert d["sensor_var"] == "V.E.SENSOR" and d["sollw_prog"] is None and d["f_freeze"] == 0

    d = _diag_at(m, sc, 6, 100)                                  # DRYRUN CONST_DIST
    assert (d["hli_state"], d["zstd"]) == ("DRYRUN_CONST_DIST (6)", "DRYRUN (15)")
    assert d["mode"] == "CONST_DIST (1)" and d["sollw"] == 1.5 and d["sollw_prog"] == 1.5
    assert d["active_mode"] == "ACS (4)" and d["act_offset"] == 0.0

    d = _diag_at(m, sc, 8, 5)                                    # WAIT ON: the block waits
    assert d["f_wait_for_finished"] == 1 and d["hli_state"] == "ACTIVE (1)"

    d = _diag_at(m, sc, 9, 250)                                  # ACTIVE, SET_POS (surface)
    assert d["f_wait_for_finished"] == 0
    assert (d["hli_state"], d["zstd"]) == ("ACTIVE (1)", "ACTIVE (2)")
    assert d["mode"] == "SET_POS (0)" and d["sollw"] == 8.6 and d["sollw_prog"] == 8.6
    assert d["cmd_offset"] == pytest.approx(0.2, abs=2e-3) and d["act_offset"] == d["cmd_offset"]
    assert d["f_freeze"] == 0 and d["cmd_offset_frozen"] == 0.0
    assert d["sensor_var"] == "V.E.SENSOR" and d["sensor_source"] == "VARIABLE"

    d = _diag_at(m, sc, 11, 250)                                 # FREEZE
    assert (d["hli_state"], d["zstd"]) == ("FREEZE (2)", "FREEZE (3)")
    assert d["f_freeze"] == 1 and d["cmd_offset_frozen"] == d["cmd_offset"] != 0.0
    assert d["cmd_offset_frozen"] == pytest.approx(0.2, abs=2e-3)

    d = _diag_at(m, sc, 14, 250)                                 # ACTIVE_CONST_DIST
    assert (d["hli_state"], d["zstd"]) == ("ACTIVE_CONST_DIST (4)", "ACTIVE (2)")
    assert d["mode"] == "CONST_DIST (1)" and d["sollw"] == 1.5 and d["sollw_prog"] == 1.5
    assert d["set_distance"] == 1.5 and d["f_freeze"] == 0 and d["cmd_offset_frozen"] == 0.0
    assert d["cmd_offset"] == pytest.approx(0.3, abs=0.02)

    d = _diag_at(m, sc, 16, 5)                                   # TURNING_OFF
    assert (d["hli_state"], d["zstd"]) == ("TURNING_OFF (3)", "OFF (4)")
    assert d["mode"] == "CONST_DIST (1)" and d["active_mode"] == "ACS (4)" and d["cmd_offset"] > 0.1

    d = _diag_at(m, sc, 16, 400)                                 # run out: INACTIVE again
    assert (d["hli_state"], d["zstd"]) == ("INACTIVE (0)", "IDLE (0)") and d["cmd_offset"] == 0.0
    assert d["active_mode"] == "OFF (0)" and d["new_mode"] == "ACS (4)"


def test_3d_diag_on_a_running_machine_in_error():
    """A sensor jump (310018) while ACTIVE_CONST_DIST: ERROR, the error and its line in the block."""
    sc, m = _states_machine(events=[{"t": 3.6, "sensor_fault": {"kind": "jump", "value": 20.0}}])
    _diag_at(m, sc, 18, 0)                                       # the #TIME 2 after the select (line 17)
    assert m.cycle * sc.cycle_time < 3.6 and m.out3d.core.hli_state == 4
    while m.cycle * sc.cycle_time < 3.7:
        m.step()
    d = _diag_at(m, sc, 18, 0)
    assert d["hli_state"] == "ERROR (5)" and d["zstd"] == "ERROR_SENSOR_JUMP (6)"
    assert d["last_error"] == 310018 and d["last_error_line"] == 18
    assert d["mode"] == "CONST_DIST (1)" and d["sollw"] == 1.5
    assert any("ID 310018" in ev for ev in d["logged_events"])
