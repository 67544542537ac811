"""The 3D error catalogue against FCT-M3 §12.7 / §12.8.2 and SPEC §7."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from distctrl.base.states import InternalState
from distctrl.errors import CATALOGUE, ErrorEvent, ErrorId, make_event
from distctrl.errors.three_d import (AXIS_TO_3D, CATALOGUE_3D, ERROR_CODE_BY_ID_3D, THREE_D_TO_AXIS, event_to_3d,
                               make_event_3d, render, severity_and_text, to_3d_id)

ROOT = Path(__file__).resolve().parents[2]

# FCT-M3 §12.7, verbatim: (axis ID or None, 3D ID, text)
DOCUMENT_127 = [
    (70329, 310018, "Actual value change of sensor signal greater than limit"),
    (70330, 310019, "Sensor completely run out"),
    (70331, 310017, "Excessive sensing deviation"),
    (70332, 310021, "Distance control still active at program end"),
    (70333, 310022, "Distance control active for axis that is to be specified."),
    (70334, 310023, "On repeat selection, deselection of distance control not yet complete"),
    (70335, 310026, "Distance control selected without programmed position"),
    (70336, 310015, "Function is not available"),
    (None, 310027, "Distance control turned on without valid sensor variable"),
    (None, 310028, "Change of sensor source while distance control is active not allowed"),
    (None, 51061, "3D distance control not configured"),
    (None, 51062, "Initialization of axis positions during active distance control not allowed."),
    (None, 51064, "Mode setting only allowed when 3D distance control is inactive."),
    (None, 20209, "Unknown Nc-command"),                     # §12.7 notice
]

# SPEC §7's pairs (axis / 3D)
SPEC_7_PAIRS = {70329: 310018, 70330: 310019, 70331: 310017, 70332: 310021, 70333: 310022, 70334: 310023,
                70335: 310026, 70336: 310015}


def test_every_documented_3d_id_is_present_with_its_text():
    for _axis, eid, text in DOCUMENT_127:
        assert eid in CATALOGUE_3D, eid
        assert CATALOGUE_3D[eid].text == text, eid
        assert CATALOGUE_3D[eid].when and CATALOGUE_3D[eid].source


def test_the_other_ids_are_present():
    assert 315001 in CATALOGUE_3D and "P-CHAN-00803" in CATALOGUE_3D[315001].when
    assert CATALOGUE_3D[315001].severity == "error"
    # 900020 is referenced from distctrl.errors, not redefined
    e = CATALOGUE_3D[int(ErrorId.KIN98_MAX_INCLINATION)]
    assert e.id == 900020 and (e.severity, e.text) == CATALOGUE[900020]
    assert set(CATALOGUE_3D) == {eid for _, eid, _ in DOCUMENT_127} | {315001, 900020, 900023, 900024}
    for eid in (900023, 900024):                     # warnings of the project range, from distctrl.errors
        assert (CATALOGUE_3D[eid].severity, CATALOGUE_3D[eid].text) == CATALOGUE[eid]


def test_severities():
    warnings = {310021, 900023, 900024}                                   # 310021 like 70332
    assert all(CATALOGUE_3D[eid].severity == "warning" for eid in warnings)
    assert all(e.severity == "error" for e in CATALOGUE_3D.values() if e.id not in warnings)
    for axis, three_d in SPEC_7_PAIRS.items():
        assert CATALOGUE_3D[three_d].severity == CATALOGUE[axis][0]


def test_axis_to_3d_pairs_per_spec_7():
    for axis, three_d in SPEC_7_PAIRS.items():
        assert AXIS_TO_3D[axis] == three_d
        assert CATALOGUE_3D[three_d].axis_id == axis
    for axis, three_d, _ in DOCUMENT_127:
        if axis is not None:
            assert AXIS_TO_3D[axis] == three_d
    # the project's pairings: the lower run-out limit and the sensor source change
    assert AXIS_TO_3D[70576] == 310019 and AXIS_TO_3D[int(ErrorId.SENSOR_SOURCE_CHANGED)] == 310028
    assert set(AXIS_TO_3D) == set(SPEC_7_PAIRS) | {70576, 900004}
    assert THREE_D_TO_AXIS[310019] == 70330 and THREE_D_TO_AXIS[310015] == 70336


def test_to_3d_id():
    assert to_3d_id(70331) == 310017 and to_3d_id(310017) == 310017
    assert to_3d_id(900001) == 900001 and to_3d_id(900020) == 900020      # shared project IDs
    with pytest.raises(KeyError):
        to_3d_id(12345)


def test_internal_error_codes_follow_the_axis_partner():
    assert ERROR_CODE_BY_ID_3D[310018] == InternalState.ERROR_SENSOR_JUMP
    assert ERROR_CODE_BY_ID_3D[310019] == InternalState.ERROR_SENSOR_MAX
    assert ERROR_CODE_BY_ID_3D[310017] == InternalState.ERROR_MAX_DEVIATION
    assert ERROR_CODE_BY_ID_3D[310026] == InternalState.ERROR_NO_SET_VALUE
    assert ERROR_CODE_BY_ID_3D[310028] == InternalState.ERROR_COMMAND


def test_make_event_3d():
    ev = make_event_3d(310019, 120, 35, "reading 5.2 mm above max_pos - tolerance")
    assert isinstance(ev, ErrorEvent)
    assert (ev.id, ev.cycle, ev.line, ev.severity) == (310019, 120, 35, "error")
    assert ev.message == "Sensor completely run out: reading 5.2 mm above max_pos - tolerance"
    assert "310019" in str(ev) and "NC line 35" in str(ev)
    warn = make_event_3d(310021, 7, None)
    assert warn.severity == "warning" and warn.message == "Distance control still active at program end"
    assert make_event_3d(315001, 0, 3, severity="warning").severity == "warning"
    assert make_event_3d(900020, 5, 40).message == CATALOGUE[900020][1]
    assert make_event_3d(900003, 5, 40).id == 900003                        # shared project range
    with pytest.raises(KeyError, match="310018"):
        make_event_3d(70329, 0, None)                                      # axis ID: use AXIS_TO_3D
    with pytest.raises(KeyError):
        make_event_3d(4711, 0, None)
    assert severity_and_text(51062) == ("error", CATALOGUE_3D[51062].text)


def test_event_to_3d_keeps_cycle_line_and_detail():
    core = make_event(70576, 88, 12, "s = -4.9 mm below min_pos + tolerance")
    ev = event_to_3d(core)
    assert (ev.id, ev.cycle, ev.line, ev.severity) == (310019, 88, 12, "error")
    assert ev.message == "Sensor completely run out: s = -4.9 mm below min_pos + tolerance"
    assert event_to_3d(make_event(70332, 3, None)).severity == "warning"
    plain = event_to_3d(make_event(70335, 1, 9))
    assert plain.message == "Distance control selected without programmed position" and plain.id == 310026
    shared = make_event(900005, 2, 4, "KP=3")
    assert event_to_3d(shared) is shared


def test_docs_errors_3d_md_is_generated():
    generated = subprocess.run([sys.executable, "-m", "distctrl.errors.three_d"], capture_output=True, text=True,
                               cwd=ROOT, check=True).stdout
    assert generated == render()
    assert (ROOT / "docs" / "errors-3d.md").read_text(encoding="utf-8") == generated
    for e in CATALOGUE_3D.values():
        assert f"| {e.id} | {e.severity} | {e.text} | {e.when} |" in generated
