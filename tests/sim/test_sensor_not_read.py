"""A sensor that nobody reads is reported (issue 13): a distance sensor writes V.E.GAP, the axis still
reads the second encoder (no SENSOR_SOURCE=VARIABLE) → warning 900031 at the select, naming
SENSOR_SOURCE and the variable, before 70331 ends it."""
from __future__ import annotations

from distctrl.sim.runner import run

from .test_run import base_scenario

GAP = {"axis": "Z", "kind": "distance", "variable": "GAP", "range_max": 5.0}


def test_a_select_that_keeps_reading_the_second_encoder_warns_900031():
    r = run(base_scenario("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=1.5]\nN20 #TIME 0.5\nN30 Z[DIST_CTRL OFF]\n"
                          "N40 M30\n", start_z=41.0, surface={"base": 40.0}, sensor=GAP))
    hint = [w for w in r.warnings if w["id"] == 900031]
    assert len(hint) == 1 and hint[0]["line"] == 1
    assert "V.E.GAP" in hint[0]["message"] and "SENSOR_SOURCE=VARIABLE" in hint[0]["message"]
    assert "SENSOR_SOURCE=SECOND_ENCODER" in hint[0]["message"] or "SENSOR_SOURCE=DEFAULT" in hint[0]["message"]
    # the hint comes first: then the loop runs into the documents' error
    assert any(e["id"] == 70331 for e in r.errors) and hint[0]["t"] <= r.errors[0]["t"]


def test_no_hint_when_the_variable_is_read():
    r = run(base_scenario("N10 Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.GAP]\n"
                          "N20 Z[DIST_CTRL ON CONST_DIST SET_DIST=1.5]\nN30 #TIME 0.5\nN40 Z[DIST_CTRL OFF]\n"
                          "N50 M30\n", start_z=41.0, surface={"base": 40.0}, sensor=GAP))
    assert r.errors == [] and not [w for w in r.warnings if w["id"] == 900031]
