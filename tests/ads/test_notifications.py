"""Device notifications (AddDeviceNotification / DeleteDeviceNotification) over a raw socket."""
from __future__ import annotations

import pathlib
import socket
import struct
import time

import pytest

from distctrl.ads import AdsServer
from distctrl.ads import errors as E
from distctrl.ads import protocol as P

from . import IG_DATA, MemoryDevice, RawClient, wait_for

SERVER_CYCLE, ON_CHANGE, CLIENT_CYCLE = 3, 4, 1


@pytest.fixture(scope="module")
def device():
    return MemoryDevice()


@pytest.fixture(scope="module")
def server(device):
    srv = AdsServer({851: device, 551: MemoryDevice("NC")}, port=0, max_notifications=4)
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


def test_frame_format_and_first_sample(c):
    r = c.add_notification(IG_DATA, 0, 4, ON_CHANGE, source_port=33000)
    assert r.result == 0
    handle = u32(r.data)
    hdr, samples = c.recv_notification()
    assert hdr.command == P.CMD_DEVICE_NOTIFICATION and hdr.state_flags == P.SF_ADS_COMMAND
    assert P.format_net_id(hdr.target_net_id) == "127.0.0.1.1.2" and hdr.target_port == 33000
    assert P.format_net_id(hdr.source_net_id) == "127.0.0.1.1.1" and hdr.source_port == 851
    assert hdr.invoke_id == 0 and hdr.error_code == 0
    [(ts, h, data)] = samples
    assert h == handle and len(data) == 4
    now_filetime = (time.time() + 11644473600) * 1e7
    assert abs(ts - now_filetime) < 5 * 1e7


def test_on_change_only_sends_changes(c, server):
    c.write(IG_DATA, 48, struct.pack("<h", 7))
    handle = u32(c.add_notification(IG_DATA, 48, 2, ON_CHANGE).data)
    assert c.recv_notification()[1][0][1:] == (handle, struct.pack("<h", 7))
    c.sock.settimeout(0.2)
    with pytest.raises(TimeoutError):
        c.recv_frame()                              # unchanged: nothing
    c.sock.settimeout(5)
    with RawClient(server.port) as other:
        assert other.write(IG_DATA, 48, struct.pack("<h", 8)).result == 0
    assert c.recv_notification()[1][0][1:] == (handle, struct.pack("<h", 8))
    assert c.del_notification(handle).result == 0


def test_cyclic_by_handle_and_delete(c):
    h = c.handle("MAIN.value")
    handle = u32(c.add_notification(P.ADSIGRP_SYM_VALBYHND, h, 8, SERVER_CYCLE, cycle_100ns=0).data)
    t0 = time.monotonic()
    for _ in range(5):
        _, [(_, hh, data)] = c.recv_notification()
        assert hh == handle and len(data) == 8
    assert time.monotonic() - t0 < 2.0             # cycle 0 is raised to the 10 ms minimum
    assert c.del_notification(handle).result == 0
    assert c.del_notification(handle).result == E.ADSERR_DEVICE_NOTIFYHNDINVALID
    c.notes.clear()
    time.sleep(0.1)
    c.sock.settimeout(0.05)                        # drain what was in flight, then silence
    try:
        while True:
            c.recv_frame()
    except TimeoutError:
        pass
    c.sock.settimeout(0.3)
    with pytest.raises(TimeoutError):
        c.recv_frame()


def test_add_errors(c):
    assert c.add_notification(IG_DATA, 0, 4, CLIENT_CYCLE).result == E.ADSERR_DEVICE_TRANSMODENOTSUPP
    assert c.add_notification(IG_DATA, 0, 0).result == E.ADSERR_DEVICE_INVALIDSIZE
    assert c.add_notification(IG_DATA, 0, 1 << 20).result == E.ADSERR_DEVICE_INVALIDWATCHSIZE
    assert c.add_notification(0x1234, 0, 4).result == E.ADSERR_DEVICE_INVALIDGRP
    assert c.add_notification(IG_DATA, 0, 2).result == E.ADSERR_DEVICE_INVALIDSIZE
    r = c.call(P.request, P.CMD_ADD_DEVICE_NOTIFICATION, b"\0" * 10)
    assert r.result == E.ADSERR_DEVICE_INVALIDSIZE and len(r.data) == 4
    assert c.del_notification(12345).result == E.ADSERR_DEVICE_NOTIFYHNDINVALID


def test_limit_and_port_scope(c):
    handles = [u32(c.add_notification(IG_DATA, 0, 4).data) for _ in range(4)]
    assert c.add_notification(IG_DATA, 0, 4).result == E.ADSERR_DEVICE_NOMOREHDLS
    assert c.del_notification(handles[0], target_port=551).result == E.ADSERR_DEVICE_NOTIFYHNDINVALID
    assert c.del_notification(handles[0]).result == 0
    assert c.add_notification(IG_DATA, 0, 4).result == 0


def test_closing_the_connection_ends_its_notifications(server):
    before = set(server._writers)
    c = RawClient(server.port)
    assert c.add_notification(IG_DATA, 0, 4, SERVER_CYCLE, cycle_100ns=100_000).result == 0
    c.recv_notification()
    assert wait_for(lambda: len(set(server._writers) - before) == 1, timeout=5.0)
    (link,) = set(server._writers) - before
    notifier = link.conn.notifier
    assert notifier is not None and notifier.is_alive()   # this connection's notification thread
    c.close()
    notifier.join(3.0)
    link.thread.join(3.0)
    assert not notifier.is_alive() and not link.thread.is_alive()
    assert link not in server._writers


def blocked_for(link, count, seconds: float, meanwhile=None, deadline_s: float = 20.0) -> None:
    """Wait until ``count()`` (what the link has sent) stays the same for ``seconds`` while the link
    waits in a send; ``meanwhile()`` (which must return true) runs all along."""
    deadline = time.monotonic() + deadline_s
    while True:
        before, t0 = count(), time.monotonic()
        while time.monotonic() - t0 < seconds:
            if meanwhile is None:
                time.sleep(0.01)
            else:
                assert meanwhile()
        if count() <= before + 1 and link.sending:
            return
        assert time.monotonic() < deadline, "the link's sends never stayed blocked"


def test_client_that_does_not_read_notifications(server):
    """64 KiB cyclic samples to a client that never reads: the notification thread blocks in its send
    (no samples are taken meanwhile: the unsent output stays bounded) and other clients are served
    meanwhile."""
    before = set(server._writers)
    lazy = RawClient(server.port)
    try:
        lazy.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        assert wait_for(lambda: len(set(server._writers) - before) == 1, timeout=5.0)
        (link,) = set(server._writers) - before
        for _ in range(4):   # a STRING(20) read with a 64 KiB buffer: 64 KiB samples, zero-padded
            assert lazy.add_notification(IG_DATA, 20, 65536, SERVER_CYCLE).result == 0
        with RawClient(server.port) as good:
            # once the kernel's buffers for the lazy client are full its sends stay blocked: then in
            # 0.5 s (50 sampling cycles of 4 samples) no sample is taken, and the other client is
            # served all along (on a loaded machine that can take a few windows of looking)
            blocked_for(link, lambda: link.conn.notification_frames, 0.5,
                        lambda: good.read(IG_DATA, 8, 8).result == 0)
        # what was sent before fits the kernel's socket buffers (their most) plus one round of 4
        wmem_max = int(pathlib.Path("/proc/sys/net/ipv4/tcp_wmem").read_text().split()[2])
        assert link.conn.notification_frames * 65536 <= wmem_max + 4096 + 4 * 65600
        _, samples = lazy.recv_notification()      # and it still gets samples once it reads
        assert samples and len(samples[0][2]) == 65536
    finally:
        lazy.close()


def test_a_client_that_half_closes_and_never_reads_is_closed(server):
    """End of input from a client whose notification samples wait in a send (it does not read): the
    connection ends (its threads too) instead of waiting for the client forever."""
    before = set(server._writers)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)     # before connect: a small window
    sock.settimeout(5.0)
    sock.connect(("127.0.0.1", server.port))
    lazy = RawClient.__new__(RawClient)
    lazy.sock, lazy.invoke, lazy.notes = sock, 0, []
    try:
        assert wait_for(lambda: len(set(server._writers) - before) == 1, timeout=5.0)
        (link,) = set(server._writers) - before
        for _ in range(4):
            assert lazy.add_notification(IG_DATA, 20, 65536, SERVER_CYCLE).result == 0
        blocked_for(link, lambda: link.conn.notification_frames, 0.3)   # its send waits
        lazy.sock.shutdown(socket.SHUT_WR)
        link.thread.join(5.0)
        assert not link.thread.is_alive()
        assert not link.conn.notifier.is_alive()
        assert link not in server._writers
    finally:
        lazy.close()
