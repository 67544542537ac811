"""What a TwinCAT 3 target answers before any symbol is read (issue 14): the system service on AMS port
10000, the PLC runtime state at index group 0xF100 (read and notification), WriteControl RUN/STOP."""
from __future__ import annotations

import struct
import time
from pathlib import Path

import pytest

from distctrl.ads import errors as E
from distctrl.ads import protocol as P
from distctrl.ads.devices import CNC_PORT, DEVICE_DATA_GROUP, SYSTEM_SERVICE_PORT, serve_over_ads
from distctrl.sim.scenario import load_scenario

from . import RawClient, wait_for

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


@pytest.fixture()
def served():
    with serve_over_ads(load_scenario(SCN / "serve_z.toml"), port=0) as s:
        yield s


@pytest.fixture()
def c(served):
    with RawClient(served.services["ads"].server.port) as client:
        yield client


def test_the_system_service_on_port_10000_says_run_and_who_it_is(c):
    r = c.call(P.request, P.CMD_READ_STATE, b"", target_port=SYSTEM_SERVICE_PORT)
    assert r.result == 0 and struct.unpack("<HH", r.data) == (P.ADSSTATE_RUN, 0)
    r = c.call(P.request, P.CMD_READ_DEVICE_INFO, b"", target_port=SYSTEM_SERVICE_PORT)
    assert r.result == 0 and r.data[4:].rstrip(b"\0") == b"TwinCAT System"
    assert c.read(0x4020, 0, 8, target_port=SYSTEM_SERVICE_PORT).result == E.ADSERR_DEVICE_INVALIDGRP


def test_the_plc_runtime_state_is_read_at_0xf100(c):
    r = c.read(DEVICE_DATA_GROUP, 0, 4)
    assert r.result == 0 and struct.unpack("<HH", r.data) == (P.ADSSTATE_RUN, 0)
    assert c.read(DEVICE_DATA_GROUP, 0, 8).result == E.ADSERR_DEVICE_INVALIDSIZE


def test_write_control_stop_pauses_the_machine_and_run_resumes_it(served, c):
    r = c.add_notification(DEVICE_DATA_GROUP, 0, 4)               # on change, as ads-client subscribes
    assert r.result == 0
    _, first = c.recv_notification()
    assert struct.unpack("<HH", first[0][2]) == (P.ADSSTATE_RUN, 0)
    stop = c.call(P.request, P.CMD_WRITE_CONTROL, P.WRITE_CONTROL_REQ.pack(P.ADSSTATE_STOP, 0, 0))
    assert stop.result == 0
    _, changed = c.recv_notification()
    assert struct.unpack("<HH", changed[-1][2]) == (P.ADSSTATE_STOP, 0)
    r = c.call(P.request, P.CMD_READ_STATE, b"")
    assert struct.unpack("<HH", r.data) == (P.ADSSTATE_STOP, 0)
    held = served.machine.cycle
    time.sleep(0.1)
    assert served.machine.cycle == held                            # the cycle holds
    assert c.call(P.request, P.CMD_WRITE_CONTROL, P.WRITE_CONTROL_REQ.pack(P.ADSSTATE_RUN, 0, 0)).result == 0
    assert wait_for(lambda: served.machine.cycle > held + 10)
    bad = c.call(P.request, P.CMD_WRITE_CONTROL, P.WRITE_CONTROL_REQ.pack(P.ADSSTATE_INIT, 0, 0))
    assert bad.result == E.ADSERR_DEVICE_INVALIDPARM


def test_port_close_is_answered_by_closing_the_connection(c):
    """ads-client's disconnect unregisters its AMS port (AMS/TCP 0x0001, 2 bytes: the port) and waits
    for the router to drop the connection."""
    r = c.call(P.request, P.CMD_READ_STATE, b"")
    assert r.result == 0
    c.send(P.AMS_TCP_HEADER.pack(P.AMS_TCP_PORT_CLOSE, 2) + struct.pack("<H", 32905))
    assert c.is_closed_by_server(timeout=2.0)


def test_the_cnc_port_serves_the_runtime_state_too(served, c):
    """ads-client's default connect subscribes to 0xF100 of the port it targets: on port 551 (the GEO
    task's CNC objects) too, so it connects there without its rawClient setting."""
    r = c.read(DEVICE_DATA_GROUP, 0, 4, target_port=CNC_PORT)
    assert r.result == 0 and struct.unpack("<HH", r.data) == (P.ADSSTATE_RUN, 0)
    served.set_paused(True)
    try:
        r = c.read(DEVICE_DATA_GROUP, 0, 4, target_port=CNC_PORT)
        assert struct.unpack("<HH", r.data) == (P.ADSSTATE_STOP, 0)
    finally:
        served.set_paused(False)
    assert c.read(DEVICE_DATA_GROUP, 0, 8, target_port=CNC_PORT).result == E.ADSERR_DEVICE_INVALIDSIZE
