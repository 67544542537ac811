"""Scenario loader: the documented example loads; every validation rule names file, key and allowed values."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from distctrl.base.states import HliTransition
from distctrl.errors import DistCtrlError, ParameterError
from distctrl.params.axis import AxisParameters
from distctrl.errors.config import ConfigError
from distctrl.sim.drive import Drive
from distctrl.sim.interpolator import AxisLimits
from distctrl.sim.scenario import (AXIS_KEYS, EVENT_KINDS, SENSOR_KEYS, TOP_LEVEL_KEYS, AxisConfig, Event,
                                   Scenario, ScenarioError, SensorConfig, load_scenario, scenario_from_dict,
                                   scenario_from_text)
from distctrl.sim.sensors import DistanceSensor, EncoderProbe, Fault

ROOT = Path(__file__).resolve().parents[2]

PROGRAM = "N10 G0 X0 Z40\nN20 G1 X100 F3000\nN30 M30\n"
Z_LIS = "lr_param.distance_control_on 1   # on\nkenngr.distc.kp 0.5\nkenngr.distc.n_cycles 8\n"

EXAMPLE = '''\
name = "laser sheet"
cycle_time = 0.001
program = "part.nc"
duration = 6.0
settle_time = 0.5
seed = 1
[variables]
SENSOR = 0.0
[tool]
length = 0.0
[axes.Z]
params = "z.lis"
start = 40.0
kv = 40.0
v_max = 500.0
a_max = 10000.0
v_rapid = 500.0
bus_delay_cycles = 1
resolution = 0.0001
[axes.X]
start = 0.0
[surface]
base = 20.0
features = [ { type = "step", axis = "X", at = 50.0, height = 2.8 } ]
[sensor]
axis = "Z"
kind = "encoder"
noise_std = 0.001
delay_cycles = 1
seed = 1
range_min = -5.0
range_max = 5.0
[[events]]
t = 1.0
plc = { axis = "Z", transition = "ON", position = 40.0 }
[[events]]
t = 0.5
override = { axis = "Z", value = 0.0 }
'''


def write(tmp_path: Path, text: str = EXAMPLE, lis: str = Z_LIS) -> Path:
    (tmp_path / "part.nc").write_text(PROGRAM)
    (tmp_path / "z.lis").write_text(lis)
    path = tmp_path / "scn.toml"
    path.write_text(text)
    return path


# --- the example -------------------------------------------------------------------------------------
def test_issue_example_loads(tmp_path):
    path = write(tmp_path)
    sc = load_scenario(path)
    assert isinstance(sc, Scenario)
    assert sc.path == path and sc.base_dir == tmp_path
    assert sc.name == "laser sheet"
    assert sc.cycle_time == 0.001 and sc.duration == 6.0 and sc.settle_time == 0.5 and sc.seed == 1
    assert sc.program_text == PROGRAM and sc.program_file == tmp_path / "part.nc"
    assert sc.variables == {"SENSOR": 0.0} and sc.tool_length == 0.0
    assert list(sc.axes) == ["X", "Z"]
    z = sc.axes["Z"]
    assert isinstance(z, AxisConfig)
    assert z.params_file == tmp_path / "z.lis"
    assert z.params.enabled is True and z.params.kp == 0.5 and z.params.n_cycles == 8
    assert (z.start, z.kv, z.v_max, z.a_max, z.v_rapid, z.a_rapid) == \
        (40.0, 40.0, 500.0, 10000.0, 500.0, 10000.0)
    assert z.bus_delay_cycles == 1 and z.resolution == 1e-4
    x = sc.axes["X"]
    assert x.params == AxisParameters() and x.params_file is None
    assert (x.start, x.kv, x.v_max, x.a_max, x.resolution) == (0.0, 40.0, 500.0, 10000.0, 1e-4)
    assert sc.surface.height(49.0) == 20.0 and sc.surface.height(50.0) == pytest.approx(22.8)
    assert sc.surface_config["base"] == 20.0
    assert sc.sensor == SensorConfig(axis="Z", kind="encoder", variable=None, noise_std=0.001, delay_cycles=1,
                                     seed=1, range_min=-5.0, range_max=5.0)
    # sorted by t
    assert [(e.t, e.kind) for e in sc.events] == [(0.5, "override"), (1.0, "plc")]
    assert sc.events[1].data == {"axis": "Z", "transition": 1, "position": 40.0}
    assert sc.events[1].index == 0
    assert sc.events[0].data == {"axis": "Z", "value": 0.0}


def test_example_builds_models(tmp_path):
    sc = load_scenario(write(tmp_path))
    sensor = sc.make_sensor()
    assert isinstance(sensor, EncoderProbe)
    assert (sensor.range_min, sensor.range_max) == (-5.0, 5.0)
    assert (sensor.noise_std, sensor.delay_cycles) == (0.001, 1)
    drives = sc.make_drives()
    assert set(drives) == {"X", "Z"} and all(isinstance(d, Drive) for d in drives.values())
    assert drives["Z"].position == 40.0 and drives["Z"].kv == 40.0
    assert sc.axis_limits()["Z"] == AxisLimits(500.0, 10000.0, 500.0, 10000.0)


def test_documented_example_loads(tmp_path):
    text = (ROOT / "docs" / "scenarios.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```toml\n(.*?)```", text, re.S)
    assert blocks, "docs/scenarios.md has a TOML example"
    sc = load_scenario(write(tmp_path, blocks[0]))
    assert sc.sensor is not None and sc.axes["Z"].params.kp == 0.5
    kinds = [e.kind for e in sc.events]
    assert kinds == ["plc", "sensor_fault", "override", "plc_cyclic", "plc"]
    # the second block is a distance-sensor table that replaces the first one
    distance = blocks[0].split("[sensor]")[0] + blocks[1] + "\n[[events]]\nt = 1.0\nreset = {}\n"
    sc2 = load_scenario(write(tmp_path, distance))
    assert sc2.sensor.kind == "distance" and sc2.sensor.variable == "GAP"
    assert isinstance(sc2.make_sensor(), DistanceSensor)


def test_docs_mention_every_key():
    text = (ROOT / "docs" / "scenarios.md").read_text(encoding="utf-8")
    for key in TOP_LEVEL_KEYS + AXIS_KEYS + SENSOR_KEYS + tuple(EVENT_KINDS) + ("length",):
        assert f"`{key}`" in text, key
    for keys, _ in EVENT_KINDS.values():
        for key in keys:
            assert f"`{key}`" in text, key


# --- from dict / text, defaults and normalisation ----------------------------------------------------
def test_minimal_dict_defaults():
    sc = scenario_from_dict({"program_text": "M30\n", "axes": {"Z": {}}})
    assert sc.path is None and sc.base_dir == Path(".") and sc.name == "scenario"
    assert sc.cycle_time == 0.001 and sc.duration is None and sc.settle_time == 0.5 and sc.seed == 0
    assert sc.program_file is None and sc.program_text == "M30\n"
    assert sc.variables == {} and sc.tool_length == 0.0
    z = sc.axes["Z"]
    assert z == AxisConfig("Z", AxisParameters(), None)
    assert z.v_rapid == z.v_max == 500.0 and z.a_rapid == z.a_max == 10000.0
    assert sc.surface.height(123.0, 4.0) == 0.0 and sc.surface_config == {}
    assert sc.sensor is None and sc.events == [] and sc.make_sensor() is None


def test_rapid_defaults_follow_v_max_a_max():
    sc = scenario_from_dict({"program_text": "", "axes": {"X": {"v_max": 100, "a_max": 2000}}})
    assert sc.axes["X"].v_rapid == 100.0 and sc.axes["X"].a_rapid == 2000.0


def test_from_text_and_relative_paths(tmp_path):
    (tmp_path / "p.nc").write_text("M30\n")
    sc = scenario_from_text('program = "p.nc"\n[axes.Z]\n', base_dir=tmp_path)
    assert sc.program_text == "M30\n" and sc.program_file == tmp_path / "p.nc"


def test_events_sorted_stably_and_normalised():
    events = [
        {"t": 2.0, "reset": {}},
        {"t": 1.0, "plc": {"axis": "Z", "transition": "on_const_dist", "position": 1}},
        {"t": 1.0, "plc": {"axis": "Z", "transition": 3}},
        {"t": 0.0, "override": {"value": 1.27}},
        {"t": 1.0, "feed_hold": {"axis": "Z"}},
        {"t": 3.0, "axis_error": {"axis": "Z"}},
        {"t": 3.0, "variable": {"name": "V.E.HEIGHT", "value": 2}},
        {"t": 3.0, "plc_cyclic": {"axis": "Z", "distance": 1}},
        {"t": 4.0, "sensor_fault": {"kind": "drift", "rate": 0.5, "duration_cycles": 10}},
    ]
    sc = scenario_from_dict({"program_text": "", "axes": {"Z": {}},
                             "sensor": {"axis": "Z", "kind": "distance"},
                             "events": events})
    assert [(e.t, e.kind, e.index) for e in sc.events] == [
        (0.0, "override", 3), (1.0, "plc", 1), (1.0, "plc", 2), (1.0, "feed_hold", 4), (2.0, "reset", 0),
        (3.0, "axis_error", 5), (3.0, "variable", 6), (3.0, "plc_cyclic", 7), (4.0, "sensor_fault", 8)]
    by_index = {e.index: e for e in sc.events}
    assert by_index[1].data == {"axis": "Z", "transition": int(HliTransition.ON_CONST_DIST), "position": 1.0}
    assert isinstance(by_index[1].data["position"], float)
    assert by_index[2].data == {"axis": "Z", "transition": 3, "position": 0.0}
    assert by_index[3].data == {"axis": None, "value": 1.27}
    assert by_index[4].data == {"axis": "Z", "value": True}
    assert by_index[6].data == {"name": "HEIGHT", "value": 2.0}
    assert by_index[7].data == {"axis": "Z", "distance": 1.0}
    assert by_index[8].data == {"kind": "drift", "rate": 0.5, "duration_cycles": 10}
    assert Fault(**by_index[8].data, start_time=by_index[8].t) == \
        Fault("drift", start_time=4.0, duration_cycles=10, rate=0.5)
    assert all(isinstance(e, Event) for e in sc.events)


def test_distance_sensor_config():
    sc = scenario_from_dict({
        "program_text": "", "seed": 7, "axes": {"Z": {}},
        "sensor": {"axis": "Z", "kind": "distance", "variable": "V.E.GAP", "range_max": 8,
                   "characteristic": [[0, 0], [5, 5.2], [8, 8]], "resolution": 0.001,
                   "faults": [{"kind": "freeze", "start_cycle": 10, "duration": 0.1}]}})
    s = sc.sensor
    assert s.kind == "distance" and s.variable == "GAP" and s.range_min is None and s.range_max == 8.0
    assert s.seed == 7  # the global seed
    assert s.characteristic == ((0.0, 0.0), (5.0, 5.2), (8.0, 8.0)) and s.resolution == 0.001
    assert s.faults == (Fault("freeze", start_cycle=10, duration=0.1),)
    sensor = sc.make_sensor()
    assert isinstance(sensor, DistanceSensor) and len(sensor.faults) == 1
    assert scenario_from_dict({"program_text": "", "axes": {"Z": {}},
                               "sensor": {"axis": "Z", "kind": "distance"}}).sensor.variable == "SENSOR"


def test_encoder_probe_uses_axis_list_resolution(tmp_path):
    lis = "lr_hw[1].encoder_resolution_num 10\nlr_hw[1].encoder_resolution_denom 1\n"
    sc = load_scenario(write(tmp_path, lis=lis))
    probe = sc.make_sensor()
    assert probe.resolution_num == 10 and probe.increments_per_mm == pytest.approx(1e5)


def test_param_list_warnings_kept(tmp_path):
    sc = load_scenario(write(tmp_path, lis=Z_LIS + "kenngr.distc.kp 0.7\n"))
    assert sc.axes["Z"].params.kp == 0.7
    assert len(sc.axes["Z"].params_warnings) == 1 and "z.lis:4" in sc.axes["Z"].params_warnings[0]


# --- validation: every rule names file, key path, value and what is allowed -----------------------------
def _replace(old: str, new: str):
    def edit(text: str) -> str:
        assert old in text, old
        return text.replace(old, new, 1)
    return edit


def _prepend(line: str):
    return lambda text: line + "\n" + text


def _append(block: str):
    return lambda text: text + block


BAD = [
    # id, edit, key, substrings of the message (besides file and key)
    ("unknown top-level key", _prepend("colour = 1"),
     "colour", ["unknown key", "cycle_time", "program_text"]),
    ("cycle_time too large", _replace("cycle_time = 0.001", "cycle_time = 1.0"), "cycle_time",
     ["1.0", "[0.0001, 0.1]"]),
    ("cycle_time not a number", _replace("cycle_time = 0.001", 'cycle_time = "1ms"'), "cycle_time",
     ["'1ms'", "finite number"]),
    ("unknown axis name", _replace("[axes.X]", "[axes.W]"), "axes.W", ["'W'", "X, Y, Z, A, B, C"]),
    ("unknown axis key", _replace("kv = 40.0", "kv = 40.0\ngain = 2"), "axes.Z.gain",
     ["'gain'", "params", "bus_delay_cycles"]),
    ("kv*T >= 1", _replace("kv = 40.0", "kv = 1000.0"),
     "axes.Z.kv", ["1000.0", "kv * cycle_time < 1", "(0, 1000)"]),
    ("default kv*T >= 1", _replace("cycle_time = 0.001", "cycle_time = 0.05"), "axes.X.kv",
     ["40.0", "kv * cycle_time < 1", "default"]),
    ("negative kv", _replace("kv = 40.0", "kv = -1"), "axes.Z.kv", ["-1", "(0, 1000)"]),
    ("v_max zero", _replace("v_max = 500.0", "v_max = 0"), "axes.Z.v_max", ["0", "(0, inf)"]),
    ("bus delay not an integer", _replace("bus_delay_cycles = 1", "bus_delay_cycles = 1.5"),
     "axes.Z.bus_delay_cycles", ["1.5", "integer"]),
    ("negative resolution", _replace("resolution = 0.0001", "resolution = -1e-4"), "axes.Z.resolution",
     ["-0.0001", "[0, inf)"]),
    ("missing params file", _replace('params = "z.lis"', 'params = "nope.lis"'), "axes.Z.params",
     ["'nope.lis'", "not found", "parameter list"]),
    ("no axes", lambda t: t.replace("[axes.Z]", "[zz]").replace("[axes.X]", "[yy]"), "zz",
     ["unknown key", "axes"]),
    ("negative noise", _replace("noise_std = 0.001", "noise_std = -0.1"),
     "sensor.noise_std", ["-0.1", "[0, inf)"]),
    ("sensor axis not among axes", _replace('axis = "Z"\nkind', 'axis = "Y"\nkind'), "sensor.axis",
     ["'Y'", "configured axes", "'X', 'Z'"]),
    ("sensor kind", _replace('kind = "encoder"', 'kind = "laser"'),
     "sensor.kind", ["'laser'", "'encoder', 'distance'"]),
    ("sensor unknown key", _replace("seed = 1\nrange_min", "gain = 1\nrange_min"), "sensor.gain",
     ["'gain'", "noise_std", "characteristic"]),
    ("variable for encoder", _replace('kind = "encoder"', 'kind = "encoder"\nvariable = "S"'),
     "sensor.variable", ["'S'", "only with kind = 'distance'"]),
    ("range_max below range_min", _replace("range_max = 5.0", "range_max = -6.0"), "sensor.range_max",
     ["-6.0", "(-5, inf)"]),
    ("negative delay", _replace("\ndelay_cycles = 1", "\ndelay_cycles = -1"),
     "sensor.delay_cycles", ["-1", "[0, 100000]"]),
    ("both program and program_text", _prepend('program_text = "M30"'), "program_text",
     ["exactly one of 'program'", "'program_text'"]),
    ("neither program nor program_text", _replace('program = "part.nc"\n', ""), "program",
     ["missing", "exactly one of 'program'"]),
    ("missing program file", _replace('program = "part.nc"', 'program = "nope.nc"'), "program",
     ["'nope.nc'", "not found", "NC program file"]),
    ("duration zero", _replace("duration = 6.0", "duration = 0"), "duration", ["0", "(0, inf)"]),
    ("negative settle_time", _replace("settle_time = 0.5", "settle_time = -1"),
     "settle_time", ["-1", "[0, inf)"]),
    ("negative seed", _replace("seed = 1\n[variables]", "seed = -1\n[variables]"),
     "seed", ["-1", "[0, inf)"]),
    ("bad variable name", _replace("SENSOR = 0.0", '"1X" = 0.0'),
     "variables.1X", ["'1X'", "V.E. variable name"]),
    ("variable not a number", _replace("SENSOR = 0.0", 'SENSOR = "a"'),
     "variables.SENSOR", ["'a'", "number"]),
    ("unknown tool key", _replace("length = 0.0", "radius = 1.0"), "tool.radius", ["'radius'", "length"]),
    ("surface feature", _replace("height = 2.8", 'height = "x"'), "surface.features[0].height",
     ["'x'", "finite number"]),
    ("unknown event action", _replace("plc = {", "plcx = {"), "events[0].plcx",
     ["'plcx'", "plc, override, feed_hold, reset, axis_error, axis_release, sensor_fault, variable, plc_cyclic"]),
    ("two actions in one event", _replace("t = 1.0\n", "t = 1.0\nreset = {}\n"), "events[0]",
     ["more than one action", "exactly one action key", "'reset'"]),
    ("no action", _append("[[events]]\nt = 2.0\n"), "events[2]", ["missing", "exactly one action key"]),
    ("event without t", _append("[[events]]\nreset = {}\n"), "events[2].t", ["missing"]),
    ("negative t", _replace("t = 1.0", "t = -1.0"), "events[0].t", ["-1.0", "[0, 6]"]),
    ("t after duration", _replace("t = 1.0", "t = 7.0"), "events[0].t", ["7.0", "[0, 6]"]),
    ("unknown transition name", _replace('transition = "ON"', 'transition = "ONN"'),
     "events[0].plc.transition",
     ["'ONN'", "OFF (0)", "ON_CONST_DIST (4)", "CONST_DIST (6)", "0..6"]),
    ("transition number 7", _replace('transition = "ON"', "transition = 7"), "events[0].plc.transition",
     ["out of range", "7", "0..6"]),
    ("transition 1.5", _replace('transition = "ON"', "transition = 1.5"), "events[0].plc.transition",
     ["1.5", "0..6"]),
    ("plc axis not configured", _replace('plc = { axis = "Z"', 'plc = { axis = "Y"'), "events[0].plc.axis",
     ["'Y'", "'X', 'Z'"]),
    ("plc unknown key", _replace("position = 40.0 }", "pos = 40.0 }"), "events[0].plc.pos",
     ["'pos'", "axis, transition, position"]),
    ("plc missing transition", _replace('transition = "ON", ', ""), "events[0].plc.transition", ["missing"]),
    ("override > 1 for an axis", _replace("value = 0.0 }", "value = 1.1 }"), "events[1].override.value",
     ["1.1", "axis feed override", "[0, 1]"]),
    ("channel override > 1.27",
     _replace('override = { axis = "Z", value = 0.0 }', "override = { value = 1.3 }"),
     "events[1].override.value", ["1.3", "channel path override", "[0, 1.27]"]),
    ("feed_hold not bool", _append('[[events]]\nt = 2.0\nfeed_hold = { axis = "Z", value = "yes" }\n'),
     "events[2].feed_hold.value", ["'yes'", "true or false"]),
    ("reset with a key", _append("[[events]]\nt = 2.0\nreset = { now = true }\n"), "events[2].reset.now",
     ["'now'", "unknown key"]),
    ("sensor_fault kind", _append('[[events]]\nt = 2.0\nsensor_fault = { kind = "boom" }\n'),
     "events[2].sensor_fault.kind", ["'boom'", "'jump'", "'noise_burst'"]),
    ("sensor_fault jump without value", _append('[[events]]\nt = 2.0\nsensor_fault = { kind = "jump" }\n'),
     "events[2].sensor_fault.value", ["missing", "jump height"]),
    ("sensor_fault negative duration",
     _append('[[events]]\nt = 2.0\nsensor_fault = { kind = "freeze", duration = -1 }\n'),
     "events[2].sensor_fault.duration", ["-1", "[0, inf)"]),
    ("sensor_fault start key",
     _append('[[events]]\nt = 2.0\nsensor_fault = { kind = "freeze", start_time = 1 }\n'),
     "events[2].sensor_fault.start_time", ["unknown key", "duration_cycles"]),
    ("variable event bad name", _append('[[events]]\nt = 2.0\nvariable = { name = "a b", value = 1 }\n'),
     "events[2].variable.name", ["'a b'", "V.E. variable name"]),
    ("plc_cyclic both",
     _append('[[events]]\nt = 2.0\nplc_cyclic = { axis = "Z", position = 1, distance = 2 }\n'),
     "events[2].plc_cyclic", ["both position and distance", "exactly one of 'position'"]),
    ("plc_cyclic neither", _append('[[events]]\nt = 2.0\nplc_cyclic = { axis = "Z" }\n'),
     "events[2].plc_cyclic", ["neither", "exactly one of 'position'"]),
    ("sensor fault list without start",
     _replace("range_max = 5.0", 'range_max = 5.0\nfaults = [{ kind = "nan" }]'),
     "sensor.faults[0].start_time", ["missing", "start_cycle"]),
]


@pytest.mark.parametrize("edit, key, parts", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_validation_error_names_file_key_value_and_allowed(tmp_path, edit, key, parts):
    path = write(tmp_path, edit(EXAMPLE))
    with pytest.raises(ConfigError) as info:
        load_scenario(path)
    err = info.value
    msg = str(err)
    assert isinstance(err, ScenarioError) and isinstance(err, DistCtrlError)
    assert err.file == str(path)
    assert msg.startswith(f"{path}: {key}: "), msg
    assert err.key == key
    assert "allowed:" in msg or "required:" in msg, msg
    for part in parts:
        assert part in msg, (part, msg)


def test_sensor_fault_event_needs_a_sensor():
    with pytest.raises(ConfigError, match=r"^<dict>: events\[0\]\.sensor_fault: .*\[sensor\]"):
        scenario_from_dict({"program_text": "", "axes": {"Z": {}},
                            "events": [{"t": 0, "sensor_fault": {"kind": "nan"}}]})


def test_empty_axes_table():
    with pytest.raises(ConfigError, match=r"^<string>: axes: empty: \{\}; allowed: at least one axis"):
        scenario_from_text('program_text = ""\n[axes]\n')


def test_missing_axes():
    with pytest.raises(ConfigError, match=r"^<dict>: axes: missing; required: at least one axis"):
        scenario_from_dict({"program_text": ""})


def test_characteristic_checked():
    with pytest.raises(ConfigError, match=r"^<dict>: sensor\.characteristic: .*strictly increasing"):
        scenario_from_dict({"program_text": "", "axes": {"Z": {}},
                            "sensor": {"axis": "Z", "kind": "distance", "characteristic": [[0, 0], [0, 1]]}})


def test_not_a_table_at_top():
    with pytest.raises(ConfigError, match=r"^src: scenario: not a table"):
        scenario_from_dict([1, 2], source="src")  # type: ignore[arg-type]


def test_bad_toml_syntax_names_line(tmp_path):
    path = write(tmp_path, EXAMPLE.replace("seed = 1\n[variables]", "seed = 1\n[variables]\nA B = 1"))
    line = EXAMPLE.splitlines().index("[variables]") + 2
    with pytest.raises(ConfigError) as info:
        load_scenario(path)
    err = info.value
    assert err.line == line
    assert str(err).startswith(f"{path}:{line}: toml: syntax error"), str(err)
    assert "valid TOML" in str(err)


def test_bad_toml_text_source():
    with pytest.raises(ConfigError, match=r"^<string>:2: toml: syntax error"):
        scenario_from_text('program_text = ""\n[axes\n')


def test_missing_scenario_file(tmp_path):
    with pytest.raises(ConfigError, match=r"cannot read .*readable TOML scenario file"):
        load_scenario(tmp_path / "none.toml")


def test_parameter_error_keeps_file_and_line(tmp_path):
    lis = "lr_param.distance_control_on 1\nkenngr.distc.kp 0.5\nkenngr.distc.kpp 0.5\n"
    path = write(tmp_path, lis=lis)
    with pytest.raises(ParameterError) as info:
        load_scenario(path)
    err = info.value
    assert isinstance(err, DistCtrlError)
    msg = str(err)
    assert msg.startswith(f"{tmp_path / 'z.lis'}:3: "), msg
    assert "kenngr.distc.kpp" in msg and f"axes.Z.params in {path}" in msg
    assert err.file == str(tmp_path / "z.lis") and err.line == 3


def test_parameter_range_error_keeps_file_and_line(tmp_path):
    path = write(tmp_path, lis="kenngr.distc.kp 5\n")
    with pytest.raises(ParameterError, match=r"z\.lis:1: kenngr\.distc\.kp .*out of range"):
        load_scenario(path)


def test_sensor_fault_event_data_is_normalised():
    fault = {"kind": "jump", "value": 3, "duration": 1}
    sc = scenario_from_dict({"program_text": "", "axes": {"Z": {}},
                             "sensor": {"axis": "Z", "kind": "encoder"},
                             "events": [{"t": 1, "sensor_fault": fault}]})
    (ev,) = sc.events
    assert ev.t == 1.0 and ev.data == {"kind": "jump", "value": 3.0, "duration": 1.0}
    assert all(isinstance(v, float) for k, v in ev.data.items() if k != "kind")
    probe = sc.make_sensor()
    probe.inject(Fault(**ev.data), at_cycle=1000)
    assert probe.faults[0].end == 2000


# issue 30 (bench/stress.py scenario campaign): a dead time of 1e300 or 2**63-1 cycles passed the
# validation (an integer >= 0) and the run ended in OverflowError / MemoryError while it allocated
# the delay line; both keys now have an upper bound and say so
@pytest.mark.parametrize("section, key, value", [
    ("axes", {"Z": {"bus_delay_cycles": 1e300}}, "axes.Z.bus_delay_cycles"),
    ("axes", {"Z": {"bus_delay_cycles": 2**63 - 1}}, "axes.Z.bus_delay_cycles"),
    ("sensor", {"axis": "Z", "kind": "encoder", "delay_cycles": 2**63 - 1}, "sensor.delay_cycles"),
    ("sensor", {"axis": "Z", "kind": "distance", "variable": "SENSOR", "delay_cycles": 10**6}, "sensor.delay_cycles"),
], ids=["bus-1e300", "bus-2**63", "encoder-2**63", "distance-1e6"])
def test_delay_lines_have_an_upper_bound(section, key, value):
    data = {"program_text": "M30\n", "axes": {"Z": {}}, "variables": {"SENSOR": 1.0}, section: key}
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(data, source="s.toml")
    assert info.value.key == value and "out of range" in str(info.value) and "100000" in str(info.value)


def test_delay_lines_up_to_the_bound_run():
    from distctrl.sim.runner import run

    sc = scenario_from_dict({"program_text": "M30\n", "duration": 0.01, "axes": {"Z": {"bus_delay_cycles": 100_000}},
                             "sensor": {"axis": "Z", "kind": "encoder", "delay_cycles": 100_000}})
    assert run(sc, keep_trace=False).cycles > 0


# issue 30 (bench/stress_atheris.py scenario, not found by the generated campaign): a referenced file
# whose name is too long for the OS made Path.is_file raise OSError (ENAMETOOLONG) out of the loader
@pytest.mark.parametrize("key, data", [
    ("axes.Z.params", {"axes": {"Z": {"params": "z_l" + "\ufffd" * 300 + "aser.lis"}}}),
    ("program", {"program": "p" * 5000 + ".nc", "axes": {"Z": {}}}),
])
def test_a_file_name_too_long_is_the_scenarios_error(key, data):
    data = {"program_text": "M30\n", **data} if "program" not in data else data
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(data, source="s.toml")
    assert info.value.key == key and "s.toml" in str(info.value), str(info.value)
