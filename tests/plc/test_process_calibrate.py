"""The calibrate process function (issue 16) on the example scenario, its [[process]] keys, and the PLC's
linearisation table of a distance sensor ([sensor] linearisation)."""
import math
from pathlib import Path

import numpy as np
import pytest

from distctrl.plc.linearisation import DistanceLinearisation
from distctrl.sim.machine import Machine
from distctrl.sim.runner import load_program
from distctrl.sim.scenario import ScenarioError, load_scenario, scenario_from_text

EX = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
SCN = EX / "calibrate_capacitive.toml"


def _machine(text=None):
    sc = load_scenario(SCN) if text is None else scenario_from_text(text, base_dir=EX)
    return Machine(sc, load_program(sc))


def _until_ended(m, f, limit=40000):
    while f.phase not in ("DONE", "FAILED") and m.cycle < limit:
        m.step()


def test_calibrate_drives_down_and_up_twice_records_and_switches_off():
    m = _machine()
    f = m.process_program.function("calibrate", "Z")
    assert f.phase == "WAITING" and f.status()["phase"] == "WAITING"
    _until_ended(m, f)
    assert f.phase == "DONE" and f.error is None
    rec = f.completed
    a, r = np.array(rec.axis), np.array(rec.reading)
    assert sorted(set(rec.run)) == [1, 2] and sorted(set(rec.direction)) == [-1, 1]
    assert rec.top == pytest.approx(4.85, abs=0.01)              # the reading at 5 mm true (8 % curve)
    assert a.max() == pytest.approx(35.0, abs=0.01) and a.min() < 30.3   # 0.3 mm measured ~ 0.27 mm true
    assert np.all(np.diff(a[np.array(rec.direction) < 0][:500]) <= 1e-3)    # moving down
    assert np.corrcoef(a, r)[0, 1] > 0.999
    for _ in range(300):
        m.step()
    assert m.hli["Z"].state_r.actual_state == 0                   # OFF at the end
    assert m.true_distance == pytest.approx(5.0, abs=0.005)       # back where it started
    assert not any(ev.severity == "error" for _, ev in m.events)


def test_calibrate_disabled_waits_and_runs_once_switched_on():
    text = SCN.read_text().replace('function = "calibrate"', 'function = "calibrate"\nenabled = false\nruns = 1\n'
                                   'speed = 5.0')
    m = _machine(text)
    f = m.process_program.function("calibrate", "Z")
    for _ in range(1500):
        m.step()
    assert f.phase == "WAITING" and len(f.record) == 0 and m.hli["Z"].state_r.actual_state == 0
    m.process_program.set_enabled("calibrate", "Z", True)
    _until_ended(m, f)
    assert f.phase == "DONE" and set(f.completed.run) == {1}


@pytest.mark.parametrize("extra, key, words", [
    ("runs = 0", "process[0].runs", "out of range"),
    ("bottom = 10.0", "process[0].bottom", "out of range"),
    ("speed = 0", "process[0].speed", "out of range"),
    ("variable = \"a b\"", "process[0].variable", "V.E. variable"),
])
def test_calibrate_keys_are_validated(extra, key, words):
    text = SCN.read_text().replace('function = "calibrate"', 'function = "calibrate"\n' + extra)
    with pytest.raises(ScenarioError) as exc:
        scenario_from_text(text, base_dir=EX)
    assert exc.value.key == key and words in str(exc.value)


def test_calibrate_needs_a_distance_sensor_on_its_axis():
    text = (EX / "process_void.toml").read_text().replace('function = "void_lock"', 'function = "calibrate"')
    with pytest.raises(ScenarioError) as exc:
        scenario_from_text(text, base_dir=EX)
    assert exc.value.key == "process[0].axis" and "kind = 'distance'" in str(exc.value)


# ---------------------------------------------------------------------- the PLC's linearisation table
def test_linearisation_interpolates_extends_the_end_segments_and_passes_nan():
    lin = DistanceLinearisation([[0.0, 0.0], [1.0, 2.0], [3.0, 4.0]])
    assert [lin._one(x) for x in (-1.0, 0.5, 2.0, 4.0)] == [-2.0, 1.0, 3.0, 5.0]
    assert math.isnan(lin._one(math.nan))
    assert list(lin.distance([-1.0, 0.5, 2.0, 4.0])) == [-2.0, 1.0, 3.0, 5.0]


def test_scenario_linearisation_inline_or_from_a_file(tmp_path):
    table = tmp_path / "t.toml"
    table.write_text("linearisation = [[0.0, 0.0], [4.85, 5.0], [9.5, 10.0]]\n")
    for value in (f'"{table.as_posix()}"', "[[0.0, 0.0], [4.85, 5.0], [9.5, 10.0]]"):
        text = SCN.read_text().replace('# linearisation = "calibrate_capacitive_linearisation.toml"',
                                       f"linearisation = {value}")
        text = text.replace('function = "calibrate"', 'function = "calibrate"\nenabled = false')   # at rest
        sc = scenario_from_text(text, base_dir=EX)
        assert sc.sensor.linearisation == ((0.0, 0.0), (4.85, 5.0), (9.5, 10.0))
        assert sc.sensor.raw_variable == "SENSOR_RAW" and sc.sensor.output_variable == "SENSOR_RAW"
        assert sc.processes[0].params["variable"] == "SENSOR_RAW"        # calibrate records the raw reading
        m = Machine(sc, load_program(sc))
        for _ in range(400):
            m.step()
        raw, dist = m.variables["V.E.SENSOR_RAW"], m.variables["V.E.SENSOR"]
        assert raw == pytest.approx(4.85, abs=0.01) and dist == pytest.approx(5.0, abs=0.01)


@pytest.mark.parametrize("value, extra, key, words", [
    ("[[1.0, 0.0], [0.5, 1.0]]", "", "sensor.linearisation[1]", "not increasing"),
    ("[[1.0, 0.0]]", "", "sensor.linearisation", "too short"),
    ('"missing.toml"', "", "sensor.linearisation", "existing"),
    ("[[0.0, 0.0], [1.0, 1.0]]", 'raw_variable = "SENSOR"', "sensor.raw_variable", "the same as variable"),
])
def test_scenario_linearisation_errors_name_the_key(value, extra, key, words):
    text = SCN.read_text().replace('# linearisation = "calibrate_capacitive_linearisation.toml"',
                                   f"linearisation = {value}\n{extra}")
    with pytest.raises(ScenarioError) as exc:
        scenario_from_text(text, base_dir=EX)
    assert exc.value.key == key and words in str(exc.value)


def test_raw_variable_without_a_linearisation_is_refused():
    text = SCN.read_text().replace('# linearisation = "calibrate_capacitive_linearisation.toml"',
                                   'raw_variable = "RAW"')
    with pytest.raises(ScenarioError) as exc:
        scenario_from_text(text, base_dir=EX)
    assert exc.value.key == "sensor.raw_variable"


def test_the_locks_cannot_freeze_the_calibration_run():
    # the automatic set value requests a FREEZE at every select (INACTIVE -> ACTIVE): the calibration's
    # own select would be frozen and fail without the interlock (FreezeHold.inhibitors)
    text = SCN.read_text() + '\n[[process]]\nfunction = "auto_set_value"\naxis = "Z"\n'
    m = _machine(text.replace('function = "calibrate"', 'function = "calibrate"\nruns = 1\nspeed = 5.0'))
    f = m.process_program.function("calibrate", "Z")
    hold = m.process_program.holds["Z"]
    _until_ended(m, f)
    assert f.phase == "DONE", f.error
    assert m.process_program.function("auto_set_value", "Z").log    # it did sample: its request came
    assert hold.log == [] and "calibrate" not in hold.inhibitors    # ... and no FREEZE was sent


def test_a_reset_during_the_run_fails_it_with_the_reason_and_stops_the_cyclic_command():
    m = _machine()
    f = m.process_program.function("calibrate", "Z")
    while f.phase != "DOWN":
        m.step()
    for _ in range(200):
        m.step()
    m.reset()                                        # the channel reset: distance control INACTIVE at once
    for _ in range(3):
        m.step()
    assert f.phase == "FAILED" and "left ACTIVE_CONST_DIST during run 1" in f.error
    assert f.completed is f.record and len(f.completed) > 100
    cyc = m.hli["Z"].cyclic
    assert not cyc.valid_distance and not cyc.valid_position
    assert "calibrate" not in m.process_program.holds["Z"].inhibitors
