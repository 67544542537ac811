"""ADS services over a raw socket: symbol services, sum commands, handles, lock, routing errors."""
from __future__ import annotations

import struct
import threading
import time

import pytest

from distctrl.ads import AdsServer
from distctrl.ads import errors as E
from distctrl.ads import protocol as P

from . import IG_BOOM, IG_DATA, IG_RO, MemoryDevice, RawClient


@pytest.fixture(scope="module")
def lock():
    return threading.Lock()


@pytest.fixture(scope="module")
def device(lock):
    return MemoryDevice(lock=lock)


@pytest.fixture(scope="module")
def server(device, lock):
    srv = AdsServer({851: device, 551: MemoryDevice("NC", (1, 0, 0), lock=lock)}, port=0, lock=lock,
                    max_handles=8)
    srv.start()
    try:
        yield srv
    finally:
        srv.stop()


@pytest.fixture()
def c(server):
    with RawClient(server.port) as client:
        yield client


def u32(data: bytes) -> int:
    return struct.unpack("<I", data)[0]


# --- basic commands ------------------------------------------------------------------------------
def test_read_state_device_info(c):
    r = c.call(P.request, P.CMD_READ_STATE, b"")
    assert r.result == 0 and struct.unpack("<HH", r.data) == (P.ADSSTATE_RUN, 0)
    r = c.call(P.request, P.CMD_READ_DEVICE_INFO, b"")
    assert r.result == 0
    major, minor, build = struct.unpack("<BBH", r.data[:4])
    assert (major, minor, build) == (3, 1, 4024) and r.data[4:].rstrip(b"\0") == b"TestPLC"


def test_write_control_not_supported(c):
    r = c.call(P.request, P.CMD_WRITE_CONTROL, P.WRITE_CONTROL_REQ.pack(6, 0, 0))
    assert r.result == E.ADSERR_DEVICE_SRVNOTSUPP


def test_write_control_if_the_device_has_it(c, server, device):
    seen = []
    device.write_control = lambda a, d, data: seen.append((a, d, data))
    try:
        r = c.call(P.request, P.CMD_WRITE_CONTROL, P.WRITE_CONTROL_REQ.pack(6, 1, 2) + b"xy")
        assert r.result == 0 and seen == [(6, 1, b"xy")]
    finally:
        del device.write_control


def test_routing_errors_in_ams_header(c):
    r = c.read(IG_DATA, 0, 4, target_port=999)
    assert r.header.error_code == E.ERR_TARGETPORTNOTFOUND and r.header.length == 0 and r.result is None
    r = c.read(IG_DATA, 0, 4, target="5.6.7.8.1.1")
    assert r.header.error_code == E.ERR_TARGETMACHINENOTFOUND and r.header.length == 0


def test_net_id_check_can_be_disabled():
    with AdsServer({851: MemoryDevice()}, port=0, check_net_id=False) as srv, RawClient(srv.port) as c:
        assert c.read(IG_DATA, 0, 4, target="5.6.7.8.1.1").result == 0


def test_raw_read_write(c, device):
    assert c.write(IG_DATA, 0, struct.pack("<I", 4711)).result == 0
    assert device.udint(0) == 4711
    r = c.read(IG_DATA, 0, 4)
    assert r.result == 0 and u32(r.data) == 4711
    assert c.read(0x9999, 0, 4).result == E.ADSERR_DEVICE_INVALIDGRP
    assert c.write(IG_RO, 0, b"\0\0\0\0").result == E.ADSERR_DEVICE_INVALIDACCESS
    assert c.read(IG_DATA, 0, 2).result == E.ADSERR_DEVICE_INVALIDSIZE


def test_device_exception_is_0x700(c, caplog):
    r = c.read(IG_BOOM, 0, 4)
    assert r.result == E.ADSERR_DEVICE_ERROR
    assert "simulated device fault" in caplog.text
    assert c.read(IG_DATA, 0, 4).result == 0


# --- symbols -------------------------------------------------------------------------------------
def test_handle_lifecycle(c, device):
    h = c.handle("MAIN.value")
    assert c.write(P.ADSIGRP_SYM_VALBYHND, h, struct.pack("<d", 8.5)).result == 0
    assert device.lreal(8) == 8.5
    r = c.read(P.ADSIGRP_SYM_VALBYHND, h, 8)
    assert r.result == 0 and struct.unpack("<d", r.data)[0] == 8.5
    assert c.read(P.ADSIGRP_SYM_VALBYHND, h, 4).result == E.ADSERR_DEVICE_INVALIDSIZE
    assert c.write(P.ADSIGRP_SYM_RELEASEHND, 0, struct.pack("<I", h)).result == 0
    assert c.read(P.ADSIGRP_SYM_VALBYHND, h, 8).result == E.ADSERR_DEVICE_SYMBOLNOTFOUND
    assert c.write(P.ADSIGRP_SYM_RELEASEHND, 0, struct.pack("<I", h)).result == E.ADSERR_DEVICE_SYMBOLNOTFOUND


def test_handle_names_without_nul_and_case(c):
    r = c.read_write(P.ADSIGRP_SYM_HNDBYNAME, 0, 4, b"main.Value")
    assert r.result == 0 and len(r.data) == 4
    r = c.read_write(P.ADSIGRP_SYM_HNDBYNAME, 0, 4, b"MAIN.nope\0")
    assert r.result == E.ADSERR_DEVICE_SYMBOLNOTFOUND
    r = c.read_write(P.ADSIGRP_SYM_HNDBYNAME, 0, 2, b"MAIN.value\0")
    assert r.result == E.ADSERR_DEVICE_INVALIDSIZE


def test_handles_are_unique_per_connection_and_port(server, c):
    h1, h2 = c.handle("MAIN.value"), c.handle("MAIN.value")
    assert h1 != h2
    with RawClient(server.port) as other:
        assert other.read(P.ADSIGRP_SYM_VALBYHND, h1, 8).result == E.ADSERR_DEVICE_SYMBOLNOTFOUND
    assert c.read(P.ADSIGRP_SYM_VALBYHND, h1, 8, target_port=551).result == E.ADSERR_DEVICE_SYMBOLNOTFOUND
    assert c.read(P.ADSIGRP_SYM_VALBYHND, h1, 8).result == 0


def test_handle_limit(c):
    handles = [c.handle("MAIN.counter") for _ in range(8)]
    r = c.read_write(P.ADSIGRP_SYM_HNDBYNAME, 0, 4, b"MAIN.counter\0")
    assert r.result == E.ADSERR_DEVICE_NOMEMORY
    assert c.write(P.ADSIGRP_SYM_RELEASEHND, 0, struct.pack("<I", handles[0])).result == 0
    assert c.handle("MAIN.counter") not in handles


def test_value_by_name(c):
    r = c.read_write(P.ADSIGRP_SYM_VALBYNAME, 0, 2, b"MAIN.small\0")
    assert r.result == 0 and struct.unpack("<h", r.data)[0] == -5


def test_read_only_symbol(c, device):
    h = c.handle("GVL.version")
    r = c.read(P.ADSIGRP_SYM_VALBYHND, h, 4)
    assert r.result == 0 and u32(r.data) == 0x01020304
    assert c.write(P.ADSIGRP_SYM_VALBYHND, h, b"\0\0\0\0").result == E.ADSERR_DEVICE_INVALIDACCESS
    assert device.udint(0, IG_RO) == 0x01020304


def test_string_symbol_lengths(c, device):
    h = c.handle("GVL.text")
    assert c.write(P.ADSIGRP_SYM_VALBYHND, h, b"abc\0").result == 0     # shorter: padded
    r = c.read(P.ADSIGRP_SYM_VALBYHND, h, 1024)                          # larger buffer: whole string
    assert r.result == 0 and len(r.data) == 21 and r.data.rstrip(b"\0") == b"abc"
    r = c.read(P.ADSIGRP_SYM_VALBYHND, h, 2)
    assert r.result == 0 and r.data == b"ab"
    assert c.write(P.ADSIGRP_SYM_VALBYHND, h, b"x" * 22).result == E.ADSERR_DEVICE_INVALIDSIZE


def test_symbol_info_by_name_ex(c):
    r = c.read_write(P.ADSIGRP_SYM_INFOBYNAMEEX, 0, P.SYMBOL_ENTRY_MAX, b"gvl.VERSION\0")
    assert r.result == 0
    assert u32(r.data[:4]) == len(r.data)                 # entryLength == bytes returned
    sym = P.decode_symbol_entry(r.data)
    assert sym.name == "GVL.version" and sym.type_name == "UDINT" and sym.comment == "read-only"
    assert (sym.index_group, sym.index_offset, sym.size, sym.ads_type) == (IG_RO, 0, 4, P.ADST_UINT32)
    assert sym.read_only
    r = c.read_write(P.ADSIGRP_SYM_INFOBYNAMEEX, 0, 10, b"GVL.version\0")
    assert r.result == E.ADSERR_DEVICE_INVALIDSIZE


def test_symbol_upload(c, device):
    r = c.read(P.ADSIGRP_SYM_UPLOADINFO2, 0, 24)
    assert r.result == 0
    count, size = struct.unpack("<II", r.data[:8])
    assert count == len(device.symbols())
    r = c.read(P.ADSIGRP_SYM_UPLOAD, 0, size)
    assert r.result == 0 and len(r.data) == size
    pos, names = 0, []
    while pos < size:
        names.append(P.decode_symbol_entry(r.data[pos:]).name)
        pos += u32(r.data[pos:pos + 4])
    assert names == list(device.symbols())


# --- sum commands ----------------------------------------------------------------------------------
def test_sum_read_with_a_failing_item(c):
    reqs = [(IG_DATA, 0, 4), (0x9999, 0, 4), (IG_DATA, 8, 8), (IG_DATA, 8, 2)]
    data = b"".join(P.SUM_REQ.pack(*r) for r in reqs)
    rlen = 4 * len(reqs) + sum(r[2] for r in reqs)
    r = c.read_write(P.ADSIGRP_SUMUP_READ, len(reqs), rlen, data)
    assert r.result == 0 and len(r.data) == rlen
    codes = struct.unpack("<4I", r.data[:16])
    assert codes == (0, E.ADSERR_DEVICE_INVALIDGRP, 0, E.ADSERR_DEVICE_INVALIDSIZE)
    assert r.data[20:24] == b"\0\0\0\0"                   # failed item: zero-filled, layout kept
    # too small a buffer for the answer
    assert c.read_write(P.ADSIGRP_SUMUP_READ, len(reqs), rlen - 1, data).result == E.ADSERR_DEVICE_INVALIDSIZE
    # fewer sub-requests than announced
    assert c.read_write(P.ADSIGRP_SUMUP_READ, 9, 500, data).result == E.ADSERR_DEVICE_INVALIDSIZE


def test_sum_read_by_handles_and_exception_item(c):
    h = c.handle("MAIN.small")
    data = P.SUM_REQ.pack(P.ADSIGRP_SYM_VALBYHND, h, 2) + P.SUM_REQ.pack(IG_BOOM, 0, 4)
    r = c.read_write(P.ADSIGRP_SUMUP_READ, 2, 8 + 6, data)
    assert struct.unpack("<II", r.data[:8]) == (0, E.ADSERR_DEVICE_ERROR)
    assert struct.unpack("<h", r.data[8:10])[0] == -5


def test_sum_write(c, device):
    head = P.SUM_REQ.pack(IG_DATA, 0, 4) + P.SUM_REQ.pack(IG_RO, 0, 4) + P.SUM_REQ.pack(IG_DATA, 8, 8)
    data = head + struct.pack("<I", 31) + struct.pack("<I", 1) + struct.pack("<d", -1.5)
    r = c.read_write(P.ADSIGRP_SUMUP_WRITE, 3, 12, data)
    assert r.result == 0
    assert struct.unpack("<3I", r.data) == (0, E.ADSERR_DEVICE_INVALIDACCESS, 0)
    assert device.udint(0) == 31 and device.lreal(8) == -1.5
    assert c.read_write(P.ADSIGRP_SUMUP_WRITE, 3, 12, data[:-1]).result == E.ADSERR_DEVICE_INVALIDSIZE


def test_sum_read_write_gets_handles(c):
    names = [b"MAIN.counter\0", b"MAIN.nope\0", b"GVL.flag\0"]
    head = b"".join(P.SUM_RW_REQ.pack(P.ADSIGRP_SYM_HNDBYNAME, 0, 4, len(n)) for n in names)
    r = c.read_write(P.ADSIGRP_SUMUP_READWRITE, 3, 3 * 8 + 12, head + b"".join(names))
    assert r.result == 0
    res = [struct.unpack_from("<II", r.data, 8 * i) for i in range(3)]
    assert res == [(0, 4), (E.ADSERR_DEVICE_SYMBOLNOTFOUND, 0), (0, 4)]
    h_counter, h_flag = struct.unpack_from("<II", r.data, 24)
    rr = c.read(P.ADSIGRP_SYM_VALBYHND, h_flag, 1)
    assert rr.result == 0 and len(rr.data) == 1
    assert c.read(P.ADSIGRP_SYM_VALBYHND, h_counter, 4).result == 0
    # a nested sum command is refused per item
    nested = P.SUM_RW_REQ.pack(P.ADSIGRP_SUMUP_READ, 0, 4, 0)
    r = c.read_write(P.ADSIGRP_SUMUP_READWRITE, 1, 8, nested)
    assert struct.unpack("<II", r.data) == (E.ADSERR_DEVICE_SRVNOTSUPP, 0)


# --- lock ----------------------------------------------------------------------------------------
def test_requests_wait_for_the_lock(server, lock, c):
    """While the simulation holds the lock no device call happens; the answer comes after release."""
    done = threading.Event()
    result = {}

    def reader():
        with RawClient(server.port) as other:
            result["r"] = other.read(IG_DATA, 0, 4)
        done.set()

    with lock:
        t = threading.Thread(target=reader)
        t.start()
        assert not done.wait(0.3)
    assert done.wait(3.0)
    t.join()
    assert result["r"].result == 0
    # the device asserts the lock is held on every call (MemoryDevice(lock=...)); it was:
    assert c.read(IG_DATA, 0, 4).result == 0


def test_lock_timeout_answers_busy():
    lock = threading.Lock()
    with AdsServer({851: MemoryDevice(lock=lock)}, port=0, lock=lock, lock_timeout=0.1) as srv, \
            RawClient(srv.port) as c:
        with lock:
            assert c.read(IG_DATA, 0, 4).result == E.ADSERR_DEVICE_BUSY
        assert c.read(IG_DATA, 0, 4).result == 0


def test_many_small_requests_are_fast(c):
    t0 = time.perf_counter()
    for _ in range(500):
        assert c.read(IG_DATA, 0, 4).result == 0
    assert time.perf_counter() - t0 < 5.0


# --- "any size" reads of the symbol services (issue 14: ads-client asks with 0xFFFFFFFF) -----------------
ANY = 0xFFFFFFFF


def test_symbol_reads_take_the_length_as_a_capacity_and_answer_the_real_size(c, device):
    h = c.handle("MAIN.value")
    assert c.write(P.ADSIGRP_SYM_VALBYHND, h, struct.pack("<d", 2.25)).result == 0
    for length in (9, 64, ANY):
        r = c.read(P.ADSIGRP_SYM_VALBYHND, h, length)
        assert r.result == 0 and struct.unpack("<d", r.data) == (2.25,), length
    r = c.read_write(P.ADSIGRP_SYM_VALBYNAME, 0, ANY, b"MAIN.value\0")
    assert r.result == 0 and struct.unpack("<d", r.data) == (2.25,)
    r = c.read_write(P.ADSIGRP_SYM_INFOBYNAMEEX, 0, ANY, b"MAIN.value\0")
    assert r.result == 0 and P.decode_symbol_entry(r.data).name == "MAIN.value"
    r = c.read_write(P.ADSIGRP_SYM_HNDBYNAME, 0, ANY, b"MAIN.value\0")   # + size, decoration, type name
    assert r.result == 0 and struct.unpack_from("<IIIH", r.data)[1:] == (8, 0, 5) and r.data[14:] == b"LREAL\0"
    # smaller than the symbol stays an error; a device's own index group keeps the exact-size rule
    assert c.read(P.ADSIGRP_SYM_VALBYHND, h, 7).result == E.ADSERR_DEVICE_INVALIDSIZE
    assert c.read(IG_DATA, 0, ANY).result == E.ADSERR_DEVICE_INVALIDSIZE


# --- the dispatch tables ---------------------------------------------------------------------------
def test_every_index_group_the_server_answers_itself_has_a_service(c):
    """An index group in the server's own set is never passed to a device, so it must be served:
    0xF007 (SymbolInfoByName) was in the set with no service and answered 0x701 to everything."""
    from distctrl.ads.server import SYMBOL_GROUPS

    for ig in sorted(SYMBOL_GROUPS):
        results = {c.read(ig, 0, 4).result, c.write(ig, 0, b"\0" * 4).result,
                   c.read_write(ig, 0, 4, b"MAIN.value\0").result}
        assert results != {E.ADSERR_DEVICE_SRVNOTSUPP}, hex(ig)


def test_the_dispatch_tables_cover_every_command_and_served_group():
    from distctrl.ads import services as S

    # every request command has a handler and an error reply (DeviceNotification goes server -> client)
    assert set(S._COMMANDS) == set(P.COMMAND_NAMES) - {P.CMD_DEVICE_NOTIFICATION}
    for cmd, (handler, error_reply) in S._COMMANDS.items():
        assert callable(handler) and error_reply(E.ADSERR_DEVICE_ERROR)[:4] == struct.pack("<I", E.ADSERR_DEVICE_ERROR)
    assert S._SYMBOL_GROUPS == frozenset(S._SYMBOL_SERVICES)
    for ig, service in S._SYMBOL_SERVICES.items():
        assert any((service.read, service.write, service.read_write)), hex(ig)
