"""The server against the REAL pyads client (pyads 3.6 with its bundled Linux AdsLib).

The bundled AdsLib always connects to TCP port 48898 of the given IP, so the server of this module
runs on 127.0.0.1:48898 (module-scoped; stopped at the end). If the port is taken the module is
skipped with that reason.
"""
from __future__ import annotations

import logging
import math
import socket
import time

import pytest

pyads = pytest.importorskip("pyads")

from pyads.errorcodes import ERROR_CODES

from distctrl.ads import AdsServer
from distctrl.ads import errors as E

from . import IG_DATA, IG_RO, MemoryDevice, wait_for

NET_ID = "127.0.0.1.1.1"
PLC_PORT = 851
NC_PORT = 551


def _port_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


@pytest.fixture(scope="module")
def devices():
    return {PLC_PORT: MemoryDevice("TestPLC", (3, 1, 4024)), NC_PORT: MemoryDevice("TestNC", (1, 2, 3))}


@pytest.fixture(scope="module")
def server(devices):
    if not _port_free(48898):
        pytest.skip("TCP port 48898 is in use; the pyads AdsLib can only connect to 48898")
    srv = AdsServer(devices, host="127.0.0.1", port=48898, net_id=NET_ID)
    srv.start()
    try:
        yield srv
    finally:
        srv.stop()


@pytest.fixture(scope="module")
def plc(server):
    # The recipe for pyads on Linux: a Connection(<server NetId>, <AMS port>, <server IP>) - open()
    # adds the AdsLib route NetId -> IP itself. set_local_address only chooses our source NetId.
    pyads.set_local_address("127.0.0.1.1.2")
    conn = pyads.Connection(NET_ID, PLC_PORT, "127.0.0.1")
    conn.open()
    try:
        yield conn
    finally:
        conn.close()


@pytest.fixture()
def conn_to(server):
    opened = []

    def make(port: int, net_id: str = NET_ID):
        c = pyads.Connection(net_id, port, "127.0.0.1")
        c.open()
        opened.append(c)
        return c

    yield make
    for c in opened:
        c.close()


def _err(excinfo) -> int:
    return excinfo.value.err_code


# ---------------------------------------------------------------------------------------------
def test_read_state_and_device_info(plc):
    assert plc.read_state() == (pyads.ADSSTATE_RUN, 0)
    name, version = plc.read_device_info()
    assert name == "TestPLC"
    assert (version.version, version.revision, version.build) == (3, 1, 4024)


def test_second_ams_port_is_a_second_device(conn_to):
    nc = conn_to(NC_PORT)
    name, version = nc.read_device_info()
    assert name == "TestNC"
    assert (version.version, version.revision, version.build) == (1, 2, 3)


def test_read_write_by_index_group_offset(plc, devices):
    assert plc.read(IG_DATA, 8, pyads.PLCTYPE_LREAL) == pytest.approx(3.25)
    plc.write(IG_DATA, 8, -12.5, pyads.PLCTYPE_LREAL)
    assert plc.read(IG_DATA, 8, pyads.PLCTYPE_LREAL) == -12.5
    assert devices[PLC_PORT].lreal(8) == -12.5

    plc.write(IG_DATA, 0, 4000000000, pyads.PLCTYPE_UDINT)
    assert plc.read(IG_DATA, 0, pyads.PLCTYPE_UDINT) == 4000000000

    plc.write(IG_DATA, 16, False, pyads.PLCTYPE_BOOL)
    assert plc.read(IG_DATA, 16, pyads.PLCTYPE_BOOL) is False
    plc.write(IG_DATA, 16, True, pyads.PLCTYPE_BOOL)
    assert plc.read(IG_DATA, 16, pyads.PLCTYPE_BOOL) is True


def test_read_write_by_name(plc):
    plc.write_by_name("MAIN.value", 1.75)               # type from the symbol info
    assert plc.read_by_name("MAIN.value") == 1.75
    plc.write_by_name("MAIN.counter", 17, pyads.PLCTYPE_UDINT)
    assert plc.read_by_name("MAIN.counter", pyads.PLCTYPE_UDINT) == 17
    assert plc.read_by_name("main.COUNTER", pyads.PLCTYPE_UDINT) == 17  # case-insensitive
    plc.write_by_name("GVL.flag", False)
    assert plc.read_by_name("GVL.flag") is False
    plc.write_by_name("MAIN.small", -300)
    assert plc.read_by_name("MAIN.small") == -300


def test_string_symbol(plc):
    assert plc.read_by_name("GVL.text", pyads.PLCTYPE_STRING) == "hello"
    plc.write_by_name("GVL.text", "distance", pyads.PLCTYPE_STRING)
    assert plc.read_by_name("GVL.text", pyads.PLCTYPE_STRING) == "distance"
    plc.write_by_name("GVL.text", "ok", pyads.PLCTYPE_STRING)   # shorter: the rest is cleared
    assert plc.read_by_name("GVL.text", pyads.PLCTYPE_STRING) == "ok"


def test_handles(plc):
    h = plc.get_handle("MAIN.value")
    h2 = plc.get_handle("MAIN.counter")
    assert h and h2 and h != h2
    plc.write_by_name("", 99.5, pyads.PLCTYPE_LREAL, handle=h)
    assert plc.read_by_name("", pyads.PLCTYPE_LREAL, handle=h) == 99.5
    plc.write_by_name("", 5, pyads.PLCTYPE_UDINT, handle=h2)
    assert plc.read_by_name("", pyads.PLCTYPE_UDINT, handle=h2) == 5
    plc.release_handle(h)
    plc.release_handle(h2)
    with pytest.raises(pyads.ADSError) as ei:
        plc.read_by_name("", pyads.PLCTYPE_LREAL, handle=h)
    assert _err(ei) == E.ADSERR_DEVICE_SYMBOLNOTFOUND
    with pytest.raises(pyads.ADSError) as ei:
        plc.release_handle(h)
    assert _err(ei) == E.ADSERR_DEVICE_SYMBOLNOTFOUND


def test_sum_read_and_write(plc, devices):
    res = plc.write_list_by_name({"MAIN.value": 6.5, "MAIN.counter": 123, "GVL.flag": True})
    assert res == {"MAIN.value": "no error", "MAIN.counter": "no error", "GVL.flag": "no error"}
    dev = devices[PLC_PORT]
    assert dev.lreal(8) == 6.5 and dev.udint(0) == 123
    values = plc.read_list_by_name(["MAIN.value", "MAIN.counter", "GVL.flag", "GVL.version"])
    assert values == {"MAIN.value": 6.5, "MAIN.counter": 123, "GVL.flag": True, "GVL.version": 0x01020304}
    # more names than one sum command takes: pyads splits them
    many = plc.read_list_by_name(["MAIN.counter", "MAIN.value"] * 3, ads_sub_commands=2)
    assert many == {"MAIN.counter": 123, "MAIN.value": 6.5}


def test_sum_write_reports_errors_per_item(plc, devices):
    res = plc.write_list_by_name({"MAIN.counter": 7, "GVL.version": 1})
    assert res["MAIN.counter"] == "no error"
    assert res["GVL.version"] == ERROR_CODES[E.ADSERR_DEVICE_INVALIDACCESS]
    assert devices[PLC_PORT].udint(0) == 7
    assert devices[PLC_PORT].udint(0, IG_RO) == 0x01020304


def test_symbol_info(plc):
    sym = plc.get_symbol("MAIN.value")
    assert (sym.index_group, sym.index_offset) == (IG_DATA, 8)
    assert sym.symbol_type == "LREAL"
    assert sym.comment == "a real value"
    sym.write(2.0)
    assert sym.read() == 2.0
    flag = plc.get_symbol("GVL.flag")
    assert flag.symbol_type == "BOOL" and flag.plc_type == pyads.PLCTYPE_BOOL
    names = {s.name: s.symbol_type for s in plc.get_all_symbols()}
    assert names["MAIN.counter"] == "UDINT" and names["GVL.text"] == "STRING(20)"
    assert len(names) == 7


def test_error_unknown_index_group(plc):
    with pytest.raises(pyads.ADSError) as ei:
        plc.read(0x1234, 0, pyads.PLCTYPE_UDINT)
    assert _err(ei) == E.ADSERR_DEVICE_INVALIDGRP == 0x702
    with pytest.raises(pyads.ADSError) as ei:
        plc.read(IG_DATA, 4, pyads.PLCTYPE_UDINT)
    assert _err(ei) == E.ADSERR_DEVICE_INVALIDOFFSET == 0x703


def test_error_wrong_size(plc):
    with pytest.raises(pyads.ADSError) as ei:
        plc.read(IG_DATA, 8, pyads.PLCTYPE_UDINT)        # LREAL object read as 4 bytes
    assert _err(ei) == E.ADSERR_DEVICE_INVALIDSIZE == 0x705
    with pytest.raises(pyads.ADSError) as ei:
        plc.write_by_name("MAIN.counter", 1, pyads.PLCTYPE_LREAL)  # 8 bytes into a UDINT
    assert _err(ei) == 0x705
    with pytest.raises(pyads.ADSError) as ei:
        plc.read_by_name("MAIN.value", pyads.PLCTYPE_UINT)
    assert _err(ei) == 0x705


def test_error_read_only(plc):
    assert plc.read_by_name("GVL.version") == 0x01020304
    with pytest.raises(pyads.ADSError) as ei:
        plc.write_by_name("GVL.version", 5)
    assert _err(ei) == E.ADSERR_DEVICE_INVALIDACCESS == 0x704
    with pytest.raises(pyads.ADSError) as ei:
        plc.write(IG_RO, 0, 5, pyads.PLCTYPE_UDINT)       # the device refuses raw writes too
    assert _err(ei) == 0x704


def test_error_unknown_symbol(plc):
    with pytest.raises(pyads.ADSError) as ei:
        plc.read_by_name("MAIN.nothing", pyads.PLCTYPE_INT)
    assert _err(ei) == E.ADSERR_DEVICE_SYMBOLNOTFOUND == 0x710
    with pytest.raises(pyads.ADSError) as ei:
        plc.get_handle("MAIN.nothing")
    assert _err(ei) == 0x710
    with pytest.raises(pyads.ADSError) as ei:
        plc.get_symbol("MAIN.nothing")
    assert _err(ei) == 0x710


def test_error_unknown_ams_port_and_net_id(conn_to):
    with pytest.raises(pyads.ADSError) as ei:
        conn_to(999).read_state()
    assert _err(ei) == E.ERR_TARGETPORTNOTFOUND == 0x6
    with pytest.raises(pyads.ADSError) as ei:
        conn_to(PLC_PORT, "10.20.30.40.1.1").read_state()   # routed to our IP, but not our NetId
    assert _err(ei) == E.ERR_TARGETMACHINENOTFOUND == 0x7


def test_device_exception_is_0x700_and_logged(plc, caplog):
    with caplog.at_level(logging.ERROR, logger="distctrl.ads"), pytest.raises(pyads.ADSError) as ei:
        plc.read_by_name("MAIN.boom", pyads.PLCTYPE_UDINT)
    assert _err(ei) == E.ADSERR_DEVICE_ERROR == 0x700
    assert "simulated device fault" in caplog.text
    assert plc.read_state() == (pyads.ADSSTATE_RUN, 0)   # and the server is fine


def test_notification_on_change(plc, server):
    got = []

    def callback(notification, name):
        got.append(plc.parse_notification(notification, pyads.PLCTYPE_UDINT)[2])

    plc.write_by_name("MAIN.counter", 1000, pyads.PLCTYPE_UDINT)
    handles = plc.add_device_notification("MAIN.counter", pyads.NotificationAttrib(4), callback)
    try:
        assert wait_for(lambda: got == [1000])           # the current value first
        for v in (1001, 1002, 1003):
            plc.write_by_name("MAIN.counter", v, pyads.PLCTYPE_UDINT)
            assert wait_for(lambda v=v: got[-1:] == [v])
        time.sleep(0.1)
        assert got == [1000, 1001, 1002, 1003]             # no sample without a change
    finally:
        plc.del_device_notification(*handles)
    plc.write_by_name("MAIN.counter", 5, pyads.PLCTYPE_UDINT)
    time.sleep(0.1)
    assert got[-1] == 1003                                  # deleted: no more samples


def test_notification_cyclic_by_index_group(plc):
    got = []

    def callback(notification, name):
        got.append(plc.parse_notification(notification, pyads.PLCTYPE_LREAL)[2])

    plc.write(IG_DATA, 8, 0.5, pyads.PLCTYPE_LREAL)
    attr = pyads.NotificationAttrib(8, trans_mode=pyads.ADSTRANS_SERVERCYCLE, cycle_time=20)  # ms
    handles = plc.add_device_notification((IG_DATA, 8), attr, callback)
    try:
        assert wait_for(lambda: len(got) >= 5)            # unchanged value, sent every cycle
        assert set(got) == {0.5}
    finally:
        plc.del_device_notification(*handles)


def test_notification_errors(plc):
    with pytest.raises(pyads.ADSError) as ei:
        plc.add_device_notification((0x1234, 0), pyads.NotificationAttrib(4), lambda *a: None)
    assert _err(ei) == E.ADSERR_DEVICE_INVALIDGRP
    with pytest.raises(pyads.ADSError) as ei:
        plc.add_device_notification((IG_DATA, 0), pyads.NotificationAttrib(4, trans_mode=pyads.ADSTRANS_CLIENTCYCLE),
                                    lambda *a: None)
    assert _err(ei) == E.ADSERR_DEVICE_TRANSMODENOTSUPP == 0x713


def test_write_control_not_supported(plc):
    with pytest.raises(pyads.ADSError) as ei:
        plc.write_control(pyads.ADSSTATE_STOP, 0, 0, pyads.PLCTYPE_INT)
    assert _err(ei) == E.ADSERR_DEVICE_SRVNOTSUPP == 0x701
    assert math.isfinite(plc.read_by_name("MAIN.value", pyads.PLCTYPE_LREAL))


def test_many_requests_on_one_connection(plc, server):
    before = server.frames
    for i in range(200):
        plc.write(IG_DATA, 0, i, pyads.PLCTYPE_UDINT)
        assert plc.read(IG_DATA, 0, pyads.PLCTYPE_UDINT) == i
    assert server.frames - before == 400
