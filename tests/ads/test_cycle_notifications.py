"""Cycle-synchronous device notifications: a cyclic notification on a port the cycle's owner samples
(:meth:`~distctrl.ads.notifications.NotificationService.sample_cycle`) gets every cycle's sample once,
stamped with the cycle's time, batched by the notification's max delay (issue 28: recording at the
CNC cycle)."""
from __future__ import annotations

import struct

import pytest

from distctrl.ads import AdsServer
from distctrl.ads import protocol as P

from . import IG_DATA, MemoryDevice, RawClient

SERVER_CYCLE = 3
T = 0.001


@pytest.fixture()
def server():
    srv = AdsServer({851: MemoryDevice()}, port=0)
    srv.cycle_time = T
    srv.cycle_ports = frozenset({851})
    srv.start()
    try:
        yield srv
    finally:
        srv.stop()


def add(c: RawClient, cycle_s: float, max_delay_s: float, offset: int = 0, length: int = 4) -> int:
    data = P.ADD_NOTIFICATION_REQ.pack(IG_DATA, offset, length, SERVER_CYCLE, int(max_delay_s * 1e7),
                                       int(cycle_s * 1e7), b"")
    r = c.call(P.request, P.CMD_ADD_DEVICE_NOTIFICATION, data)
    assert r.result == 0, hex(r.result)
    return struct.unpack("<I", r.data)[0]


def cycles(srv: AdsServer, first: int, n: int) -> None:
    for k in range(first, first + n):
        with srv.lock:
            srv.sample_cycle(1000 + k * 10_000)      # FILETIME stamps 1 ms apart


def collect(c: RawClient, n: int) -> tuple[list, int]:
    got, frames = [], 0
    while len(got) < n:
        got += c.recv_notification()[1]
        frames += 1
    return got, frames


def test_every_cycle_once_with_the_cycle_stamp(server):
    with RawClient(server.port) as c:
        h = add(c, T, 0.0)
        cycles(server, 1, 50)
        got, _ = collect(c, 50)
        assert [s[1] for s in got] == [h] * 50
        assert [s[0] for s in got] == [1000 + k * 10_000 for k in range(1, 51)]


def test_samples_batched_by_max_delay_one_stamp_per_cycle(server):
    with RawClient(server.port) as c:
        h1, h2 = add(c, T, 0.2), add(c, T, 0.2, offset=8, length=8)
        cycles(server, 1, 40)                        # well within 0.2 s: kept, sent together
        got, frames = collect(c, 80)
        assert frames < 10
        assert [s[0] for s in got] == [1000 + k * 10_000 for k in range(1, 41) for _ in (0, 1)]
        assert {s[1] for s in got} == {h1, h2}


def test_cycle_multiple_samples_every_nth_cycle(server):
    with RawClient(server.port) as c:
        add(c, 5 * T, 0.0)
        cycles(server, 1, 20)
        got, _ = collect(c, 4)
        assert [s[0] for s in got] == [1000 + k * 10_000 for k in (1, 6, 11, 16)]


def test_without_cycle_owner_still_thread_sampled():
    srv = AdsServer({851: MemoryDevice()}, port=0)
    with srv, RawClient(srv.port) as c:
        h = add(c, T, 0.0)
        assert c.recv_notification()[1][0][1] == h     # the thread samples at min_notification_cycle


def test_the_cycles_own_sampling_is_bounded(server, monkeypatch):
    """Beyond the bound a cyclic notification is sampled by the thread (every 10 ms), so clients
    cannot make the cycle read more than MAX_SYNC_NOTIFICATIONS objects."""
    from distctrl.ads import notifications as N

    monkeypatch.setattr(N, "MAX_SYNC_NOTIFICATIONS", 2)
    with RawClient(server.port) as c:
        handles = [add(c, T, 0.0) for _ in range(3)]
        synced = [n for conn in server._sync_conns() for n in conn.notifications.values() if n.every]
        assert len(synced) == 2
        cycles(server, 1, 5)
        got, _ = collect(c, 10)
        assert {s[1] for s in got} <= set(handles)
