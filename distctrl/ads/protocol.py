"""AMS/TCP framing, the AMS header, ADS command payloads and the device-side types.

Wire format (all integers little-endian)::

    AMS/TCP header   6 bytes   reserved (uint16, 0 for ADS) | length (uint32) of what follows
    AMS header      32 bytes   target NetId (6) | target port (2) | source NetId (6) | source port (2)
                               | command id (2) | state flags (2) | data length (4)
                               | error code (4) | invoke id (4)
    ADS data         n bytes   command specific (see the ``*_REQ`` / ``*_RES`` structs below)

A response swaps target and source, sets the response bit (0x0001) in the state flags (keeping
the ADS-command bit 0x0004) and echoes the invoke id. Router errors (unknown port / NetId) go
into the AMS header's error field with no data; device errors go into the ADS result field.

This module is pure (no I/O): the server in :mod:`distctrl.ads.server` and the raw-socket tests
both use it.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import NamedTuple, Protocol, runtime_checkable

# --- AMS/TCP --------------------------------------------------------------------------------
ADS_TCP_PORT = 48898
AMS_TCP_HEADER = struct.Struct("<HI")
AMS_TCP_HEADER_SIZE = AMS_TCP_HEADER.size  # 6
#: reserved field values of the AMS/TCP header (0 = an AMS packet follows)
AMS_TCP_PORT_AMS_CMD = 0x0000
AMS_TCP_PORT_CONNECT = 0x1000      # a router client asks for a (dynamic) AMS port
AMS_TCP_PORT_CLOSE = 0x0001

AMS_HEADER = struct.Struct("<6sH6sHHHIII")
AMS_HEADER_SIZE = AMS_HEADER.size  # 32

# --- command ids ------------------------------------------------------------------------------
CMD_INVALID = 0
CMD_READ_DEVICE_INFO = 1
CMD_READ = 2
CMD_WRITE = 3
CMD_READ_STATE = 4
CMD_WRITE_CONTROL = 5
CMD_ADD_DEVICE_NOTIFICATION = 6
CMD_DEL_DEVICE_NOTIFICATION = 7
CMD_DEVICE_NOTIFICATION = 8
CMD_READ_WRITE = 9

COMMAND_NAMES = {
    CMD_READ_DEVICE_INFO: "ReadDeviceInfo",
    CMD_READ: "Read",
    CMD_WRITE: "Write",
    CMD_READ_STATE: "ReadState",
    CMD_WRITE_CONTROL: "WriteControl",
    CMD_ADD_DEVICE_NOTIFICATION: "AddDeviceNotification",
    CMD_DEL_DEVICE_NOTIFICATION: "DeleteDeviceNotification",
    CMD_DEVICE_NOTIFICATION: "DeviceNotification",
    CMD_READ_WRITE: "ReadWrite",
}

# --- state flags ------------------------------------------------------------------------------
SF_RESPONSE = 0x0001
SF_NO_RETURN = 0x0002
SF_ADS_COMMAND = 0x0004
SF_SYSTEM_COMMAND = 0x0008
SF_HIGH_PRIORITY = 0x0010
SF_TIMESTAMP_ADDED = 0x0020
SF_UDP = 0x0040

# --- request payloads (after the AMS header) ---------------------------------------------------
READ_REQ = struct.Struct("<III")            # index group, index offset, length
WRITE_REQ = struct.Struct("<III")           # index group, index offset, length, + data
READ_WRITE_REQ = struct.Struct("<IIII")     # index group, index offset, read length, write length, + data
WRITE_CONTROL_REQ = struct.Struct("<HHI")   # ads state, device state, length, + data
ADD_NOTIFICATION_REQ = struct.Struct("<IIIIII16s")  # ig, io, length, trans mode, max delay, cycle time
DEL_NOTIFICATION_REQ = struct.Struct("<I")  # notification handle

# --- response payloads ------------------------------------------------------------------------
RESULT_RES = struct.Struct("<I")            # Write, WriteControl, DelNotification, unknown command
READ_RES = struct.Struct("<II")             # result, length, + data (Read and ReadWrite)
READ_STATE_RES = struct.Struct("<IHH")      # result, ads state, device state
DEVICE_INFO_RES = struct.Struct("<IBBH16s")  # result, major, minor, build, name
ADD_NOTIFICATION_RES = struct.Struct("<II")  # result, notification handle

# --- symbol / system index groups ---------------------------------------------------------------
ADSIGRP_SYM_HNDBYNAME = 0xF003
ADSIGRP_SYM_VALBYNAME = 0xF004
ADSIGRP_SYM_VALBYHND = 0xF005
ADSIGRP_SYM_RELEASEHND = 0xF006
ADSIGRP_SYM_INFOBYNAME = 0xF007
ADSIGRP_SYM_VERSION = 0xF008
ADSIGRP_SYM_INFOBYNAMEEX = 0xF009
ADSIGRP_SYM_UPLOAD = 0xF00B
ADSIGRP_SYM_UPLOADINFO = 0xF00C
ADSIGRP_SYM_DT_UPLOAD = 0xF00E
ADSIGRP_SYM_DT_INFOBYNAMEEX = 0xF011   # data type by name
ADSIGRP_SYM_UPLOADINFO2 = 0xF00F
ADSIGRP_SUMUP_READ = 0xF080
ADSIGRP_SUMUP_WRITE = 0xF081
ADSIGRP_SUMUP_READWRITE = 0xF082

SUM_REQ = struct.Struct("<III")             # sum read / sum write sub-request: ig, io, length
SUM_RW_REQ = struct.Struct("<IIII")         # sum read-write sub-request: ig, io, read length, write length
SUM_RW_RES = struct.Struct("<II")           # sum read-write sub-result: error, returned length

# --- ADS data type ids (AdsDataTypeId) -----------------------------------------------------------
ADST_VOID = 0
ADST_INT16 = 2
ADST_INT32 = 3
ADST_REAL32 = 4
ADST_REAL64 = 5
ADST_INT8 = 16
ADST_UINT8 = 17
ADST_UINT16 = 18
ADST_UINT32 = 19
ADST_INT64 = 20
ADST_UINT64 = 21
ADST_STRING = 30
ADST_WSTRING = 31
ADST_REAL80 = 32
ADST_BIT = 33          # BOOL (size 1)
ADST_BIGTYPE = 65      # structures, arrays of bytes, ...

#: variable-length types: a read may ask for more (clamped to the symbol size), a write may send
#: fewer bytes (zero-padded to the symbol size)
STRING_TYPES = frozenset({ADST_STRING, ADST_WSTRING})

#: IEC type name -> (ADS data type id, size in bytes), for building symbol tables
IEC_TYPES: dict[str, tuple[int, int]] = {
    "BOOL": (ADST_BIT, 1),
    "BYTE": (ADST_UINT8, 1),
    "USINT": (ADST_UINT8, 1),
    "SINT": (ADST_INT8, 1),
    "WORD": (ADST_UINT16, 2),
    "UINT": (ADST_UINT16, 2),
    "INT": (ADST_INT16, 2),
    "DWORD": (ADST_UINT32, 4),
    "UDINT": (ADST_UINT32, 4),
    "DINT": (ADST_INT32, 4),
    "LWORD": (ADST_UINT64, 8),
    "ULINT": (ADST_UINT64, 8),
    "LINT": (ADST_INT64, 8),
    "REAL": (ADST_REAL32, 4),
    "LREAL": (ADST_REAL64, 8),
}

# --- symbol flags ------------------------------------------------------------------------------
ADSSYMBOLFLAG_PERSISTENT = 0x0001
ADSSYMBOLFLAG_BITVALUE = 0x0002
ADSSYMBOLFLAG_READONLY = 0x0020

# --- ADS states ----------------------------------------------------------------------------------
ADSSTATE_INVALID = 0
ADSSTATE_IDLE = 1
ADSSTATE_RESET = 2
ADSSTATE_INIT = 3
ADSSTATE_START = 4
ADSSTATE_RUN = 5
ADSSTATE_STOP = 6
ADSSTATE_ERROR = 11

#: TwinCAT encodes strings in the symbol table as Windows-1252
SYMBOL_ENCODING = "cp1252"


# ================================================================================================
# NetId
# ================================================================================================
def parse_net_id(text: str) -> bytes:
    """``"127.0.0.1.1.1"`` -> 6 bytes. Raises ``ValueError`` for anything else."""
    parts = str(text).strip().split(".")
    if len(parts) != 6:
        raise ValueError(f"AMS NetId must have 6 dot-separated numbers: {text!r}")
    try:
        values = [int(p, 10) for p in parts]
    except ValueError:
        raise ValueError(f"AMS NetId must have 6 dot-separated numbers: {text!r}") from None
    if any(not 0 <= v <= 255 for v in values):
        raise ValueError(f"AMS NetId numbers must be 0..255: {text!r}")
    return bytes(values)


def format_net_id(raw: bytes) -> str:
    """6 bytes -> ``"a.b.c.d.e.f"``."""
    return ".".join(str(b) for b in raw)


# ================================================================================================
# AMS header
# ================================================================================================
class AmsHeader(NamedTuple):
    """The 32-byte AMS header (NetIds as 6 raw bytes)."""

    target_net_id: bytes
    target_port: int
    source_net_id: bytes
    source_port: int
    command: int
    state_flags: int
    length: int
    error_code: int
    invoke_id: int

    def pack(self) -> bytes:
        return AMS_HEADER.pack(*self)

    @classmethod
    def unpack(cls, data: bytes | bytearray | memoryview) -> AmsHeader:
        return cls._make(AMS_HEADER.unpack_from(data, 0))

    @property
    def is_response(self) -> bool:
        return bool(self.state_flags & SF_RESPONSE)

    def response(self, length: int, error_code: int = 0) -> AmsHeader:
        """The header of the answer to this request: addresses swapped, response bit set."""
        return AmsHeader(
            self.source_net_id, self.source_port, self.target_net_id, self.target_port,
            self.command, (self.state_flags | SF_RESPONSE | SF_ADS_COMMAND) & 0xFFFF,
            length, error_code & 0xFFFFFFFF, self.invoke_id,
        )


def frame(header: AmsHeader, data: bytes = b"") -> bytes:
    """A complete AMS/TCP frame: AMS/TCP header + AMS header + data. ``header.length`` is replaced
    by ``len(data)``."""
    if header.length != len(data):
        header = header._replace(length=len(data))
    return AMS_TCP_HEADER.pack(0, AMS_HEADER_SIZE + len(data)) + header.pack() + data


def request(command: int, data: bytes, *, target: str | bytes = "127.0.0.1.1.1", target_port: int = 851,
            source: str | bytes = "127.0.0.1.1.2", source_port: int = 32905, invoke_id: int = 1,
            state_flags: int = SF_ADS_COMMAND) -> bytes:
    """A complete request frame (for raw clients and tests)."""
    tnet = target if isinstance(target, bytes) else parse_net_id(target)
    snet = source if isinstance(source, bytes) else parse_net_id(source)
    hdr = AmsHeader(tnet, target_port, snet, source_port, command, state_flags, len(data), 0, invoke_id)
    return frame(hdr, data)


def read_request(index_group: int, index_offset: int, length: int, **kw) -> bytes:
    return request(CMD_READ, READ_REQ.pack(index_group, index_offset, length), **kw)


def write_request(index_group: int, index_offset: int, data: bytes, **kw) -> bytes:
    return request(CMD_WRITE, WRITE_REQ.pack(index_group, index_offset, len(data)) + data, **kw)


def read_write_request(index_group: int, index_offset: int, read_length: int, data: bytes, **kw) -> bytes:
    return request(CMD_READ_WRITE,
                   READ_WRITE_REQ.pack(index_group, index_offset, read_length, len(data)) + data, **kw)


class Response(NamedTuple):
    """A parsed response frame: AMS header, ADS result (None if the frame carries no data) and the
    data after the fixed response fields (for Read/ReadWrite: the returned bytes)."""

    header: AmsHeader
    result: int | None
    data: bytes


def parse_response(body: bytes) -> Response:
    """Parse the part of a frame after the AMS/TCP header (the AMS header and its data)."""
    hdr = AmsHeader.unpack(body)
    payload = bytes(body[AMS_HEADER_SIZE:AMS_HEADER_SIZE + hdr.length])
    if len(payload) < 4:
        return Response(hdr, None, payload)
    result = RESULT_RES.unpack_from(payload)[0]
    if hdr.command in (CMD_READ, CMD_READ_WRITE) and len(payload) >= READ_RES.size:
        n = READ_RES.unpack_from(payload)[1]
        return Response(hdr, result, payload[READ_RES.size:READ_RES.size + n])
    return Response(hdr, result, payload[4:])


# ================================================================================================
# Device side
# ================================================================================================
@dataclass(frozen=True)
class SymbolInfo:
    """One entry of a device's symbol table.

    ``index_group``/``index_offset`` must be readable/writable through the device's raw
    ``read``/``write`` (clients such as pyads' sum commands access symbols by IG/IO).
    ``ads_type`` is an ``ADST_*`` id, ``type_name`` the IEC type text (``"LREAL"``, ``"BOOL"``,
    ``"STRING(80)"``); pyads derives the value type from ``type_name``. ``read_only`` (extension)
    makes the server refuse writes by handle/name with 0x704 and sets ADSSYMBOLFLAG_READONLY.
    """

    name: str
    index_group: int
    index_offset: int
    size: int
    ads_type: int
    type_name: str
    comment: str = ""
    read_only: bool = False

    @property
    def flags(self) -> int:
        return ADSSYMBOLFLAG_READONLY if self.read_only else 0


@runtime_checkable
class AdsDevice(Protocol):
    """One ADS device behind one AMS port (e.g. 551 CNC objects, 851 PLC).

    The server calls these (with the server's lock held) from its connections' threads, one at a time;
    they must be quick and must not take that lock themselves. Raise
    :class:`~distctrl.ads.errors.AdsError` to answer with an ADS error code.

    Optional extensions the server uses if present:
    ``read_write(index_group, index_offset, read_length, data) -> bytes`` for ReadWrite requests
    to non-symbol index groups, ``write_control(ads_state, device_state, data) -> None``,
    ``data_types() -> dict[str, DataType]`` (:mod:`distctrl.ads.datatypes`): the structures among the
    symbols, which the server publishes by name (0xF011) and in the data-type upload (0xF00E), and
    ``fast_reader(index_group, index_offset, length) -> Callable[[], bytes] | None``: after ``read``
    has answered a request, a function giving the same answer for it from then on (the server keeps
    it and calls it, under the lock, for that request's repetitions; None: ask ``read`` each time).
    """

    name: str
    version: tuple[int, int, int]

    def read(self, index_group: int, index_offset: int, length: int) -> bytes: ...

    def write(self, index_group: int, index_offset: int, data: bytes) -> None: ...

    def symbols(self) -> dict[str, SymbolInfo]: ...

    def state(self) -> tuple[int, int]: ...


def lookup(table, name: str):
    """``table[name]``, else the entry whose key equals ``name`` ignoring case (as TwinCAT matches
    symbol and type names), else None."""
    value = table.get(name)
    if value is None and name:
        low = name.lower()
        value = next((v for k, v in table.items() if k.lower() == low), None)
    return value


SYMBOL_ENTRY_HEAD = struct.Struct("<IIIIIIHHH")   # 30 bytes, then name\0 type\0 comment\0
SYMBOL_ENTRY_MAX = SYMBOL_ENTRY_HEAD.size + 3 * 256  # = sizeof(SAdsSymbolEntry) in pyads


def _enc(text: str, limit: int = 255) -> bytes:
    return text.encode(SYMBOL_ENCODING, errors="replace")[:limit]


def encode_symbol_entry(sym: SymbolInfo) -> bytes:
    """The ADS symbol entry (AdsSymbolEntry, as returned by ADSIGRP_SYM_INFOBYNAMEEX and in the
    symbol upload): entryLength, iGroup, iOffs, size, dataType, flags, nameLength, typeLength,
    commentLength, then ``name\\0 type\\0 comment\\0``. Strings are cut to 255 bytes, so an entry
    never exceeds :data:`SYMBOL_ENTRY_MAX` (798) bytes; entryLength is the exact entry size."""
    name, typ, com = _enc(sym.name), _enc(sym.type_name), _enc(sym.comment)
    strings = name + b"\0" + typ + b"\0" + com + b"\0"
    total = SYMBOL_ENTRY_HEAD.size + len(strings)
    head = SYMBOL_ENTRY_HEAD.pack(total, sym.index_group & 0xFFFFFFFF, sym.index_offset & 0xFFFFFFFF,
                                  sym.size & 0xFFFFFFFF, sym.ads_type & 0xFFFFFFFF, sym.flags,
                                  len(name), len(typ), len(com))
    return head + strings


def decode_symbol_entry(data: bytes) -> SymbolInfo:
    """Inverse of :func:`encode_symbol_entry` (for tests and raw clients)."""
    (_total, ig, io, size, typ, flags, nlen, tlen, clen) = SYMBOL_ENTRY_HEAD.unpack_from(data)
    p = SYMBOL_ENTRY_HEAD.size
    name = data[p:p + nlen].decode(SYMBOL_ENCODING)
    p += nlen + 1
    tname = data[p:p + tlen].decode(SYMBOL_ENCODING)
    p += tlen + 1
    comment = data[p:p + clen].decode(SYMBOL_ENCODING)
    return SymbolInfo(name, ig, io, size, typ, tname, comment, bool(flags & ADSSYMBOLFLAG_READONLY))
