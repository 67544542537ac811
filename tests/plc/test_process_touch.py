"""Touch-off (issue 16, docs/process.md): the PLC program's logic on the simulated machine (the HLI
control unit, the v_max CNC object, the V.E. handshake and #WAIT FOR), its errors, and the example
through `distctrl run`."""
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from distctrl.errors import ErrorId
from distctrl.plc.process import TOUCH_DEFAULTS, TouchOff
from distctrl.plc.process.plc_io import read_object
from distctrl.plc.process.touch_off import IDLE, PROBING
from distctrl.sim import run
from distctrl.sim.machine import Machine
from distctrl.sim.runner import load_program
from distctrl.sim.scenario import ScenarioError, load_scenario, scenario_from_text

EX = Path(__file__).resolve().parents[2] / "examples" / "scenarios"

PROGRAM = ("N10 G90 G0 X20 Z{start}\\n"
           "N20 Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]\\n"
           "{before}"
           "N30 V.E.TOUCH_OFF = 1\\n"
           "N40 #WAIT FOR V.E.TOUCH_OFF == 0\\n"
           "N50 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]\\n"
           "N60 G1 X60 F6000\\n"
           "N70 M30\\n")
SCENARIO = """
name = "touch"
cycle_time = 0.001
duration = {duration}
program_text = "{program}"
[axes.X]
[axes.Z]
params = "{lis}"
start = {start}
kv = 60.0
v_max = 300.0
a_max = 20000.0
[surface]
base = {base}
[sensor]
axis = "Z"
kind = "distance"
variable = "SENSOR"
range_max = 10.0
noise_std = 0.002
delay_cycles = 1
{events}
[[process]]
function = "touch_off"
axis = "Z"
{keys}
"""


def scenario(base=33.2, start=40.0, keys="", events="", before="", duration=4.0):
    program = PROGRAM.format(start=start, before=before)
    text = SCENARIO.format(duration=duration, program=program, lis=(EX / "z_laser.lis").as_posix(), start=start,
                           base=base, events=events, keys=keys)
    return scenario_from_text(text, base_dir=EX)


def simulate(sc, seconds):
    """The machine after ``seconds`` (or once the program has ended and distance control is idle)."""
    m = Machine(sc, load_program(sc))
    for _ in range(int(round(seconds / sc.cycle_time))):
        m.step()
    return m


def touch(m) -> TouchOff:
    return m.process_program.function("touch_off", "Z")


def errors(m):
    return [ev for _, ev in m.events if ev.severity == "error"]


# ------------------------------------------------------------------ configuration
def test_defaults_are_filled_in_and_the_stroke_stays_inside_max_deviation():
    (pc,) = scenario().processes
    p = pc.params
    assert p["variable"] == "SENSOR" and p["request"] == "TOUCH_OFF"
    assert (p["probe_speed"], p["detect"], p["pierce_height"], p["retries"]) == (10.0, 0.5, 3.0, 2)
    # z_laser.lis: max_deviation 8 mm -> the default stroke is 90 % of it (the 10 mm default would hit 70331)
    assert p["stroke"] == pytest.approx(7.2)
    assert TOUCH_DEFAULTS["stroke"] == 10.0


@pytest.mark.parametrize("keys, key, words", [
    ("stroke = 8.0", "process[0].stroke", "out of range"),          # = max_deviation of z_laser.lis
    ("probe_speed = 0", "process[0].probe_speed", "out of range"),
    ("probe_speed = 400", "process[0].probe_speed", "out of range"),  # above the axis's v_max 300 mm/s
    ("pierce_height = 0", "process[0].pierce_height", "out of range"),
    ("retries = 11", "process[0].retries", "out of range"),
    ('request = "a b"', "process[0].request", "V.E. variable"),
    ('variable = 3', "process[0].variable", "V.E. variable"),
    ("height = 3", "process[0].height", "unknown key"),
])
def test_invalid_keys_name_key_value_and_range(keys, key, words):
    with pytest.raises(ScenarioError) as exc:
        scenario(keys=keys)
    assert exc.value.key == key and words in str(exc.value)


# ------------------------------------------------------------------ the logic on the machine
def test_touch_off_finds_the_surface_backs_off_to_the_pierce_height_and_hands_back_to_the_nc():
    sc = scenario()
    m = Machine(sc, load_program(sc))
    f = touch(m)
    unit = m.hli["Z"]
    v_max_before = read_object(m, "Z", "DIST_CTRL_PARAM[0]::v_max")
    z, probing_z, states = [], [], []
    while m.nc.line != 5 and m.cycle < 3000:          # until N50 (the select after the touch-off)
        d_before = m.true_distance
        states.append((unit.state_r.actual_state, unit.state_r.command_source))
        m.step()
        z.append(m.drives["Z"].actual)
        if f.phase == PROBING:
            probing_z.append(m.drives["Z"].actual)
    assert m.nc.line == 5 and not errors(m)
    res = f.log[0]
    assert res["attempts"] == 1 and res["cycle"] == m.cycle - 1      # the NC went on in that very cycle
    assert res["surface"] == pytest.approx(33.2, abs=0.05)           # state_r.actual_position
    assert d_before == pytest.approx(3.0, abs=0.05)                   # held at the pierce height
    assert states[-1] == (2, 1) and m.variables["V.E.TOUCH_OFF"] == 0.0   # FREEZE commanded by the PLC
    # the probing ran at the probe speed: the Z velocity in the middle of the descent
    v = np.diff(probing_z[100:-100]) / sc.cycle_time
    assert np.median(v) == pytest.approx(-10.0, rel=0.02) and v.min() > -10.5
    # v_max was written back before the back-off: the parameter reads what it read before
    assert read_object(m, "Z", "DIST_CTRL_PARAM[0]::v_max") == v_max_before == 200000
    assert min(z) > 33.2 + 0.2                                        # never near the sheet


def test_no_surface_within_the_stroke_is_error_900050_at_the_wait_line_and_the_head_returns():
    sc = scenario(base=20.0)                            # 20 mm below the start, the stroke is 7.2 mm
    m = simulate(sc, 2.5)
    (ev,) = errors(m)
    assert ev.id == int(ErrorId.TOUCH_OFF_NO_SURFACE) == 900050
    assert ev.line == 4                                  # the #WAIT FOR block (N40, physical line 4)
    assert "stroke 7.2 mm" in ev.message and "10.000 mm" in ev.message
    assert m.nc.aborted and m.variables["V.E.TOUCH_OFF"] == -1.0
    assert m.hli["Z"].state_r.actual_state == 0                       # OFF ran the offset out
    assert m.drives["Z"].actual == pytest.approx(40.0, abs=0.01)      # back at the programmed height
    assert touch(m).phase == IDLE


def test_run_result_reports_the_touch_off_error_and_exit_code_2():
    result = run(scenario(base=20.0))
    assert result.outcome == "aborted" and result.exit_code == 2
    assert [e["id"] for e in result.errors] == [900050]
    assert "Touch-off: no surface within the stroke" in result.errors[0]["message"]


SPIKE = """
[[events]]
t = {t}
sensor_fault = {{ kind = "jump", value = -6.5, duration = 0.003 }}
"""


def test_a_spike_is_a_false_detection_the_probe_goes_on_and_finds_the_surface():
    sc = scenario(events=SPIKE.format(t=0.3))            # the reading drops to ~0 for 3 ms, far above the sheet
    m = simulate(sc, 3.0)
    f = touch(m)
    assert not errors(m) and f.log and f.log[0]["attempts"] == 2
    assert f.log[0]["surface"] == pytest.approx(33.2, abs=0.05)
    assert m.nc.ended and not m.nc.aborted


def test_retries_exhausted_is_error_900051():
    sc = scenario(keys="retries = 0", events=SPIKE.format(t=0.3))
    m = simulate(sc, 2.0)
    (ev,) = errors(m)
    assert ev.id == int(ErrorId.TOUCH_OFF_RETRIES) and ev.line == 4 and "retries 0" in ev.message
    assert m.nc.aborted and m.variables["V.E.TOUCH_OFF"] == -1.0


def test_a_request_while_distance_control_tracks_is_refused_with_900052():
    before = "N25 Z[DIST_CTRL ON CONST_DIST SET_DIST=1 WAIT]\\n"
    sc = scenario(start=36.0, before=before)
    m = simulate(sc, 1.0)
    (ev,) = errors(m)
    assert ev.id == int(ErrorId.TOUCH_OFF_FAILED) and "ACTIVE_CONST_DIST" in ev.message
    assert m.nc.aborted


def test_reset_while_probing_ends_the_touch_off_safely_and_when_idle_returns_to_the_initial_state():
    sc = scenario()
    m = simulate(sc, 0.3)
    f = touch(m)
    assert f.phase == PROBING and f.hold.inhibitors == {"touch_off"}
    f.reset()                                    # dropped now, distance control would go on down at SET_DIST 0
    assert f.phase == PROBING and f.enabled
    m.step()
    (ev,) = errors(m)
    assert ev.id == int(ErrorId.TOUCH_OFF_FAILED) and "reset while PROBING" in ev.message
    assert f.phase == IDLE and not f.hold.inhibitors and m.nc.aborted
    f.reset()
    assert f.phase == IDLE and f.attempts == 0 and f.result is None and f._pending is None and not f._abort


def test_switched_off_during_the_probe_it_ends_it_then_stays_off():
    sc = scenario()
    m = simulate(sc, 0.3)
    f = touch(m)
    m.process_program.set_enabled("touch_off", "Z", False)
    assert f.enabled and not f.switched_on                  # still ending the probe
    for _ in range(300):
        m.step()
    (ev,) = errors(m)
    assert ev.id == int(ErrorId.TOUCH_OFF_FAILED) and "switched off" in ev.message
    assert not f.enabled and m.hli["Z"].state_r.actual_state == 0      # OFF ran the offset out
    assert m.variables["V.E.TOUCH_OFF"] == -1.0


def test_switched_off_before_the_request_nobody_answers_and_the_program_waits():
    sc = scenario(keys="enabled = false")
    m = simulate(sc, 1.5)
    assert not errors(m) and not touch(m).log and m.nc.running and m.nc.line == 4    # at #WAIT FOR
    assert m.hli["Z"].state_r.actual_state == 0


# ------------------------------------------------------------------ the example through distctrl run
def test_example_through_distctrl_run_json():
    proc = subprocess.run([sys.executable, "-m", "distctrl", "run", str(EX / "process_touch.toml"), "--json"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["outcome"] == "completed" and data["errors"] == []
    m = data["metrics"]
    assert m["collisions"] == 0 and 0.2 < m["min_distance_mm"] < 0.5     # the touch came within 0.5 mm
    # the probe and the back-off are not tracking: the metrics start with the NC's select (3 mm -> 1 mm)
    assert m["distance_error_max"] == pytest.approx(2.02, abs=0.05)


def test_example_figures():
    sc = load_scenario(EX / "process_touch.toml")
    m = Machine(sc, load_program(sc))
    f = touch(m)
    while not f.log and m.cycle < 3000:
        m.step()
    res = f.log[0]
    assert res["surface"] == pytest.approx(33.2, abs=0.05) and res["attempts"] == 1
    assert res["distance"] == pytest.approx(3.0, abs=0.05)            # state_r.actual_distance
    assert math.isclose(m.true_distance, 3.0, abs_tol=0.05)
    assert 0.6 < res["cycle"] * sc.cycle_time < 1.2                   # probe 0.65 s + back-off + settling


def test_an_axis_that_does_not_read_the_sensor_ends_the_probe_with_900052():
    # without SENSOR_SOURCE=VARIABLE the axis reads its second encoder: the head never moves down
    sc = scenario()
    text = PROGRAM.format(start=40.0, before="").replace(
        "N20 Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]\\n", "")
    sc = scenario_from_text(SCENARIO.format(duration=4.0, program=text, lis=(EX / "z_laser.lis").as_posix(),
                                            start=40.0, base=33.2, events="", keys=""), base_dir=EX)
    f_cycles = touch(Machine(sc, load_program(sc))).probe_cycles
    assert f_cycles == round((2 * 7.2 / 10.0 + 1.0) / 0.001)
    m = simulate(sc, 3.0)
    (ev,) = errors(m)
    assert ev.id == int(ErrorId.TOUCH_OFF_FAILED) and "SENSOR_SOURCE" in ev.message
    assert m.nc.aborted and m.variables["V.E.TOUCH_OFF"] == -1.0


def test_a_void_lock_does_not_freeze_the_back_off():
    # the back-off lifts the head at 200 mm/s: the distance changes faster than the void lock's 80 mm/s,
    # so the lock asks for FREEZE; the touch-off inhibits the hold while it runs
    sc = scenario(keys='[[process]]\nfunction = "void_lock"\naxis = "Z"\n')
    m = simulate(sc, 2.5)
    assert not errors(m) and touch(m).log and m.nc.ended
    assert not m.process_program.holds["Z"].inhibitors
    void = m.process_program.function("void_lock", "Z")
    assert void.rate == void.rate                                     # it did watch


PLASMA = """
name = "plasma touch"
cycle_time = 0.001
duration = 4.0
program_text = "{program}"
[axes.X]
[axes.Z]
params = "{lis}"
start = 40.0
kv = 40.0
v_max = 200.0
a_max = 5000.0
[surface]
base = 32.0
[sensor]
axis = "Z"
kind = "arc_voltage"
variable = "SENSOR"
voltage_variable = "ARC_VOLTAGE"
arc_v0 = 95.0
arc_k = 6.0
arc_ripple = 2.0
arc_noise_std = 0.3
seed = 3
[[process]]
function = "touch_off"
axis = "Z"
"""


def test_touch_off_on_a_plasma_torch_with_ripple_and_noise():
    # the linearised arc voltage carries a 0.33 mm 50 Hz ripple; the back-off is judged on the filtered
    # distance (target deviation) and the drive's following error
    sc = scenario_from_text(PLASMA.format(program=PROGRAM.format(start=40.0, before=""),
                                          lis=(EX / "z_plasma.lis").as_posix()), base_dir=EX)
    assert sc.processes[0].params["stroke"] == pytest.approx(9.0)     # 0.9 x max_deviation 10 mm
    m = Machine(sc, load_program(sc))
    f = touch(m)
    while not f.log and not errors(m) and m.cycle < 3000:
        m.step()
    assert not errors(m)
    res = f.log[0]
    assert res["surface"] == pytest.approx(32.0, abs=0.4) and res["attempts"] == 1
    assert m.true_distance == pytest.approx(3.0, abs=0.1)


PROBE = """
name = "probe touch"
cycle_time = 0.001
duration = 4.0
program_text = "N10 G90 G0 X20 Z45\\nN30 V.E.TOUCH_OFF = 1\\nN40 #WAIT FOR V.E.TOUCH_OFF == 0\\nN50 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]\\nN60 G1 X60 F6000\\nN70 M30\\n"
[axes.X]
[axes.Z]
params = "{lis}"
start = 45.0
kv = 60.0
v_max = 300.0
a_max = 20000.0
[surface]
base = 37.0
[sensor]
axis = "Z"
kind = "encoder"
range_min = -20.0
range_max = 20.0
[[process]]
function = "touch_off"
axis = "Z"
"""


def test_touch_off_with_the_probe_on_encoder_2_reads_state_r_actual_distance():
    sc = scenario_from_text(PROBE.format(lis=(EX / "z_probe.lis").as_posix()), base_dir=EX)
    assert sc.processes[0].params["variable"] is None and sc.processes[0].params["stroke"] == 10.0
    m = Machine(sc, load_program(sc))
    f = touch(m)
    while not f.log and not errors(m) and m.cycle < 3000:
        m.step()
    res = f.log[0]
    assert res["surface"] == pytest.approx(37.0, abs=1e-3) and res["distance"] == pytest.approx(3.0, abs=0.01)
    assert m.true_distance == pytest.approx(3.0, abs=0.02)        # the offset stood before the FREEZE
