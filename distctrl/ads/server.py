"""An ADS server over AMS/TCP (TCP port 48898), so standard Beckhoff ADS clients (pyads, TwinCAT,
the Beckhoff AdsLib, ...) can reach the virtual CNC.

The server owns the wire; devices own the data. Every request is dispatched by its target AMS port
to an :class:`~distctrl.ads.protocol.AdsDevice`, which only provides raw index-group/index-offset
access, its state and a symbol table. Symbol services (handles, value by name/handle, symbol info,
symbol upload) and the sum commands are implemented here on top of that.

Threading: :meth:`AdsServer.start` runs an asyncio loop in a daemon thread that accepts connections
and serves the attached endpoints (UDP route discovery); each accepted connection is served by a
thread of its own with a blocking socket (:class:`~distctrl.ads.transport.ClientLink`, which says
why), and its device notifications by one more thread. Each request (a whole sum command included)
is executed while holding ``lock`` (the served machine's: it then sees the data of one complete
simulation cycle; without one a private lock), so devices are called by one thread at a time.

Layers: :mod:`~distctrl.ads.transport` (connections, framing, flow control),
:mod:`~distctrl.ads.services` (the ADS commands and symbol services, :class:`AdsServices`, this
class's base), :mod:`~distctrl.ads.notifications` (device notifications); this module owns the life
cycle, the listening socket, the allowed networks and the AMS routing (NetId, port).

Robustness: a frame whose length is impossible (shorter than an AMS header, longer than
``max_frame``, or disagreeing with the AMS header's data length) closes only that connection;
frames split over several TCP segments are reassembled; unknown command ids are answered with
0x701; a client vanishing mid-frame is a normal close. Exceptions from devices become ADS error
0x700 and are logged; nothing a client sends stops the server.
"""
from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
import struct
import threading
from collections.abc import Iterable, Mapping
from typing import Any

from ..serve.net import address_allowed, networks
from .errors import ADSERR_DEVICE_BUSY, ERR_TARGETMACHINENOTFOUND, ERR_TARGETPORTNOTFOUND
from .protocol import (
    AMS_HEADER,
    AMS_HEADER_SIZE,
    AMS_TCP_HEADER,
    AMS_TCP_PORT_CLOSE,
    AMS_TCP_HEADER_SIZE,
    AMS_TCP_PORT_CONNECT,
    CMD_DEVICE_NOTIFICATION,
    CMD_READ,
    READ_REQ,
    READ_RES,
    SF_ADS_COMMAND,
    SF_RESPONSE,
    AdsDevice,
    format_net_id,
    parse_net_id,
)
from .services import _SYMBOL_GROUPS as SYMBOL_GROUPS
from .services import AdsServices
from .transport import CLOSE, PORT_CLOSED, ClientLink, Connection

LOGGER_NAME = "distctrl.ads"

_PORT_CONNECT_RES = struct.Struct("<6sH")

#: a response's AMS/TCP header and AMS header, packed at once
_RESPONSE_HEAD = struct.Struct("<HI6sH6sHHHIII")
_pack_response_head = _RESPONSE_HEAD.pack
_unpack_ams_header = AMS_HEADER.unpack_from
_RESPONSE_FLAGS = SF_RESPONSE | SF_ADS_COMMAND
#: an AMS Read request's size (AMS header and index group, offset, length), its success code, and
#: how many answered Read requests the read cache keeps (it starts afresh when full)
_READ_REQUEST_SIZE = AMS_HEADER_SIZE + READ_REQ.size
_RESULT_OK = bytes(4)
_READ_CACHE_SIZE = 1024
#: seconds a new connection waits at ``max_connections`` for one that is ending before it is refused
_LIMIT_GRACE = 0.2


def listening_sockets(host: str | None, port: int, backlog: int = 128) -> list[socket.socket]:
    """Bound, listening, non-blocking TCP sockets for ``host`` (every address it resolves to, as
    asyncio's ``create_server`` binds them; ``""``/None: all interfaces) on ``port`` (0: one free
    port, the same on every address). Raises ``OSError`` if an address cannot be bound."""
    infos = socket.getaddrinfo(host or None, port, socket.AF_UNSPEC, socket.SOCK_STREAM, 0, socket.AI_PASSIVE)
    socks: list[socket.socket] = []
    seen = set()
    try:
        for family, kind, proto, _name, addr in infos:
            if (family, addr[:2]) in seen:
                continue
            seen.add((family, addr[:2]))
            try:
                sock = socket.socket(family, kind, proto)
            except OSError:       # a family this system lacks (IPv6 turned off): skipped, as asyncio does
                continue
            socks.append(sock)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            if family == socket.AF_INET6:
                sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 1)
            if socks[1:] and addr[1] == 0:          # port 0: the port the first address got
                addr = (addr[0], socks[0].getsockname()[1], *addr[2:])
            sock.bind(addr)
            sock.listen(backlog)
            sock.setblocking(False)
    except OSError:
        for sock in socks:
            sock.close()
        raise
    if not socks:
        raise OSError(f"no address of {host!r} can be served on this system: {[i[4] for i in infos]}")
    return socks


class AdsServer(AdsServices):
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
        at most ``lock_timeout`` seconds for it, then answers 0x708 (device busy); that
        connection's thread is blocked while it waits, so hold the lock only for a cycle step.
        Without a lock the server uses a private one (devices are called by one thread at a time).
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
        self.allowed = networks(allowed)
        self.log = log if log is not None else logging.getLogger(LOGGER_NAME)
        self.max_frame = int(max_frame)
        #: held around every request's device calls; without a given lock a private one, so devices
        #: are called by one connection's thread at a time, as they were by the one event loop
        self.lock = lock if lock is not None else threading.Lock()
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
        self._listeners: list[socket.socket] = []
        self._accepting: list[asyncio.Task] = []
        self._writers: set[ClientLink] = set()       # open connections
        self._count_lock = threading.Lock()          # connections, accepted, _writers, dynamic ports
        self._next_dynamic_port = 32768
        #: answered Read requests (bytes but the invoke id) -> (response head, result and length,
        #: reader, device, AMS port, value size): see :meth:`_handle_ams`
        self._read_cache: dict[bytes, tuple] = {}
        #: endpoints run on this server's loop, e.g. the UDP discovery responder
        #: (:class:`~distctrl.ads.discovery.DiscoveryResponder`): ``await a.open(self)`` once the TCP
        #: socket is bound, ``a.close()`` when the server stops
        self.attached: list[Any] = []

    # ------------------------------------------------------------------------------------------
    # life cycle
    # ------------------------------------------------------------------------------------------
    def start(self) -> None:
        """Start listening (the accepting and the attached endpoints in a daemon thread, each
        connection in a thread of its own); returns once the socket is bound.

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
            try:      # end the accept tasks on their loop (closes the listeners and the endpoints)
                asyncio.run_coroutine_threadsafe(self._close(), loop).result(timeout=5.0)
            except Exception:  # pragma: no cover - the start's own error is what matters
                for sock in self._listeners:
                    sock.close()
                self._listeners = []
            loop.call_soon_threadsafe(loop.stop)
            thread.join(timeout=5.0)
            loop.close()
            raise
        self._loop, self._thread = loop, thread
        self.log.info("ADS server %s listening on %s:%d (ports %s)", self.net_id, self.host, self.port,
                      ", ".join(str(p) for p in sorted(self.devices)))

    def stop(self) -> None:
        """Close the listening socket and all connections, stop the threads. Idempotent."""
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
        for link in list(self._writers):
            link.abort("server stopping")
        for link in list(self._writers):
            link.thread.join(timeout=5.0)
        self._loop = self._thread = None
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
        self._listeners = listening_sockets(self.host, self.port)
        self.port = self._listeners[0].getsockname()[1]
        self._accepting = [loop.create_task(self._accept(sock)) for sock in self._listeners]
        for endpoint in self.attached:
            await endpoint.open(self)

    async def _close(self) -> None:
        for endpoint in self.attached:
            with contextlib.suppress(Exception):
                endpoint.close()
        for task in self._accepting:
            task.cancel()
        if self._accepting:
            await asyncio.gather(*self._accepting, return_exceptions=True)
        self._accepting = []
        for sock in self._listeners:
            sock.close()
        self._listeners = []

    async def _accept(self, listener: socket.socket) -> None:
        """Accept connections on ``listener`` and hand each to a :class:`ClientLink` thread."""
        loop = asyncio.get_running_loop()
        last_warning = -1e9
        while True:
            try:
                sock, peername = await loop.sock_accept(listener)
            except asyncio.CancelledError:
                raise
            except OSError as exc:   # e.g. out of descriptors: keep listening (and say so every 10 s)
                if loop.time() - last_warning >= 10.0:
                    last_warning = loop.time()
                    self.log.warning("accept failed: %s", exc)
                await asyncio.sleep(0.1)
                continue
            ip = str(peername[0]) if peername else "?"
            if self.connections >= self.max_connections and self.is_allowed(ip):
                # a client that has just closed a connection and connects again: the thread of its
                # old connection may not have seen the close yet (the asyncio transport had)
                deadline = loop.time() + _LIMIT_GRACE
                while self.connections >= self.max_connections and loop.time() < deadline:
                    await asyncio.sleep(0.002)
            try:
                self._accepted(sock, peername)
            except Exception:
                self.log.exception("connection from %s not served", ip)
                sock.close()

    def _accepted(self, sock: socket.socket, peername) -> None:
        ip = str(peername[0]) if peername else "?"
        if not self.is_allowed(ip) or self.connections >= self.max_connections:
            self.refused += 1
            if self.is_allowed(ip):
                self.log.warning("refused %s (more than %d connections)", ip, self.max_connections)
            else:
                self.log.warning("refused %s", ip)
            sock.close()
            return
        sock.setblocking(True)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        link = ClientLink(self, sock, f"{ip}:{peername[1]}" if peername else ip)
        with self._count_lock:
            self.connections += 1
            self.accepted += 1
            self._writers.add(link)
        self.log.info("connection from %s", link.conn.peer)
        try:
            link.start()
        except BaseException:
            self._link_closed(link)
            raise

    def _link_closed(self, link: ClientLink) -> None:
        """Called by a link's thread when its connection has ended."""
        with self._count_lock:
            if link in self._writers:
                self._writers.discard(link)
                self.connections -= 1

    # ------------------------------------------------------------------------------------------
    # connections
    # ------------------------------------------------------------------------------------------
    def is_allowed(self, ip: str) -> bool:
        """True if ``ip`` lies in one of the ``allowed`` networks."""
        return address_allowed(ip, self.allowed)

    def _handle_tcp_command(self, conn: Connection, reserved: int, body: bytes) -> bytes | None:
        """AMS/TCP frames that are not AMS packets (router-client commands)."""
        if reserved == AMS_TCP_PORT_CONNECT:
            # a router client asks for an AMS port: hand out our NetId and a dynamic port
            with self._count_lock:
                port = self._next_dynamic_port
                self._next_dynamic_port = 32768 + (self._next_dynamic_port - 32768 + 1) % 32000
            data = _PORT_CONNECT_RES.pack(self._net_id, port)
            return AMS_TCP_HEADER.pack(AMS_TCP_PORT_CONNECT, len(data)) + data
        if reserved == AMS_TCP_PORT_CLOSE:
            # the client unregisters its AMS port (ads-client's disconnect): a TwinCAT router drops the
            # TCP connection then, which is the answer the client waits for
            return PORT_CLOSED
        self.log.debug("%s: ignoring AMS/TCP command 0x%04X (%d bytes)", conn.peer, reserved, len(body))
        return None

    # ------------------------------------------------------------------------------------------
    # AMS packets
    # ------------------------------------------------------------------------------------------
    def _handle_ams(self, conn: Connection, body: bytes) -> bytes | None | object:
        """Answer one AMS packet (``body``: AMS header and data, as ``bytes``): the complete
        response frame, None (no answer) or ``CLOSE``.

        A Read request that was answered before (the same bytes but for the invoke id) is answered
        from the read cache when its device gave a ``fast_reader`` for it: the response's headers
        are kept, only the value is read (under the lock). Its answer is byte for byte the one of
        the full path (tests/ads/test_read_cache.py), which answers everything else and every
        error; the cache saves the header parsing and the dispatch, about half of a read's time on
        the server (docs/serve.md, "Round-trip speed").

        The header is kept as the plain tuple of :data:`~distctrl.ads.protocol.AMS_HEADER` fields
        (no :class:`AmsHeader` object per request) and the response's AMS/TCP and AMS headers are
        packed by one struct call."""
        if len(body) == _READ_REQUEST_SIZE:
            entry = self._read_cache.get(body[:28] + body[32:])     # the request but its invoke id
            if entry is not None:
                head, tail, reader, dev, port, n = entry
                if self.devices.get(port) is dev:
                    if not self._lock_acquired(conn):
                        return self._busy_answer(body)
                    try:
                        data = reader()
                    except Exception:     # the full path answers with the error
                        data = None
                    finally:
                        self.lock.release()
                    if data is not None and len(data) == n:
                        return head + body[28:32] + tail + data
        hdr = _unpack_ams_header(body)
        (target_net_id, target_port, source_net_id, source_port, cmd, flags, length, _err,
         invoke_id) = hdr
        if length != len(body) - AMS_HEADER_SIZE:
            self.log.warning("%s: AMS data length %d disagrees with frame length %d; closing",
                             conn.peer, length, len(body) - AMS_HEADER_SIZE)
            return CLOSE
        if flags & SF_RESPONSE or cmd == CMD_DEVICE_NOTIFICATION:
            return None  # nothing we asked for / needs no answer
        flags |= _RESPONSE_FLAGS
        if self.check_net_id and target_net_id != self._net_id:
            self.log.debug("%s: target NetId %s is not ours (%s)", conn.peer,
                           format_net_id(target_net_id), self.net_id)
            return _pack_response_head(0, AMS_HEADER_SIZE, source_net_id, source_port, target_net_id,
                                       target_port, cmd, flags, 0, ERR_TARGETMACHINENOTFOUND, invoke_id)
        device = self.devices.get(target_port)
        if device is None:
            return _pack_response_head(0, AMS_HEADER_SIZE, source_net_id, source_port, target_net_id,
                                       target_port, cmd, flags, 0, ERR_TARGETPORTNOTFOUND, invoke_id)
        data = self._execute(conn, hdr, device, body)
        n = len(data)
        out = _pack_response_head(0, AMS_HEADER_SIZE + n, source_net_id, source_port, target_net_id,
                                  target_port, cmd, flags, n, 0, invoke_id) + data
        if cmd == CMD_READ and length == READ_REQ.size and data[:4] == _RESULT_OK:
            self._cache_read(body, out, device, target_port, n)
        return out

    def _cache_read(self, body: bytes, out: bytes, device: AdsDevice, port: int, n: int) -> None:
        """Keep the answered Read request ``body`` (response ``out``, ``n`` bytes of payload) in the
        read cache if its device gives a ``fast_reader`` for it."""
        fast_reader = getattr(device, "fast_reader", None)
        if fast_reader is None:
            return
        ig, io, length = READ_REQ.unpack_from(body, AMS_HEADER_SIZE)
        if ig in SYMBOL_GROUPS or not self.lock.acquire(False):   # devices are called under the lock
            return
        try:
            reader = fast_reader(ig, io, length)
        finally:
            self.lock.release()
        if reader is None:
            return
        cache = self._read_cache
        if len(cache) >= _READ_CACHE_SIZE:
            cache.clear()
        split = AMS_TCP_HEADER_SIZE + 28                         # the response's invoke id
        cache[body[:28] + body[32:]] = (out[:split], out[split + 4:split + 4 + READ_RES.size], reader,
                                        device, port, n - READ_RES.size)

    @staticmethod
    def _busy_answer(body: bytes) -> bytes:
        """The answer 0x708 (device busy) to the Read request ``body``, as the full path gives it when
        the lock is not free within ``lock_timeout``."""
        (target_net_id, target_port, source_net_id, source_port, cmd, flags, _length, _err,
         invoke_id) = _unpack_ams_header(body)
        data = READ_RES.pack(ADSERR_DEVICE_BUSY, 0)
        return _pack_response_head(0, AMS_HEADER_SIZE + len(data), source_net_id, source_port, target_net_id,
                                   target_port, cmd, flags | _RESPONSE_FLAGS, len(data), 0, invoke_id) + data
