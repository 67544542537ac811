"""The remaining 3D errors, each produced by a test program on the 5-axis machine."""
from __future__ import annotations

from .test_run3d import KIN98, SELECT, channel_list, head_scenario, only_error, run

TRAFO = KIN98 + "#KIN ID[9.98]\n#TRAFO ON\n"


def test_310018_sensor_jump_while_active(tmp_path):
    sc = head_scenario(TRAFO + SELECT + "#TIME 3\nM30\n", channel=channel_list(tmp_path, max_act_value_change=100000),
                       events=[{"t": 1.0, "sensor_fault": {"kind": "jump", "value": 3.0}}])
    err = only_error(run(sc))
    assert err["id"] == 310018 and 1.0 <= err["t"] < 1.1


def test_310019_sensor_run_out_while_active(tmp_path):
    # the sensor window is -100..100 mm (s = -d); the distance jumps from 80 to 105 mm
    sc = head_scenario(TRAFO + SELECT + "#TIME 3\nM30\n",
                       channel=channel_list(tmp_path, min_pos=-1000000, max_pos=1000000,
                                            max_act_value_change=100000000),
                       events=[{"t": 1.0, "sensor_fault": {"kind": "jump", "value": 25.0}}])
    err = only_error(run(sc))
    assert err["id"] == 310019


def test_310022_axis_released_while_active():
    sc = head_scenario(TRAFO + SELECT + "#TIME 2\nM30\n", events=[{"t": 1.0, "axis_release": {"axis": "Z"}}])
    err = only_error(run(sc))
    assert err["id"] == 310022


def test_310023_select_while_turning_off():
    sc = head_scenario(TRAFO + SELECT + "#DIST CTRL OFF\n"
                       "#DIST CTRL ON [CONST_DIST SET_DIST=80 MODE=MCS SENSOR_VAR=V.E.SENSOR]\nM30\n", surface=-3.0)
    err = only_error(run(sc))
    assert err["id"] == 310023 and err["line"] == 10


def test_310028_sensor_variable_changed_while_active():
    sc = head_scenario(TRAFO + SELECT + "#DIST CTRL [SENSOR_VAR=V.E.OTHER]\nM30\n")
    err = only_error(run(sc))
    assert err["id"] == 310028 and err["line"] == 9


def test_900024_set_distance_other_than_the_tool_length_with_a_transformation():
    """FCT-M3 §12.1.2: 'Tool length = set distance' with a kinematic transformation. SET_DIST=60 with
    V.G.WZ_AKT.L = 80 and #TRAFO ON warns 900024 at the select's line; the run goes on. After the tool
    length is set to 60 (the transformation is re-planned) the same select is silent."""
    select = "#DIST CTRL WAIT ON [CONST_DIST SET_DIST=60 MODE=MCS SENSOR_VAR=V.E.SENSOR]\n"
    r = run(head_scenario(TRAFO + select + "#DIST CTRL WAIT OFF\nM30\n"))
    assert r.completed and r.errors == []
    assert [(w["id"], w["line"]) for w in r.warnings] == [(900024, 8)]
    assert "SET_DIST 60 mm, tool length 80 mm" in r.warnings[0]["message"]
    same = KIN98.replace("V.G.WZ_AKT.L = 80", "V.G.WZ_AKT.L = 60")
    r = run(head_scenario(same + "#KIN ID[9.98]\n#TRAFO ON\n" + select + "#DIST CTRL WAIT OFF\nM30\n"))
    assert r.completed and r.errors == [] and r.warnings == []
