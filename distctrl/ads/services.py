"""The ADS services of the server: one command executed against a device under the server's lock
(Read, Write, ReadWrite, ReadState, ReadDeviceInfo, WriteControl, notifications), the symbol
services (handles, value by name/handle, symbol info, uploads) and the sum commands, on top of a
device's raw index-group/index-offset access. Exceptions from devices become ADS error 0x700 and
are logged."""
from __future__ import annotations

import struct
from collections.abc import Mapping
from dataclasses import dataclass
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
        entry = _COMMANDS.get(hdr[4])
        return entry[1](code) if entry is not None else _result_error(code)

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
        entry = _COMMANDS.get(cmd)
        if entry is None:
            raise AdsError(ADSERR_DEVICE_SRVNOTSUPP, f"unknown command id {cmd}")
        return entry[0](self, conn, hdr, dev, memoryview(body)[AMS_HEADER_SIZE:])

    # --- the commands (the table _COMMANDS below; Read's hot path is inline in _command) -------------
    def _cmd_read(self, conn: Connection, hdr: tuple, dev: AdsDevice, p: memoryview) -> bytes:
        if len(p) < READ_REQ.size:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "short Read request")
        ig, io, length = READ_REQ.unpack_from(p)
        if length > self.max_frame:
            length = self._capacity(ig, length)
        data = self._read(conn, hdr[1], dev, ig, io, length)
        return _pack_read_res(0, len(data)) + data

    def _cmd_write(self, conn: Connection, hdr: tuple, dev: AdsDevice, p: memoryview) -> bytes:
        if len(p) < WRITE_REQ.size:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "short Write request")
        ig, io, length = WRITE_REQ.unpack_from(p)
        if length > len(p) - WRITE_REQ.size:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "Write data shorter than its length field")
        self._write(conn, hdr[1], dev, ig, io, bytes(p[WRITE_REQ.size:WRITE_REQ.size + length]))
        return RESULT_RES.pack(0)

    def _cmd_read_write(self, conn: Connection, hdr: tuple, dev: AdsDevice, p: memoryview) -> bytes:
        if len(p) < READ_WRITE_REQ.size:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "short ReadWrite request")
        ig, io, rlen, wlen = READ_WRITE_REQ.unpack_from(p)
        if wlen > len(p) - READ_WRITE_REQ.size:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "ReadWrite data shorter than its length field")
        if rlen > self.max_frame:
            rlen = self._capacity(ig, rlen)
        wdata = bytes(p[READ_WRITE_REQ.size:READ_WRITE_REQ.size + wlen])
        data = self._read_write(conn, hdr[1], dev, ig, io, rlen, wdata)
        return READ_RES.pack(0, len(data)) + data

    def _cmd_read_state(self, conn: Connection, hdr: tuple, dev: AdsDevice, p: memoryview) -> bytes:
        ads_state, dev_state = dev.state()
        return READ_STATE_RES.pack(0, int(ads_state) & 0xFFFF, int(dev_state) & 0xFFFF)

    def _cmd_read_device_info(self, conn: Connection, hdr: tuple, dev: AdsDevice, p: memoryview) -> bytes:
        major, minor, build = (tuple(dev.version) + (0, 0, 0))[:3]
        name = str(dev.name).encode(SYMBOL_ENCODING, errors="replace")[:15]
        return DEVICE_INFO_RES.pack(0, int(major) & 0xFF, int(minor) & 0xFF, int(build) & 0xFFFF, name)

    def _cmd_write_control(self, conn: Connection, hdr: tuple, dev: AdsDevice, p: memoryview) -> bytes:
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

    def _cmd_add_notification(self, conn: Connection, hdr: tuple, dev: AdsDevice, p: memoryview) -> bytes:
        return ADD_NOTIFICATION_RES.pack(0, self._add_notification(conn, AmsHeader._make(hdr), dev, p))

    def _cmd_del_notification(self, conn: Connection, hdr: tuple, dev: AdsDevice, p: memoryview) -> bytes:
        if len(p) < DEL_NOTIFICATION_REQ.size:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "short DeleteDeviceNotification request")
        handle = DEL_NOTIFICATION_REQ.unpack_from(p)[0]
        n = conn.notifications.get(handle)
        if n is None or n.ams_port != hdr[1]:
            raise AdsError(ADSERR_DEVICE_NOTIFYHNDINVALID, f"unknown notification 0x{handle:X}")
        del conn.notifications[handle]
        return RESULT_RES.pack(0)

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
            fn = _SYMBOL_SERVICES[ig].read
            if fn is None:
                raise AdsError(ADSERR_DEVICE_SRVNOTSUPP, f"Read of index group 0x{ig:X}")
            return fn(self, conn, ams_port, dev, io, length)
        data = bytes(dev.read(ig, io, length))
        if len(data) > length:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"0x{ig:X}:0x{io:X} has {len(data)} bytes, "
                                                        f"{length} requested")
        return data

    def _write(self, conn: Connection, ams_port: int, dev: AdsDevice, ig: int, io: int, data: bytes) -> None:
        if ig in _SYMBOL_GROUPS:
            fn = _SYMBOL_SERVICES[ig].write
            if fn is None:
                raise AdsError(ADSERR_DEVICE_SRVNOTSUPP, f"Write to index group 0x{ig:X}")
            fn(self, conn, ams_port, dev, io, data)
        else:
            dev.write(ig, io, data)

    def _read_write(self, conn: Connection, ams_port: int, dev: AdsDevice, ig: int, io: int, rlen: int,
                    data: bytes, nested: bool = False) -> bytes:
        service = _SYMBOL_SERVICES.get(ig)
        if service is not None and service.read_write is not None:
            if nested and service.sum:
                raise AdsError(ADSERR_DEVICE_SRVNOTSUPP, "nested sum command")
            out = service.read_write(self, conn, ams_port, dev, io, rlen, data)
        elif service is None and hasattr(dev, "read_write"):
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

    # --- the symbol services (the table _SYMBOL_SERVICES below) -------------------------------------
    def _sym_valbyhnd_read(self, conn, ams_port, dev, io, length) -> bytes:
        return self._sym_read(dev, conn.symbol(ams_port, io), length)

    def _sym_valbyhnd_write(self, conn, ams_port, dev, io, data) -> None:
        self._sym_write(dev, conn.symbol(ams_port, io), data)

    def _sym_release_handle(self, conn, ams_port, dev, io, data) -> None:
        if len(data) < 4:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "release handle needs a 4-byte handle")
        conn.release(ams_port, _U32.unpack_from(data)[0])

    def _sym_upload_info2(self, conn, ams_port, dev, io, length) -> bytes:
        syms = self._symbols(dev)
        total = sum(len(encode_symbol_entry(s)) for s in syms.values())
        types = self._types(dev)
        types_total = sum(len(encode_data_type(t)) for t in types.values())
        return self._fit(_UPLOADINFO2.pack(len(syms), total, len(types), types_total, 0, 0), length)

    def _sym_upload_info(self, conn, ams_port, dev, io, length) -> bytes:
        syms = self._symbols(dev)
        total = sum(len(encode_symbol_entry(s)) for s in syms.values())
        return self._fit(_UPLOADINFO.pack(len(syms), total), length)

    def _sym_upload(self, conn, ams_port, dev, io, length) -> bytes:
        return self._fit(b"".join(encode_symbol_entry(s) for s in self._symbols(dev).values()), length)

    def _sym_version(self, conn, ams_port, dev, io, length) -> bytes:
        return self._fit(b"\x01", length)

    def _sym_dt_upload(self, conn, ams_port, dev, io, length) -> bytes:
        return self._fit(b"".join(encode_data_type(t) for t in self._types(dev).values()), length)

    def _sym_handle_by_name(self, conn, ams_port, dev, io, rlen, data) -> bytes:
        if rlen < 4:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, "handle needs a 4-byte read buffer")
        sym = self._find(dev, data)
        return _handle_answer(conn.new_handle(ams_port, sym), sym, rlen)

    def _sym_value_by_name(self, conn, ams_port, dev, io, rlen, data) -> bytes:
        return self._sym_read(dev, self._find(dev, data), rlen)

    def _sym_info_by_name_ex(self, conn, ams_port, dev, io, rlen, data) -> bytes:
        return encode_symbol_entry(self._find(dev, data))

    def _sym_dt_info_by_name_ex(self, conn, ams_port, dev, io, rlen, data) -> bytes:
        name = _name(data)
        t = find_type(self._types(dev), name)
        if t is None:
            raise AdsError(ADSERR_DEVICE_SYMBOLNOTFOUND, f"data type {name!r} not found")
        return encode_data_type(t)

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


# ----------------------------------------------------------------------------------------------------
# the dispatch tables
# ----------------------------------------------------------------------------------------------------
def _reply_read(code: int) -> bytes:
    return READ_RES.pack(code, 0)


def _result_error(code: int) -> bytes:
    return RESULT_RES.pack(code)


#: AMS command id -> (handler, the error reply: code -> payload of that command's response structure).
#: Read is dispatched inline first in ``AdsServices._command`` (the hot path); its entry serves the error
#: reply and documents it.
_COMMANDS: dict[int, tuple[Any, Any]] = {
    CMD_READ: (AdsServices._cmd_read, _reply_read),
    CMD_WRITE: (AdsServices._cmd_write, _result_error),
    CMD_READ_WRITE: (AdsServices._cmd_read_write, _reply_read),
    CMD_READ_STATE: (AdsServices._cmd_read_state, lambda code: READ_STATE_RES.pack(code, 0, 0)),
    CMD_READ_DEVICE_INFO: (AdsServices._cmd_read_device_info, lambda code: DEVICE_INFO_RES.pack(code, 0, 0, 0, b"")),
    CMD_WRITE_CONTROL: (AdsServices._cmd_write_control, _result_error),
    CMD_ADD_DEVICE_NOTIFICATION: (AdsServices._cmd_add_notification, lambda code: ADD_NOTIFICATION_RES.pack(code, 0)),
    CMD_DEL_DEVICE_NOTIFICATION: (AdsServices._cmd_del_notification, _result_error),
}


@dataclass(frozen=True)
class SymbolService:
    """What the server does itself for one index group: ``read(self, conn, ams_port, dev, io, length)``,
    ``write(self, conn, ams_port, dev, io, data)``, ``read_write(self, conn, ams_port, dev, io, rlen,
    data)``; None: that access is answered 0x701 (a ReadWrite without its own handler falls back to the
    read with no data, the write with rlen 0). ``sum``: a sum command (not allowed inside another)."""

    read: Any = None
    write: Any = None
    read_write: Any = None
    sum: bool = False


#: index group -> the server's own service for it (never passed to a device). ADSIGRP_SYM_INFOBYNAME
#: (0xF007, the TwinCAT 2 symbol info by name) is not served: clients use ADSIGRP_SYM_INFOBYNAMEEX;
#: a request for it goes to the device like any index group the server does not serve.
_SYMBOL_SERVICES: dict[int, SymbolService] = {
    ADSIGRP_SYM_HNDBYNAME: SymbolService(read_write=AdsServices._sym_handle_by_name),
    ADSIGRP_SYM_VALBYNAME: SymbolService(read_write=AdsServices._sym_value_by_name),
    ADSIGRP_SYM_VALBYHND: SymbolService(read=AdsServices._sym_valbyhnd_read, write=AdsServices._sym_valbyhnd_write),
    ADSIGRP_SYM_RELEASEHND: SymbolService(write=AdsServices._sym_release_handle),
    ADSIGRP_SYM_VERSION: SymbolService(read=AdsServices._sym_version),
    ADSIGRP_SYM_INFOBYNAMEEX: SymbolService(read_write=AdsServices._sym_info_by_name_ex),
    ADSIGRP_SYM_UPLOAD: SymbolService(read=AdsServices._sym_upload),
    ADSIGRP_SYM_UPLOADINFO: SymbolService(read=AdsServices._sym_upload_info),
    ADSIGRP_SYM_DT_UPLOAD: SymbolService(read=AdsServices._sym_dt_upload),
    ADSIGRP_SYM_UPLOADINFO2: SymbolService(read=AdsServices._sym_upload_info2),
    ADSIGRP_SYM_DT_INFOBYNAMEEX: SymbolService(read_write=AdsServices._sym_dt_info_by_name_ex),
    ADSIGRP_SUMUP_READ: SymbolService(read_write=AdsServices._sum_read, sum=True),
    ADSIGRP_SUMUP_WRITE: SymbolService(read_write=AdsServices._sum_write, sum=True),
    ADSIGRP_SUMUP_READWRITE: SymbolService(read_write=AdsServices._sum_read_write, sum=True),
}
#: index groups the server answers itself: exactly those with a service
_SYMBOL_GROUPS = frozenset(_SYMBOL_SERVICES)
