"""The external-variable list that declares the sensor variable (FCT-M3 §12.8.4)."""
from __future__ import annotations

from pathlib import Path

import pytest

from distctrl.errors import ParameterError
from distctrl.params.external_variables import (ExternalVariable, load_external_variables,
                                                parse_external_variables)
from distctrl.sim.runner import run
from distctrl.sim.scenario import ScenarioError, scenario_from_dict

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "external_variables_12_8_4.lis"
SCN = ROOT / "examples" / "scenarios"


def test_the_example_of_12_8_4_loads_with_its_values():
    assert load_external_variables(EXAMPLE) == {
        "SENSOR": ExternalVariable("SENSOR", "REAL64", "CHANNEL", True, "READ_ONLY", line=5)}


def test_several_variables_defaults_and_the_v_e_prefix():
    got = parse_external_variables("number_used_variables 2\nvar[1].name V.E.HEIGHT\nvar[0].name SENSOR\n"
                                   "var[1].type sgn32\nvar[1].synchronisation 0\n")
    assert list(got) == ["SENSOR", "HEIGHT"]
    assert got["SENSOR"] == ExternalVariable("SENSOR", line=3)
    assert (got["HEIGHT"].type, got["HEIGHT"].synchronisation) == ("SGN32", False)


@pytest.mark.parametrize("text, line, words", [
    ("var[0].name SENSOR\n", None, ["number_used_variables is missing"]),
    ("number_used_variables -1\n", 1, ["0 ... 10000"]),
    ("number_used_variables 1\nvar[0].nmae SENSOR\n", 2, ["unknown key 'var[0].nmae'", "var[i].name"]),
    ("number_used_variables 1\nvar[0].name 1SENSOR\n", 2, ["not a variable name"]),
    ("number_used_variables 1\nvar[0].name SENSOR\nvar[0].type STRING\n", 3, ["REAL64", "allowed"]),
    ("number_used_variables 1\nvar[0].name SENSOR\nvar[0].scope AXIS\n", 3, ["CHANNEL, GLOBAL"]),
    ("number_used_variables 1\nvar[0].name SENSOR\nvar[0].access_rights ALL\n", 3, ["READ_ONLY, READ_WRITE"]),
    ("number_used_variables 1\nvar[0].name SENSOR\nvar[0].synchronisation YES\n", 3, ["TRUE, FALSE"]),
    ("number_used_variables 1\nvar[0].name\n", 2, ["missing value"]),
    ("number_used_variables 1\nvar[0].name A B\n", 2, ["unexpected text"]),
    ("number_used_variables 1\nvar[1].name SENSOR\n", 2, ["beyond number_used_variables 1"]),
    ("number_used_variables 2\nvar[0].name SENSOR\n", 1, ["var[1] is not declared"]),
    ("number_used_variables 2\nvar[0].name SENSOR\nvar[1].name SENSOR\n", 3, ["declared twice (line 2)"]),
    ("number_used_variables 1\nvar[0].type REAL64\n", 2, ["var[0].name is missing"]),
])
def test_every_error_names_file_line_key_and_what_is_allowed(text, line, words):
    with pytest.raises(ParameterError) as exc:
        parse_external_variables(text, "extv.lis")
    assert exc.value.file == "extv.lis" and exc.value.line == line
    assert str(exc.value).startswith(f"extv.lis:{line}: " if line else "extv.lis: ")
    for w in words:
        assert w in str(exc.value)


def test_an_unreadable_list_names_the_file(tmp_path):
    with pytest.raises(ParameterError) as exc:
        load_external_variables(tmp_path / "missing.lis")
    assert "missing.lis" in str(exc.value)


def _scenario(extra: dict, program: str = "N10 M30\n") -> dict:
    return {"name": "t", "program_text": program, "duration": 0.05, "axes": {"X": {}, "Z": {"start": 10.0}},
            "external_variables": str(EXAMPLE), **extra}


def test_a_scenario_declares_its_variables_through_the_list():
    sc = scenario_from_dict(_scenario({}))
    assert sc.external_variables == load_external_variables(EXAMPLE)
    assert sc.variables == {"SENSOR": 0.0}


@pytest.mark.parametrize("extra, key", [
    ({"variables": {"HEIGHT": 1.0}}, "variables.HEIGHT"),
    ({"sensor": {"axis": "Z", "kind": "distance", "variable": "GAP"}, "surface": {"base": 0.0}}, "sensor.variable"),
    ({"events": [{"t": 0.01, "variable": {"name": "GAP", "value": 1.0}}]}, "events[0].name"),
])
def test_with_a_list_every_v_e_name_of_the_scenario_must_be_declared(extra, key):
    with pytest.raises(ScenarioError) as exc:
        scenario_from_dict(_scenario(extra))
    assert exc.value.key == key and "external_variables_12_8_4.lis (SENSOR)" in str(exc.value)


def test_list_errors_in_a_scenario_keep_file_line_and_key(tmp_path):
    bad = tmp_path / "bad.lis"
    bad.write_text("number_used_variables 1\nvar[0].name SENSOR\nvar[0].type TEXT\n")
    with pytest.raises(ParameterError) as exc:
        scenario_from_dict(_scenario({"external_variables": str(bad)}))
    assert f"{bad}:3" in str(exc.value) and "external_variables" in str(exc.value)


def test_an_undeclared_sensor_var_in_the_program_is_310027():
    """PROG #DIST CTRL example 1 on its scenario, with the SENSOR_VAR changed to a name the list does
    not declare: 'Distance control turned on without valid sensor variable' at the select."""
    ok = run(SCN / "dist3d_1.toml")
    assert ok.completed and ok.errors == []
    text = (ROOT / "examples" / "dist3d_1.nc").read_text().replace("SENSOR_VAR=V.E.SENSOR", "SENSOR_VAR=V.E.GAP")
    data = {"name": "t", "program_text": text, "duration": 2.0, "external_variables": str(EXAMPLE),
            "channel": {"params": str(ROOT / "examples" / "channel_3d_12_8_3.lis"), "kinematics": "none"},
            "axes": {"X": {}, "Y": {}, "Z": {"start": 10.0}}, "surface": {"base": 8.8},
            "sensor": {"kind": "distance", "mode": "orthogonal_clamping_point", "variable": "SENSOR",
                       "range_max": 150.0}}
    r = run(scenario_from_dict(data))
    assert [e["id"] for e in r.errors] == [310027] and "V.E.GAP" in r.errors[0]["message"]
