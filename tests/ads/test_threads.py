"""The server's threads (a thread per connection, a notification thread per connection, the accept
loop): what a client must not notice of them. Found by a review of the threaded transport; each
test failed before its fix."""
from __future__ import annotations

import functools
import gc
import logging
import socket
import struct
import threading
import time

import pytest

from distctrl.ads import AdsServer
from distctrl.ads import errors as E
from distctrl.ads import protocol as P
from distctrl.ads import server as server_module
from distctrl.ads import transport as T

from . import IG_DATA, MemoryDevice, RawClient, wait_for


def test_close_and_reconnect_at_the_connection_limit_is_served():
    """A client that closes and connects again at once is not refused because the thread of its old
    connection has not yet noticed the close (the asyncio transport served these all)."""
    srv = AdsServer({851: MemoryDevice()}, port=0, max_connections=1)
    srv.start()
    try:
        for _ in range(100):
            with RawClient(srv.port, timeout=5.0) as c:
                assert c.read(IG_DATA, 8, 8).result == 0
        assert srv.refused == 0
        with RawClient(srv.port) as a:          # the limit still holds for a connection that stays
            assert a.read(IG_DATA, 8, 8).result == 0
            with RawClient(srv.port) as b:
                assert b.is_closed_by_server()
        assert srv.refused == 1
    finally:
        srv.stop()


def test_a_connection_thread_that_cannot_start_does_not_stop_accepting(monkeypatch, caplog):
    srv = AdsServer({851: MemoryDevice()}, port=0)
    srv.start()
    try:
        real_start = T.ClientLink.start
        failed = []

        def start_once_failing(self):
            if not failed:
                failed.append(self)
                raise RuntimeError("can't start new thread")
            real_start(self)

        monkeypatch.setattr(T.ClientLink, "start", start_once_failing)
        with caplog.at_level(logging.ERROR, logger="distctrl.ads"):
            with RawClient(srv.port) as c:
                assert c.is_closed_by_server()
        assert "can't start new thread" in caplog.text
        with RawClient(srv.port) as c:          # the next client is served
            assert c.read(IG_DATA, 8, 8).result == 0
        assert wait_for(lambda: srv.connections == 0)
    finally:
        srv.stop()
    assert not srv.running


class SlowDevice(MemoryDevice):
    """A device whose read takes 2 ms (samples are taken under the lock)."""

    def read(self, ig, io, length):
        time.sleep(0.002)
        return super().read(ig, io, length)


def test_no_sample_of_a_notification_after_its_delete_answer():
    srv = AdsServer({851: SlowDevice()}, port=0, min_notification_cycle=0.002)
    srv.start()
    late = 0
    try:
        with RawClient(srv.port) as c:
            for i in range(150):
                r = c.add_notification(IG_DATA, 0, 4, 3, cycle_100ns=20_000)     # cyclic, 2 ms
                assert r.result == 0
                handle = struct.unpack_from("<I", r.data)[0]
                c.recv_notification()
                time.sleep(0.001 * (i % 4))
                assert c.del_notification(handle).result == 0
                c.notes.clear()                   # samples before the delete's answer are fine
                c.sock.settimeout(0.02)
                try:
                    while True:
                        _, body = c.recv_frame()
                        data = body[P.AMS_HEADER_SIZE:]
                        pos = 20
                        for _ in range(struct.unpack_from("<I", data, 16)[0]):
                            h, size = struct.unpack_from("<II", data, pos)
                            pos += 8 + size
                            late += h == handle
                except TimeoutError:
                    pass
                c.sock.settimeout(5.0)
    finally:
        srv.stop()
    assert late == 0


class CachingDevice(MemoryDevice):
    def fast_reader(self, ig, io, length):
        return functools.partial(self.read, ig, io, length)


def test_a_cached_read_waits_for_the_lock_once():
    lock = threading.Lock()
    srv = AdsServer({851: CachingDevice()}, port=0, lock=lock, lock_timeout=0.3)
    srv.start()
    try:
        with RawClient(srv.port) as c:
            assert c.read(IG_DATA, 8, 8).result == 0
            assert srv._read_cache
            with lock:
                t0 = time.monotonic()
                r = c.read(IG_DATA, 8, 8)
                waited = time.monotonic() - t0
            assert r.result == E.ADSERR_DEVICE_BUSY and r.data == b""
            assert 0.25 <= waited < 0.5
            assert c.read(IG_DATA, 8, 8).result == 0     # and from the cache again once free
    finally:
        srv.stop()


def test_a_host_name_binds_each_of_its_addresses_on_one_port(monkeypatch):
    real = socket.getaddrinfo

    def two_addresses(host, port, *args, **kw):
        if host == "twohost":
            return [(socket.AF_INET, socket.SOCK_STREAM, 6, "", ("127.0.0.1", port)),
                    (socket.AF_INET, socket.SOCK_STREAM, 6, "", ("127.0.0.2", port))]
        return real(host, port, *args, **kw)

    monkeypatch.setattr(server_module.socket, "getaddrinfo", two_addresses)
    srv = AdsServer({851: MemoryDevice()}, host="twohost", port=0)
    srv.start()
    try:
        assert [s.getsockname() for s in srv._listeners] == [("127.0.0.1", srv.port), ("127.0.0.2", srv.port)]
        for host in ("127.0.0.1", "127.0.0.2"):
            with RawClient(srv.port, host=host) as c:
                assert c.read(IG_DATA, 8, 8).result == 0
    finally:
        srv.stop()
    assert not srv._listeners


def test_an_address_family_the_system_lacks_is_skipped(monkeypatch):
    """As asyncio's create_server: host "" on a system without IPv6 serves IPv4."""
    real_socket = socket.socket

    def no_ipv6(family=socket.AF_INET, *args, **kw):
        if family == socket.AF_INET6:
            raise OSError(97, "Address family not supported by protocol")
        return real_socket(family, *args, **kw)

    monkeypatch.setattr(server_module.socket, "socket", no_ipv6)
    srv = AdsServer({851: MemoryDevice()}, host="", port=0, allowed=["127.0.0.0/8"])
    srv.start()
    try:
        assert srv._listeners and all(s.family == socket.AF_INET for s in srv._listeners)
        with RawClient(srv.port) as c:
            assert c.read(IG_DATA, 8, 8).result == 0
    finally:
        srv.stop()
    monkeypatch.setattr(server_module.socket, "getaddrinfo",
                        lambda *a, **k: [(socket.AF_INET6, socket.SOCK_STREAM, 6, "", ("::1", 0, 0, 0))])
    with pytest.raises(OSError):
        AdsServer({851: MemoryDevice()}, host="::1", port=0).start()


class FailingEndpoint:
    async def open(self, server):
        raise OSError("cannot open")

    def close(self):
        pass


def test_a_failing_start_leaves_no_pending_task(caplog):
    srv = AdsServer({851: MemoryDevice()}, port=0)
    srv.attached.append(FailingEndpoint())
    with caplog.at_level(logging.ERROR, logger="asyncio"):
        with pytest.raises(OSError, match="cannot open"):
            srv.start()
        gc.collect()
    assert "was destroyed but it is pending" not in caplog.text
    assert not srv.running and not srv._listeners
    assert not srv._accepting          # the accept tasks were ended on their loop, not left pending
