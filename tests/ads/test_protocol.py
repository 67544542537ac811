"""Pure codec tests of distctrl.ads.protocol and distctrl.ads.errors."""
from __future__ import annotations

import struct

import pytest

from distctrl.ads import AdsError, SymbolInfo
from distctrl.ads import errors as E
from distctrl.ads import protocol as P


def test_net_id_roundtrip():
    raw = P.parse_net_id("192.168.0.10.1.1")
    assert raw == bytes([192, 168, 0, 10, 1, 1])
    assert P.format_net_id(raw) == "192.168.0.10.1.1"
    for bad in ("1.2.3.4.5", "1.2.3.4.5.256", "a.b.c.d.e.f", ""):
        with pytest.raises(ValueError):
            P.parse_net_id(bad)


def test_header_layout_and_response():
    frame = P.read_request(0x4020, 8, 8, target="1.2.3.4.1.1", target_port=851, source="5.6.7.8.1.1",
                           source_port=32905, invoke_id=0x11223344)
    reserved, length = P.AMS_TCP_HEADER.unpack_from(frame)
    assert reserved == 0 and length == len(frame) - 6 == 32 + 12
    hdr = P.AmsHeader.unpack(frame[6:])
    assert hdr.target_net_id == bytes([1, 2, 3, 4, 1, 1]) and hdr.target_port == 851
    assert hdr.source_port == 32905 and hdr.command == P.CMD_READ
    assert hdr.state_flags == P.SF_ADS_COMMAND and hdr.length == 12 and hdr.invoke_id == 0x11223344
    # byte offsets of the AMS header fields (little-endian)
    body = frame[6:]
    assert struct.unpack_from("<H", body, 6)[0] == 851
    assert struct.unpack_from("<H", body, 16)[0] == P.CMD_READ
    assert struct.unpack_from("<I", body, 28)[0] == 0x11223344
    resp = hdr.response(8, 0)
    assert resp.target_net_id == hdr.source_net_id and resp.target_port == 32905
    assert resp.source_net_id == hdr.target_net_id and resp.source_port == 851
    assert resp.state_flags == P.SF_RESPONSE | P.SF_ADS_COMMAND and resp.invoke_id == hdr.invoke_id
    assert P.AmsHeader.unpack(resp.pack()) == resp


def test_parse_response_read():
    hdr = P.AmsHeader(b"\1" * 6, 1, b"\2" * 6, 2, P.CMD_READ, 5, 0, 0, 9)
    frame = P.frame(hdr, P.READ_RES.pack(0, 3) + b"abc")
    r = P.parse_response(frame[6:])
    assert r.result == 0 and r.data == b"abc" and r.header.length == 11


def test_symbol_entry_roundtrip_and_limits():
    sym = SymbolInfo("MAIN.x", 0x4020, 12, 8, P.ADST_REAL64, "LREAL", "größe", read_only=True)
    entry = P.encode_symbol_entry(sym)
    assert struct.unpack_from("<I", entry)[0] == len(entry) == 30 + 7 + 6 + 6
    assert struct.unpack_from("<I", entry, 20)[0] == P.ADSSYMBOLFLAG_READONLY
    assert P.decode_symbol_entry(entry) == sym
    huge = SymbolInfo("N" * 400, 1, 2, 4, P.ADST_UINT32, "T" * 400, "C" * 400)
    assert len(P.encode_symbol_entry(huge)) == P.SYMBOL_ENTRY_MAX == 798


def test_ads_error():
    e = AdsError(0x705, "UDINT is 4 bytes")
    assert e.code == 0x705 and "0x705" in str(e) and "size" in str(e)
    assert E.describe(0x12345) .startswith("unknown")
    assert E.ADSERR_DEVICE_SYMBOLNOTFOUND == 1808 and E.ERR_TARGETPORTNOTFOUND == 6
