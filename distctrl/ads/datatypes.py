"""ADS data types: what a TwinCAT 3 target publishes so that clients decode symbols by type name.

A client that reads a symbol by name (ads-client's ``readValue``) asks for the symbol's entry
(0xF009), then for its type by name (0xF011, "data type info by name ex"), recursively for each
member of a structure, and decodes the raw bytes with the result. The data-type upload (0xF00E,
sized by the upload info 0xF00F) holds every type at once.

Wire format of one data-type entry (AdsDataTypeEntry, little-endian)::

    entryLength u32 (whole entry, this field included) | version u32 | hashValue u32
    | typeHashValue u32 | size u32 | offset u32 | dataType u32 (ADST_*) | flags u32
    | nameLength u16 | typeLength u16 | commentLength u16 | arrayDim u16 | subItems u16
    | name\\0 | type\\0 | comment\\0 | arrayDim x (lBound i32, elements u32) | subItems x entry

A type has the flag DATATYPE; the entries of its members (sub items) have the flag DATAITEM and
carry the member's name, its type name in ``type`` and its byte offset in the structure. A base
type (``UDINT``) has an empty ``type``. This module is pure (no I/O).
"""
from __future__ import annotations

import re
import struct
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from .protocol import ADST_BIGTYPE, ADST_STRING, IEC_TYPES, SYMBOL_ENCODING, SymbolInfo, lookup

ADSDATATYPEFLAG_DATATYPE = 0x0001
ADSDATATYPEFLAG_DATAITEM = 0x0002

DATA_TYPE_HEAD = struct.Struct("<IIIIIIIIHHHHH")   # 42 bytes, then name\0 type\0 comment\0 ...
DATA_TYPE_VERSION = 1

#: ``STRING(n)``: n characters and the terminating NUL; plain ``STRING`` is ``STRING(80)``
_STRING = re.compile(r"^STRING(?:\((\d{1,5})\))?$", re.IGNORECASE)


@dataclass(frozen=True)
class DataItem:
    """One member of a structure: its name, type name, byte offset and size in the structure."""

    name: str
    type_name: str
    offset: int
    size: int
    ads_type: int
    comment: str = ""


@dataclass(frozen=True)
class DataType:
    """A data type by name: size in bytes, ADST_* id, members (empty for a base type)."""

    name: str
    size: int
    ads_type: int
    comment: str = ""
    items: tuple[DataItem, ...] = ()


def base_type(name: str) -> DataType | None:
    """The IEC base type ``name`` (``UDINT``, ``lreal``, ``STRING(30)``), or None."""
    key = name.strip().upper()
    if key in IEC_TYPES:
        ads_type, size = IEC_TYPES[key]
        return DataType(key, size, ads_type)
    m = _STRING.match(key)
    if m:
        n = int(m.group(1) or 80)
        return DataType(f"STRING({n})", n + 1, ADST_STRING)
    return None


def types_of(symbols: Mapping[str, SymbolInfo], structs: Mapping[str, DataType]) -> dict[str, DataType]:
    """Every data type the ``symbols`` use, keyed by name: the ``structs`` they name, the base types
    of the symbols and of the structures' members. Order: structures first, then base types."""
    out: dict[str, DataType] = dict(structs)
    names: list[str] = [s.type_name for s in symbols.values()]
    names += [i.type_name for t in structs.values() for i in t.items]
    for name in names:
        if name in out:
            continue
        t = base_type(name)
        if t is not None:
            out[t.name] = t
    return out


def find_type(types: Mapping[str, DataType], name: str) -> DataType | None:
    """``name`` in ``types`` (case-insensitive, as TwinCAT), else a base type of that name, else None."""
    name = name.strip()
    t = lookup(types, name)
    return t if t is not None else base_type(name)


def _enc(text: str) -> bytes:
    return text.encode(SYMBOL_ENCODING, errors="replace")[:255]


def _entry(name: str, type_name: str, comment: str, size: int, offset: int, ads_type: int, flags: int,
           subitems: Iterable[bytes] = ()) -> bytes:
    subs = list(subitems)
    n, t, c = _enc(name), _enc(type_name), _enc(comment)
    tail = n + b"\0" + t + b"\0" + c + b"\0" + b"".join(subs)
    head = DATA_TYPE_HEAD.pack(DATA_TYPE_HEAD.size + len(tail), DATA_TYPE_VERSION, 0, 0, size, offset,
                               ads_type, flags, len(n), len(t), len(c), 0, len(subs))
    return head + tail


def encode_data_type(t: DataType) -> bytes:
    """The data-type entry of ``t`` with its members (see the module docstring)."""
    items = (_entry(i.name, i.type_name, i.comment, i.size, i.offset, i.ads_type, ADSDATATYPEFLAG_DATAITEM)
             for i in t.items)
    return _entry(t.name, "", t.comment, t.size, 0, t.ads_type, ADSDATATYPEFLAG_DATATYPE, items)


def decode_data_type(data: bytes) -> tuple[DataType, int]:
    """Inverse of :func:`encode_data_type` for tests and raw clients: (type, entry length). A member's
    entry is returned as a :class:`DataItem` inside ``items``."""
    (length, _v, _h, _th, size, _off, ads_type, _flags, nlen, tlen, clen, dims,
     nsub) = DATA_TYPE_HEAD.unpack_from(data)
    p = DATA_TYPE_HEAD.size
    name = bytes(data[p:p + nlen]).decode(SYMBOL_ENCODING)
    p += nlen + 1 + tlen + 1
    comment = bytes(data[p:p + clen]).decode(SYMBOL_ENCODING)
    p += clen + 1 + 8 * dims
    items = []
    for _ in range(nsub):
        (ilen, _v, _h, _th, isize, ioff, iads, _f, inl, itl, icl, _d, _n) = DATA_TYPE_HEAD.unpack_from(data, p)
        q = p + DATA_TYPE_HEAD.size
        iname = bytes(data[q:q + inl]).decode(SYMBOL_ENCODING)
        q += inl + 1
        itype = bytes(data[q:q + itl]).decode(SYMBOL_ENCODING)
        q += itl + 1
        icom = bytes(data[q:q + icl]).decode(SYMBOL_ENCODING)
        items.append(DataItem(iname, itype, ioff, isize, iads, icom))
        p += ilen
    return DataType(name, size, ads_type, comment, tuple(items)), length


def struct_type(name: str, members: Iterable[SymbolInfo], prefix: str, comment: str = "") -> DataType:
    """A structure whose members are the symbols ``members`` (named ``prefix + member``), packed in
    that order without padding (as the served structures' raw values are)."""
    items, offset = [], 0
    for m in members:
        items.append(DataItem(m.name[len(prefix):], m.type_name, offset, m.size, m.ads_type, m.comment))
        offset += m.size
    return DataType(name, offset, ADST_BIGTYPE, comment, tuple(items))
