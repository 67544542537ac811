"""Device notifications of the ADS server (AddDeviceNotification, DeleteDeviceNotification, and the
DeviceNotification frames it sends): cyclic and on-change, sampled under the server's lock, bounded
per connection (count, sampling cycle, unsent output).

Each connection with notifications has one thread that sleeps until the next sample is due, samples
and sends. While a client does not read, that send blocks and no samples are taken meanwhile (they
are dropped; on-change ones are sent when their value next differs from the last one sent), so the
unsent output per connection is at most one round of samples beside the kernel's socket buffer."""
from __future__ import annotations

import struct
import threading
import time

from .errors import (
    ADSERR_DEVICE_INVALIDSIZE,
    ADSERR_DEVICE_INVALIDWATCHSIZE,
    ADSERR_DEVICE_NOMOREHDLS,
    ADSERR_DEVICE_TRANSMODENOTSUPP,
    AdsError,
)
from .protocol import (
    ADD_NOTIFICATION_REQ,
    CMD_DEVICE_NOTIFICATION,
    SF_ADS_COMMAND,
    AdsDevice,
    AmsHeader,
    frame,
)
from .transport import Connection, Notification

#: ADS transmission modes the server can serve (server cycle / server on change, and the "2"
#: variants that TwinCAT treats the same way here)
_TRANS_CYCLE = frozenset({3, 5})
_TRANS_ON_CHANGE = frozenset({4, 6})
#: seconds between 1601-01-01 (FILETIME epoch) and 1970-01-01
_FILETIME_EPOCH = 11644473600
_NOTIFY_STREAM_HEAD = struct.Struct("<IIQI")   # length, stamps, timestamp, samples
_NOTIFY_SAMPLE_HEAD = struct.Struct("<II")     # notification handle, size
_NOTIFY_FRAME_DATA = 60000                     # bytes of samples per notification frame (before splitting)
_NOTIFY_STAMP_HEAD = struct.Struct("<QI")      # timestamp, samples (one per stamp of a stream)
#: cycles of samples kept per connection for a client that does not read (then the oldest are dropped)
SYNC_BACKLOG = 20000
#: the cycle's own sampling is bounded, over all connections: notifications and bytes per cycle
#: (beyond them a cyclic notification is sampled by its connection's thread, at most every
#: ``min_notification_cycle``), so clients cannot slow the cycle down
MAX_SYNC_NOTIFICATIONS = 256
MAX_SYNC_BYTES = 64 * 1024




class NotificationService:
    """The notification part of :class:`~distctrl.ads.server.AdsServer` (a mixin: it uses the server's
    ``devices``, ``lock``, ``lock_timeout``, ``log``, ``max_frame``, ``max_notifications``,
    ``min_notification_cycle`` and ``_read``).

    Cycle-synchronous notifications: when the owner of a cycle (the served machine) sets
    :attr:`cycle_time` and calls :meth:`sample_cycle` after every cycle, a cyclic notification
    (ADSTRANS_SERVERCYCLE) on an AMS port in :attr:`cycle_ports` is sampled by the cycle itself, every
    ``round(cycle / cycle_time)``-th cycle (at least every cycle), stamped with the cycle's time, and the
    samples are kept for the notification's max delay and sent together, one stamp per cycle in one
    frame, as TwinCAT does for a notification of a cyclic task (no sample lost or repeated however the
    threads are scheduled)."""

    #: the cycle time (s) of the owner calling :meth:`sample_cycle`; None: no cycle-synchronous sampling
    cycle_time: float | None = None
    #: the AMS ports whose cyclic notifications are sampled by the cycle
    cycle_ports: frozenset = frozenset()

    # device notifications
    # ------------------------------------------------------------------------------------------
    def _add_notification(self, conn: Connection, hdr: AmsHeader, dev: AdsDevice, p: memoryview) -> int:
        if len(p) < ADD_NOTIFICATION_REQ.size:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "short AddDeviceNotification request")
        ig, io, length, mode, _max_delay, cycle, _ = ADD_NOTIFICATION_REQ.unpack_from(p)
        if mode not in _TRANS_CYCLE and mode not in _TRANS_ON_CHANGE:
            raise AdsError(ADSERR_DEVICE_TRANSMODENOTSUPP, f"transmission mode {mode}")
        if length == 0:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "notification length 0")
        if length > min(65536, self.max_frame):
            raise AdsError(ADSERR_DEVICE_INVALIDWATCHSIZE, f"notification length {length}")
        if len(conn.notifications) >= self.max_notifications:
            raise AdsError(ADSERR_DEVICE_NOMOREHDLS,
                           f"at most {self.max_notifications} notifications per connection")
        self._read(conn, hdr.target_port, dev, ig, io, length)  # must be readable now
        now = time.monotonic()
        sync = (mode in _TRANS_CYCLE and self.cycle_time is not None and hdr.target_port in self.cycle_ports
                and self._sync_room(length))
        n = Notification(
            handle=conn.new_notification_handle(), ams_port=hdr.target_port, index_group=ig,
            index_offset=io, length=length, on_change=mode in _TRANS_ON_CHANGE,
            cycle=max(cycle * 1e-7, self.min_notification_cycle),
            route=(hdr.source_net_id, hdr.source_port, hdr.target_net_id, hdr.target_port),
            # the first sample follows the response after a moment: the client must have
            # registered the handle before the first sample arrives
            due=now + 0.05,
        )
        if sync:    # sampled by the cycle (under the lock, as this request is): never by the thread
            n.every = max(1, round(cycle * 1e-7 / self.cycle_time))
            n.max_delay = min(max(_max_delay * 1e-7, 0.0), 1.0)
            n.due = float("inf")
            n.count = n.every - 1          # the next cycle is sampled
            self._sync_conns()[conn] = None
        conn.notifications[n.handle] = n
        if conn.notifier is None:
            conn.notifier = threading.Thread(target=self._notify_loop, args=(conn,), daemon=True,
                                             name=f"distctrl-ads notifications {conn.peer}")
            conn.notifier.start()
        conn.wake.set()
        return n.handle

    def _sync_room(self, length: int) -> bool:
        """True while one more cycle-synchronous notification of ``length`` bytes stays within
        :data:`MAX_SYNC_NOTIFICATIONS` and :data:`MAX_SYNC_BYTES` (called under the lock)."""
        count, size = 1, length
        for conn in self._sync_conns():
            for n in list(conn.notifications.values()):
                if n.every:
                    count += 1
                    size += n.length
        return count <= MAX_SYNC_NOTIFICATIONS and size <= MAX_SYNC_BYTES

    def _sync_conns(self) -> dict:
        conns = self.__dict__.get("_sync_connections")
        if conns is None:
            conns = self.__dict__.setdefault("_sync_connections", {})
        return conns

    def sample_cycle(self, stamp: int) -> None:
        """Sample the cycle-synchronous notifications of every connection (call after every cycle, under
        :attr:`lock`); ``stamp``: the cycle's time as FILETIME (100 ns since 1601-01-01 UTC)."""
        conns = self.__dict__.get("_sync_connections")
        if not conns:
            return
        now = time.monotonic()
        for conn in list(conns):
            writer = conn.writer
            items = []
            wait = 1.0
            for n in list(conn.notifications.values()):
                if not n.every:
                    continue
                n.count += 1
                if n.count < n.every:
                    continue
                n.count = 0
                dev = self.devices.get(n.ams_port)
                err, data = self._sub(conn, self._read, conn, n.ams_port, dev, n.index_group, n.index_offset,
                                      n.length) if dev is not None else (1, None)
                if not err:
                    items.append((n.handle, data.ljust(n.length, b"\0")))
                    wait = min(wait, n.max_delay)
            if writer is None or writer.closing or not any(n.every for n in conn.notifications.values()):
                del conns[conn]
                continue
            if not items:
                continue
            sync = conn.sync
            if len(sync) >= SYNC_BACKLOG:            # a client that does not read: drop the oldest
                sync.popleft()
                conn.sync_dropped += 1
            first = not sync
            if first:
                conn.sync_flush_due = now + wait
            sync.append((stamp, items))
            if first or now >= conn.sync_flush_due:     # the thread waits until the batch is due
                conn.wake.set()

    def _sync_frames(self, conn: Connection) -> list[bytes]:
        """The DeviceNotification frames of the kept cycle-synchronous samples (one stamp per cycle)."""
        sync = conn.sync
        by_route: dict[tuple, list] = {}
        routes = {h: n.route for h, n in list(conn.notifications.items())}
        while sync:
            stamp, items = sync.popleft()
            for handle, data in items:
                route = routes.get(handle)
                if route is None:                    # deleted meanwhile
                    continue
                stamps = by_route.setdefault(route, [])
                if not stamps or stamps[-1][0] != stamp:
                    stamps.append((stamp, []))
                stamps[-1][1].append((handle, data))
        frames = []
        for route, stamps in by_route.items():
            parts, size, count = [], 0, 0
            for i, (stamp, items) in enumerate(stamps):
                body = b"".join(_NOTIFY_SAMPLE_HEAD.pack(h, len(d)) + d for h, d in items)
                parts.append(_NOTIFY_STAMP_HEAD.pack(stamp, len(items)) + body)
                size += len(parts[-1])
                count += 1
                if size >= _NOTIFY_FRAME_DATA or i == len(stamps) - 1:
                    payload = b"".join(parts)
                    data = struct.pack("<II", len(payload) + 4, count) + payload
                    hdr = AmsHeader(route[0], route[1], route[2], route[3], CMD_DEVICE_NOTIFICATION,
                                    SF_ADS_COMMAND, len(data), 0, 0)
                    frames.append(frame(hdr, data))
                    parts, size, count = [], 0, 0
        return frames

    def _notify_loop(self, conn: Connection) -> None:
        """The notification thread of one connection: send the due samples until the connection ends."""
        writer = conn.writer
        try:
            while writer is not None and not writer.closing:
                now = time.monotonic()
                pending = list(conn.notifications.values())    # a copy: the link's thread adds/deletes
                due = [n for n in pending if n.due <= now]
                if conn.sync and now >= conn.sync_flush_due:
                    with writer.send_lock:
                        for chunk in self._sync_frames(conn):
                            writer.send_locked(chunk)
                            conn.notification_frames += 1
                if due:
                    # sampled and sent under the send lock: a DeleteDeviceNotification answered meanwhile
                    # is answered after these samples, and one answered before is not sampled
                    with writer.send_lock:
                        for chunk in self._notification_frames(conn, due, now):
                            writer.send_locked(chunk)
                            conn.notification_frames += 1
                conn.wake.clear()
                pending = list(conn.notifications.values())
                if writer.closing:
                    break
                wake = min((n.due for n in pending), default=float("inf"))
                if conn.sync:
                    wake = min(wake, conn.sync_flush_due)
                conn.wake.wait(None if wake == float("inf") else max(0.0, wake - time.monotonic()))
        except Exception:  # pragma: no cover - defensive
            self.log.exception("%s: notification thread failed", conn.peer)

    def _notification_frames(self, conn: Connection, due: list[Notification], now: float) -> list[bytes]:
        """Sample ``due`` (under the lock) and build the DeviceNotification frames to send."""
        for n in due:   # schedule the next sample (no burst after a stall)
            n.due = n.due + n.cycle if n.due + n.cycle > now else now + n.cycle
        lock = self.lock
        if not lock.acquire(timeout=min(self.lock_timeout, 0.05)):
            return []   # try again at the next cycle
        samples: dict[tuple[bytes, int, bytes, int], list[tuple[int, bytes]]] = {}
        try:
            for n in due:
                dev = self.devices.get(n.ams_port)
                if dev is None or conn.notifications.get(n.handle) is not n:   # deleted meanwhile
                    continue
                err, data = self._sub(conn, self._read, conn, n.ams_port, dev, n.index_group,
                                      n.index_offset, n.length)
                if err:
                    continue
                data = data.ljust(n.length, b"\0")
                if n.on_change and data == n.last:
                    continue
                n.last = data
                samples.setdefault(n.route, []).append((n.handle, data))
        finally:
            lock.release()
        stamp = int((time.time() + _FILETIME_EPOCH) * 10_000_000)
        frames = []
        for route, items in samples.items():
            while items:
                part, size = [], 0
                while items and (not part or size + len(items[0][1]) <= _NOTIFY_FRAME_DATA):
                    handle, data = items.pop(0)
                    part.append(_NOTIFY_SAMPLE_HEAD.pack(handle, len(data)) + data)
                    size += len(data)
                body = b"".join(part)
                data = _NOTIFY_STREAM_HEAD.pack(len(body) + 16, 1, stamp, len(part)) + body
                hdr = AmsHeader(route[0], route[1], route[2], route[3], CMD_DEVICE_NOTIFICATION,
                                SF_ADS_COMMAND, len(data), 0, 0)
                frames.append(frame(hdr, data))
        return frames
