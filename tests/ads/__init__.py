"""Helpers shared by the ADS server tests: an in-memory test device and a raw AMS/TCP client.

The device lives here (not in the package): it is only a stand-in for the real CNC/PLC devices.
"""
from __future__ import annotations

import socket
import struct
import threading
import time
from dataclasses import dataclass

from distctrl.ads import AdsError, SymbolInfo
from distctrl.ads import errors as E
from distctrl.ads import protocol as P

IG_DATA = 0x4020       # read/write memory objects
IG_RO = 0x4021         # read-only objects
IG_BOOM = 0x4030       # every access raises a plain exception (-> 0x700)


@dataclass
class _Obj:
    value: bytearray
    string: bool = False


class MemoryDevice:
    """A tiny typed object store addressed by (index group, index offset), with a symbol table.

    Raw reads must ask for exactly the object size (strings: at least 1 byte; a larger request gets
    the whole string) - else 0x705; unknown group 0x702, unknown offset 0x703; writes to IG_RO 0x704.
    """

    def __init__(self, name: str = "TestPLC", version: tuple[int, int, int] = (3, 1, 4024),
                 lock: threading.Lock | None = None) -> None:
        self.name = name
        self.version = version
        self.lock = lock              # if set: every call asserts it is held (server passes it)
        self.calls = 0
        self.objects: dict[tuple[int, int], _Obj] = {
            (IG_DATA, 0): _Obj(bytearray(struct.pack("<I", 42))),          # MAIN.counter UDINT
            (IG_DATA, 8): _Obj(bytearray(struct.pack("<d", 3.25))),        # MAIN.value LREAL
            (IG_DATA, 16): _Obj(bytearray(b"\x01")),                       # GVL.flag BOOL
            (IG_DATA, 20): _Obj(bytearray(b"hello".ljust(21, b"\0")), string=True),  # GVL.text STRING(20)
            (IG_DATA, 48): _Obj(bytearray(struct.pack("<h", -5))),         # MAIN.small INT
            (IG_RO, 0): _Obj(bytearray(struct.pack("<I", 0x01020304))),    # GVL.version UDINT (read-only)
        }
        self._symbols = {
            "MAIN.counter": SymbolInfo("MAIN.counter", IG_DATA, 0, 4, P.ADST_UINT32, "UDINT", "cycle counter"),
            "MAIN.value": SymbolInfo("MAIN.value", IG_DATA, 8, 8, P.ADST_REAL64, "LREAL", "a real value"),
            "GVL.flag": SymbolInfo("GVL.flag", IG_DATA, 16, 1, P.ADST_BIT, "BOOL"),
            "GVL.text": SymbolInfo("GVL.text", IG_DATA, 20, 21, P.ADST_STRING, "STRING(20)"),
            "MAIN.small": SymbolInfo("MAIN.small", IG_DATA, 48, 2, P.ADST_INT16, "INT"),
            "GVL.version": SymbolInfo("GVL.version", IG_RO, 0, 4, P.ADST_UINT32, "UDINT", "read-only",
                                      read_only=True),
            "MAIN.boom": SymbolInfo("MAIN.boom", IG_BOOM, 0, 4, P.ADST_UINT32, "UDINT"),
        }

    def _check_lock(self) -> None:
        self.calls += 1
        if self.lock is not None:
            assert self.lock.locked(), "device called without the server lock held"

    def _obj(self, ig: int, io: int) -> _Obj:
        if ig == IG_BOOM:
            raise RuntimeError("simulated device fault")
        if ig not in (IG_DATA, IG_RO):
            raise AdsError(E.ADSERR_DEVICE_INVALIDGRP)
        obj = self.objects.get((ig, io))
        if obj is None:
            raise AdsError(E.ADSERR_DEVICE_INVALIDOFFSET)
        return obj

    def read(self, index_group: int, index_offset: int, length: int) -> bytes:
        self._check_lock()
        obj = self._obj(index_group, index_offset)
        if obj.string:
            if length < 1:
                raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE)
            return bytes(obj.value[:length])
        if length != len(obj.value):
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE)
        return bytes(obj.value)

    def write(self, index_group: int, index_offset: int, data: bytes) -> None:
        self._check_lock()
        obj = self._obj(index_group, index_offset)
        if index_group == IG_RO:
            raise AdsError(E.ADSERR_DEVICE_INVALIDACCESS)
        if obj.string:
            if len(data) > len(obj.value):
                raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE)
            obj.value[:] = bytes(data).ljust(len(obj.value), b"\0")
            return
        if len(data) != len(obj.value):
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE)
        obj.value[:] = data

    def symbols(self) -> dict[str, SymbolInfo]:
        return self._symbols

    def state(self) -> tuple[int, int]:
        self._check_lock()
        return (P.ADSSTATE_RUN, 0)

    # helpers for assertions
    def udint(self, io: int, ig: int = IG_DATA) -> int:
        return struct.unpack("<I", self.objects[(ig, io)].value)[0]

    def lreal(self, io: int) -> float:
        return struct.unpack("<d", self.objects[(IG_DATA, io)].value)[0]


class RawClient:
    """A minimal blocking AMS/TCP client on a plain socket (no pyads)."""

    def __init__(self, port: int, host: str = "127.0.0.1", timeout: float = 5.0) -> None:
        self.sock = socket.create_connection((host, port), timeout=timeout)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.invoke = 0
        self.notes: list[tuple[P.AmsHeader, bytes]] = []

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:
            pass

    def __enter__(self) -> RawClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def _recv_exact(self, n: int) -> bytes:
        buf = bytearray()
        while len(buf) < n:
            chunk = self.sock.recv(n - len(buf))
            if not chunk:
                raise ConnectionError(f"connection closed after {len(buf)} of {n} bytes")
            buf += chunk
        return bytes(buf)

    def recv_frame(self) -> tuple[int, bytes]:
        """(AMS/TCP reserved field, body) of the next frame."""
        reserved, length = P.AMS_TCP_HEADER.unpack(self._recv_exact(P.AMS_TCP_HEADER_SIZE))
        return reserved, self._recv_exact(length)

    def recv_response(self) -> P.Response:
        """The next response frame; DeviceNotification frames met on the way are kept in
        :attr:`notes`."""
        while True:
            _, body = self.recv_frame()
            hdr = P.AmsHeader.unpack(body)
            if hdr.command == P.CMD_DEVICE_NOTIFICATION and not hdr.is_response:
                self.notes.append((hdr, body[P.AMS_HEADER_SIZE:]))
                continue
            return P.parse_response(body)

    def recv_notification(self, timeout: float = 3.0) -> tuple[P.AmsHeader, list[tuple[int, int, bytes]]]:
        """(AMS header, [(timestamp, notification handle, data), ...]) of the next DeviceNotification."""
        if self.notes:
            hdr, data = self.notes.pop(0)
        else:
            old = self.sock.gettimeout()
            self.sock.settimeout(timeout)
            try:
                _, body = self.recv_frame()
            finally:
                self.sock.settimeout(old)
            hdr, data = P.AmsHeader.unpack(body), body[P.AMS_HEADER_SIZE:]
            assert hdr.command == P.CMD_DEVICE_NOTIFICATION, hdr
        length, stamps = struct.unpack_from("<II", data)
        assert length == len(data) - 4
        pos, samples = 8, []
        for _ in range(stamps):
            ts, n = struct.unpack_from("<QI", data, pos)
            pos += 12
            for _ in range(n):
                handle, size = struct.unpack_from("<II", data, pos)
                pos += 8
                samples.append((ts, handle, data[pos:pos + size]))
                pos += size
        assert pos == len(data)
        return hdr, samples

    def is_closed_by_server(self, timeout: float = 3.0) -> bool:
        """True if the server closes the connection (EOF or reset) within ``timeout``."""
        self.sock.settimeout(timeout)
        try:
            while True:
                data = self.sock.recv(4096)
                if not data:
                    return True
        except (ConnectionResetError, BrokenPipeError):
            return True
        except TimeoutError:
            return False

    def next_invoke(self) -> int:
        self.invoke += 1
        return self.invoke

    def call(self, make, *args, target_port: int = 851, **kw) -> P.Response:
        """Send ``make(*args, invoke_id=..., target_port=...)`` and return the matching response."""
        inv = self.next_invoke()
        self.send(make(*args, invoke_id=inv, target_port=target_port, **kw))
        resp = self.recv_response()
        assert resp.header.invoke_id == inv
        return resp

    def read(self, ig: int, io: int, length: int, **kw) -> P.Response:
        return self.call(P.read_request, ig, io, length, **kw)

    def write(self, ig: int, io: int, data: bytes, **kw) -> P.Response:
        return self.call(P.write_request, ig, io, data, **kw)

    def read_write(self, ig: int, io: int, rlen: int, data: bytes, **kw) -> P.Response:
        return self.call(P.read_write_request, ig, io, rlen, data, **kw)

    def add_notification(self, ig: int, io: int, length: int, mode: int = 4, cycle_100ns: int = 0,
                         **kw) -> P.Response:
        data = P.ADD_NOTIFICATION_REQ.pack(ig, io, length, mode, 0, cycle_100ns, b"")
        return self.call(P.request, P.CMD_ADD_DEVICE_NOTIFICATION, data, **kw)

    def del_notification(self, handle: int, **kw) -> P.Response:
        return self.call(P.request, P.CMD_DEL_DEVICE_NOTIFICATION, struct.pack("<I", handle), **kw)

    def handle(self, name: str, **kw) -> int:
        r = self.read_write(P.ADSIGRP_SYM_HNDBYNAME, 0, 4, name.encode() + b"\0", **kw)
        assert r.result == 0, hex(r.result)
        return struct.unpack("<I", r.data)[0]


def port_free(host: str, port: int) -> bool:
    """True when TCP ``port`` on ``host`` can be bound (no server of another test or program on it)."""
    import socket

    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError:
            return False
    return True


def wait_for(cond, timeout: float = 3.0) -> bool:
    """Poll ``cond()`` until it is true or ``timeout`` seconds passed; its last value."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.005)
    return bool(cond())
