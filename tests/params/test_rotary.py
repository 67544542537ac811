"""Rotary distance-controlled axes (axis type R, P-AXIS-00018 ACHSTYP_ROTATOR; SPEC §12).

Every distance-control parameter of FCT-M3 §9.2 is documented for the axis types T and R; on an R axis
the list units are the column "Dimension R" (0.0001° for 0.1 µm, 0.001°/s for µm/s, °/s² for mm/s²,
0.0001°/s for P-AXIS-00417), internal lengths are degrees, and P-AXIS-00424 = 0 ("depending on axis
type") is modulo. The PLC interface (HLI DistanceControl: "0.1 µm or 0.0001°"), the CNC objects and the
NC words work in the axis unit.
"""
from __future__ import annotations

import pytest

from distctrl.control import Action, AxisDistanceController, Command, CycleInput, CycleOutput, SensorSource
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
    unit.write_command(transition=1, position=120000)              # command_w: ON, SET_POS 12° in 0.0001°
    unit.enable_w = unit.command_semaphore_rw = True
    cmd = unit.prepare(inp)
    assert (cmd.action, cmd.set_pos) == (Action.ON, pytest.approx(12.0))
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
    from distctrl.errors.config import ConfigError
    from distctrl.sim.scenario import scenario_from_dict

    (tmp_path / "a.lis").write_text(ROTARY_LIST, encoding="utf-8")
    with pytest.raises(ConfigError) as exc:
        scenario_from_dict({"program_text": "M30\n", "axes": {"A": {"params": "a.lis"}},
                            "sensor": {"axis": "A", "kind": "encoder"}}, base_dir=tmp_path)
    assert "sensor.axis" in str(exc.value) and "ACHSTYP_ROTATOR" in str(exc.value)


# FCT-M3 §9.2, column "Dimension" of every distance-control parameter as printed: (T, R)
DOCUMENT_DIMENSION = {
    "P-AXIS-00414": ("0.1 µm", "0.0001°"), "P-AXIS-00415": ("µm/s", "0.001°/s"),   # T printed '0.001 mm/s'
    "P-AXIS-00416": ("mm/s²", "°/s²"), "P-AXIS-00417": ("µm/s", "0.0001°/s"),
    "P-AXIS-00418": ("0.1 µm", "0.0001°"), "P-AXIS-00419": ("0.1 µm", "0.0001°"),
    "P-AXIS-00420": ("0.1 µm", "0.0001°"), "P-AXIS-00421": ("0.1 µm", "0.0001°"),
    "P-AXIS-00502": ("mm/s²", "mm/s²"),
    "P-AXIS-00504": ("0.1 µm", "0.0001°"), "P-AXIS-00505": ("0.1 µm", "0.0001°"),
    "P-AXIS-00508": ("Hz", "Hz"), "P-AXIS-00533": ("0.1 %", "0.1 %"), "P-AXIS-00534": ("0.1 %", "0.1 %"),
    "P-AXIS-00422": ("increments", "increments"), "P-AXIS-00423": ("0.1 µm", "0.0001°"),
    "P-AXIS-00764": ("s", "s"), "P-AXIS-00765": ("s", "s"),
}


def test_the_r_units_are_the_documents_dimension_r_column():
    """Every list unit on a rotary axis is FCT-M3 §9.2's 'Dimension R'; the one the project reads
    differently (P-AXIS-00502 a_min, printed 'mm/s²' for R too, blended with a_max in °/s²) says so."""
    from distctrl.params.table import BY_ID

    for pid, (unit_t, unit_r) in DOCUMENT_DIMENSION.items():
        spec = BY_ID[pid]
        assert spec.unit == unit_t, pid
        if pid == "P-AXIS-00502":
            assert spec.unit_rotary == "°/s²"
            assert "mm/s²" in spec.note and "°/s²" in spec.note and "P-AXIS-00416" in spec.note
        else:
            assert (spec.unit_rotary or spec.unit) == unit_r, pid
    # every other length-like distance-control parameter is dimensionless ('----' for T and R)
    for spec in BY_ID.values():
        if spec.id.startswith("P-AXIS-") and spec.id not in DOCUMENT_DIMENSION and spec.unit != "-":
            assert spec.id in ("P-AXIS-00008", "P-AXIS-00177", "P-AXIS-00178"), spec.id   # ISG axis data


def test_the_generated_list_says_what_p_axis_00424_zero_does_on_each_axis_type():
    from distctrl.params.docgen import render

    row = next(line for line in render().splitlines() if line.startswith("| P-AXIS-00424 "))
    assert "linear on a translatory axis" in row and "modulo on a rotary axis" in row
    row = next(line for line in render().splitlines() if line.startswith("| P-AXIS-00423 "))
    assert "0.0001°" in row.split("|")[9]                                      # the description names R too


def test_load_errors_of_a_rotary_list_give_degrees():
    """Exceptions at the edge name the value in the axis's unit: a rotary list is read in degrees."""
    with pytest.raises(ParameterError) as exc:
        rotary(min_pos=10.0, max_pos=10.0)
    assert "10 °" in str(exc.value) and "mm" not in str(exc.value)
    with pytest.raises(ParameterError) as exc:
        rotary(sw_limit_min=5.0, sw_limit_max=-5.0)
    assert "5 °" in str(exc.value) and "mm" not in str(exc.value)
    with pytest.raises(ParameterError) as exc:
        parse_list_text(ROTARY_LIST.replace("-1800000", "1800000"), "r.lis")
    assert "r.lis" in str(exc.value) and "180 °" in str(exc.value)


def test_a_modulo_reading_that_crosses_the_wrap_point_is_continuous_for_the_law():
    """P-AXIS-00424 modulo: the reading wraps into [min_pos, max_pos) = [-180°, 180°), but a reading
    rising at 20 °/s past 180° is no jump of 360° (70329) and the filter, the target deviation and
    the feedback see it move on continuously; DIST_CTRL::sensor_value shows the wrapped reading."""
    p = rotary(filter_type="MOVING_AVERAGE", n_cycles=10)
    ctrl = AxisDistanceController(p, 0.001)
    inp, out = CycleInput(programmed_position=0.0, actual_position=0.0), CycleOutput()
    inp.commands.append(Command(Action.DRYRUN, set_pos=175.0))
    feedback, events = [], []
    for k in range(1500):                                  # 170° ... 200°, wraps at k = 500
        angle = 170.0 + 0.02 * k
        inp.sensor_increments = angle / p.sensor_mm_per_increment
        ctrl.update(inp, out)
        events += out.events
        feedback.append(out.filtered_feedback)
    assert events == []
    assert out.hli_state == 7                                # DRYRUN_SETPOS, no error
    steps = [b - a for a, b in zip(feedback[20:], feedback[21:])]
    assert max(abs(s) for s in steps) < 0.03                 # continuous: 0.02° per cycle
    assert out.filtered_feedback == pytest.approx(170.0 + 0.02 * 1499 - 0.02 * 4.5, abs=1e-6)  # the mean of 10
    assert out.target_deviation == pytest.approx(out.filtered_feedback - 175.0, abs=1e-9)
    assert out.sensor_value == pytest.approx(-160.02, abs=1e-6)


def test_a_modulo_reading_wraps_continuously_through_the_v_e_variable_too():
    p = rotary()
    ctrl = AxisDistanceController(p, 0.001)
    inp, out = CycleInput(), CycleOutput()
    inp.commands += [Command(sensor_source=SensorSource.VARIABLE, sensor_var="V.E.GAP"), Command(Action.DRYRUN, set_pos=0.0)]
    events = []
    for k in range(1000):                                  # the distance d = -s falls past -180°
        inp.sensor_variable = 175.0 + 0.02 * k
        ctrl.update(inp, out)
        events += out.events
    assert events == [] and out.feedback_value == pytest.approx(-(175.0 + 0.02 * 999), abs=1e-6)
