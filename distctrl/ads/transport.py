"""AMS/TCP transport of the ADS server: one :class:`ClientLink` (a thread with a blocking socket)
per client connection, and the per-connection state (:class:`Connection`: symbol handles, device
notifications).

Why a thread per connection and not the event loop: an ADS client such as pyads waits for each answer
before it sends the next request, so a round trip is one wake-up of the server on the client's
request. A thread blocked in ``recv_into`` is woken by the kernel directly and answers with one
``send``; an event loop adds its own poll, callback dispatch and write path on top, which on the 2-vCPU
VM of bench/bench_ads.py made a no-work server 1.15x slower (docs/serve.md, "Round-trip speed").

Each link reads its socket into a fixed buffer, answers every complete frame in order and sends the
answer before it reads again (``sendall``, under the link's send lock, which the connection's
notification thread shares). Flow control follows from that: while a client does not read its
answers, the send blocks, so the server neither parses further frames of that client nor reads from
its socket; per connection at most one partial frame plus one read chunk of input and one answer (or
one round of notification samples) of output are held beside the kernel's socket buffers. Other
clients are served meanwhile by their own threads.

Robustness: a frame whose length is impossible (shorter than an AMS header, longer than
``max_frame``, or disagreeing with the AMS header's data length) closes only that connection;
frames split over several TCP segments are reassembled; a client vanishing mid-frame is a normal
close.
"""
from __future__ import annotations

import collections

import logging
import socket
import threading
from dataclasses import dataclass
from typing import Protocol

from .errors import ADSERR_DEVICE_NOMEMORY, ADSERR_DEVICE_SYMBOLNOTFOUND, AdsError
from .protocol import AMS_HEADER_SIZE, AMS_TCP_HEADER, AMS_TCP_HEADER_SIZE, SymbolInfo

CLOSE = object()  # sentinel: close this connection
PORT_CLOSED = object()  # sentinel: the client unregistered its AMS port: close as a TwinCAT router does

_unpack_tcp_header = AMS_TCP_HEADER.unpack_from
_MIN_AMS_FRAME = AMS_TCP_HEADER_SIZE + AMS_HEADER_SIZE
#: bytes read from a socket at once (into a fixed per-connection buffer)
_RECV_CHUNK = 64 * 1024


class LinkOwner(Protocol):
    """What a :class:`ClientLink` uses of the server that owns it (:class:`~distctrl.ads.server.AdsServer`).
    Declared here so that the transport, the lowest layer of the server, imports none of the layers above."""

    log: logging.Logger
    max_frame: int
    max_handles: int
    frames: int

    def _handle_ams(self, conn: Connection, body: bytes) -> bytes | None | object: ...

    def _handle_tcp_command(self, conn: Connection, reserved: int, body: bytes) -> bytes | None: ...

    def _link_closed(self, link: ClientLink) -> None: ...


@dataclass
class Notification:
    handle: int
    ams_port: int
    index_group: int
    index_offset: int
    length: int
    on_change: bool
    cycle: float                 # seconds
    route: tuple[bytes, int, bytes, int]   # client NetId, client port, our NetId, device port
    due: float = 0.0
    last: bytes | None = None
    #: cycle-synchronous (sampled by the machine's cycle, :meth:`NotificationService.sample_cycle`):
    #: every ``every``-th cycle, the samples kept until ``max_delay`` s and sent together
    every: int = 0
    max_delay: float = 0.0
    count: int = 0


class Connection:
    """Per-connection state: symbol handles and device notifications (both bounded)."""

    __slots__ = ("_next_handle", "_next_notification", "frames", "handles", "max_handles",
                 "notification_frames", "notifications", "notifier", "peer", "sync", "sync_dropped",
                 "sync_flush_due", "wake", "writer")

    def __init__(self, peer: str, max_handles: int, writer: ClientLink | None = None) -> None:
        self.peer = peer
        self.writer = writer
        self.handles: dict[int, tuple[int, SymbolInfo]] = {}
        self.max_handles = max_handles
        self._next_handle = 1
        self.frames = 0                  # frames received
        self.notification_frames = 0     # DeviceNotification frames sent
        self.notifications: dict[int, Notification] = {}
        self._next_notification = 1
        self.notifier: threading.Thread | None = None   # sends the samples (started by the first one)
        self.wake = threading.Event()                     # a notification was added, or the link closes
        #: cycle-synchronous samples not sent yet: (FILETIME stamp, [(handle, data), ...]) per cycle
        self.sync: collections.deque = collections.deque()
        self.sync_dropped = 0                             # cycles' samples dropped (client not reading)
        self.sync_flush_due = 0.0                         # monotonic time the kept samples are due

    def new_notification_handle(self) -> int:
        h = self._next_notification
        while h == 0 or h in self.notifications:
            h = (h + 1) & 0xFFFFFFFF
        self._next_notification = (h + 1) & 0xFFFFFFFF
        return h

    def new_handle(self, ams_port: int, sym: SymbolInfo) -> int:
        if len(self.handles) >= self.max_handles:
            raise AdsError(ADSERR_DEVICE_NOMEMORY,
                           f"at most {self.max_handles} handles per connection; release some")
        h = self._next_handle
        while h == 0 or h in self.handles:
            h = (h + 1) & 0xFFFFFFFF
        self._next_handle = (h + 1) & 0xFFFFFFFF
        self.handles[h] = (ams_port, sym)
        return h

    def symbol(self, ams_port: int, handle: int) -> SymbolInfo:
        entry = self.handles.get(handle)
        if entry is None or entry[0] != ams_port:
            raise AdsError(ADSERR_DEVICE_SYMBOLNOTFOUND, f"unknown handle 0x{handle:X}")
        return entry[1]

    def release(self, ams_port: int, handle: int) -> None:
        self.symbol(ams_port, handle)
        del self.handles[handle]


class ClientLink:
    """One client connection: its socket, the thread that reads, frames and answers it, and the send
    lock shared with the connection's notification thread. Also the connection's ``writer``.

    :attr:`sending` is true while a send waits for the client to read (the flow-control state);
    :attr:`buf` is the reassembly buffer of frames split over reads.
    """

    __slots__ = ("_closed", "_fd_lock", "buf", "closing", "conn", "reason", "send_lock", "sending", "server",
                 "sock", "thread")

    def __init__(self, server: LinkOwner, sock: socket.socket, peer: str) -> None:
        self.server = server
        self.sock = sock
        self.buf = bytearray()
        self.closing = False      # closed or closing: ignore further input
        self.sending = False      # blocked in a send: the client does not read
        self.reason = "closed by peer"
        self.send_lock = threading.Lock()
        self._fd_lock = threading.Lock()    # the socket's shutdown (any thread) against its close
        self._closed = False
        self.conn = Connection(peer, server.max_handles, self)
        self.thread = threading.Thread(target=self._run, name=f"distctrl-ads {peer}", daemon=True)

    def start(self) -> None:
        self.thread.start()

    # --- the connection's thread ---------------------------------------------------------------
    def _run(self) -> None:
        srv, conn, sock = self.server, self.conn, self.sock
        rx = bytearray(_RECV_CHUNK)
        rxview = memoryview(rx)
        buf = self.buf
        recv_into = sock.recv_into
        try:
            while not self.closing:
                nbytes = recv_into(rx)
                if nbytes == 0:
                    if buf:
                        self.reason = "peer closed mid-frame"
                    break
                if not buf and nbytes >= _MIN_AMS_FRAME:
                    # fast path: the read is exactly one AMS frame (a client waiting for each answer)
                    reserved, length = _unpack_tcp_header(rx)
                    if reserved == 0 and length == nbytes - AMS_TCP_HEADER_SIZE and length <= srv.max_frame:
                        srv.frames += 1
                        conn.frames += 1
                        self._deliver(srv._handle_ams(conn, bytes(rxview[AMS_TCP_HEADER_SIZE:nbytes])))
                        continue
                buf += rxview[:nbytes]
                self._process()
        except OSError as exc:
            if not self.closing:
                self.reason = f"connection error: {exc}"
        except Exception:  # pragma: no cover - defensive: a bug here must not kill the server
            srv.log.exception("%s: unexpected error in the connection handler", conn.peer)
            self.reason = "internal error"
        finally:
            self._finish()

    def _process(self) -> None:
        """Answer the complete frames in the buffer (until closed); check each AMS/TCP header as soon
        as it is complete."""
        buf, srv = self.buf, self.server
        max_frame = srv.max_frame
        pos, size = 0, len(buf)
        try:
            while size - pos >= AMS_TCP_HEADER_SIZE and not self.closing:
                reserved, length = _unpack_tcp_header(buf, pos)
                if length > max_frame:
                    self._bad_frame(f"frame length {length} exceeds max_frame {max_frame}")
                    return
                if reserved == 0 and length < AMS_HEADER_SIZE:
                    self._bad_frame(f"frame length {length} shorter than an AMS header")
                    return
                end = pos + AMS_TCP_HEADER_SIZE + length
                if end > size:
                    break
                body = bytes(buf[pos + AMS_TCP_HEADER_SIZE:end])
                pos = end
                srv.frames += 1
                self.conn.frames += 1
                if reserved == 0:
                    out = srv._handle_ams(self.conn, body)
                else:
                    out = srv._handle_tcp_command(self.conn, reserved, body)
                self._deliver(out)
        finally:
            if self.closing:
                buf.clear()
            elif pos:
                del buf[:pos]

    def _deliver(self, out) -> None:
        """Act on a handler's result: send the answer frame, close (``CLOSE``, ``PORT_CLOSED``), or
        nothing (None: no answer)."""
        if out is CLOSE:
            self.close("malformed frame")
        elif out is PORT_CLOSED:
            self.close("AMS port closed by the client")
        elif out:
            self.write(out)

    def _bad_frame(self, reason: str) -> None:
        self.server.log.warning("%s: %s; closing", self.conn.peer, reason)
        self.close(reason)

    def _finish(self) -> None:
        """End of the connection (in its thread): stop the notifications, close the socket, count."""
        srv, conn = self.server, self.conn
        self.closing = True
        self.buf.clear()
        conn.notifications.clear()
        conn.wake.set()                     # the notification thread ends
        notifier = conn.notifier
        # every answer has been sent (before the next read); a notification send that waits for a
        # client which does not read any more is woken by the shutdown (the data already queued is
        # still delivered before the FIN)
        self._shutdown()
        with self.send_lock, self._fd_lock:   # not while the notification thread sends
            self._closed = True
            try:
                self.sock.close()
            except OSError:  # pragma: no cover
                pass
        srv._link_closed(self)              # counted as closed before the wait for the notifier
        if notifier is not None and notifier is not threading.current_thread():
            notifier.join(timeout=2.0)
        srv.log.info("connection %s closed (%s, %d frames)", conn.peer, self.reason, conn.frames)

    # --- output / closing (any thread) ---------------------------------------------------------
    def write(self, data: bytes) -> None:
        """Send ``data`` (an answer or notification frames) unless the connection is closing; blocks
        while the client does not read. A failing send closes the connection."""
        with self.send_lock:
            self.send_locked(data)

    def send_locked(self, data: bytes) -> None:
        """:meth:`write` for a caller that holds :attr:`send_lock`."""
        if self.closing:
            return
        self.sending = True
        try:
            self.sock.sendall(data)
        except OSError as exc:
            if not self.closing:
                self.reason = f"connection error: {exc}"
            self._shutdown()
        finally:
            self.sending = False

    def close(self, reason: str) -> None:
        """Close after sending what is pending (answers are sent before the next read)."""
        if not self.closing:
            self.reason = reason
            self._shutdown()

    def abort(self, reason: str) -> None:
        """Close at once, also while a send waits for the client (from any thread)."""
        if not self.closing:
            self.reason = reason
        self._shutdown()

    def _shutdown(self) -> None:
        # shutdown, not close: it wakes this link's thread from recv/send, which then closes the
        # socket itself (closing a descriptor another thread waits on could hit a reused one); the
        # descriptor lock keeps a shutdown from another thread off a descriptor closed meanwhile
        self.closing = True
        with self._fd_lock:
            if self._closed:
                return
            try:
                self.sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
