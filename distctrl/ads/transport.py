"""AMS/TCP transport of the ADS server: one :class:`AdsProtocol` per client connection on the
server's event loop, and the per-connection state (:class:`Connection`: symbol handles, device
notifications).

Each connection is a low-level :class:`asyncio.BufferedProtocol` (no stream coroutine per
connection): the socket is read into a fixed per-connection buffer, every complete frame is answered
synchronously in ``buffer_updated`` and the answer is written straight to the transport (one send
call in the usual case). Flow control: while more than 64 KiB of answers wait to be sent to a client
(it does not read), the server neither parses further frames of that client nor reads from its
socket, until the backlog has drained to 16 KiB.

Robustness: a frame whose length is impossible (shorter than an AMS header, longer than
``max_frame``, or disagreeing with the AMS header's data length) closes only that connection;
frames split over several TCP segments are reassembled; a client vanishing mid-frame is a normal
close.
"""
from __future__ import annotations

import asyncio
from typing import TYPE_CHECKING

from . import errors as E
from .errors import AdsError
from .protocol import AMS_HEADER_SIZE, AMS_TCP_HEADER, AMS_TCP_HEADER_SIZE, SymbolInfo

if TYPE_CHECKING:
    from .notifications import Notification
    from .server import AdsServer

CLOSE = object()  # sentinel: close this connection
PORT_CLOSED = object()  # sentinel: the client unregistered its AMS port: close as a TwinCAT router does

_unpack_tcp_header = AMS_TCP_HEADER.unpack_from
_MIN_AMS_FRAME = AMS_TCP_HEADER_SIZE + AMS_HEADER_SIZE
#: per-connection output backlog (bytes handed to the transport but not yet sent) above which the
#: server stops reading and answering that client, and below which it resumes
_WRITE_HIGH = 64 * 1024
_WRITE_LOW = 16 * 1024
#: bytes read from a socket at once (into a fixed per-connection buffer)
_RECV_CHUNK = 64 * 1024


class Connection:
    """Per-connection state: symbol handles and device notifications (both bounded)."""

    __slots__ = ("_next_handle", "_next_notification", "frames", "handles", "max_handles",
                 "notifications", "notifier", "peer", "wake", "writer")

    def __init__(self, peer: str, max_handles: int, writer: AdsProtocol | None = None) -> None:
        self.peer = peer
        self.writer = writer
        self.handles: dict[int, tuple[int, SymbolInfo]] = {}
        self.max_handles = max_handles
        self._next_handle = 1
        self.frames = 0
        self.notifications: dict[int, Notification] = {}
        self._next_notification = 1
        self.notifier: asyncio.Task | None = None
        self.wake = asyncio.Event()

    def new_notification_handle(self) -> int:
        h = self._next_notification
        while h == 0 or h in self.notifications:
            h = (h + 1) & 0xFFFFFFFF
        self._next_notification = (h + 1) & 0xFFFFFFFF
        return h

    def new_handle(self, ams_port: int, sym: SymbolInfo) -> int:
        if len(self.handles) >= self.max_handles:
            raise AdsError(E.ADSERR_DEVICE_NOMEMORY,
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
            raise AdsError(E.ADSERR_DEVICE_SYMBOLNOTFOUND, f"unknown handle 0x{handle:X}")
        return entry[1]

    def release(self, ams_port: int, handle: int) -> None:
        self.symbol(ams_port, handle)
        del self.handles[handle]


class AdsProtocol(asyncio.BufferedProtocol):
    """One client connection on the event loop: AMS/TCP framing, answers and flow control.

    The socket is read into a fixed per-connection buffer (``recv_into``). A plain ``Protocol``
    gets a fresh ``bytes`` of up to 256 KiB per read, which glibc serves with mmap/mremap/munmap
    (until some other free has raised its mmap threshold): about 14 µs per request here.
    Complete frames are answered synchronously and in order from :meth:`buffer_updated`; the
    usual case (a read holding exactly one request) bypasses the reassembly buffer. When the
    transport's unsent backlog exceeds ``_WRITE_HIGH`` (the client does not read),
    :meth:`pause_writing` stops both parsing and reading until :meth:`resume_writing`, so per
    connection at most one partial frame plus one read chunk of input and ``_WRITE_HIGH`` plus one
    answer of output are held (notification samples have their own bound, ``_NOTIFY_BACKLOG``).
    The object also serves as the connection's ``writer`` (``write`` and ``transport``).
    """

    __slots__ = ("buf", "closing", "conn", "paused", "reason", "rx", "rxview", "server", "transport")

    def __init__(self, server: AdsServer) -> None:
        self.server = server
        self.transport: asyncio.Transport | None = None
        self.conn: Connection | None = None
        self.rx = self.rxview = None           # one read lands here (allocated once accepted)
        self.buf = bytearray()                 # reassembly of frames split over reads
        self.paused = False       # output backlog above the high-water mark: not reading/answering
        self.closing = False      # closed or closing: ignore further input
        self.reason = "closed by peer"

    # --- asyncio callbacks ---------------------------------------------------------------------
    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]
        srv = self.server
        peername = transport.get_extra_info("peername")
        ip = str(peername[0]) if peername else "?"
        if not srv.is_allowed(ip):
            srv.refused += 1
            srv.log.warning("refused %s", ip)
            self.closing = True
            transport.abort()
            return
        if srv.connections >= srv.max_connections:
            srv.refused += 1
            srv.log.warning("refused %s (more than %d connections)", ip, srv.max_connections)
            self.closing = True
            transport.abort()
            return
        transport.set_write_buffer_limits(_WRITE_HIGH, _WRITE_LOW)  # type: ignore[attr-defined]
        self.rx = bytearray(_RECV_CHUNK)   # never resized: the transport may still hold a view of it
        self.rxview = memoryview(self.rx)
        srv._writers.add(self)
        srv.connections += 1
        srv.accepted += 1
        self.conn = Connection(f"{ip}:{peername[1]}" if peername else ip, srv.max_handles, self)
        srv.log.info("connection from %s", self.conn.peer)

    def get_buffer(self, sizehint: int) -> memoryview:
        return self.rxview  # type: ignore[return-value]

    def buffer_updated(self, nbytes: int) -> None:
        if self.closing:
            return
        buf = self.buf
        if not buf and not self.paused and nbytes >= _MIN_AMS_FRAME:
            # fast path: the read is exactly one AMS frame (a client waiting for each answer)
            reserved, length = _unpack_tcp_header(self.rx)  # type: ignore[arg-type]
            if reserved == 0 and length == nbytes - AMS_TCP_HEADER_SIZE and length <= self.server.max_frame:
                srv, conn = self.server, self.conn
                srv.frames += 1
                conn.frames += 1  # type: ignore[union-attr]
                body = bytes(self.rxview[AMS_TCP_HEADER_SIZE:nbytes])
                try:
                    self._deliver(srv._handle_ams(conn, body))  # type: ignore[arg-type]
                except Exception:  # pragma: no cover - defensive: a bug here must not kill the server
                    self._internal_error()
                return
        buf += self.rxview[:nbytes]
        self._process()

    def eof_received(self) -> bool | None:
        if self.buf and not self.closing:
            self.reason = "peer closed mid-frame"
        return None   # the transport closes itself (after sending what is pending)

    def pause_writing(self) -> None:
        self.paused = True
        if not self.closing:
            self.transport.pause_reading()  # type: ignore[union-attr]

    def resume_writing(self) -> None:
        self.paused = False
        if self.closing:
            return
        self._process()   # frames received before the pause
        if not self.paused and not self.closing:
            self.transport.resume_reading()  # type: ignore[union-attr]

    def connection_lost(self, exc: Exception | None) -> None:
        conn, srv = self.conn, self.server
        if conn is None:          # refused
            return
        self.conn = None
        if exc is not None and not self.closing:
            self.reason = f"connection error: {exc}"
        self.closing = True
        self.buf = bytearray()
        if conn.notifier is not None:
            conn.notifier.cancel()
            srv._tasks.discard(conn.notifier)
        conn.notifications.clear()
        conn.writer = None
        srv.connections -= 1
        srv._writers.discard(self)
        srv.log.info("connection %s closed (%s, %d frames)", conn.peer, self.reason, conn.frames)

    # --- framing -------------------------------------------------------------------------------
    def _process(self) -> None:
        """Answer the complete frames in the buffer (until paused or closed); check each AMS/TCP
        header as soon as it is complete."""
        buf, srv = self.buf, self.server
        max_frame = srv.max_frame
        pos, size = 0, len(buf)
        try:
            while size - pos >= AMS_TCP_HEADER_SIZE and not self.paused and not self.closing:
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
                self.conn.frames += 1  # type: ignore[union-attr]
                if reserved == 0:
                    out = srv._handle_ams(self.conn, body)  # type: ignore[arg-type]
                else:
                    out = srv._handle_tcp_command(self.conn, reserved, body)  # type: ignore[arg-type]
                self._deliver(out)
        except Exception:  # pragma: no cover - defensive: a bug here must not kill the server
            self._internal_error()
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
            self.transport.write(out)  # type: ignore[union-attr, arg-type]

    def _bad_frame(self, reason: str) -> None:
        self.server.log.warning("%s: %s; closing", self.conn.peer, reason)  # type: ignore[union-attr]
        self.close(reason)

    def _internal_error(self) -> None:
        peer = self.conn.peer if self.conn is not None else "?"
        self.server.log.exception("%s: unexpected error in the connection handler", peer)
        self.close("internal error")

    # --- output / closing ----------------------------------------------------------------------
    def write(self, data: bytes) -> None:
        """Send ``data`` (notification frames) unless the connection is closing."""
        if not self.closing:
            self.transport.write(data)  # type: ignore[union-attr]

    def close(self, reason: str) -> None:
        """Close after sending what is pending (like ``StreamWriter.close``)."""
        if not self.closing:
            self.closing = True
            self.reason = reason
            self.transport.close()  # type: ignore[union-attr]

    def abort(self, reason: str) -> None:
        """Close at once, dropping what is pending."""
        if not self.closing:
            self.reason = reason
        self.closing = True
        self.transport.abort()  # type: ignore[union-attr]

