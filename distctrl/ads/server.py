"""An ADS server over AMS/TCP (TCP port 48898), so standard Beckhoff ADS clients (pyads, TwinCAT,
the Beckhoff AdsLib, ...) can reach the virtual CNC.

The server owns the wire; devices own the data. Every request is dispatched by its target AMS port
to an :class:`~distctrl.ads.protocol.AdsDevice`, which only provides raw index-group/index-offset
access, its state and a symbol table. Symbol services (handles, value by name/handle, symbol info,
symbol upload) and the sum commands are implemented here on top of that.

Threading: :meth:`AdsServer.start` runs an asyncio loop in a daemon thread. All device calls
happen in that thread; if a ``lock`` was given, each request (a whole sum command included) is
executed while holding it, so it sees the data of one complete simulation cycle.

Transport: each connection is a low-level :class:`asyncio.BufferedProtocol` (no stream coroutine
per connection): the socket is read into a fixed per-connection buffer, every complete frame is
answered synchronously in ``buffer_updated`` and the answer is written straight to the transport
(one send call in the usual case). Flow control: while more than 64 KiB of answers wait to be
sent to a client (it does not read), the server neither parses further frames of that client nor
reads from its socket, until the backlog has drained to 16 KiB.

Robustness: a frame whose length is impossible (shorter than an AMS header, longer than
``max_frame``, or disagreeing with the AMS header's data length) closes only that connection;
frames split over several TCP segments are reassembled; unknown command ids are answered with
0x701; a client vanishing mid-frame is a normal close. Exceptions from devices become ADS error
0x700 and are logged; nothing a client sends stops the server.
"""
from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import logging
import struct
import threading
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from . import errors as E
from .errors import AdsError
from .protocol import (
    ADD_NOTIFICATION_REQ,
    ADD_NOTIFICATION_RES,
    ADSIGRP_SUMUP_READ,
    ADSIGRP_SUMUP_READWRITE,
    ADSIGRP_SUMUP_WRITE,
    ADSIGRP_SYM_DT_UPLOAD,
    ADSIGRP_SYM_HNDBYNAME,
    ADSIGRP_SYM_INFOBYNAME,
    ADSIGRP_SYM_INFOBYNAMEEX,
    ADSIGRP_SYM_RELEASEHND,
    ADSIGRP_SYM_UPLOAD,
    ADSIGRP_SYM_UPLOADINFO,
    ADSIGRP_SYM_UPLOADINFO2,
    ADSIGRP_SYM_VALBYHND,
    ADSIGRP_SYM_VALBYNAME,
    ADSIGRP_SYM_VERSION,
    AMS_HEADER,
    AMS_HEADER_SIZE,
    AMS_TCP_HEADER,
    AMS_TCP_HEADER_SIZE,
    AMS_TCP_PORT_CLOSE,
    AMS_TCP_PORT_CONNECT,
    CMD_ADD_DEVICE_NOTIFICATION,
    CMD_DEL_DEVICE_NOTIFICATION,
    CMD_DEVICE_NOTIFICATION,
    CMD_READ,
    CMD_READ_DEVICE_INFO,
    CMD_READ_STATE,
    CMD_READ_WRITE,
    CMD_WRITE,
    CMD_WRITE_CONTROL,
    DEL_NOTIFICATION_REQ,
    DEVICE_INFO_RES,
    READ_REQ,
    READ_RES,
    READ_STATE_RES,
    READ_WRITE_REQ,
    RESULT_RES,
    SF_ADS_COMMAND,
    SF_RESPONSE,
    STRING_TYPES,
    SUM_REQ,
    SUM_RW_REQ,
    SUM_RW_RES,
    SYMBOL_ENCODING,
    WRITE_CONTROL_REQ,
    WRITE_REQ,
    AdsDevice,
    AmsHeader,
    SymbolInfo,
    encode_symbol_entry,
    format_net_id,
    frame,
    parse_net_id,
)

LOGGER_NAME = "distctrl.ads"

_U32 = struct.Struct("<I")
_UPLOADINFO = struct.Struct("<II")
_UPLOADINFO2 = struct.Struct("<IIIIII")
_PORT_CONNECT_RES = struct.Struct("<6sH")

#: index groups the server answers itself (never passed to a device)
_SYMBOL_GROUPS = frozenset({
    ADSIGRP_SYM_HNDBYNAME, ADSIGRP_SYM_VALBYNAME, ADSIGRP_SYM_VALBYHND, ADSIGRP_SYM_RELEASEHND,
    ADSIGRP_SYM_INFOBYNAME, ADSIGRP_SYM_VERSION, ADSIGRP_SYM_INFOBYNAMEEX, ADSIGRP_SYM_UPLOAD,
    ADSIGRP_SYM_UPLOADINFO, ADSIGRP_SYM_DT_UPLOAD, ADSIGRP_SYM_UPLOADINFO2,
    ADSIGRP_SUMUP_READ, ADSIGRP_SUMUP_WRITE, ADSIGRP_SUMUP_READWRITE,
})

_CLOSE = object()  # sentinel: close this connection
_PORT_CLOSED = object()  # sentinel: the client unregistered its AMS port: close as a TwinCAT router does

#: a response's AMS/TCP header and AMS header, packed at once
_RESPONSE_HEAD = struct.Struct("<HI6sH6sHHHIII")
_pack_response_head = _RESPONSE_HEAD.pack
_unpack_ams_header = AMS_HEADER.unpack_from
_unpack_tcp_header = AMS_TCP_HEADER.unpack_from
_pack_read_res = READ_RES.pack
_unpack_read_req = READ_REQ.unpack_from
_READ_REQ_END = AMS_HEADER_SIZE + READ_REQ.size
_MIN_AMS_FRAME = AMS_TCP_HEADER_SIZE + AMS_HEADER_SIZE
_RESPONSE_FLAGS = SF_RESPONSE | SF_ADS_COMMAND
#: per-connection output backlog (bytes handed to the transport but not yet sent) above which the
#: server stops reading and answering that client, and below which it resumes
_WRITE_HIGH = 64 * 1024
_WRITE_LOW = 16 * 1024
#: bytes read from a socket at once (into a fixed per-connection buffer)
_RECV_CHUNK = 64 * 1024


#: ADS transmission modes the server can serve (server cycle / server on change, and the "2"
#: variants that TwinCAT treats the same way here)
_TRANS_CYCLE = frozenset({3, 5})
_TRANS_ON_CHANGE = frozenset({4, 6})
#: seconds between 1601-01-01 (FILETIME epoch) and 1970-01-01
_FILETIME_EPOCH = 11644473600
_NOTIFY_STREAM_HEAD = struct.Struct("<IIQI")   # length, stamps, timestamp, samples
_NOTIFY_SAMPLE_HEAD = struct.Struct("<II")     # notification handle, size
_NOTIFY_FRAME_DATA = 60000                     # bytes of samples per notification frame (before splitting)
_NOTIFY_BACKLOG = 1 << 20                      # unsent bytes to a client above which samples are dropped


@dataclass
class _Notification:
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


class _Connection:
    """Per-connection state: symbol handles and device notifications (both bounded)."""

    __slots__ = ("_next_handle", "_next_notification", "frames", "handles", "max_handles",
                 "notifications", "notifier", "peer", "wake", "writer")

    def __init__(self, peer: str, max_handles: int, writer: _AdsProtocol | None = None) -> None:
        self.peer = peer
        self.writer = writer
        self.handles: dict[int, tuple[int, SymbolInfo]] = {}
        self.max_handles = max_handles
        self._next_handle = 1
        self.frames = 0
        self.notifications: dict[int, _Notification] = {}
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


class _AdsProtocol(asyncio.BufferedProtocol):
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
        self.conn: _Connection | None = None
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
        self.conn = _Connection(f"{ip}:{peername[1]}" if peername else ip, srv.max_handles, self)
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
                    out = srv._handle_ams(conn, body)  # type: ignore[arg-type]
                    if out is _CLOSE:
                        self.close("malformed frame")
                    elif out:
                        self.transport.write(out)  # type: ignore[union-attr, arg-type]
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
                if out is _CLOSE:
                    self.close("malformed frame")
                elif out is _PORT_CLOSED:
                    self.close("AMS port closed by the client")
                elif out:
                    self.transport.write(out)  # type: ignore[union-attr, arg-type]
        except Exception:  # pragma: no cover - defensive: a bug here must not kill the server
            self._internal_error()
        finally:
            if self.closing:
                buf.clear()
            elif pos:
                del buf[:pos]

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


class AdsServer:
    """ADS server over AMS/TCP.

    :param devices: AMS port -> device (e.g. ``{551: cnc_objects, 851: plc}``); the mapping is
        referenced, not copied, so devices may be added before :meth:`start`.
    :param host: address to bind (default loopback only).
    :param port: TCP port (48898 is what ADS clients use; 0 picks a free port, see :attr:`port`).
    :param net_id: the AMS NetId of this (virtual) machine; requests to another NetId are answered
        with router error 0x7 unless ``check_net_id`` is False.
    :param allowed: networks (CIDR strings) whose peers may connect; others are closed at once,
        counted in :attr:`refused` and logged as ``refused <ip>``.
    :param log: a :class:`logging.Logger` (default: logger ``distctrl.ads``).
    :param max_frame: largest accepted AMS/TCP frame (and largest read length) in bytes.
    :param lock: a ``threading.Lock``/``RLock`` held around every request's device calls (a whole
        sum command included), so a request sees one complete simulation cycle. The server waits
        at most ``lock_timeout`` seconds for it, then answers 0x708 (device busy); the I/O thread
        is blocked while it waits, so hold the lock only for a cycle step.
    :param max_connections: simultaneous connections; more are refused like a foreign address.
    :param max_handles: symbol handles per connection; more are answered with 0x70A.
    :param check_net_id: answer requests to another target NetId with router error 0x7.
    :param lock_timeout: see ``lock``.
    :param max_notifications: device notifications per connection; more are answered with 0x716.
    :param min_notification_cycle: shortest notification cycle in seconds (clients' cycle times
        are raised to it; it bounds the sampling load).

    Counters (read from any thread): :attr:`connections` currently open connections,
    :attr:`accepted` connections accepted so far, :attr:`frames` frames received,
    :attr:`refused` connections refused.
    """

    def __init__(self, devices: Mapping[int, AdsDevice], host: str = "127.0.0.1", port: int = 48898,
                 net_id: str = "127.0.0.1.1.1", allowed: Iterable[str] = ("127.0.0.0/8",),
                 log: logging.Logger | None = None, max_frame: int = 1 << 20,
                 lock: Any = None, *, max_connections: int = 64, max_handles: int = 256,
                 check_net_id: bool = True, lock_timeout: float = 1.0, max_notifications: int = 128,
                 min_notification_cycle: float = 0.01) -> None:
        if max_frame < AMS_HEADER_SIZE + 64:
            raise ValueError(f"max_frame must be at least {AMS_HEADER_SIZE + 64}: {max_frame}")
        self.devices = devices
        self.host = host
        self.port = int(port)
        self.net_id = net_id
        self._net_id = parse_net_id(net_id)
        if isinstance(allowed, str):
            allowed = [allowed]
        self.allowed = [ipaddress.ip_network(a, strict=False) for a in allowed]
        self.log = log if log is not None else logging.getLogger(LOGGER_NAME)
        self.max_frame = int(max_frame)
        self.lock = lock
        self.max_connections = int(max_connections)
        self.max_handles = int(max_handles)
        self.check_net_id = bool(check_net_id)
        self.lock_timeout = float(lock_timeout)
        self.max_notifications = int(max_notifications)
        self.min_notification_cycle = float(min_notification_cycle)

        self.connections = 0
        self.accepted = 0
        self.frames = 0
        self.refused = 0

        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._server: asyncio.AbstractServer | None = None
        self._writers: set[_AdsProtocol] = set()
        self._tasks: set[asyncio.Task] = set()
        self._next_dynamic_port = 32768

    # ------------------------------------------------------------------------------------------
    # life cycle
    # ------------------------------------------------------------------------------------------
    def start(self) -> None:
        """Start listening (in a daemon thread); returns once the socket is bound.

        Raises ``OSError`` if the address cannot be bound (e.g. port 48898 in use)."""
        if self._thread is not None:
            raise RuntimeError("AdsServer already started")
        loop = asyncio.new_event_loop()
        thread = threading.Thread(target=self._run_loop, args=(loop,), name="distctrl-ads", daemon=True)
        thread.start()
        fut = asyncio.run_coroutine_threadsafe(self._open(), loop)
        try:
            fut.result(timeout=10.0)
        except BaseException:
            loop.call_soon_threadsafe(loop.stop)
            thread.join(timeout=5.0)
            loop.close()
            raise
        self._loop, self._thread = loop, thread
        self.log.info("ADS server %s listening on %s:%d (ports %s)", self.net_id, self.host, self.port,
                      ", ".join(str(p) for p in sorted(self.devices)))

    def stop(self) -> None:
        """Close the listening socket and all connections, stop the thread. Idempotent."""
        loop, thread = self._loop, self._thread
        if loop is None or thread is None:
            return
        try:
            asyncio.run_coroutine_threadsafe(self._close(), loop).result(timeout=10.0)
        except Exception:  # pragma: no cover - shutdown must not raise
            self.log.exception("error while stopping the ADS server")
        loop.call_soon_threadsafe(loop.stop)
        thread.join(timeout=10.0)
        if not thread.is_alive():
            loop.close()
        self._loop = self._thread = self._server = None
        self.log.info("ADS server stopped")

    @property
    def running(self) -> bool:
        return self._thread is not None

    def __enter__(self) -> AdsServer:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @staticmethod
    def _run_loop(loop: asyncio.AbstractEventLoop) -> None:
        asyncio.set_event_loop(loop)
        loop.run_forever()

    async def _open(self) -> None:
        loop = asyncio.get_running_loop()
        self._server = await loop.create_server(lambda: _AdsProtocol(self), self.host, self.port, backlog=128)
        self.port = self._server.sockets[0].getsockname()[1]

    async def _close(self) -> None:
        if self._server is not None:
            self._server.close()
        for w in list(self._writers):
            with contextlib.suppress(Exception):
                w.abort("server stopping")
        await asyncio.sleep(0)   # let the aborted connections run connection_lost
        tasks = [t for t in self._tasks if not t.done()]
        for t in tasks:
            t.cancel()
        if tasks:
            await asyncio.gather(*tasks, return_exceptions=True)
        if self._server is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._server.wait_closed(), 2.0)

    # ------------------------------------------------------------------------------------------
    # connections
    # ------------------------------------------------------------------------------------------
    def is_allowed(self, ip: str) -> bool:
        """True if ``ip`` lies in one of the ``allowed`` networks."""
        try:
            addr = ipaddress.ip_address(ip.split("%", 1)[0])
        except ValueError:
            return False
        if addr.version == 6 and addr.ipv4_mapped is not None:
            addr = addr.ipv4_mapped
        return any(addr.version == net.version and addr in net for net in self.allowed)

    def _handle_tcp_command(self, conn: _Connection, reserved: int, body: bytes) -> bytes | None:
        """AMS/TCP frames that are not AMS packets (router-client commands)."""
        if reserved == AMS_TCP_PORT_CONNECT:
            # a router client asks for an AMS port: hand out our NetId and a dynamic port
            port = self._next_dynamic_port
            self._next_dynamic_port = 32768 + (self._next_dynamic_port - 32768 + 1) % 32000
            data = _PORT_CONNECT_RES.pack(self._net_id, port)
            return AMS_TCP_HEADER.pack(AMS_TCP_PORT_CONNECT, len(data)) + data
        if reserved == AMS_TCP_PORT_CLOSE:
            # the client unregisters its AMS port (ads-client's disconnect): a TwinCAT router drops the
            # TCP connection then, which is the answer the client waits for
            return _PORT_CLOSED
        self.log.debug("%s: ignoring AMS/TCP command 0x%04X (%d bytes)", conn.peer, reserved, len(body))
        return None

    # ------------------------------------------------------------------------------------------
    # AMS packets
    # ------------------------------------------------------------------------------------------
    def _handle_ams(self, conn: _Connection, body: bytes) -> bytes | None | object:
        """Answer one AMS packet (``body``: AMS header and data, as ``bytes``): the complete
        response frame, None (no answer) or ``_CLOSE``.

        The header is kept as the plain tuple of :data:`~distctrl.ads.protocol.AMS_HEADER` fields
        (no :class:`AmsHeader` object per request) and the response's AMS/TCP and AMS headers are
        packed by one struct call."""
        hdr = _unpack_ams_header(body)
        (target_net_id, target_port, source_net_id, source_port, cmd, flags, length, _err,
         invoke_id) = hdr
        if length != len(body) - AMS_HEADER_SIZE:
            self.log.warning("%s: AMS data length %d disagrees with frame length %d; closing",
                             conn.peer, length, len(body) - AMS_HEADER_SIZE)
            return _CLOSE
        if flags & SF_RESPONSE or cmd == CMD_DEVICE_NOTIFICATION:
            return None  # nothing we asked for / needs no answer
        flags |= _RESPONSE_FLAGS
        if self.check_net_id and target_net_id != self._net_id:
            self.log.debug("%s: target NetId %s is not ours (%s)", conn.peer,
                           format_net_id(target_net_id), self.net_id)
            return _pack_response_head(0, AMS_HEADER_SIZE, source_net_id, source_port, target_net_id,
                                       target_port, cmd, flags, 0, E.ERR_TARGETMACHINENOTFOUND, invoke_id)
        device = self.devices.get(target_port)
        if device is None:
            return _pack_response_head(0, AMS_HEADER_SIZE, source_net_id, source_port, target_net_id,
                                       target_port, cmd, flags, 0, E.ERR_TARGETPORTNOTFOUND, invoke_id)
        data = self._execute(conn, hdr, device, body)
        n = len(data)
        return _pack_response_head(0, AMS_HEADER_SIZE + n, source_net_id, source_port, target_net_id,
                                   target_port, cmd, flags, n, 0, invoke_id) + data

    def _execute(self, conn: _Connection, hdr: tuple, dev: AdsDevice, body: bytes) -> bytes:
        """Run one ADS command (``hdr``: the unpacked AMS header fields, ``body``: AMS header and
        data); always returns the response payload (errors included)."""
        try:
            lock = self.lock
            if lock is None:
                return self._command(conn, hdr, dev, body)
            if not lock.acquire(True, self.lock_timeout):
                self.log.warning("%s: lock not free within %.3g s; answered 0x708 (busy)",
                                 conn.peer, self.lock_timeout)
                raise AdsError(E.ADSERR_DEVICE_BUSY, "simulation lock not available")
            try:
                return self._command(conn, hdr, dev, body)
            finally:
                lock.release()
        except AdsError as e:
            code = e.code
        except Exception:
            self.log.exception("%s: device %r failed on command %d (answered 0x700)", conn.peer,
                               getattr(dev, "name", hdr[1]), hdr[4])
            code = E.ADSERR_DEVICE_ERROR
        cmd = hdr[4]
        if cmd in (CMD_READ, CMD_READ_WRITE):
            return READ_RES.pack(code, 0)
        if cmd == CMD_READ_STATE:
            return READ_STATE_RES.pack(code, 0, 0)
        if cmd == CMD_READ_DEVICE_INFO:
            return DEVICE_INFO_RES.pack(code, 0, 0, 0, b"")
        if cmd == CMD_ADD_DEVICE_NOTIFICATION:
            return ADD_NOTIFICATION_RES.pack(code, 0)
        return RESULT_RES.pack(code)

    def _command(self, conn: _Connection, hdr: tuple, dev: AdsDevice, body: bytes) -> bytes:
        cmd, ams_port = hdr[4], hdr[1]
        if cmd == CMD_READ:   # the hot path: no memoryview, no method call for the length check
            if len(body) < _READ_REQ_END:
                raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, "short Read request")
            ig, io, length = _unpack_read_req(body, AMS_HEADER_SIZE)
            if length > self.max_frame:
                length = self._capacity(ig, length)
            data = self._read(conn, ams_port, dev, ig, io, length)
            return _pack_read_res(0, len(data)) + data
        p = memoryview(body)[AMS_HEADER_SIZE:]
        if cmd == CMD_WRITE:
            if len(p) < WRITE_REQ.size:
                raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, "short Write request")
            ig, io, length = WRITE_REQ.unpack_from(p)
            if length > len(p) - WRITE_REQ.size:
                raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, "Write data shorter than its length field")
            self._write(conn, ams_port, dev, ig, io, bytes(p[WRITE_REQ.size:WRITE_REQ.size + length]))
            return RESULT_RES.pack(0)
        if cmd == CMD_READ_WRITE:
            if len(p) < READ_WRITE_REQ.size:
                raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, "short ReadWrite request")
            ig, io, rlen, wlen = READ_WRITE_REQ.unpack_from(p)
            if wlen > len(p) - READ_WRITE_REQ.size:
                raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, "ReadWrite data shorter than its length field")
            if rlen > self.max_frame:
                rlen = self._capacity(ig, rlen)
            wdata = bytes(p[READ_WRITE_REQ.size:READ_WRITE_REQ.size + wlen])
            data = self._read_write(conn, ams_port, dev, ig, io, rlen, wdata)
            return READ_RES.pack(0, len(data)) + data
        if cmd == CMD_READ_STATE:
            ads_state, dev_state = dev.state()
            return READ_STATE_RES.pack(0, int(ads_state) & 0xFFFF, int(dev_state) & 0xFFFF)
        if cmd == CMD_READ_DEVICE_INFO:
            major, minor, build = (tuple(dev.version) + (0, 0, 0))[:3]
            name = str(dev.name).encode(SYMBOL_ENCODING, errors="replace")[:15]
            return DEVICE_INFO_RES.pack(0, int(major) & 0xFF, int(minor) & 0xFF, int(build) & 0xFFFF, name)
        if cmd == CMD_WRITE_CONTROL:
            fn = getattr(dev, "write_control", None)
            if fn is None:
                raise AdsError(E.ADSERR_DEVICE_SRVNOTSUPP, "WriteControl")
            if len(p) < WRITE_CONTROL_REQ.size:
                raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, "short WriteControl request")
            ads_state, dev_state, length = WRITE_CONTROL_REQ.unpack_from(p)
            if length > len(p) - WRITE_CONTROL_REQ.size:
                raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, "WriteControl data shorter than its length field")
            fn(ads_state, dev_state, bytes(p[WRITE_CONTROL_REQ.size:WRITE_CONTROL_REQ.size + length]))
            return RESULT_RES.pack(0)
        if cmd == CMD_ADD_DEVICE_NOTIFICATION:
            return ADD_NOTIFICATION_RES.pack(0, self._add_notification(conn, AmsHeader._make(hdr), dev, p))
        if cmd == CMD_DEL_DEVICE_NOTIFICATION:
            if len(p) < DEL_NOTIFICATION_REQ.size:
                raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, "short DeleteDeviceNotification request")
            handle = DEL_NOTIFICATION_REQ.unpack_from(p)[0]
            n = conn.notifications.get(handle)
            if n is None or n.ams_port != ams_port:
                raise AdsError(E.ADSERR_DEVICE_NOTIFYHNDINVALID, f"unknown notification 0x{handle:X}")
            del conn.notifications[handle]
            return RESULT_RES.pack(0)
        raise AdsError(E.ADSERR_DEVICE_SRVNOTSUPP, f"unknown command id {cmd}")

    def _check_length(self, length: int) -> None:
        if length > self.max_frame:
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, f"read length {length} exceeds {self.max_frame}")

    def _capacity(self, ig: int, length: int) -> int:
        """A read length above the frame limit: for the symbol services it is a buffer's capacity (ads-client
        asks with 0xFFFFFFFF, "any size") and the answer has the real size; for a device's own index
        groups it is refused (0x705)."""
        if ig in _SYMBOL_GROUPS:
            return self.max_frame
        self._check_length(length)
        return length

    # ------------------------------------------------------------------------------------------
    # device notifications
    # ------------------------------------------------------------------------------------------
    def _add_notification(self, conn: _Connection, hdr: AmsHeader, dev: AdsDevice, p: memoryview) -> int:
        if len(p) < ADD_NOTIFICATION_REQ.size:
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, "short AddDeviceNotification request")
        ig, io, length, mode, _max_delay, cycle, _ = ADD_NOTIFICATION_REQ.unpack_from(p)
        if mode not in _TRANS_CYCLE and mode not in _TRANS_ON_CHANGE:
            raise AdsError(E.ADSERR_DEVICE_TRANSMODENOTSUPP, f"transmission mode {mode}")
        if length == 0:
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, "notification length 0")
        if length > min(65536, self.max_frame):
            raise AdsError(E.ADSERR_DEVICE_INVALIDWATCHSIZE, f"notification length {length}")
        if len(conn.notifications) >= self.max_notifications:
            raise AdsError(E.ADSERR_DEVICE_NOMOREHDLS,
                           f"at most {self.max_notifications} notifications per connection")
        self._read(conn, hdr.target_port, dev, ig, io, length)  # must be readable now
        now = asyncio.get_running_loop().time()
        n = _Notification(
            handle=conn.new_notification_handle(), ams_port=hdr.target_port, index_group=ig,
            index_offset=io, length=length, on_change=mode in _TRANS_ON_CHANGE,
            cycle=max(cycle * 1e-7, self.min_notification_cycle),
            route=(hdr.source_net_id, hdr.source_port, hdr.target_net_id, hdr.target_port),
            # the first sample follows the response after a moment: the client must have
            # registered the handle before the first sample arrives
            due=now + 0.05,
        )
        conn.notifications[n.handle] = n
        if conn.notifier is None or conn.notifier.done():
            conn.notifier = asyncio.get_running_loop().create_task(self._notify_loop(conn))
            self._tasks.add(conn.notifier)
        conn.wake.set()
        return n.handle

    async def _notify_loop(self, conn: _Connection) -> None:
        """Send the due notification samples of one connection, until it has none."""
        loop = asyncio.get_running_loop()
        try:
            while conn.notifications:
                now = loop.time()
                due = [n for n in conn.notifications.values() if n.due <= now]
                if due:
                    for chunk in self._notification_frames(conn, due, now):
                        conn.writer.write(chunk)
                if not conn.notifications:
                    break
                conn.wake.clear()
                wait = min(n.due for n in conn.notifications.values()) - loop.time()
                if wait > 0:
                    with contextlib.suppress(asyncio.TimeoutError):
                        await asyncio.wait_for(conn.wake.wait(), wait)
                else:
                    await asyncio.sleep(0)
        except asyncio.CancelledError:
            raise
        except Exception:  # pragma: no cover - defensive
            self.log.exception("%s: notification loop failed", conn.peer)

    def _notification_frames(self, conn: _Connection, due: list[_Notification], now: float) -> list[bytes]:
        """Sample ``due`` (under the lock) and build the DeviceNotification frames to send."""
        for n in due:   # schedule the next sample (no burst after a stall)
            n.due = n.due + n.cycle if n.due + n.cycle > now else now + n.cycle
        writer = conn.writer
        if writer is None or writer.transport.get_write_buffer_size() > _NOTIFY_BACKLOG:
            return []   # the client does not read: drop this round (on-change ones are resent)
        lock = self.lock
        if lock is not None and not lock.acquire(timeout=min(self.lock_timeout, 0.05)):
            return []   # try again at the next cycle
        samples: dict[tuple[bytes, int, bytes, int], list[tuple[int, bytes]]] = {}
        try:
            for n in due:
                dev = self.devices.get(n.ams_port)
                if dev is None:
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
            if lock is not None:
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

    # ------------------------------------------------------------------------------------------
    # services (shared by the plain commands and the sum commands)
    # ------------------------------------------------------------------------------------------
    def _read(self, conn: _Connection, ams_port: int, dev: AdsDevice, ig: int, io: int, length: int) -> bytes:
        if ig in _SYMBOL_GROUPS:   # (one test on the hot path: a device's own index group)
            if ig == ADSIGRP_SYM_VALBYHND:
                return self._sym_read(dev, conn.symbol(ams_port, io), length)
            if ig == ADSIGRP_SYM_UPLOADINFO2:
                syms = self._symbols(dev)
                total = sum(len(encode_symbol_entry(s)) for s in syms.values())
                return self._fit(_UPLOADINFO2.pack(len(syms), total, 0, 0, 0, 0), length)
            if ig == ADSIGRP_SYM_UPLOADINFO:
                syms = self._symbols(dev)
                total = sum(len(encode_symbol_entry(s)) for s in syms.values())
                return self._fit(_UPLOADINFO.pack(len(syms), total), length)
            if ig == ADSIGRP_SYM_UPLOAD:
                blob = b"".join(encode_symbol_entry(s) for s in self._symbols(dev).values())
                return self._fit(blob, length)
            if ig == ADSIGRP_SYM_VERSION:
                return self._fit(b"\x01", length)
            if ig == ADSIGRP_SYM_DT_UPLOAD:
                return b""  # no data types are published
            raise AdsError(E.ADSERR_DEVICE_SRVNOTSUPP, f"Read of index group 0x{ig:X}")
        data = bytes(dev.read(ig, io, length))
        if len(data) > length:
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, f"0x{ig:X}:0x{io:X} has {len(data)} bytes, "
                                                        f"{length} requested")
        return data

    def _write(self, conn: _Connection, ams_port: int, dev: AdsDevice, ig: int, io: int, data: bytes) -> None:
        if ig == ADSIGRP_SYM_VALBYHND:
            self._sym_write(dev, conn.symbol(ams_port, io), data)
        elif ig == ADSIGRP_SYM_RELEASEHND:
            if len(data) < 4:
                raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, "release handle needs a 4-byte handle")
            conn.release(ams_port, _U32.unpack_from(data)[0])
        elif ig in _SYMBOL_GROUPS:
            raise AdsError(E.ADSERR_DEVICE_SRVNOTSUPP, f"Write to index group 0x{ig:X}")
        else:
            dev.write(ig, io, data)

    def _read_write(self, conn: _Connection, ams_port: int, dev: AdsDevice, ig: int, io: int, rlen: int,
                    data: bytes, nested: bool = False) -> bytes:
        if ig == ADSIGRP_SYM_HNDBYNAME:
            if rlen < 4:
                raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, "handle needs a 4-byte read buffer")
            sym = self._find(dev, data)
            out = _U32.pack(conn.new_handle(ams_port, sym))
        elif ig == ADSIGRP_SYM_VALBYNAME:
            out = self._sym_read(dev, self._find(dev, data), rlen)
        elif ig == ADSIGRP_SYM_INFOBYNAMEEX:
            out = encode_symbol_entry(self._find(dev, data))
        elif ig in (ADSIGRP_SUMUP_READ, ADSIGRP_SUMUP_WRITE, ADSIGRP_SUMUP_READWRITE):
            if nested:
                raise AdsError(E.ADSERR_DEVICE_SRVNOTSUPP, "nested sum command")
            if ig == ADSIGRP_SUMUP_READ:
                out = self._sum_read(conn, ams_port, dev, io, rlen, data)
            elif ig == ADSIGRP_SUMUP_WRITE:
                out = self._sum_write(conn, ams_port, dev, io, rlen, data)
            else:
                out = self._sum_read_write(conn, ams_port, dev, io, rlen, data)
        elif ig not in _SYMBOL_GROUPS and hasattr(dev, "read_write"):
            out = bytes(dev.read_write(ig, io, rlen, data))  # type: ignore[attr-defined]
        elif not data:
            out = self._read(conn, ams_port, dev, ig, io, rlen)
        elif rlen == 0:
            self._write(conn, ams_port, dev, ig, io, data)
            out = b""
        else:
            raise AdsError(E.ADSERR_DEVICE_SRVNOTSUPP, f"ReadWrite on index group 0x{ig:X}")
        if len(out) > rlen:
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, f"answer has {len(out)} bytes, buffer {rlen}")
        return out

    # --- sum commands ---------------------------------------------------------------------------
    def _sub(self, conn: _Connection, fn, *args) -> tuple[int, Any]:
        """Run one sub-request of a sum command: (error code, result)."""
        try:
            return 0, fn(*args)
        except AdsError as e:
            return e.code, None
        except Exception:
            self.log.exception("%s: device failed in a sum sub-request (answered 0x700)", conn.peer)
            return E.ADSERR_DEVICE_ERROR, None

    @staticmethod
    def _check_count(n: int, item: int, data: bytes) -> None:
        if n * item > len(data):
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, f"sum command: {n} sub-requests need "
                                                        f"{n * item} bytes, got {len(data)}")

    def _sum_read(self, conn, ams_port, dev, n, rlen, data) -> bytes:
        """IG 0xF080: ``n`` × (ig, io, length) -> ``n`` error codes, then each sub-request's data
        at its full requested length (zero-filled where it failed or returned less)."""
        self._check_count(n, SUM_REQ.size, data)
        reqs = [SUM_REQ.unpack_from(data, i * SUM_REQ.size) for i in range(n)]
        total = 4 * n + sum(r[2] for r in reqs)
        if total > rlen:
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, f"sum read needs {total} bytes, buffer {rlen}")
        codes, chunks = [], []
        for ig, io, size in reqs:
            err, out = self._sub(conn, self._read, conn, ams_port, dev, ig, io, size)
            codes.append(err)
            out = out if err == 0 else b""
            chunks.append(out.ljust(size, b"\0"))
        return struct.pack(f"<{n}I", *codes) + b"".join(chunks)

    def _sum_write(self, conn, ams_port, dev, n, rlen, data) -> bytes:
        """IG 0xF081: ``n`` × (ig, io, length), then the concatenated data -> ``n`` error codes."""
        self._check_count(n, SUM_REQ.size, data)
        reqs = [SUM_REQ.unpack_from(data, i * SUM_REQ.size) for i in range(n)]
        pos = n * SUM_REQ.size
        if pos + sum(r[2] for r in reqs) > len(data):
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, "sum write: data shorter than announced")
        if 4 * n > rlen:
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, f"sum write needs {4 * n} bytes, buffer {rlen}")
        codes = []
        for ig, io, size in reqs:
            err, _ = self._sub(conn, self._write, conn, ams_port, dev, ig, io, data[pos:pos + size])
            pos += size
            codes.append(err)
        return struct.pack(f"<{n}I", *codes)

    def _sum_read_write(self, conn, ams_port, dev, n, rlen, data) -> bytes:
        """IG 0xF082: ``n`` × (ig, io, read length, write length), then the concatenated write data
        -> ``n`` × (error, returned length), then the concatenated returned data."""
        self._check_count(n, SUM_RW_REQ.size, data)
        reqs = [SUM_RW_REQ.unpack_from(data, i * SUM_RW_REQ.size) for i in range(n)]
        pos = n * SUM_RW_REQ.size
        if pos + sum(r[3] for r in reqs) > len(data):
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, "sum read-write: data shorter than announced")
        heads, chunks, total = [], [], SUM_RW_RES.size * n
        for ig, io, sub_rlen, sub_wlen in reqs:
            err, out = self._sub(conn, self._read_write, conn, ams_port, dev, ig, io, sub_rlen,
                                 data[pos:pos + sub_wlen], True)
            pos += sub_wlen
            out = out if err == 0 else b""
            heads.append(SUM_RW_RES.pack(err, len(out)))
            chunks.append(out)
            total += len(out)
        if total > rlen:
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, f"sum read-write needs {total} bytes, buffer {rlen}")
        return b"".join(heads) + b"".join(chunks)

    # --- symbols -------------------------------------------------------------------------------
    @staticmethod
    def _symbols(dev: AdsDevice) -> Mapping[str, SymbolInfo]:
        return dev.symbols() or {}

    def _find(self, dev: AdsDevice, raw: bytes) -> SymbolInfo:
        """The symbol named by ``raw`` (NUL-terminated or not; case-insensitive)."""
        name = bytes(raw).split(b"\0", 1)[0].decode(SYMBOL_ENCODING, errors="replace").strip()
        syms = self._symbols(dev)
        sym = syms.get(name)
        if sym is None and name:
            low = name.lower()
            for key, value in syms.items():
                if key.lower() == low:
                    sym = value
                    break
        if sym is None:
            raise AdsError(E.ADSERR_DEVICE_SYMBOLNOTFOUND, f"symbol {name!r} not found")
        return sym

    @staticmethod
    def _fit(data: bytes, length: int) -> bytes:
        if len(data) > length:
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, f"{len(data)} bytes, buffer {length}")
        return data

    def _sym_read(self, dev: AdsDevice, sym: SymbolInfo, length: int) -> bytes:
        """Value of a symbol. Strings: any length (the value is cut to it, a larger buffer gets the
        whole string); other types: the length is a capacity, at least the symbol's size, and the answer
        has the symbol's size (as a TwinCAT 3 target answers ads-client's "any size" reads)."""
        if sym.ads_type in STRING_TYPES:
            data = bytes(dev.read(sym.index_group, sym.index_offset, sym.size))[:sym.size]
            return data[:length]
        if length < sym.size:
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, f"{sym.name} has {sym.size} bytes, {length} requested")
        data = bytes(dev.read(sym.index_group, sym.index_offset, sym.size))
        if len(data) > sym.size:
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, f"{sym.name}: device returned {len(data)} bytes")
        return data

    def _sym_write(self, dev: AdsDevice, sym: SymbolInfo, data: bytes) -> None:
        """Write a symbol. Strings may be shorter than the symbol (zero-padded), other types must
        match its size exactly. Read-only symbols answer 0x704."""
        if sym.read_only:
            raise AdsError(E.ADSERR_DEVICE_INVALIDACCESS, f"{sym.name} is read-only")
        if sym.ads_type in STRING_TYPES:
            if len(data) > sym.size:
                raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, f"{sym.name} has {sym.size} bytes, got {len(data)}")
            data = data.ljust(sym.size, b"\0")
        elif len(data) != sym.size:
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE, f"{sym.name} has {sym.size} bytes, got {len(data)}")
        dev.write(sym.index_group, sym.index_offset, data)
