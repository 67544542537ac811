"""DIST_CTRL::sensor_value (FCT-M3 §9.4, 0x3113, SGN64 in 0.01 nm): the return value of the sensor.

The value is tied to what the sensor delivers, not to the controller field it is published from:
raw encoder-2 increments scaled by P-AXIS-00422/00423 (num increments per denom x 0.1 µm), sign
reversed by P-AXIS-00230, shifted by P-AXIS-00418 ref_offset (SPEC §2), in 0.01 nm = 1e-8 mm.
"""
from __future__ import annotations

import pytest

from distctrl.control import Action, AxisDistanceController, Command, CycleInput, CycleOutput
from distctrl.objects import BY_NAME, AxisObjectContext, read_bytes, read_value
from distctrl.params import AxisParameters

SENSOR_VALUE = BY_NAME["DIST_CTRL::sensor_value"]


def read_sensor_value(changes: dict, increments: list[float], command=None) -> list[int]:
    """Feed the raw increments cycle by cycle; the object read after each cycle."""
    kw = dict(enabled=True, v_max=20.0, a_max=2000.0, max_act_value_change=1e5, max_pos=50.0, min_pos=-50.0,
              optimized_scheduling=True)
    kw.update(changes)
    ctrl = AxisDistanceController(AxisParameters(**kw), 0.001)
    inp, out = CycleInput(), CycleOutput()
    values = []
    for k, incr in enumerate(increments):
        inp.programmed_position = inp.actual_position = 40.0
        inp.sensor_increments = incr
        if k == 0 and command is not None:
            inp.commands.append(command)
        ctrl.update(inp, out)
        values.append(read_value(SENSOR_VALUE, AxisObjectContext(1, "Z", ctrl, out)))
    return values


def test_sensor_value_is_the_encoder_reading_in_0_01_nm():
    """1 increment = 0.1 µm (P-AXIS-00422/00423 = 1/1): 12345 increments are 1.2345 mm = 123450000 x
    0.01 nm, whatever the controller does (inactive, then tracking)."""
    increments = [12345, 12345, -2500, 7, 0]
    assert read_sensor_value({}, increments) == [i * 10_000 for i in increments]
    assert read_sensor_value({}, increments, Command(Action.ON, set_pos=40.0)) == [i * 10_000 for i in increments]


@pytest.mark.parametrize("num, denom, sign, ref_offset_01um, incr, expected_mm", [
    (4, 1, False, 0, 1000, 0.025),          # 4 increments per 0.1 µm: 1000 incr = 25 µm
    (1, 5, False, 0, 1000, 0.5),            # 1 increment per 0.5 µm
    (1, 1, True, 0, 1000, -0.1),            # P-AXIS-00230: the sign is reversed
    (1, 1, False, 20000, 1000, 2.1),        # P-AXIS-00418: shifted by 2 mm
    (2, 3, True, -5000, 4000, -0.6 - 0.5),  # all three
])
def test_sensor_value_follows_resolution_sign_and_reference_offset(num, denom, sign, ref_offset_01um, incr,
                                                                   expected_mm):
    changes = dict(encoder_resolution_num=num, encoder_resolution_denom=denom, sensor_sign_reversal=sign,
                   ref_offset=ref_offset_01um * 1e-4)
    (value,) = read_sensor_value(changes, [incr])
    assert value == round(expected_mm * 1e8)
    # and as the 8 raw little-endian bytes an ADS client reads
    kw = dict(enabled=True, max_pos=50.0, min_pos=-50.0, optimized_scheduling=True, **changes)
    ctrl = AxisDistanceController(AxisParameters(**kw), 0.001)
    out = CycleOutput()
    ctrl.update(CycleInput(programmed_position=40.0, actual_position=40.0, sensor_increments=incr), out)
    assert read_bytes(SENSOR_VALUE, AxisObjectContext(1, "Z", ctrl, out)) == \
        round(expected_mm * 1e8).to_bytes(8, "little", signed=True)
