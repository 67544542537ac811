"""The 3D CNC-object table against FCT-M3 §12.6 (expected table written from the document)."""
from __future__ import annotations

import math
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from distctrl.control import ObjectWrite
from distctrl.control.cycle_io import CycleOutput
from distctrl.objects.channel3d import (BY_NAME_3D, CHANNEL3D_OBJECTS, COLUMNS_3D, INDEX_GROUP_3D_BASE,
                                        OBJECT_ATTRIBUTES, Channel3DObjectContext, Channel3DSource,
                                        Channel3DValues, ObjectSpec3D, find_object_3d, find_spec_3d,
                                        index_group_3d, object_table_3d, read_bytes, read_value_3d, render,
                                        write_bytes, write_value)
from distctrl.objects.registry import (AXIS_OBJECTS, ObjectAccessError, ObjectSpec, ObjectValueError, decode,
                                       encode, format_object_table)

ROOT = Path(__file__).resolve().parents[2]

# FCT-M3 §12.6, one row per object: name, index offset, type, length, access, unit. The document's
# typos are corrected as noted: "0x<3105" -> 0x3105; "DIST_CTRL_PARAM[0]:a_max",
# "DIST_CTRL_IFC[0]:actual_offset", "DIST_CTRL_IFC[0]:delta_offset" (single colon) -> "::".
DOCUMENT_126 = [
    ("DIST_CTRL_IFC[0]::a_max_int", 0x3000, "REAL64", 8, "read", "0.1 µm/s²"),
    ("DIST_CTRL_IFC[0]::sloped_delta_deviation", 0x3001, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL[0]::m_actual_offset", 0x3100, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL[0]::v_max_int", 0x3102, "REAL64", 8, "read", "0.1 µm/s"),
    ("DIST_CTRL[0]::set_distance", 0x3103, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL[0]::set_pos", 0x3104, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL[0]::state", 0x3105, "UNS32", 4, "read", "-"),
    ("DIST_CTRL[0]::kp", 0x3106, "REAL64", 8, "read/write", "-"),
    ("DIST_CTRL[0]::i_tn", 0x3107, "REAL64", 8, "read/write", "s"),
    ("DIST_CTRL[0]::d_tv", 0x3108, "REAL64", 8, "read/write", "s"),
    ("DIST_CTRL[0]::smoothing_fact", 0x3109, "REAL64", 8, "read", "-"),
    ("DIST_CTRL[0]::kalman_sigma", 0x310A, "REAL64", 8, "read", "-"),
    ("DIST_CTRL[0]::n_cycles", 0x310B, "SGN32", 4, "read", "-"),
    ("DIST_CTRL[0]::skip_dist_ctrl", 0x310C, "BOOLEAN", 1, "read", "-"),
    ("DIST_CTRL[0]::filter_type", 0x310D, "STRING", 30, "read", "-"),
    ("DIST_CTRL[0]::max_dist_change", 0x310E, "REAL64", 8, "read", "0.1 µm"),
    ("DIST_CTRL[0]::filtered_feedback", 0x310F, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL[0]::feedback_value", 0x3110, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL[0]::target_deviation", 0x3111, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL[0]::delta_deviation_pre_limiter", 0x3112, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL[0]::sensor_value", 0x3113, "SGN64", 8, "read", "0.01 nm"),
    ("DIST_CTRL_PARAM[0]::v_max", 0x3500, "SGN32", 4, "read/write", "µm/s"),
    ("DIST_CTRL_PARAM[0]::a_max", 0x3501, "SGN32", 4, "read/write", "mm/s²"),
    ("DIST_CTRL_IFC[0]::actual_offset", 0x3900, "SGN32", 4, "read", "Incr."),
    ("DIST_CTRL_IFC[0]::delta_offset", 0x3901, "SGN32", 4, "read", "Incr."),
]


def fake_values(**kw) -> Channel3DValues:
    """A 3D controller's values mid-run (SET_POS, surface 0.4321 mm above the programmed one)."""
    base = dict(offset=0.123456789, delta_offset=0.0004321, m_actual_offset=0.12346,
                sloped_delta_deviation=0.0004321,
                delta_deviation_pre_limiter=0.0031, set_pos=12.5, set_distance=1.25, target_deviation=0.3087,
                sensor_value=1.7654321, feedback_value=12.9321, filtered_feedback=12.8087, state=2, hli_state=1,
                kp=0.8, i_tn=0.02, d_tv=0.001, smoothing_fact=0.3, kalman_sigma=250.0, n_cycles=7,
                filter_type="KALMAN_MA", v_max_int=4.5, a_max_int=123.25, v_max_param=5.0, a_max_param=150.0,
                inclination_rad=math.radians(30.0), virtual_tool_length=11.547, compensation_mode=3)
    base.update(kw)
    return Channel3DValues(**base)


def ctx1(values=None, res: float = 1e-4, channel: int = 1) -> Channel3DObjectContext:
    values = values if values is not None else fake_values()
    return Channel3DObjectContext(channel, values, drive_resolution_mm=res)


# ----------------------------------------------------------------------------- the table

def test_every_documented_object_is_registered_as_documented():
    assert len(CHANNEL3D_OBJECTS) == len(DOCUMENT_126)
    assert [s.name for s in CHANNEL3D_OBJECTS] == [row[0] for row in DOCUMENT_126]     # offset order
    for name, low, typ, length, access, unit in DOCUMENT_126:
        spec = BY_NAME_3D[name]
        got = (spec.low_offset, spec.type, spec.length, spec.access, spec.unit)
        assert got == (low, typ, length, access, unit), name
        assert spec.task == "GEO" and spec.port == 551 and spec.index_group == 0x121300
        assert spec.description and spec.source and spec.conversion


def test_the_3d_specs_are_the_registry_spec_type():
    assert all(isinstance(s, ObjectSpec3D) and isinstance(s, ObjectSpec) for s in CHANNEL3D_OBJECTS)
    # the same low offsets and types as the axis objects (§12.6 mirrors §9.4)
    assert [(s.low_offset, s.type, s.length, s.unit, s.access) for s in CHANNEL3D_OBJECTS] == \
        [(s.low_offset, s.type, s.length, s.unit, s.access) for s in AXIS_OBJECTS]


def test_only_the_documented_objects_are_writable():
    assert {s.name for s in CHANNEL3D_OBJECTS if s.writable} == {
        "DIST_CTRL[0]::kp", "DIST_CTRL[0]::i_tn", "DIST_CTRL[0]::d_tv", "DIST_CTRL_PARAM[0]::v_max",
        "DIST_CTRL_PARAM[0]::a_max"}


def test_find_spec_by_name_short_name_and_the_documents_spelling():
    assert find_spec_3d("DIST_CTRL[0]::kp").low_offset == 0x3106
    assert find_spec_3d("kp").name == "DIST_CTRL[0]::kp"
    assert find_spec_3d("DIST_CTRL_PARAM[0]:a_max").name == "DIST_CTRL_PARAM[0]::a_max"
    assert find_spec_3d("DIST_CTRL_IFC[0]:actual_offset").low_offset == 0x3900
    with pytest.raises(KeyError):
        find_spec_3d("nonexistent")


# ----------------------------------------------------------------------------- addressing

def test_addressing_channel_in_the_index_group_no_axis_part():
    assert index_group_3d(1) == 0x121301 and index_group_3d(3) == 0x121303 and INDEX_GROUP_3D_BASE == 0x121300
    kp = BY_NAME_3D["DIST_CTRL[0]::kp"]
    assert kp.index_offset(1) == 0x3106 and kp.index_offset(5) == 0x3106 and kp.index_group_for(2) == 0x121302
    for bad in (0, -1, 256, 1.0, True):
        with pytest.raises(ValueError):
            index_group_3d(bad)
        with pytest.raises(ValueError):
            Channel3DObjectContext(bad, fake_values())


def test_find_object_3d():
    c1, c2 = ctx1(channel=1), ctx1(channel=2)
    contexts = {1: c1, 2: c2}
    spec, ctx = find_object_3d(0x121301, 0x3106, contexts)
    assert spec.name == "DIST_CTRL[0]::kp" and ctx is c1
    spec, ctx = find_object_3d(0x121302, 0x3501, [c1, c2])               # any iterable of contexts
    assert spec.name == "DIST_CTRL_PARAM[0]::a_max" and ctx is c2
    assert find_object_3d(0x121303, 0x3106, contexts) is None               # no channel 3
    assert find_object_3d(0x121300, 0x3106, contexts) is None               # channel 0 does not exist
    assert find_object_3d(0x121301, 0x3101, contexts) is None               # no object 0x3101
    assert find_object_3d(0x121301, 0x13106, contexts) is None              # no axis part in 3D offsets
    assert find_object_3d(0x120300, 0x13106, contexts) is None              # the axis group is not ours
    assert find_object_3d(0x221301, 0x3106, contexts) is None


# ----------------------------------------------------------------------------- values

def half_away(x: float) -> int:
    return int(math.copysign(math.floor(abs(x) + 0.5), x))


def test_values_from_a_fake_source_convert_to_the_object_units():
    v = fake_values()
    ctx = ctx1(v)
    r = {s.name: read_value_3d(s, ctx) for s in CHANNEL3D_OBJECTS}
    assert r["DIST_CTRL_IFC[0]::a_max_int"] == pytest.approx(1_232_500.0)        # 123.25 mm/s² in 0.1 µm/s²
    assert r["DIST_CTRL[0]::v_max_int"] == pytest.approx(45_000.0)               # 4.5 mm/s in 0.1 µm/s
    assert r["DIST_CTRL_IFC[0]::sloped_delta_deviation"] == 43_210                # 0.0004321 mm in 0.01 nm
    assert r["DIST_CTRL[0]::m_actual_offset"] == 12_346_000
    assert r["DIST_CTRL[0]::set_pos"] == 1_250_000_000                           # 12.5 mm
    assert r["DIST_CTRL[0]::set_distance"] == 125_000_000
    assert r["DIST_CTRL[0]::state"] == 2
    assert (r["DIST_CTRL[0]::kp"], r["DIST_CTRL[0]::i_tn"], r["DIST_CTRL[0]::d_tv"]) == (0.8, 0.02, 0.001)
    assert (r["DIST_CTRL[0]::smoothing_fact"], r["DIST_CTRL[0]::kalman_sigma"]) == (0.3, 250.0)
    assert r["DIST_CTRL[0]::n_cycles"] == 7
    assert r["DIST_CTRL[0]::skip_dist_ctrl"] is False
    assert r["DIST_CTRL[0]::filter_type"] == "KALMAN_MA"
    assert r["DIST_CTRL[0]::max_dist_change"] == 0.0
    assert r["DIST_CTRL[0]::filtered_feedback"] == 1_280_870_000
    assert r["DIST_CTRL[0]::feedback_value"] == 1_293_210_000
    assert r["DIST_CTRL[0]::target_deviation"] == 30_870_000
    assert r["DIST_CTRL[0]::delta_deviation_pre_limiter"] == 310_000
    assert r["DIST_CTRL[0]::sensor_value"] == 176_543_210
    assert r["DIST_CTRL_PARAM[0]::v_max"] == 5000                                # 5 mm/s in µm/s
    assert r["DIST_CTRL_PARAM[0]::a_max"] == 150
    assert r["DIST_CTRL_IFC[0]::actual_offset"] == 1235                          # 0.123456789 mm / 1e-4
    assert r["DIST_CTRL_IFC[0]::delta_offset"] == 1235 - half_away((0.123456789 - 0.0004321) / 1e-4)
    for s in CHANNEL3D_OBJECTS:
        assert type(r[s.name]) is {"REAL64": float, "SGN64": int, "SGN32": int, "UNS32": int, "BOOLEAN": bool,
                                   "STRING": str}[s.type], s.name


def test_increments_follow_the_drive_resolution_and_deltas_add_up():
    assert read_value_3d(BY_NAME_3D["DIST_CTRL_IFC[0]::actual_offset"], ctx1(res=1e-3)) == 123
    values = Channel3DValues()
    ctx = Channel3DObjectContext(1, values, drive_resolution_mm=3.7e-4)
    total, o_prev = 0, 0.0
    for k in range(1, 300):
        o = 0.5 * (1 - math.cos(k / 40.0))
        values.offset, values.delta_offset = o, o - o_prev
        o_prev = o
        total += read_value_3d(BY_NAME_3D["DIST_CTRL_IFC[0]::delta_offset"], ctx)
        assert total == read_value_3d(BY_NAME_3D["DIST_CTRL_IFC[0]::actual_offset"], ctx)


def test_pending_writes_show_in_the_param_objects():
    ctx = ctx1(fake_values(pending={"v_max": 7.5, "a_max": 80.0}))
    assert read_value_3d(BY_NAME_3D["DIST_CTRL_PARAM[0]::v_max"], ctx) == 7500
    assert read_value_3d(BY_NAME_3D["DIST_CTRL_PARAM[0]::a_max"], ctx) == 80


def test_rounding_and_saturation():
    ctx = ctx1(fake_values(set_pos=-0.000000005, offset=1e9, feedback_value=1e300, sensor_value=float("nan")))
    assert read_value_3d(BY_NAME_3D["DIST_CTRL[0]::set_pos"], ctx) == -1          # half a count: away from zero
    assert read_value_3d(BY_NAME_3D["DIST_CTRL_IFC[0]::actual_offset"], ctx) == 2**31 - 1
    assert read_value_3d(BY_NAME_3D["DIST_CTRL[0]::feedback_value"], ctx) == 2**63 - 1
    assert read_value_3d(BY_NAME_3D["DIST_CTRL[0]::sensor_value"], ctx) == 0
    with pytest.raises(ValueError):
        Channel3DObjectContext(1, fake_values(), drive_resolution_mm=0.0)


def test_a_cycle_output_is_a_valid_source():
    out = CycleOutput(offset=0.25, m_actual_offset=0.25, set_pos=3.0, state=3, kp=0.6, filter_type="LOWPASS")
    assert isinstance(out, Channel3DSource) and isinstance(fake_values(), Channel3DSource)
    assert all(hasattr(out, a) for a in OBJECT_ATTRIBUTES)
    ctx = Channel3DObjectContext(1, out)
    assert read_value_3d(BY_NAME_3D["DIST_CTRL[0]::set_pos"], ctx) == 300_000_000
    assert read_value_3d(BY_NAME_3D["DIST_CTRL[0]::state"], ctx) == 3
    assert read_value_3d(BY_NAME_3D["DIST_CTRL[0]::filter_type"], ctx) == "LOWPASS"
    v = Channel3DValues.from_cycle_output(out, inclination_rad=0.1)
    assert (v.offset, v.kp, v.inclination_rad, v.state) == (0.25, 0.6, 0.1, 3)
    empty = Channel3DObjectContext(1, None)                  # no source yet: zeros, IDLE
    assert read_value_3d(BY_NAME_3D["DIST_CTRL[0]::state"], empty) == 0


def test_read_bytes_are_little_endian_encodings():
    ctx = ctx1()
    for spec in CHANNEL3D_OBJECTS:
        raw = read_bytes(spec, ctx)
        assert len(raw) == spec.length
        assert decode(spec, raw) == read_value_3d(spec, ctx), spec.name
    assert read_bytes(BY_NAME_3D["DIST_CTRL[0]::kp"], ctx) == struct.pack("<d", 0.8)
    want = (1_250_000_000).to_bytes(8, "little", signed=True)
    assert read_bytes(BY_NAME_3D["DIST_CTRL[0]::set_pos"], ctx) == want
    assert read_bytes(BY_NAME_3D["DIST_CTRL[0]::state"], ctx) == b"\x02\x00\x00\x00"
    assert read_bytes(BY_NAME_3D["DIST_CTRL[0]::filter_type"], ctx) == b"KALMAN_MA".ljust(30, b"\x00")


# ----------------------------------------------------------------------------- writing

def test_writes_produce_object_writes_in_internal_units():
    ctx = ctx1()
    w = write_bytes(BY_NAME_3D["DIST_CTRL[0]::kp"], ctx, struct.pack("<d", 0.5), line=7)
    assert isinstance(w, ObjectWrite) and (w.name, w.value, w.line) == ("kp", 0.5, 7)
    assert w.meta["channel_id"] == 1 and w.meta["index_group"] == 0x121301 and w.meta["index_offset"] == 0x3106
    w = write_bytes(BY_NAME_3D["DIST_CTRL_PARAM[0]::v_max"], ctx, struct.pack("<i", 12500))
    assert (w.name, w.value) == ("v_max", pytest.approx(12.5)) and w.meta["raw"] == 12500     # µm/s -> mm/s
    w = write_value(BY_NAME_3D["DIST_CTRL_PARAM[0]::a_max"], ctx, 300)
    assert (w.name, w.value) == ("a_max", 300.0)
    assert write_value(BY_NAME_3D["DIST_CTRL[0]::i_tn"], ctx, 1.5).value == 1.5
    assert write_value(BY_NAME_3D["DIST_CTRL[0]::d_tv"], ctx, 0.01).value == 0.01


@pytest.mark.parametrize("spec", [s for s in CHANNEL3D_OBJECTS if not s.writable], ids=lambda s: s.name)
def test_read_only_writes_raise(spec):
    ctx = ctx1()
    with pytest.raises(ObjectAccessError):
        write_bytes(spec, ctx, b"\x00" * spec.length)
    with pytest.raises(PermissionError):
        write_value(spec, ctx, 0)
    with pytest.raises(ObjectAccessError):
        write_bytes(spec, ctx, b"")                          # access is checked before the size


@pytest.mark.parametrize("spec", CHANNEL3D_OBJECTS, ids=lambda s: s.name)
def test_wrong_sizes_raise(spec):
    with pytest.raises(ObjectValueError):
        decode(spec, b"\x00" * (spec.length + 1))
    if spec.writable:
        for n in (0, spec.length - 1, spec.length + 1):
            with pytest.raises(ObjectValueError):
                write_bytes(spec, ctx1(), b"\x00" * n)


def test_bad_write_values_raise():
    ctx = ctx1()
    kp, v_max, a_max = (BY_NAME_3D[n] for n in ("DIST_CTRL[0]::kp", "DIST_CTRL_PARAM[0]::v_max",
                                                 "DIST_CTRL_PARAM[0]::a_max"))
    for bad in (0.0, 2.5, -1.0, float("nan"), "1", True):
        with pytest.raises(ObjectValueError):
            write_value(kp, ctx, bad)
    with pytest.raises(ObjectValueError):
        write_value(BY_NAME_3D["DIST_CTRL[0]::i_tn"], ctx, 51.0)
    with pytest.raises(ObjectValueError):
        write_value(BY_NAME_3D["DIST_CTRL[0]::d_tv"], ctx, 2.5)
    for bad in (-1, 1.5, 2**31):
        with pytest.raises(ObjectValueError):
            write_value(v_max, ctx, bad)
    with pytest.raises(ObjectValueError, match="315001"):
        write_value(a_max, ctx, 0)                            # 3D: a_max must be > 0
    with pytest.raises(ObjectValueError):
        write_bytes(a_max, ctx, struct.pack("<i", -5))


# ----------------------------------------------------------------------------- browser and docs

def test_object_table_rows():
    rows = object_table_3d({2: ctx1(channel=2), 1: ctx1(channel=1)})
    assert len(rows) == 2 * len(CHANNEL3D_OBJECTS)
    assert [r["Nr"] for r in rows] == list(range(1, len(rows) + 1))
    first = rows[0]
    assert first["Gruppe"] == "0x121301" and first["Offset"] == "0x3000" and first["Kanal"] == 1
    kp2 = next(r for r in rows if r["Gruppe"] == "0x121302" and r["Offset"] == "0x3106")
    assert kp2["Bezeichner"] == "DIST_CTRL[0]::kp" and kp2["Wert"] == "0.8" and kp2["Zugriff"] == "read/write"
    text = format_object_table(rows, COLUMNS_3D)
    lines = text.splitlines()
    assert lines[0].split() == list(COLUMNS_3D) and len(lines) == 2 + len(rows)
    assert any("0x121302" in ln and "DIST_CTRL[0]::filter_type" in ln and '"KALMAN_MA"' in ln for ln in lines)


def test_docs_objects_3d_md_is_generated():
    generated = subprocess.run([sys.executable, "-m", "distctrl.objects.channel3d"], capture_output=True,
                               text=True, cwd=ROOT, check=True).stdout
    assert generated == render()
    assert (ROOT / "docs" / "objects-3d.md").read_text(encoding="utf-8") == generated
    for name, low, typ, length, access, unit in DOCUMENT_126:
        assert f"| 0x{low:04X} | `{name}` | {typ} | {length} | {unit} | {access} |" in generated
    for attr in OBJECT_ATTRIBUTES:
        assert f"| `{attr}` |" in generated


def test_encode_round_trip():
    ctx = ctx1()
    for spec in CHANNEL3D_OBJECTS:
        value = read_value_3d(spec, ctx)
        assert decode(spec, encode(spec, value)) == value
