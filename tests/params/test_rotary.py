"""Rotary distance-controlled axes (axis type R, P-AXIS-00018 ACHSTYP_ROTATOR; SPEC §12).

Every distance-control parameter of FCT-M3 §9.2 is documented for the axis types T and R; on an R axis
the list units are the column "Dimension R" (0.0001° for 0.1 µm, 0.001°/s for µm/s, °/s² for mm/s²,
0.0001°/s for P-AXIS-00417), internal lengths are degrees, and P-AXIS-00424 = 0 ("depending on axis
type") is modulo. The PLC interface (HLI DistanceControl: "0.1 µm or 0.0001°"), the CNC objects and the
NC words work in the axis unit.
"""
from __future__ import annotations

import pytest

from distctrl.control import Action, AxisDistanceController, Command, CycleInput, CycleOutput
from distctrl.errors import ParameterError
from distctrl.nc import parse_program
from distctrl.objects import BY_NAME, AxisObjectContext, read_value
from distctrl.params import AxisParameters, format_list, parse_list_text
from distctrl.plc import DistanceControlUnit

ROTARY_LIST = """\
lr_param.distance_control_on        1
kenngr.achs_typ                     ACHSTYP_ROTATOR
kenngr.distc.max_deviation          450000      # [0.0001°] 45°
kenngr.distc.v_max                  90000       # [0.001°/s] 90 °/s
kenngr.distc.a_max                  3600        # [°/s²]
kenngr.distc.max_act_value_change   3600000     # [0.0001°/s] 360 °/s
kenngr.distc.max_pos                1800000     # [0.0001°] +180°
kenngr.distc.min_pos                -1800000    # [0.0001°] -180°
kenngr.distc.dist_error_a_min       2500        # [0.0001°] 0.25°
kenngr.distc.optimized_scheduling   1
"""


def rotary(**changes) -> AxisParameters:
    return parse_list_text(ROTARY_LIST).params.replace(**changes)


def test_a_rotary_list_reads_the_r_units_into_degrees():
    p = rotary()
    assert p.rotary and p.axis_type == "ACHSTYP_ROTATOR" and p.length_unit == "°"
    assert p.max_deviation == pytest.approx(45.0)
    assert p.v_max == pytest.approx(90.0)                   # 0.001°/s
    assert p.a_max == 3600.0
    assert p.max_act_value_change == pytest.approx(360.0)   # P-AXIS-00417 R: 0.0001°/s (T: µm/s)
    assert (p.min_pos, p.max_pos) == (pytest.approx(-180.0), pytest.approx(180.0))
    assert p.dist_error_a_min == pytest.approx(0.25)
    t = parse_list_text(ROTARY_LIST.replace("ACHSTYP_ROTATOR", "ACHSTYP_TRANSLATOR")).params
    assert not t.rotary and t.length_unit == "mm"
    assert t.max_act_value_change == pytest.approx(3600.0)   # the same number in µm/s
    # the list written back in R units loads again to the same values
    text = format_list(p)
    assert "[0.0001°/s]" in text and "ACHSTYP_ROTATOR" in text
    assert parse_list_text(text).params == p


@pytest.mark.parametrize("text", ["ACHSTYP_ROTATOR", "rotator", "0x0002", "2"])
def test_axis_type_spellings(text):
    assert parse_list_text(ROTARY_LIST.replace("ACHSTYP_ROTATOR", text)).params.rotary


def test_a_spindle_has_no_distance_control():
    with pytest.raises(ParameterError) as exc:
        parse_list_text(ROTARY_LIST.replace("ACHSTYP_ROTATOR", "ACHSTYP_SPINDEL"), "r.lis")
    msg = str(exc.value)
    assert "r.lis:2" in msg and "P-AXIS-00018" in msg and "ACHSTYP_ROTATOR" in msg


@pytest.mark.parametrize("mode, rotary_axis, wraps", [(0, True, True), (0, False, False), (1, True, False),
                                                      (2, False, True), (2, True, True)])
def test_p_axis_00424_zero_is_modulo_on_a_rotary_axis(mode, rotary_axis, wraps):
    """P-AXIS-00424: 0 'depending on axis type' (linear for TRANSLATOR, modulo for ROTATOR), 1 linear,
    2 modulo: a reading of 190° wraps to -170° in [min_pos, max_pos) = [-180°, 180°)."""
    p = rotary(sensor_mode_act_pos=mode, axis_type="ACHSTYP_ROTATOR" if rotary_axis else "ACHSTYP_TRANSLATOR",
               max_act_value_change=1e5)
    assert p.sensor_modulo == wraps
    ctrl = AxisDistanceController(p, 0.001)
    out = CycleOutput()
    ctrl.update(CycleInput(sensor_increments=190.0 / p.sensor_mm_per_increment), out)
    assert out.sensor_value == pytest.approx(-170.0 if wraps else 190.0)


def test_the_plc_interface_and_the_objects_give_a_rotary_axis_in_its_units():
    """HLI DistanceControl: actual_position / actual_offset in '0.1 µm or 0.0001°'; the CNC objects'
    0.01 nm become 1e-8° and µm/s 0.001°/s on a rotary axis (the same integer scales)."""
    p = rotary(kp=0.5)
    ctrl = AxisDistanceController(p, 0.001)
    unit = DistanceControlUnit(1)
    inp, out = CycleInput(programmed_position=10.0, actual_position=10.0), CycleOutput()
    inp.commands.append(Command(Action.ON, set_pos=12.0))         # A[DIST_CTRL ON SET_POS=12]: 12°
    actual = 10.0
    for _ in range(400):
        inp.actual_position = actual
        inp.sensor_increments = (12.5 - actual) / p.sensor_mm_per_increment   # the "surface" at 12.5°
        ctrl.update(inp, out)
        actual = out.command_position
    unit.publish(out)
    assert out.offset == pytest.approx(0.5, abs=1e-9)
    assert unit.state_r.actual_offset == 5000                       # 0.0001°
    assert unit.state_r.actual_position == 125000                   # the measured "surface" 12.5°
    ctx = AxisObjectContext(4, "A", ctrl, out)
    assert read_value(BY_NAME["DIST_CTRL::m_actual_offset"], ctx) == 50_000_000   # 1e-8°
    assert read_value(BY_NAME["DIST_CTRL_PARAM[0]::v_max"], ctx) == 90000          # 0.001°/s


def test_nc_programs_command_a_rotary_axis_in_degrees():
    prog = parse_program("%R\nN10 A[DIST_CTRL ON SET_POS=90.5]\nN20 A[DIST_CTRL OFF]\nN30 M30\n")
    words = [w for b in prog.blocks for w in getattr(b, "dist_ctrl", [])]
    assert [w.axis for w in words] == ["A", "A"]
    cmd = words[0].to_command({}, 1)
    assert cmd.action == Action.ON and cmd.set_pos == 90.5            # degrees: no conversion of NC values


def test_the_virtual_machine_refuses_a_rotary_sensor_axis(tmp_path):
    from distctrl.sim.config_errors import ConfigError
    from distctrl.sim.scenario import scenario_from_dict

    (tmp_path / "a.lis").write_text(ROTARY_LIST, encoding="utf-8")
    with pytest.raises(ConfigError) as exc:
        scenario_from_dict({"program_text": "M30\n", "axes": {"A": {"params": "a.lis"}},
                            "sensor": {"axis": "A", "kind": "encoder"}}, base_dir=tmp_path)
    assert "sensor.axis" in str(exc.value) and "ACHSTYP_ROTATOR" in str(exc.value)
