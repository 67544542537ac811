"""The CNC-object registry against FCT-M3 §9.4 (expected table written from the document)."""
from __future__ import annotations

import math
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from distctrl.control import Action, AxisDistanceController, Command, CycleInput, CycleOutput, ObjectWrite
from distctrl.objects import (ADS_PORT, ADS_TYPES, AXIS_OBJECTS, BY_NAME, INDEX_GROUP, AxisObjectContext,
                              ObjectAccessError, ObjectValueError, decode, encode, find_object, find_spec,
                              format_object_table, index_offset, object_table, read_bytes, read_value,
                              write_bytes, write_value)
from distctrl.objects.units import mm_to_nm001, round_saturate
from distctrl.params import AxisParameters

ROOT = Path(__file__).resolve().parents[2]

# FCT-M3 §9.4, one row per object: name, index offset (A_ID part left out), type, length, access, unit
DOCUMENT_94 = [
    ("DIST_CTRL_IFC::a_max_int", 0x3000, "REAL64", 8, "read", "0.1 µm/s²"),
    ("DIST_CTRL_IFC::sloped_delta_deviation", 0x3001, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL::m_actual_offset", 0x3100, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL::v_max_int", 0x3102, "REAL64", 8, "read", "0.1 µm/s"),
    ("DIST_CTRL::set_distance", 0x3103, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL::set_pos", 0x3104, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL::state", 0x3105, "UNS32", 4, "read", "-"),
    ("DIST_CTRL::kp", 0x3106, "REAL64", 8, "read/write", "-"),
    ("DIST_CTRL::i_tn", 0x3107, "REAL64", 8, "read/write", "s"),
    ("DIST_CTRL::d_tv", 0x3108, "REAL64", 8, "read/write", "s"),
    ("DIST_CTRL::smoothing_fact", 0x3109, "REAL64", 8, "read", "-"),
    ("DIST_CTRL::kalman_sigma", 0x310A, "REAL64", 8, "read", "-"),
    ("DIST_CTRL::n_cycles", 0x310B, "SGN32", 4, "read", "-"),
    ("DIST_CTRL::skip_dist_ctrl", 0x310C, "BOOLEAN", 1, "read", "-"),
    ("DIST_CTRL::filter_type", 0x310D, "STRING", 30, "read", "-"),
    ("DIST_CTRL::max_dist_change", 0x310E, "REAL64", 8, "read", "0.1 µm"),
    ("DIST_CTRL::filtered_feedback", 0x310F, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL::feedback_value", 0x3110, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL::target_deviation", 0x3111, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL::delta_deviation_pre_limiter", 0x3112, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL::sensor_value", 0x3113, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL_PARAM[0]::v_max", 0x3500, "SGN32", 4, "read/write", "µm/s"),
    ("DIST_CTRL_PARAM[0]::a_max", 0x3501, "SGN32", 4, "read/write", "mm/s²"),
    ("DIST_CTRL_IFC::actual_offset", 0x3900, "SGN32", 4, "read", "Incr."),
    ("DIST_CTRL_IFC::delta_offset", 0x3901, "SGN32", 4, "read", "Incr."),
]


# ----------------------------------------------------------------------------- a small closed loop

class Loop:
    """Axis with a probe: s = surface - actual (mm) as encoder-2 increments; the drive follows the
    command one cycle late."""

    def __init__(self, p: float = 40.0, surface: float = 40.0, T: float = 0.001, **param_changes):
        kw = dict(enabled=True, v_max=20.0, a_max=2000.0, max_act_value_change=1e5, max_pos=50.0, min_pos=-50.0,
                  optimized_scheduling=True)
        kw.update(param_changes)
        self.params = AxisParameters(**kw)
        self.ctrl = AxisDistanceController(self.params, T)
        self.p, self.surface, self.actual = p, surface, p
        self.inp, self.out = CycleInput(), CycleOutput()

    def cycle(self, *commands, n: int = 1) -> CycleOutput:
        for k in range(n):
            inp = self.inp
            inp.programmed_position, inp.actual_position = self.p, self.actual
            inp.sensor_increments = (self.surface - self.actual) / self.params.sensor_mm_per_increment
            if k == 0:
                inp.commands.extend(commands)
            self.ctrl.update(inp, self.out)
            self.actual = self.out.command_position
        return self.out


def ctx_of(loop: Loop, axis_id: int = 1, res: float = 1e-4) -> AxisObjectContext:
    return AxisObjectContext(axis_id, "Z", loop.ctrl, loop.out, drive_resolution_mm=res)


def half_away(x: float) -> int:
    return int(math.copysign(math.floor(abs(x) + 0.5), x))


# ----------------------------------------------------------------------------- the table

def test_every_documented_object_is_registered_as_documented():
    assert len(AXIS_OBJECTS) == len(DOCUMENT_94)
    for name, low, typ, length, access, unit in DOCUMENT_94:
        spec = BY_NAME[name]
        assert (spec.low_offset, spec.type, spec.length, spec.access, spec.unit) == (low, typ, length, access, unit), name
        assert spec.task == "GEO" and spec.port == 551 and spec.index_group == 0x120300
        assert spec.description
    assert [s.name for s in AXIS_OBJECTS] == [row[0] for row in DOCUMENT_94]   # in offset order
    assert ADS_PORT == 551 and INDEX_GROUP == 0x120300


def test_only_the_documented_objects_are_writable():
    writable = {s.name for s in AXIS_OBJECTS if s.writable}
    assert writable == {"DIST_CTRL::kp", "DIST_CTRL::i_tn", "DIST_CTRL::d_tv", "DIST_CTRL_PARAM[0]::v_max",
                        "DIST_CTRL_PARAM[0]::a_max"}


def test_section_7_6_differences_are_recorded():
    assert BY_NAME["DIST_CTRL::m_actual_offset"].old_name == "DIST_CTRL::actual_offset"
    assert BY_NAME["DIST_CTRL::filtered_feedback"].old_name == "DIST_CTRL::istw_filt"
    assert BY_NAME["DIST_CTRL::feedback_value"].old_name == "DIST_CTRL::sensor_data"
    assert "Incr." in BY_NAME["DIST_CTRL::m_actual_offset"].note


def test_find_spec_by_full_and_short_name():
    assert find_spec("DIST_CTRL::kp").low_offset == 0x3106
    assert find_spec("kp").name == "DIST_CTRL::kp"
    assert find_spec("m_actual_offset").low_offset == 0x3100
    with pytest.raises(KeyError):
        find_spec("actual_offset_x")


def test_ads_type_codes_match_pyads():
    constants = pytest.importorskip("pyads.constants")
    assert ADS_TYPES == {"REAL64": constants.ADST_REAL64, "SGN64": constants.ADST_INT64,
                         "SGN32": constants.ADST_INT32, "UNS32": constants.ADST_UINT32,
                         "BOOLEAN": constants.ADST_BIT, "STRING": constants.ADST_STRING}


# ----------------------------------------------------------------------------- addressing

def test_index_offset_scheme():
    kp = BY_NAME["DIST_CTRL::kp"]
    assert index_offset(1, kp) == 0x13106
    assert index_offset(3, kp) == 0x33106
    assert index_offset(2, BY_NAME["DIST_CTRL_IFC::delta_offset"]) == 0x23901
    assert kp.index_offset(16) == 0x103106
    for bad in (0, -1, 0x10000, 1.0, True):
        with pytest.raises(ValueError):
            index_offset(bad, kp)


def test_find_object_addresses_axis_and_object():
    loop = Loop()
    c1, c3 = ctx_of(loop, 1), ctx_of(loop, 3)
    contexts = {1: c1, 3: c3}
    spec, ctx = find_object(0x120300, 0x33106, contexts)
    assert spec.name == "DIST_CTRL::kp" and ctx is c3
    spec, ctx = find_object(0x120300, 0x13500, contexts)
    assert spec.name == "DIST_CTRL_PARAM[0]::v_max" and ctx is c1
    assert find_object(0x120300, 0x23106, contexts) is None       # no axis 2
    assert find_object(0x120300, 0x13101, contexts) is None       # no object 0x3101
    assert find_object(0x20300, 0x13106, contexts) is None        # old index group
    assert find_object(0x120300, 0x10152, contexts) is None       # old offset scheme (TF5200 Abstandskontrolle)
    assert find_object(0x120300, 0x33106, [c1, c3])[1] is c3      # a plain list of contexts works too


# ----------------------------------------------------------------------------- values

def expected_values(out: CycleOutput, ctrl, res: float) -> dict:
    """The object values computed from the CycleOutput with the document's units."""
    nm = lambda mm: half_away(mm * 1e8)                    # 0.01 nm = 1e-8 mm
    incr = lambda mm: half_away(mm / res)
    pend = ctrl.state.pending
    return {
        "DIST_CTRL_IFC::a_max_int": out.a_max_int * 1e4,   # mm/s² -> 0.1 µm/s²
        "DIST_CTRL_IFC::sloped_delta_deviation": nm(out.sloped_delta_deviation),
        "DIST_CTRL::m_actual_offset": nm(out.m_actual_offset),
        "DIST_CTRL::v_max_int": out.v_max_int * 1e4,       # mm/s -> 0.1 µm/s
        "DIST_CTRL::set_distance": nm(out.set_distance),
        "DIST_CTRL::set_pos": nm(out.set_pos),
        "DIST_CTRL::state": out.state,
        "DIST_CTRL::kp": out.kp, "DIST_CTRL::i_tn": out.i_tn, "DIST_CTRL::d_tv": out.d_tv,
        "DIST_CTRL::smoothing_fact": out.smoothing_fact, "DIST_CTRL::kalman_sigma": out.kalman_sigma,
        "DIST_CTRL::n_cycles": out.n_cycles, "DIST_CTRL::skip_dist_ctrl": False,
        "DIST_CTRL::filter_type": out.filter_type, "DIST_CTRL::max_dist_change": 0.0,
        "DIST_CTRL::filtered_feedback": nm(out.filtered_feedback),
        "DIST_CTRL::feedback_value": nm(out.feedback_value),
        "DIST_CTRL::target_deviation": nm(out.target_deviation),
        "DIST_CTRL::delta_deviation_pre_limiter": nm(out.delta_deviation_pre_limiter),
        "DIST_CTRL::sensor_value": nm(out.sensor_value),
        "DIST_CTRL_PARAM[0]::v_max": half_away(pend.get("v_max", out.v_max_param) * 1000),   # mm/s -> µm/s
        "DIST_CTRL_PARAM[0]::a_max": half_away(pend.get("a_max", out.a_max_param)),
        "DIST_CTRL_IFC::actual_offset": incr(out.offset),
        "DIST_CTRL_IFC::delta_offset": incr(out.offset) - incr(out.offset - out.delta_offset),
    }


def check_all(loop: Loop, res: float = 1e-4):
    ctx = ctx_of(loop, 2, res)
    want = expected_values(loop.out, loop.ctrl, res)
    for spec in AXIS_OBJECTS:
        got = read_value(spec, ctx)
        if spec.type == "REAL64":
            assert got == pytest.approx(want[spec.name], rel=1e-15, abs=0), spec.name
        else:
            assert got == want[spec.name], spec.name
        assert type(got) is {"REAL64": float, "SGN64": int, "SGN32": int, "UNS32": int, "BOOLEAN": bool,
                             "STRING": str}[spec.type], spec.name


@pytest.mark.parametrize("res", [1e-4, 5e-4, 1e-5])
def test_values_from_a_running_controller_set_pos(res):
    loop = Loop(p=40.0, surface=40.0, i_tn=0.02, d_tv=0.001, kp=0.8)
    loop.cycle(Command(Action.ON, set_pos=40.0))
    check_all(loop, res)
    loop.surface = 40.7531                                # the surface rises: the offset runs after it
    for _ in range(30):
        loop.cycle()
        check_all(loop, res)
    out = loop.out
    assert 0 < out.m_actual_offset < 0.7531 and out.delta_offset > 0      # mid-motion, non-trivial values
    ctx = ctx_of(loop)
    assert read_value(BY_NAME["DIST_CTRL::set_pos"], ctx) == 4_000_000_000          # 40 mm in 0.01 nm
    assert read_value(BY_NAME["DIST_CTRL::m_actual_offset"], ctx) == half_away(out.offset * 1e8)
    assert read_value(BY_NAME["DIST_CTRL::state"], ctx) == 2                        # ACTIVE
    assert read_value(BY_NAME["DIST_CTRL::kp"], ctx) == 0.8
    assert read_value(BY_NAME["DIST_CTRL_PARAM[0]::v_max"], ctx) == 20000            # 20 mm/s in µm/s
    assert read_value(BY_NAME["DIST_CTRL_PARAM[0]::a_max"], ctx) == 2000
    loop.cycle(n=2000)
    assert read_value(BY_NAME["DIST_CTRL::m_actual_offset"], ctx) == 75_310_000     # 0.7531 mm
    assert read_value(BY_NAME["DIST_CTRL_IFC::actual_offset"], ctx) == 7531           # 0.1 µm increments
    check_all(loop, res)


def test_values_in_const_dist_and_freeze():
    loop = Loop(p=41.0, surface=40.0, filter_type="MOVING_AVERAGE", n_cycles=7)
    loop.cycle(Command(Action.ON, const_dist=True, set_dist=1.25))
    for _ in range(40):
        loop.cycle()
        check_all(loop)
    ctx = ctx_of(loop)
    assert read_value(BY_NAME["DIST_CTRL::set_distance"], ctx) == 125_000_000
    assert read_value(BY_NAME["DIST_CTRL::filter_type"], ctx) == "MOVING_AVERAGE"
    assert read_value(BY_NAME["DIST_CTRL::n_cycles"], ctx) == 7
    loop.cycle(Command(Action.FREEZE), n=50)
    assert read_value(BY_NAME["DIST_CTRL::state"], ctx) == 3
    check_all(loop)


def test_delta_offsets_add_up_to_the_actual_offset():
    loop = Loop(p=40.0, surface=40.0)
    loop.cycle(Command(Action.ON, set_pos=40.0))
    ctx = ctx_of(loop, res=3.7e-4)                       # a resolution that does not divide the steps
    loop.surface = 40.333
    total = 0
    for _ in range(400):
        loop.cycle()
        total += read_value(BY_NAME["DIST_CTRL_IFC::delta_offset"], ctx)
        assert total == read_value(BY_NAME["DIST_CTRL_IFC::actual_offset"], ctx)


def test_values_before_the_first_cycle_come_from_the_controller():
    params = AxisParameters(enabled=True, kp=0.4, n_cycles=9, filter_type="KALMAN_MA", v_max=12.5)
    ctrl = AxisDistanceController(params)
    ctx = AxisObjectContext(1, "Z", ctrl, None)
    assert read_value(BY_NAME["DIST_CTRL::kp"], ctx) == 0.4
    assert read_value(BY_NAME["DIST_CTRL::n_cycles"], ctx) == 9
    assert read_value(BY_NAME["DIST_CTRL::filter_type"], ctx) == "KALMAN_MA"
    assert read_value(BY_NAME["DIST_CTRL_PARAM[0]::v_max"], ctx) == 12500
    assert read_value(BY_NAME["DIST_CTRL::state"], ctx) == 0


def test_conversions_round_and_saturate():
    assert mm_to_nm001(1.23456789123) == 123456789        # 1e-8 mm per count
    assert mm_to_nm001(1.234567896) == 123456790
    assert mm_to_nm001(-0.000000005) == -1                 # half a count: away from zero
    assert mm_to_nm001(1e300) == 2**63 - 1 and mm_to_nm001(-1e300) == -2**63
    assert mm_to_nm001(float("nan")) == 0
    assert round_saturate(2.5, -10, 10) == 3 and round_saturate(-2.5, -10, 10) == -3
    out = CycleOutput(offset=1e9, delta_offset=0.0)
    ctx = AxisObjectContext(1, "Z", AxisDistanceController(AxisParameters(enabled=True)), out)
    assert read_value(BY_NAME["DIST_CTRL_IFC::actual_offset"], ctx) == 2**31 - 1
    with pytest.raises(ValueError):
        AxisObjectContext(1, "Z", ctx.controller, out, drive_resolution_mm=0.0)


# ----------------------------------------------------------------------------- encoding

def test_encode_decode_round_trip_for_every_object():
    loop = Loop()
    loop.cycle(Command(Action.ON, set_pos=39.0))
    loop.surface = 39.5
    loop.cycle(n=20)
    ctx = ctx_of(loop)
    for spec in AXIS_OBJECTS:
        value = read_value(spec, ctx)
        raw = encode(spec, value)
        assert len(raw) == spec.length and raw == read_bytes(spec, ctx)
        assert decode(spec, raw) == value, spec.name


def test_encodings_are_little_endian():
    kp, pos, state = BY_NAME["DIST_CTRL::kp"], BY_NAME["DIST_CTRL::set_pos"], BY_NAME["DIST_CTRL::state"]
    assert encode(kp, 0.5) == struct.pack("<d", 0.5)
    assert encode(pos, -1) == b"\xff" * 8
    assert encode(pos, 4_000_000_000) == (4_000_000_000).to_bytes(8, "little", signed=True)
    assert encode(state, 15) == b"\x0f\x00\x00\x00"
    assert encode(BY_NAME["DIST_CTRL_PARAM[0]::v_max"], -2) == b"\xfe\xff\xff\xff"
    skip = BY_NAME["DIST_CTRL::skip_dist_ctrl"]
    assert encode(skip, False) == b"\x00" and encode(skip, True) == b"\x01"
    assert decode(skip, b"\x00") is False and decode(skip, b"\x07") is True
    ft = BY_NAME["DIST_CTRL::filter_type"]
    raw = encode(ft, "MOVING_AVERAGE")
    assert raw == b"MOVING_AVERAGE" + b"\x00" * 16 and len(raw) == 30
    assert decode(ft, raw) == "MOVING_AVERAGE"


@pytest.mark.parametrize("spec", AXIS_OBJECTS, ids=lambda s: s.name)
def test_wrong_size_raises(spec):
    for n in (0, spec.length - 1, spec.length + 1):
        with pytest.raises(ValueError):
            decode(spec, b"\x00" * n)


def test_encode_refuses_values_the_type_cannot_hold():
    with pytest.raises(ValueError):
        encode(BY_NAME["DIST_CTRL::state"], -1)                      # UNS32
    with pytest.raises(ValueError):
        encode(BY_NAME["DIST_CTRL_PARAM[0]::v_max"], 2**31)          # SGN32
    with pytest.raises(ValueError):
        encode(BY_NAME["DIST_CTRL::set_pos"], 1.5)                   # SGN64 needs an integer
    with pytest.raises(ValueError):
        encode(BY_NAME["DIST_CTRL::filter_type"], "X" * 30)          # 29 characters + NUL at most
    with pytest.raises(ValueError):
        encode(BY_NAME["DIST_CTRL::kp"], "1.0")


# ----------------------------------------------------------------------------- writes

def test_writes_produce_object_writes_in_internal_units():
    loop = Loop()
    ctx = ctx_of(loop, 3)
    w = write_value(BY_NAME["DIST_CTRL::kp"], ctx, 0.5)
    assert isinstance(w, ObjectWrite) and (w.name, w.value) == ("kp", 0.5)
    assert w.meta["index_offset"] == 0x33106 and w.meta["axis_id"] == 3
    assert (write_value(BY_NAME["DIST_CTRL::i_tn"], ctx, 0.25).name,
            write_value(BY_NAME["DIST_CTRL::i_tn"], ctx, 0.25).value) == ("i_tn", 0.25)
    assert write_value(BY_NAME["DIST_CTRL::d_tv"], ctx, 0.01) == ObjectWrite("d_tv", 0.01)
    assert write_value(BY_NAME["DIST_CTRL_PARAM[0]::v_max"], ctx, 300000) == ObjectWrite("v_max", 300.0)  # µm/s
    assert write_value(BY_NAME["DIST_CTRL_PARAM[0]::a_max"], ctx, 2500) == ObjectWrite("a_max", 2500.0)
    assert write_bytes(BY_NAME["DIST_CTRL_PARAM[0]::v_max"], ctx, struct.pack("<i", 1500)) == ObjectWrite("v_max", 1.5)
    assert write_bytes(BY_NAME["DIST_CTRL::kp"], ctx, struct.pack("<d", 1.5)) == ObjectWrite("kp", 1.5)


@pytest.mark.parametrize("spec", [s for s in AXIS_OBJECTS if not s.writable], ids=lambda s: s.name)
def test_read_only_write_raises(spec):
    ctx = ctx_of(Loop())
    with pytest.raises(ObjectAccessError):
        write_value(spec, ctx, read_value(spec, ctx))
    with pytest.raises(ObjectAccessError):
        write_bytes(spec, ctx, read_bytes(spec, ctx))


def test_bad_write_values_raise():
    ctx = ctx_of(Loop())
    for name, value in (("DIST_CTRL::kp", 0.0), ("DIST_CTRL::kp", 2.5), ("DIST_CTRL::kp", float("nan")),
                        ("DIST_CTRL::i_tn", 51.0), ("DIST_CTRL::d_tv", -0.1), ("DIST_CTRL_PARAM[0]::v_max", -1),
                        ("DIST_CTRL_PARAM[0]::a_max", 2.5), ("DIST_CTRL_PARAM[0]::a_max", 2**31),
                        ("DIST_CTRL::kp", True)):
        with pytest.raises(ObjectValueError):
            write_value(BY_NAME[name], ctx, value)
    with pytest.raises(ValueError):
        write_bytes(BY_NAME["DIST_CTRL::kp"], ctx, b"\x00" * 4)      # wrong size


def test_writes_are_adopted_only_on_freeze_to_active():
    loop = Loop(p=40.0, surface=40.0, kp=1.0, v_max=20.0, a_max=2000.0)
    ctx = ctx_of(loop)
    kp, vmax, amax = BY_NAME["DIST_CTRL::kp"], BY_NAME["DIST_CTRL_PARAM[0]::v_max"], BY_NAME["DIST_CTRL_PARAM[0]::a_max"]
    itn = BY_NAME["DIST_CTRL::i_tn"]
    loop.cycle(Command(Action.ON, set_pos=40.0))
    assert loop.out.hli_state == 1
    loop.cycle(write_value(kp, ctx, 0.5), write_value(vmax, ctx, 7000), write_value(amax, ctx, 900),
               write_value(itn, ctx, 0.1))
    loop.surface = 40.2
    v_seen = 0.0
    for _ in range(200):                                  # ACTIVE: nothing adopted
        out = loop.cycle()
        assert out.hli_state == 1 and out.kp == 1.0 and out.v_max_param == 20.0 and out.i_tn == 0.0
        assert read_value(kp, ctx) == 1.0                 # working value
        assert read_value(vmax, ctx) == 7000 and read_value(amax, ctx) == 900   # pending values
        v_seen = max(v_seen, out.offset_velocity)
    assert v_seen > 15.0                                  # the old v_max (20 mm/s) still limits
    out = loop.cycle(Command(Action.FREEZE), n=50)        # FREEZE: still not adopted
    assert out.hli_state == 2 and out.kp == 1.0 and out.a_max_param == 2000.0
    out = loop.cycle(Command(Action.ON, set_pos=40.0))    # FREEZE -> ACTIVE: adopted
    assert out.hli_state == 1
    assert (out.kp, out.v_max_param, out.a_max_param, out.i_tn) == (0.5, 7.0, 900.0, 0.1)
    assert loop.ctrl.state.pending == {}
    assert read_value(kp, ctx) == 0.5 and read_value(vmax, ctx) == 7000 and read_value(amax, ctx) == 900
    loop.surface = 41.0
    out = loop.cycle(n=3)
    assert abs(out.offset_velocity) <= 7.0 + 1e-9          # the new v_max acts


def test_writes_are_adopted_on_inactive_to_active():
    loop = Loop()
    ctx = ctx_of(loop)
    loop.cycle(write_value(BY_NAME["DIST_CTRL::d_tv"], ctx, 0.004), n=5)
    assert loop.out.d_tv == 0.0 and loop.out.hli_state == 0
    out = loop.cycle(Command(Action.ON, set_pos=40.0))
    assert out.d_tv == 0.004


# ----------------------------------------------------------------------------- browser table, docs

def test_object_table_rows_like_the_object_browser():
    loop = Loop()
    loop.cycle(Command(Action.ON, set_pos=40.0, kp=0.3))
    rows = object_table({3: ctx_of(loop, 3), 1: ctx_of(loop, 1)})
    assert len(rows) == 2 * (len(AXIS_OBJECTS) + 6)            # + Fig. 34's four and the two TF5200 aliases
    assert [r["Nr"] for r in rows] == list(range(1, len(rows) + 1))
    kp3 = next(r for r in rows if r["Offset"] == "0x33106")
    assert kp3 == {**kp3, "Gruppe": "0x120300", "Bezeichner": "DIST_CTRL::kp", "Datentyp": "REAL64", "Länge": 8,
                   "Einheit": "-", "Wert": "0.3", "Zugriff": "read/write"}
    ft = next(r for r in rows if r["Offset"] == "0x1310D")
    assert ft["Wert"] == '"DEFAULT"' and ft["Länge"] == 30
    text = format_object_table(rows)
    lines = text.splitlines()
    assert lines[0].split() == ["Nr", "Gruppe", "Offset", "Bezeichner", "Datentyp", "Länge", "Einheit", "Wert",
                                "Zugriff"]
    assert len(lines) == 2 + len(rows)
    assert any("0x33106" in ln and "DIST_CTRL::kp" in ln and "0.3" in ln for ln in lines)


def test_docs_objects_md_is_generated_from_the_registry():
    generated = subprocess.run([sys.executable, "-m", "distctrl.objects.docgen"], capture_output=True, text=True,
                               cwd=ROOT, check=True).stdout
    assert (ROOT / "docs" / "objects.md").read_text(encoding="utf-8") == generated
    for name, low, typ, length, access, unit in DOCUMENT_94:
        assert f"`{name}` | {typ} | {length} | {unit} | {access} |" in generated


def test_n_cycles_shows_the_n_the_filter_uses_four_under_default():
    """FCT-M3 §9.4 DIST_CTRL::n_cycles: 'Currently set number of measured values used for filtering';
    P-AXIS-00782 DEFAULT: 'Moving average filter where P-AXIS-00413 = 4' -- whatever n_cycles says."""
    params = AxisParameters(enabled=True, n_cycles=20, filter_type="DEFAULT")
    ctrl = AxisDistanceController(params)
    ctx = AxisObjectContext(1, "Z", ctrl, None)
    assert read_value(BY_NAME["DIST_CTRL::n_cycles"], ctx) == 4                 # before the first cycle
    out = CycleOutput()
    ctrl.update(CycleInput(), out)
    assert out.n_cycles == 4
    assert read_value(BY_NAME["DIST_CTRL::n_cycles"], AxisObjectContext(1, "Z", ctrl, out)) == 4
    ctrl2 = AxisDistanceController(params.replace(filter_type="MOVING_AVERAGE"))
    assert read_value(BY_NAME["DIST_CTRL::n_cycles"], AxisObjectContext(1, "Z", ctrl2, None)) == 20


def test_the_tf5200_addresses_are_aliases_of_the_parameter_objects():
    """TF5200 Abstandskontrolle §7.5: DISTCTRL::v_max (SGN32, µm/s) at 0x20300 / 0x10152, DISTCTRL::a_max
    (SGN32, mm/s²) at 0x10153, + 0x10000 (axis index - 1); SPEC §10: served as aliases (same value, same
    write rule)."""
    from distctrl.objects import INDEX_GROUP_TF5200, TF5200_OBJECTS

    loop = Loop(v_max=12.5, a_max=900.0)
    loop.cycle()
    ctxs = {1: ctx_of(loop, 1), 3: ctx_of(loop, 3)}
    assert INDEX_GROUP_TF5200 == 0x20300 and len(TF5200_OBJECTS) == 2
    for axis_id, offset_v, offset_a in ((1, 0x10152, 0x10153), (3, 0x30152, 0x30153)):
        v, ctx = find_object(0x20300, offset_v, ctxs)
        a, _ = find_object(0x20300, offset_a, ctxs)
        assert (v.name, v.type, v.length, v.unit, v.access) == ("DISTCTRL::v_max", "SGN32", 4, "µm/s", "read/write")
        assert (a.name, a.type, a.unit) == ("DISTCTRL::a_max", "SGN32", "mm/s²")
        assert ctx.axis_id == axis_id
        assert read_value(v, ctx) == read_value(BY_NAME["DIST_CTRL_PARAM[0]::v_max"], ctx) == 12500
        assert read_value(a, ctx) == read_value(BY_NAME["DIST_CTRL_PARAM[0]::a_max"], ctx) == 900
    spec, ctx = find_object(0x20300, 0x10152, ctxs)
    w = write_value(spec, ctx, 7000)
    assert (w.name, w.value) == ("v_max", 7.0)                          # the same ObjectWrite as 0x13500
    assert find_object(0x20300, 0x13106, ctxs) is None                  # only these two live in 0x20300
    assert find_object(0x120300, 0x10152, ctxs) is None


def test_writes_through_the_tf5200_addresses_follow_the_parameter_objects_rules():
    """TF5200 Abstandskontrolle §7.5: the new v_max / a_max are adopted only on INACTIVE -> ACTIVE or
    FREEZE -> ACTIVE; the alias checks the range like DIST_CTRL_PARAM[0]::v_max / a_max (SPEC §10)."""
    loop = Loop(v_max=20.0, a_max=2000.0)
    ctxs = {1: ctx_of(loop, 1)}
    v, ctx = find_object(0x20300, 0x10152, ctxs)
    a, _ = find_object(0x20300, 0x10153, ctxs)
    for spec, bad in ((v, -1), (a, -1), (a, 2.5), (v, 2**31), (v, float("nan"))):
        with pytest.raises(ObjectValueError):
            write_value(spec, ctx, bad)
    loop.cycle(write_value(v, ctx, 7000), write_value(a, ctx, 900), n=5)        # INACTIVE: pending
    assert (loop.out.v_max_param, loop.out.a_max_param) == (20.0, 2000.0)
    assert read_value(v, ctx) == read_value(BY_NAME["DIST_CTRL_PARAM[0]::v_max"], ctx) == 7000
    out = loop.cycle(Command(Action.ON, const_dist=True, set_dist=0.0))         # INACTIVE -> ACTIVE_CONST_DIST
    assert out.hli_state == 4 and (out.v_max_param, out.a_max_param) == (7.0, 900.0)
    loop.cycle(write_value(v, ctx, 9000), n=50)                                  # ACTIVE_CONST_DIST: pending
    assert loop.out.v_max_param == 7.0 and read_value(v, ctx) == 9000
    out = loop.cycle(Command(Action.FREEZE), n=20)                               # FREEZE: still pending
    assert out.v_max_param == 7.0
    out = loop.cycle(Command(Action.ON, set_pos=40.0))                           # FREEZE -> ACTIVE: adopted
    assert out.hli_state == 1 and out.v_max_param == 9.0 and loop.ctrl.state.pending == {}


def test_fig_34_general_axis_objects_show_p_c_and_the_drive_positions():
    """FCT-M3 §7.5 Fig. 34 (m_sollw_absolut, sollw_absolut, dig cmd pos high_res, dig act pos) beside the
    distance-control objects: programmed p, command c = p + o (0.01 nm), c and a in drive increments."""
    from distctrl.objects import GENERAL_AXIS_OBJECTS

    loop = Loop(p=40.0, surface=40.3)
    loop.cycle(Command(Action.ON, set_pos=40.0), n=200)
    ctx = ctx_of(loop, 2, res=5e-4)
    names = [s.name for s in GENERAL_AXIS_OBJECTS]
    assert names == ["m_sollw_absolut", "sollw_absolut", "dig cmd pos high_res", "dig act pos"]
    addr = {s.name: index_offset(2, s) for s in GENERAL_AXIS_OBJECTS}
    assert addr["m_sollw_absolut"] == 0x23A00 and addr["dig act pos"] == 0x23A03
    p, c, a = loop.ctrl.state.last_p, loop.out.command_position, loop.ctrl.state.last_a
    assert c == pytest.approx(40.3, abs=1e-6) and p == 40.0
    assert read_value(BY_NAME["m_sollw_absolut"], ctx) == 40 * 10**8
    assert read_value(BY_NAME["sollw_absolut"], ctx) == half_away(c * 1e8)
    assert read_value(BY_NAME["dig cmd pos high_res"], ctx) == half_away(c / 5e-4)
    assert read_value(BY_NAME["dig act pos"], ctx) == half_away(a / 5e-4)
    for s in GENERAL_AXIS_OBJECTS:
        assert not s.writable and s.index_group == 0x120300
