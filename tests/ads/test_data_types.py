"""Symbols by type name, as a TwinCAT 3 target serves them (issue 14): handle by name with the
type decoration, the data types by name (0xF011) and in the upload (0xF00E, 0xF00F), the extended
system state of the system service."""
from __future__ import annotations

import struct
from pathlib import Path

import pytest

from distctrl.ads import errors as E
from distctrl.ads import protocol as P
from distctrl.ads.datatypes import (
    ADSDATATYPEFLAG_DATATYPE,
    DATA_TYPE_HEAD,
    DataItem,
    DataType,
    base_type,
    decode_data_type,
    encode_data_type,
)
from distctrl.ads.devices import SYSTEM_SERVICE_PORT, serve_over_ads
from distctrl.sim.scenario import load_scenario

from . import RawClient

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
ANY = 0xFFFFFFFF
DT_BY_NAME = 0xF011
UPLOAD_INFO2 = 0xF00F
UNIT = "gpAx[2].lr_mc_control.distance_control"


@pytest.fixture(scope="module")
def served():
    with serve_over_ads(load_scenario(SCN / "serve_z.toml"), port=0) as s:
        yield s


@pytest.fixture()
def c(served):
    with RawClient(served.services["ads"].server.port) as client:
        yield client


def data_type(c, name: str, rlen: int = ANY):
    return c.read_write(DT_BY_NAME, 0, rlen, name.encode() + b"\0")


# --- the entry format at known bytes ----------------------------------------------------------------
def test_a_base_type_entry_at_known_bytes():
    raw = encode_data_type(DataType("UDINT", 4, P.ADST_UINT32))
    head = DATA_TYPE_HEAD.unpack_from(raw)
    # entryLength, version, hash, typeHash, size, offset, ADST, flags, lengths of name/type/comment, dims, items
    assert head == (len(raw), 1, 0, 0, 4, 0, 19, ADSDATATYPEFLAG_DATATYPE, 5, 0, 0, 0, 0)
    assert raw[42:] == b"UDINT\0\0\0" and len(raw) == 50


def test_a_structure_round_trips_with_its_members():
    t = DataType("S", 8, P.ADST_BIGTYPE, "c", (DataItem("a", "UDINT", 0, 4, 19, "first"),
                                                DataItem("b", "DINT", 4, 4, 3)))
    back, length = decode_data_type(encode_data_type(t))
    assert back == t and length == len(encode_data_type(t))


def test_base_types_by_name():
    assert base_type("lreal") == DataType("LREAL", 8, P.ADST_REAL64)
    assert base_type("STRING(30)") == DataType("STRING(30)", 31, P.ADST_STRING)
    assert base_type("STRING") == DataType("STRING(80)", 81, P.ADST_STRING)
    assert base_type("HLI_DISTANCE_CONTROL_STATE") is None


# --- handle by name --------------------------------------------------------------------------------
def test_handle_by_name_with_a_larger_buffer_answers_size_decoration_and_type_name(c):
    """ads-client's createVariableHandle asks with 0xFFFFFFFF and reads handle, size, type decoration,
    type-name length and the type name; pyads asks for 4 bytes and gets the handle alone."""
    r = c.read_write(P.ADSIGRP_SYM_HNDBYNAME, 0, ANY, f"{UNIT}.state_r.actual_state\0".encode())
    assert r.result == 0
    handle, size, decoration, n = struct.unpack_from("<IIIH", r.data)
    assert (size, decoration, n) == (4, 0, 5) and r.data[14:] == b"UDINT\0"
    v = c.read(P.ADSIGRP_SYM_VALBYHND, handle, ANY)
    assert v.result == 0 and len(v.data) == 4
    r = c.read_write(P.ADSIGRP_SYM_HNDBYNAME, 0, 4, f"{UNIT}.state_r\0".encode())
    assert r.result == 0 and len(r.data) == 4
    r = c.read_write(P.ADSIGRP_SYM_HNDBYNAME, 0, ANY, f"{UNIT}.state_r\0".encode())
    assert struct.unpack_from("<IIIH", r.data)[1:] == (20, 0, len("HLI_DISTANCE_CONTROL_STATE"))
    r = c.read_write(P.ADSIGRP_SYM_HNDBYNAME, 0, ANY, b"gpAx[2].nope\0")
    assert r.result == E.ADSERR_DEVICE_SYMBOLNOTFOUND


# --- data types by name ----------------------------------------------------------------------------
def test_the_state_r_structure_by_name(c):
    r = data_type(c, "HLI_DISTANCE_CONTROL_STATE")
    assert r.result == 0
    t, length = decode_data_type(r.data)
    assert length == len(r.data)
    assert (t.name, t.size, t.ads_type) == ("HLI_DISTANCE_CONTROL_STATE", 20, P.ADST_BIGTYPE)
    assert [(i.name, i.type_name, i.offset, i.size) for i in t.items] == [
        ("actual_state", "UDINT", 0, 4), ("actual_position", "DINT", 4, 4), ("actual_offset", "DINT", 8, 4),
        ("command_source", "UDINT", 12, 4), ("actual_distance", "DINT", 16, 4)]


@pytest.mark.parametrize("name,size,members", [
    ("HLI_DISTANCE_CONTROL_COMMAND", 8, ["transition", "position"]),
    ("HLIDistanceControlCyclicCommand", 8, ["D_Position", "D_Distance"]),
    ("HLI_CHANNEL_DISTANCE_STATUS", 8, ["virt_tool_length_r", "inclination_r"]),
])
def test_every_structure_of_the_hli_by_name(c, name, size, members):
    t, _ = decode_data_type(data_type(c, name).data)
    assert t.size == size and [i.name for i in t.items] == members


@pytest.mark.parametrize("name,size,ads_type", [("UDINT", 4, 19), ("dint", 4, 3), ("BOOL", 1, 33),
                                                ("LREAL", 8, 5)])
def test_base_types_by_name_on_the_wire(c, name, size, ads_type):
    r = data_type(c, name)
    assert r.result == 0
    t, _ = decode_data_type(r.data)
    assert (t.name, t.size, t.ads_type, t.items) == (name.upper(), size, ads_type, ())


def test_unknown_type_names_and_small_buffers(c):
    assert data_type(c, "NO_SUCH_TYPE").result == E.ADSERR_DEVICE_SYMBOLNOTFOUND
    assert data_type(c, "HLI_DISTANCE_CONTROL_STATE", rlen=16).result == E.ADSERR_DEVICE_INVALIDSIZE


def test_struct_symbols_read_as_the_structure_says(served, c):
    """The bytes of gpAx[2]...state_r decode with the published members to the member symbols' values."""
    t, _ = decode_data_type(data_type(c, "HLI_DISTANCE_CONTROL_STATE").data)
    served.set_paused(True)                    # one cycle's values for all reads
    try:
        raw = c.read_write(P.ADSIGRP_SYM_VALBYNAME, 0, ANY, f"{UNIT}.state_r\0".encode()).data
        for item in t.items:
            member = c.read_write(P.ADSIGRP_SYM_VALBYNAME, 0, ANY, f"{UNIT}.state_r.{item.name}\0".encode()).data
            assert raw[item.offset:item.offset + item.size] == member, item.name
    finally:
        served.set_paused(False)


# --- the upload ------------------------------------------------------------------------------------
def test_the_upload_holds_every_type_the_symbols_use(c):
    info = c.read(UPLOAD_INFO2, 0, 64)
    assert info.result == 0 and len(info.data) == 24
    n_sym, sym_len, n_types, types_len, _, _ = struct.unpack("<6I", info.data)
    upload = c.read(P.ADSIGRP_SYM_DT_UPLOAD, 0, types_len)
    assert upload.result == 0 and len(upload.data) == types_len
    names, p = set(), 0
    while p < len(upload.data):
        t, length = decode_data_type(upload.data[p:])
        names.add(t.name)
        p += length
    assert len(names) == n_types
    symbols = c.read(P.ADSIGRP_SYM_UPLOAD, 0, sym_len).data
    used, p = set(), 0
    while p < len(symbols):
        s = P.decode_symbol_entry(symbols[p:])
        used.add(s.type_name)
        p += struct.unpack_from("<I", symbols, p)[0]
    assert used <= names and "HLI_DISTANCE_CONTROL_STATE" in names


# --- the extended system state ---------------------------------------------------------------------
def test_the_extended_system_state_of_the_system_service(served, c):
    """ads-client reads 16 bytes at index group 0xF0 of port 10000 first (readTcSystemExtendedState):
    ADS state, device state, restart index, version, revision, build, platform, OS, flags."""
    r = c.read(0xF0, 0, 16, target_port=SYSTEM_SERVICE_PORT)
    assert r.result == 0 and len(r.data) == 16
    ads_state, dev_state, restart, version, revision, build = struct.unpack_from("<HHHBBH", r.data)
    assert (ads_state, dev_state, restart) == (P.ADSSTATE_RUN, 0, 0)
    assert (version, revision, build) == (3, 1, 4024)
    assert c.read(0xF0, 0, 32, target_port=SYSTEM_SERVICE_PORT).result == E.ADSERR_DEVICE_INVALIDSIZE
    # a stopped PLC leaves the TwinCAT system in RUN (ads-client would see a lost connection otherwise)
    assert c.call(P.request, P.CMD_WRITE_CONTROL, P.WRITE_CONTROL_REQ.pack(P.ADSSTATE_STOP, 0, 0)).result == 0
    try:
        r = c.read(0xF0, 0, 16, target_port=SYSTEM_SERVICE_PORT)
        assert struct.unpack_from("<H", r.data)[0] == P.ADSSTATE_RUN
    finally:
        c.call(P.request, P.CMD_WRITE_CONTROL, P.WRITE_CONTROL_REQ.pack(P.ADSSTATE_RUN, 0, 0))
