"""The server's read cache (``AdsServer._handle_ams``): a repeated Read request is answered byte for
byte as the full path answers it, with the value of the moment, and everything the cache cannot
answer (errors, other devices, a replaced device) goes through the full path."""
from __future__ import annotations

import pathlib
import struct

import pytest

from distctrl.ads import protocol as P
from distctrl.ads.devices import CNC_PORT, serve_over_ads
from distctrl.objects.registry import BY_NAME, INDEX_GROUP, SERVED_OBJECTS
from distctrl.sim.scenario import scenario_from_dict

from . import RawClient

SCN = pathlib.Path(__file__).resolve().parents[2] / "examples" / "scenarios"
AXIS = 1 << 16          # index offset of axis 1's objects


@pytest.fixture(scope="module")
def served():
    """The served machine with its ADS server but no cycle thread: the test steps it."""
    sc = scenario_from_dict({
        "name": "read cache", "program_text": "N10 #TIME 3600\nN20 M30\n",
        "axes": {"Z": {"params": str(SCN / "z_probe.lis"), "start": 40.0}},
        "surface": {"base": 40.0},
        "sensor": {"axis": "Z", "kind": "encoder", "range_min": -20.0, "range_max": 20.0}}, base_dir=SCN)
    sm = serve_over_ads(sc, port=0, discovery_port=None)
    sm.services["ads"].server.start()
    try:
        yield sm
    finally:
        sm.services["ads"].server.stop()


def raw_read(c: RawClient, ig: int, io: int, length: int, invoke: int, source_port: int = 32905) -> bytes:
    """The response frame's AMS part (header and data) of one Read request to the CNC port."""
    c.send(P.read_request(ig, io, length, invoke_id=invoke, target_port=CNC_PORT, source_port=source_port))
    _, body = c.recv_frame()
    return body


def without_invoke(body: bytes) -> bytes:
    return body[:28] + body[32:]


def step(served, cycles: int) -> None:
    for _ in range(cycles):
        with served.lock:
            served.step()


def no_full_path(*a, **k):
    raise AssertionError("the full path was taken")


def test_every_object_answers_from_the_cache_as_the_full_path_does(served, monkeypatch):
    srv = served.services["ads"].server
    with RawClient(srv.port) as c:
        for cycles in (0, 5):
            step(served, cycles)
            for spec in SERVED_OBJECTS:
                args = (spec.index_group, AXIS | spec.low_offset, spec.length)
                srv._read_cache.clear()
                full = raw_read(c, *args, invoke=7)
                with monkeypatch.context() as m:       # the second read: from the cache
                    m.setattr(served.services["ads"].cnc, "read", no_full_path)
                    cached = raw_read(c, *args, invoke=0x12345678)
                assert struct.unpack_from("<I", cached, 28)[0] == 0x12345678, spec.name
                assert without_invoke(cached) == without_invoke(full), spec.name
    assert srv._read_cache, "no Read request was kept"


def test_the_cache_answers_without_the_device_and_with_the_live_value(served, monkeypatch):
    srv = served.services["ads"].server
    v_max = BY_NAME["DIST_CTRL_PARAM[0]::v_max"]     # reads the pending value while a write waits
    args = (v_max.index_group, AXIS | v_max.low_offset, 4)          # SGN32, µm/s
    with RawClient(srv.port) as c:
        first = P.parse_response(raw_read(c, *args, invoke=1))
        assert first.result == 0
        with monkeypatch.context() as m:
            m.setattr(served.services["ads"].cnc, "read", no_full_path)
            again = P.parse_response(raw_read(c, *args, invoke=2))
        assert again.result == 0 and again.data == first.data
        # a write over ADS: the next read, from the cache, gives the new value
        new = struct.unpack("<i", first.data)[0] // 2
        assert new > 0
        assert c.write(v_max.index_group, AXIS | v_max.low_offset, struct.pack("<i", new),
                       target_port=CNC_PORT).result == 0
        step(served, 2)
        with monkeypatch.context() as m:
            m.setattr(served.services["ads"].cnc, "read", no_full_path)
            after = P.parse_response(raw_read(c, *args, invoke=3))
        assert after.result == 0 and struct.unpack("<i", after.data)[0] == new


def test_each_source_has_its_own_answer_head(served, monkeypatch):
    srv = served.services["ads"].server
    kp = BY_NAME["DIST_CTRL::kp"]
    args = (kp.index_group, AXIS | kp.low_offset, 8)
    srv._read_cache.clear()
    with RawClient(srv.port) as c:
        a1, b1 = raw_read(c, *args, invoke=1, source_port=30001), raw_read(c, *args, invoke=2, source_port=30002)
        monkeypatch.setattr(served.services["ads"].cnc, "read", no_full_path)
        a2, b2 = raw_read(c, *args, invoke=3, source_port=30001), raw_read(c, *args, invoke=4, source_port=30002)
    for body, port, invoke in ((a2, 30001, 3), (b2, 30002, 4)):
        hdr = P.AmsHeader.unpack(body)
        assert (hdr.target_port, hdr.invoke_id, hdr.is_response) == (port, invoke, True)
    assert without_invoke(a2) == without_invoke(a1) and without_invoke(b2) == without_invoke(b1)


def test_errors_and_replaced_devices_go_through_the_full_path(served, monkeypatch):
    srv = served.services["ads"].server
    kp = BY_NAME["DIST_CTRL::kp"]
    args = (kp.index_group, AXIS | kp.low_offset, 8)
    with RawClient(srv.port) as c:
        assert P.parse_response(raw_read(c, *args, invoke=1)).result == 0
        # a reader that fails now: the full path answers (here with the device's own error)
        for key, entry in list(srv._read_cache.items()):
            def failing():
                raise RuntimeError("the object went away")
            srv._read_cache[key] = entry[:2] + (failing,) + entry[3:]

        def busy(*a, **k):
            from distctrl.ads.errors import AdsError
            raise AdsError(0x708, "busy")

        monkeypatch.setattr(served.services["ads"].cnc, "read", busy)
        assert P.parse_response(raw_read(c, *args, invoke=2)).result == 0x708
        monkeypatch.undo()
        # another device at the port: the cached reader of the old one is not used
        srv._read_cache.clear()
        assert P.parse_response(raw_read(c, *args, invoke=3)).result == 0
        monkeypatch.setitem(srv.devices, CNC_PORT, _Refusing())
        assert P.parse_response(raw_read(c, *args, invoke=4)).result == 0x702


def test_requests_the_cache_does_not_keep(served):
    """Errors, the symbol groups and the runtime state (0xF100) are never kept."""
    srv = served.services["ads"].server
    srv._read_cache.clear()
    with RawClient(srv.port) as c:
        assert P.parse_response(raw_read(c, INDEX_GROUP, AXIS | 0xFFFF, 8, invoke=1)).result != 0
        assert P.parse_response(raw_read(c, 0xF100, 0, 1, invoke=2)).result == 0
        assert P.parse_response(raw_read(c, P.ADSIGRP_SYM_UPLOADINFO, 0, 24, invoke=3)).result == 0
    assert not srv._read_cache


class _Refusing:
    name = "refusing"
    version = (1, 0, 0)

    def read(self, index_group, index_offset, length):
        from distctrl.ads.errors import AdsError
        raise AdsError(0x702, "invalid index group")

    def write(self, index_group, index_offset, data):
        raise AssertionError

    def symbols(self):
        return {}

    def state(self):
        return (5, 0)
