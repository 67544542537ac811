"""The ADS services of the server: one command executed against a device under the server's lock
(Read, Write, ReadWrite, ReadState, ReadDeviceInfo, WriteControl, notifications), the symbol
services (handles, value by name/handle, symbol info, uploads) and the sum commands, on top of a
device's raw index-group/index-offset access. Exceptions from devices become ADS error 0x700 and
are logged."""
from __future__ import annotations

import struct
from collections.abc import Mapping
from typing import Any

from .datatypes import DataType, encode_data_type, find_type, types_of
from .errors import (
    ADSERR_DEVICE_BUSY,
    ADSERR_DEVICE_ERROR,
    ADSERR_DEVICE_INVALIDACCESS,
    ADSERR_DEVICE_INVALIDSIZE,
    ADSERR_DEVICE_NOTIFYHNDINVALID,
    ADSERR_DEVICE_SRVNOTSUPP,
    ADSERR_DEVICE_SYMBOLNOTFOUND,
    AdsError,
)
from .notifications import NotificationService
from .protocol import (
    ADD_NOTIFICATION_RES,
    ADSIGRP_SUMUP_READ,
    ADSIGRP_SUMUP_READWRITE,
    ADSIGRP_SUMUP_WRITE,
    ADSIGRP_SYM_DT_INFOBYNAMEEX,
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
    AMS_HEADER_SIZE,
    CMD_ADD_DEVICE_NOTIFICATION,
    CMD_DEL_DEVICE_NOTIFICATION,
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
    lookup,
)
from .transport import Connection

_U32 = struct.Struct("<I")
_UPLOADINFO = struct.Struct("<II")
_UPLOADINFO2 = struct.Struct("<IIIIII")
_HANDLE_EX = struct.Struct("<IIIH")    # handle, size, type decoration, type-name length

#: index groups the server answers itself (never passed to a device)
_SYMBOL_GROUPS = frozenset({
    ADSIGRP_SYM_HNDBYNAME, ADSIGRP_SYM_VALBYNAME, ADSIGRP_SYM_VALBYHND, ADSIGRP_SYM_RELEASEHND,
    ADSIGRP_SYM_INFOBYNAME, ADSIGRP_SYM_VERSION, ADSIGRP_SYM_INFOBYNAMEEX, ADSIGRP_SYM_UPLOAD,
    ADSIGRP_SYM_UPLOADINFO, ADSIGRP_SYM_DT_UPLOAD, ADSIGRP_SYM_UPLOADINFO2, ADSIGRP_SYM_DT_INFOBYNAMEEX,
    ADSIGRP_SUMUP_READ, ADSIGRP_SUMUP_WRITE, ADSIGRP_SUMUP_READWRITE,
})

_pack_read_res = READ_RES.pack
_unpack_read_req = READ_REQ.unpack_from
_READ_REQ_END = AMS_HEADER_SIZE + READ_REQ.size


def _name(raw: bytes) -> str:
    """A name sent by a client, NUL-terminated or not."""
    return bytes(raw).split(b"\0", 1)[0].decode(SYMBOL_ENCODING, errors="replace").strip()


def _handle_answer(handle: int, sym: SymbolInfo, rlen: int) -> bytes:
    """The answer to "handle by name": with a read buffer of 4 bytes (pyads) the handle alone; with a
    buffer that holds more, as a TwinCAT 3 target answers ads-client, the handle, the symbol's size,
    its type decoration (0: distctrl's symbols carry none), the type name's length and the type name
    with its NUL."""
    type_name = sym.type_name.encode(SYMBOL_ENCODING, errors="replace")[:255]
    full = _HANDLE_EX.pack(handle, sym.size, 0, len(type_name)) + type_name + b"\0"
    return full if rlen >= len(full) else _U32.pack(handle)


class AdsServices(NotificationService):
    """ADS command semantics of :class:`~distctrl.ads.server.AdsServer` (its base class: it uses the
    server's ``devices``, ``lock``, ``lock_timeout``, ``log``, ``max_frame``)."""

    def _lock_acquired(self, conn: Connection) -> bool:
        """Take the lock, waiting at most ``lock_timeout``; False (logged: the request is answered
        0x708, device busy) when it is not free by then."""
        if self.lock.acquire(True, self.lock_timeout):
            return True
        self.log.warning("%s: lock not free within %.3g s; answered 0x708 (busy)", conn.peer, self.lock_timeout)
        return False

    def _execute(self, conn: Connection, hdr: tuple, dev: AdsDevice, body: bytes) -> bytes:
        """Run one ADS command (``hdr``: the unpacked AMS header fields, ``body``: AMS header and
        data); always returns the response payload (errors included)."""
        try:
            if not self._lock_acquired(conn):
                raise AdsError(ADSERR_DEVICE_BUSY, "simulation lock not available")
            try:
                return self._command(conn, hdr, dev, body)
            finally:
                self.lock.release()
        except AdsError as e:
            code = e.code
        except Exception:
            self.log.exception("%s: device %r failed on command %d (answered 0x700)", conn.peer,
                               getattr(dev, "name", hdr[1]), hdr[4])
            code = ADSERR_DEVICE_ERROR
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

    def _command(self, conn: Connection, hdr: tuple, dev: AdsDevice, body: bytes) -> bytes:
        cmd, ams_port = hdr[4], hdr[1]
        if cmd == CMD_READ:   # the hot path: no memoryview, no method call for the length check
            if len(body) < _READ_REQ_END:
                raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "short Read request")
            ig, io, length = _unpack_read_req(body, AMS_HEADER_SIZE)
            if length > self.max_frame:
                length = self._capacity(ig, length)
            data = self._read(conn, ams_port, dev, ig, io, length)
            return _pack_read_res(0, len(data)) + data
        p = memoryview(body)[AMS_HEADER_SIZE:]
        if cmd == CMD_WRITE:
            if len(p) < WRITE_REQ.size:
                raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "short Write request")
            ig, io, length = WRITE_REQ.unpack_from(p)
            if length > len(p) - WRITE_REQ.size:
                raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "Write data shorter than its length field")
            self._write(conn, ams_port, dev, ig, io, bytes(p[WRITE_REQ.size:WRITE_REQ.size + length]))
            return RESULT_RES.pack(0)
        if cmd == CMD_READ_WRITE:
            if len(p) < READ_WRITE_REQ.size:
                raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "short ReadWrite request")
            ig, io, rlen, wlen = READ_WRITE_REQ.unpack_from(p)
            if wlen > len(p) - READ_WRITE_REQ.size:
                raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "ReadWrite data shorter than its length field")
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
                raise AdsError(ADSERR_DEVICE_SRVNOTSUPP, "WriteControl")
            if len(p) < WRITE_CONTROL_REQ.size:
                raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "short WriteControl request")
            ads_state, dev_state, length = WRITE_CONTROL_REQ.unpack_from(p)
            if length > len(p) - WRITE_CONTROL_REQ.size:
                raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "WriteControl data shorter than its length field")
            fn(ads_state, dev_state, bytes(p[WRITE_CONTROL_REQ.size:WRITE_CONTROL_REQ.size + length]))
            return RESULT_RES.pack(0)
        if cmd == CMD_ADD_DEVICE_NOTIFICATION:
            return ADD_NOTIFICATION_RES.pack(0, self._add_notification(conn, AmsHeader._make(hdr), dev, p))
        if cmd == CMD_DEL_DEVICE_NOTIFICATION:
            if len(p) < DEL_NOTIFICATION_REQ.size:
                raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "short DeleteDeviceNotification request")
            handle = DEL_NOTIFICATION_REQ.unpack_from(p)[0]
            n = conn.notifications.get(handle)
            if n is None or n.ams_port != ams_port:
                raise AdsError(ADSERR_DEVICE_NOTIFYHNDINVALID, f"unknown notification 0x{handle:X}")
            del conn.notifications[handle]
            return RESULT_RES.pack(0)
        raise AdsError(ADSERR_DEVICE_SRVNOTSUPP, f"unknown command id {cmd}")

    def _check_length(self, length: int) -> None:
        if length > self.max_frame:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"read length {length} exceeds {self.max_frame}")

    def _capacity(self, ig: int, length: int) -> int:
        """A read length above the frame limit: for the symbol services it is a buffer's capacity (ads-client
        asks with 0xFFFFFFFF, "any size") and the answer has the real size; for a device's own index
        groups it is refused (0x705)."""
        if ig in _SYMBOL_GROUPS:
            return self.max_frame
        self._check_length(length)
        return length


    # ------------------------------------------------------------------------------------------
    # services (shared by the plain commands and the sum commands)
    # ------------------------------------------------------------------------------------------
    def _read(self, conn: Connection, ams_port: int, dev: AdsDevice, ig: int, io: int, length: int) -> bytes:
        if ig in _SYMBOL_GROUPS:   # (one test on the hot path: a device's own index group)
            if ig == ADSIGRP_SYM_VALBYHND:
                return self._sym_read(dev, conn.symbol(ams_port, io), length)
            if ig == ADSIGRP_SYM_UPLOADINFO2:
                syms = self._symbols(dev)
                total = sum(len(encode_symbol_entry(s)) for s in syms.values())
                types = self._types(dev)
                types_total = sum(len(encode_data_type(t)) for t in types.values())
                return self._fit(_UPLOADINFO2.pack(len(syms), total, len(types), types_total, 0, 0), length)
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
                return self._fit(b"".join(encode_data_type(t) for t in self._types(dev).values()), length)
            raise AdsError(ADSERR_DEVICE_SRVNOTSUPP, f"Read of index group 0x{ig:X}")
        data = bytes(dev.read(ig, io, length))
        if len(data) > length:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"0x{ig:X}:0x{io:X} has {len(data)} bytes, "
                                                        f"{length} requested")
        return data

    def _write(self, conn: Connection, ams_port: int, dev: AdsDevice, ig: int, io: int, data: bytes) -> None:
        if ig == ADSIGRP_SYM_VALBYHND:
            self._sym_write(dev, conn.symbol(ams_port, io), data)
        elif ig == ADSIGRP_SYM_RELEASEHND:
            if len(data) < 4:
                raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "release handle needs a 4-byte handle")
            conn.release(ams_port, _U32.unpack_from(data)[0])
        elif ig in _SYMBOL_GROUPS:
            raise AdsError(ADSERR_DEVICE_SRVNOTSUPP, f"Write to index group 0x{ig:X}")
        else:
            dev.write(ig, io, data)

    def _read_write(self, conn: Connection, ams_port: int, dev: AdsDevice, ig: int, io: int, rlen: int,
                    data: bytes, nested: bool = False) -> bytes:
        if ig == ADSIGRP_SYM_HNDBYNAME:
            if rlen < 4:
                raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "handle needs a 4-byte read buffer")
            sym = self._find(dev, data)
            out = _handle_answer(conn.new_handle(ams_port, sym), sym, rlen)
        elif ig == ADSIGRP_SYM_VALBYNAME:
            out = self._sym_read(dev, self._find(dev, data), rlen)
        elif ig == ADSIGRP_SYM_INFOBYNAMEEX:
            out = encode_symbol_entry(self._find(dev, data))
        elif ig == ADSIGRP_SYM_DT_INFOBYNAMEEX:
            name = _name(data)
            t = find_type(self._types(dev), name)
            if t is None:
                raise AdsError(ADSERR_DEVICE_SYMBOLNOTFOUND, f"data type {name!r} not found")
            out = encode_data_type(t)
        elif ig in (ADSIGRP_SUMUP_READ, ADSIGRP_SUMUP_WRITE, ADSIGRP_SUMUP_READWRITE):
            if nested:
                raise AdsError(ADSERR_DEVICE_SRVNOTSUPP, "nested sum command")
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
            raise AdsError(ADSERR_DEVICE_SRVNOTSUPP, f"ReadWrite on index group 0x{ig:X}")
        if len(out) > rlen:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"answer has {len(out)} bytes, buffer {rlen}")
        return out

    # --- sum commands ---------------------------------------------------------------------------
    def _sub(self, conn: Connection, fn, *args) -> tuple[int, Any]:
        """Run one sub-request of a sum command: (error code, result)."""
        try:
            return 0, fn(*args)
        except AdsError as e:
            return e.code, None
        except Exception:
            self.log.exception("%s: device failed in a sum sub-request (answered 0x700)", conn.peer)
            return ADSERR_DEVICE_ERROR, None

    @staticmethod
    def _check_count(n: int, item: int, data: bytes) -> None:
        if n * item > len(data):
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"sum command: {n} sub-requests need "
                                                        f"{n * item} bytes, got {len(data)}")

    def _sum_read(self, conn, ams_port, dev, n, rlen, data) -> bytes:
        """IG 0xF080: ``n`` × (ig, io, length) -> ``n`` error codes, then each sub-request's data
        at its full requested length (zero-filled where it failed or returned less)."""
        self._check_count(n, SUM_REQ.size, data)
        reqs = [SUM_REQ.unpack_from(data, i * SUM_REQ.size) for i in range(n)]
        total = 4 * n + sum(r[2] for r in reqs)
        if total > rlen:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"sum read needs {total} bytes, buffer {rlen}")
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
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "sum write: data shorter than announced")
        if 4 * n > rlen:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"sum write needs {4 * n} bytes, buffer {rlen}")
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
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "sum read-write: data shorter than announced")
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
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"sum read-write needs {total} bytes, buffer {rlen}")
        return b"".join(heads) + b"".join(chunks)

    # --- symbols -------------------------------------------------------------------------------
    @staticmethod
    def _symbols(dev: AdsDevice) -> Mapping[str, SymbolInfo]:
        return dev.symbols() or {}

    def _find(self, dev: AdsDevice, raw: bytes) -> SymbolInfo:
        """The symbol named by ``raw`` (NUL-terminated or not; case-insensitive)."""
        name = _name(raw)
        sym = lookup(self._symbols(dev), name)
        if sym is None:
            raise AdsError(ADSERR_DEVICE_SYMBOLNOTFOUND, f"symbol {name!r} not found")
        return sym

    def _types(self, dev: AdsDevice) -> dict[str, DataType]:
        """Every data type the device's symbols use (its structures, if it has ``data_types()``, and the
        base types)."""
        structs = getattr(dev, "data_types", None)
        return types_of(self._symbols(dev), structs() if structs is not None else {})

    @staticmethod
    def _fit(data: bytes, length: int) -> bytes:
        if len(data) > length:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"{len(data)} bytes, buffer {length}")
        return data

    def _sym_read(self, dev: AdsDevice, sym: SymbolInfo, length: int) -> bytes:
        """Value of a symbol. Strings: any length (the value is cut to it, a larger buffer gets the
        whole string); other types: the length is a capacity, at least the symbol's size, and the answer
        has the symbol's size (as a TwinCAT 3 target answers ads-client's "any size" reads)."""
        if sym.ads_type in STRING_TYPES:
            data = bytes(dev.read(sym.index_group, sym.index_offset, sym.size))[:sym.size]
            return data[:length]
        if length < sym.size:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"{sym.name} has {sym.size} bytes, {length} requested")
        data = bytes(dev.read(sym.index_group, sym.index_offset, sym.size))
        if len(data) > sym.size:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"{sym.name}: device returned {len(data)} bytes")
        return data

    def _sym_write(self, dev: AdsDevice, sym: SymbolInfo, data: bytes) -> None:
        """Write a symbol. Strings may be shorter than the symbol (zero-padded), other types must
        match its size exactly. Read-only symbols answer 0x704."""
        if sym.read_only:
            raise AdsError(ADSERR_DEVICE_INVALIDACCESS, f"{sym.name} is read-only")
        if sym.ads_type in STRING_TYPES:
            if len(data) > sym.size:
                raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"{sym.name} has {sym.size} bytes, got {len(data)}")
            data = data.ljust(sym.size, b"\0")
        elif len(data) != sym.size:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"{sym.name} has {sym.size} bytes, got {len(data)}")
        dev.write(sym.index_group, sym.index_offset, data)
