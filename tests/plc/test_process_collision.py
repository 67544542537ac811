"""Collision retract (issue 16, docs/process.md): contact detection, the retract at the axis limits,
distance control off with the head up, the error with the place; no false trigger on normal plates."""
import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from distctrl.errors import ErrorId
from distctrl.plc.process import CollisionRetract
from distctrl.plc.process.collision_retract import WATCH
from distctrl.plc.process.config import ProcessConfig
from distctrl.sim import run
from distctrl.sim.machine import Machine
from distctrl.sim.runner import load_program
from distctrl.sim.scenario import ScenarioError, load_scenario, scenario_from_text

EX = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
COLLISION_ID = int(ErrorId.COLLISION_RETRACT)


def with_collision_retract(sc, **keys):
    """``sc`` with a collision_retract on its sensor's axis (the scenario defaults, ``keys`` on top)."""
    ax = sc.sensor.axis
    a = sc.axes[ax]
    var = sc.sensor.variable if sc.sensor.kind in ("distance", "arc_voltage") else None
    params = {"variable": var, "threshold": 0.2, "short_circuit": None, "confirm_cycles": 2, "retract": 5.0,
              "retract_speed": a.v_max, "retract_accel": a.a_max, **keys}
    return dataclasses.replace(sc, processes=sc.processes + (ProcessConfig("collision_retract", ax, params,
                                                                           len(sc.processes)),))


def simulate(sc, seconds):
    m = Machine(sc, load_program(sc))
    for _ in range(int(round(seconds / sc.cycle_time))):
        m.step()
    return m


# ------------------------------------------------------------------ configuration
def test_defaults_are_the_axis_limits():
    sc = load_scenario(EX / "process_collision.toml")
    (pc,) = sc.processes
    assert pc.params == {"variable": "SENSOR", "threshold": 0.2, "short_circuit": None, "confirm_cycles": 2,
                         "retract": 5.0, "retract_speed": 300.0, "retract_accel": 20000.0}
    f = pc.make(sc.cycle_time)
    assert isinstance(f, CollisionRetract) and f.phase == WATCH


@pytest.mark.parametrize("line, key, words", [
    ("retract_speed = 301", "process[0].retract_speed", "out of range"),     # above the axis's v_max
    ("retract_accel = 30000", "process[0].retract_accel", "out of range"),
    ("threshold = -1", "process[0].threshold", "out of range"),
    ("retract = 0", "process[0].retract", "out of range"),
    ("confirm_cycles = 0", "process[0].confirm_cycles", "out of range"),
    ('short_circuit = "x"', "process[0].short_circuit", "number"),
    ("lift = 3", "process[0].lift", "unknown key"),
])
def test_invalid_keys_name_key_value_and_range(line, key, words):
    text = (EX / "process_collision.toml").read_text() + line + "\n"
    with pytest.raises(ScenarioError) as exc:
        scenario_from_text(text, base_dir=EX)
    assert exc.value.key == key and words in str(exc.value)


# ------------------------------------------------------------------ the example: a tipped-up part
def test_the_head_hits_the_part_retracts_at_the_axis_limits_and_the_program_stops_with_the_place():
    sc = load_scenario(EX / "process_collision.toml")
    result = run(sc)
    assert result.outcome == "aborted" and result.exit_code == 2 and result.final_state == "INACTIVE"
    (err,) = result.errors
    assert err["id"] == COLLISION_ID and err["line"] == 7                       # N50 G1 X200
    assert err["t"] == pytest.approx(0.889, abs=0.002)
    msg = err["message"]
    assert "X=120.6" in msg and "Y=10.000 mm" in msg and "read 0.000 mm" in msg
    assert "retracted 5.0" in msg and "distance control is off" in msg
    tr = result.trace
    t, z = np.asarray(tr["t"]), np.asarray(tr["Z.act"])
    v = np.diff(z) / sc.cycle_time
    a = np.diff(v) / sc.cycle_time
    assert np.abs(v).max() <= 300.0 + 1e-6 and np.abs(a).max() <= 20000.0 + 1e-6   # the axis limits
    i = int(np.searchsorted(t, err["t"]))
    assert z[-1] - z[i] == pytest.approx(5.1, abs=0.2)               # up by the retract and stays up
    assert np.abs(np.diff(z[-200:])).max() <= 1.5e-4                  # at rest (one encoder increment)
    assert np.asarray(tr["true.distance"])[-1] > 2.0                  # above the part
    assert np.asarray(tr["Z.dc.state"])[-1] == 0


def test_retract_figures_on_the_function():
    sc = load_scenario(EX / "process_collision.toml")
    m = simulate(sc, 1.2)
    f = m.process_program.function("collision_retract", "Z")
    (c,) = f.log
    assert f.phase == WATCH and c["line"] == 7 and c["reading"] <= 0.2
    assert c["retract"] == pytest.approx(5.0, abs=0.15) and c["retract_time"] < 0.05
    assert m.nc.aborted and m.hli["Z"].state_r.actual_state == 0
    assert not m.process_program.holds["Z"].inhibitors                  # released after the retract


def test_without_the_function_the_head_runs_through_the_part():
    sc = dataclasses.replace(load_scenario(EX / "process_collision.toml"), processes=())
    result = run(sc, keep_trace=False)
    assert result.outcome == "completed" and result.metrics["collisions"] == 1
    assert result.metrics["min_distance_mm"] < -2.9


def test_distctrl_run_json_exit_code_and_error():
    proc = subprocess.run([sys.executable, "-m", "distctrl", "run", str(EX / "process_collision.toml"), "--json"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 2, proc.stderr
    data = json.loads(proc.stdout)
    assert [e["id"] for e in data["errors"]] == [COLLISION_ID]
    # the retract is not tracking: the largest distance error is the wall's 4 mm before the contact
    assert data["metrics"]["distance_error_max"] == pytest.approx(4.0, abs=0.05)


def test_a_lock_does_not_freeze_the_retract():
    # a void lock at 20 mm/s sees the reading change at the wall and during the retract and wants FREEZE:
    # the retract owns the axis (the hold is inhibited; without that it stops after 0.24 mm)
    text = (EX / "process_collision.toml").read_text().replace(
        '[[process]]\nfunction = "collision_retract"', '[[process]]\nfunction = "void_lock"\naxis = "Z"\n'
        'threshold = 20.0\n[[process]]\nfunction = "collision_retract"')
    sc = scenario_from_text(text, base_dir=EX)
    m = simulate(sc, 1.2)
    (c,) = m.process_program.function("collision_retract", "Z").log
    assert c["retract"] == pytest.approx(5.0, abs=0.15)


# ------------------------------------------------------------------ short circuit, touch-off, reset
SHEET = """
name = "sheet"
cycle_time = 0.001
duration = 3.0
program_text = "N10 G90 G0 X0 Z31\\nN20 Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]\\nN30 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]\\nN40 G1 X200 F6000\\nN50 M30\\n"
[axes.X]
[axes.Z]
params = "{lis}"
start = 31.0
kv = 60.0
v_max = 300.0
a_max = 20000.0
[surface]
base = 30.0
[sensor]
axis = "Z"
kind = "distance"
variable = "SENSOR"
range_max = 10.0
noise_std = 0.002
[[events]]
t = 1.0
sensor_fault = {{ kind = "dropout", value = 9.5 }}
"""


def test_the_short_circuit_value_triggers_and_the_retract_does_not_rely_on_the_reading():
    # the amplifier reports 9.5 mm on contact (its short-circuit value, inside the range: no run-out error):
    # a distance control following it dives
    sc = scenario_from_text(SHEET.format(lis=(EX / "z_laser.lis").as_posix()), base_dir=EX)
    without = run(sc, keep_trace=False)
    assert without.metrics["collisions"] >= 1
    m = simulate(with_collision_retract(sc, short_circuit=9.5), 1.5)
    f = m.process_program.function("collision_retract", "Z")
    (c,) = f.log
    assert c["cycle"] == pytest.approx(1002, abs=2) and c["reading"] == 9.5
    assert c["retract"] == pytest.approx(5.0, abs=0.15)               # up, although the reading says "far"
    assert m.true_distance > 5.0 and m.hli["Z"].state_r.actual_state == 0
    assert [ev.id for _, ev in m.events if ev.severity == "error"] == [COLLISION_ID]


def test_no_trigger_while_a_touch_off_probes():
    # detect 0.1 mm: the probe reads below the collision threshold before it stops
    text = (EX / "process_touch.toml").read_text() + 'detect = 0.1\n[[process]]\nfunction = "collision_retract"\naxis = "Z"\n'
    result = run(scenario_from_text(text, base_dir=EX), keep_trace=False)
    assert result.outcome == "completed" and result.errors == []
    assert 0.0 < result.metrics["min_distance_mm"] < 0.2


@pytest.mark.parametrize("name", ["process_void.toml", "process_corner.toml", "capacitive_edge.toml",
                                  "process_auto.toml"])
def test_no_false_trigger_on_normal_plates(name):
    result = run(with_collision_retract(load_scenario(EX / name)), keep_trace=False)
    assert result.outcome == "completed" and result.errors == [] and result.metrics["collisions"] == 0


def test_after_the_retract_a_new_select_arms_it_again():
    # served: after the retract the PLC selects distance control again and the head runs into the
    # obstacle a second time -> a second contact, a second retract
    sc = load_scenario(EX / "process_collision.toml")
    m = simulate(sc, 1.2)
    f = m.process_program.function("collision_retract", "Z")
    assert len(f.log) == 1 and f.phase == WATCH
    unit = m.hli["Z"]
    assert unit.plc_command("ON_CONST_DIST", -3.0)     # a distance below the part's top: down into it again
    for _ in range(500):
        m.step()
    assert len(f.log) == 2 and f.log[1]["retract"] == pytest.approx(5.0, abs=0.15)
    assert [ev.id for _, ev in m.events if ev.severity == "error"] == [COLLISION_ID, COLLISION_ID]


def test_reset_returns_to_watching():
    sc = load_scenario(EX / "process_collision.toml")
    m = simulate(sc, 0.5)
    f = m.process_program.function("collision_retract", "Z")
    f.hits = 1
    f.reset()
    assert f.phase == WATCH and f.hits == 0 and f.contact is None and not f.hold.inhibitors


def test_switched_off_during_the_retract_it_finishes_the_retract_first():
    sc = load_scenario(EX / "process_collision.toml")
    m = Machine(sc, load_program(sc))
    f = m.process_program.function("collision_retract", "Z")
    while f.phase not in ("RETRACTING",) and m.cycle < 1200:
        m.step()
    assert f.phase == "RETRACTING"
    m.process_program.set_enabled("collision_retract", "Z", False)
    assert f.enabled and f.phase == "RETRACTING"            # not dropped half-way
    for _ in range(100):
        m.step()
    (c,) = f.log
    assert c["retract"] == pytest.approx(5.0, abs=0.15) and f.phase == WATCH and not f.enabled
    f.reset()
    assert f.phase == WATCH and not f.hold.inhibitors


def test_switched_off_it_does_not_watch():
    text = (EX / "process_collision.toml").read_text() + "enabled = false\n"
    result = run(scenario_from_text(text, base_dir=EX), keep_trace=False)
    assert result.outcome == "completed" and result.metrics["collisions"] == 1 and result.errors == []


# issue 30 (bench/stress.py scenario campaign): an axis v_max of 5.5e11 mm/s passed the scenario's
# validation, and so did collision_retract's default retract_speed (the axis's v_max); the function
# itself allows at most 2e6 mm/s and raised at run start, a ConfigError without the scenario's file.
# The defaults now stay inside the function's bounds, and every [[process]] function is built once
# at load, so any other disagreement is the scenario's error with its file and process[i] key.
def _collision_scenario(z_extra: dict, process_extra: dict | None = None):
    from distctrl.sim.scenario import scenario_from_dict

    return scenario_from_dict({
        "program_text": "M30\n", "duration": 0.05,
        "axes": {"Z": {"params": "z_laser.lis", "start": 31.0, **z_extra}},
        "surface": {"base": 30.0},
        "sensor": {"axis": "Z", "kind": "distance", "variable": "SENSOR", "range_max": 10.0},
        "process": [{"function": "collision_retract", "axis": "Z", **(process_extra or {})}],
    }, base_dir=Path(__file__).resolve().parents[2] / "examples" / "scenarios", source="c.toml")


def test_collision_retract_defaults_stay_inside_its_bounds_for_a_very_fast_axis():
    from distctrl.sim.runner import run

    sc = _collision_scenario({"v_max": 546909396781.6607, "a_max": 5e12})
    assert run(sc, keep_trace=False).cycles > 0


def test_a_process_value_the_function_refuses_is_the_scenarios_error_at_load():
    from distctrl.sim.scenario import ScenarioError

    with pytest.raises(ScenarioError) as info:
        _collision_scenario({"v_max": 5e6}, {"retract_speed": 3e6})
    assert info.value.file == "c.toml" and info.value.key == "process[0].retract_speed", str(info.value)
