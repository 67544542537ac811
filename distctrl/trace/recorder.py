"""Per-cycle trace recording: a fast recorder, a CSV format that round-trips float64, and a result type.

The simulator calls :attr:`TraceRecorder.append` once per GEO cycle with one tuple of floats (one per
column). Rows are buffered as Python tuples (the cheapest thing a cycle can do) and turned into a
float64 chunk every ``chunk_rows`` rows; each chunk is written to the CSV file (whole rows, then the
file object is flushed, so the file is a valid trace after every flush) and kept in memory unless
``keep=False``. See docs/trace.md.

The CSV numbers are written by :func:`format_rows`, a vectorised, byte-exact equivalent of
``'%.17g' % x`` (17 significant digits: every float64 round-trips; integer values are written as
integers, NaN as ``nan``), about three times faster than Python's own formatting.
"""
from __future__ import annotations

import contextlib
import difflib
import itertools
import json
import math
import os
import struct
import warnings
from fractions import Fraction
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from ..base.states import HLI_STATE_NAMES
from .plot import plot_trace  # matplotlib itself is imported only when a plot is drawn

__all__ = ["Trace", "TraceRecorder", "format_rows", "sidecar_path", "HLI_STATE_NAMES"]

SIDECAR_SUFFIX = ".meta.json"
_FORMAT_NAME = "distctrl-trace"
_FORMAT_VERSION = 1


def sidecar_path(csv_path: str | os.PathLike) -> Path:
    """``<csv_path>.meta.json``: the JSON file holding the units and meta of a trace CSV."""
    return Path(os.fspath(csv_path) + SIDECAR_SUFFIX)


# ------------------------------------------------------------------------------------------------------
# '%.17g' for whole float64 arrays, vectorised
# ------------------------------------------------------------------------------------------------------
# Each value x != 0 is x = D * 10**(d - 16) with D the correctly rounded 17-digit integer mantissa
# (10**16 <= D < 10**17). D comes from a double-double product |x| * 10**(16 - d) (Dekker's exact
# product against a double-double table of powers of ten), whose error (~1e-14 of a unit of D) is far
# below what a round trip tolerates: 17 significant digits are spaced at most 0.9 ulp apart, so even a
# tie decided the other way stays within 0.45 ulp. Values outside the table's safe range (|x| < 1e-250
# or >= 1e270: subnormals, extremes) and inf/nan take the exact Python path, one value at a time.
# The text is then laid out per value in a fixed byte frame and the wanted bytes picked with a mask
# chosen by (layout, number of significant digits): sign | "0.000" | 17 integer digits | "." |
# 17 fraction digits | "e+ddd" | separator.
_SPLIT = 134217729.0            # 2**27 + 1, Dekker's splitter
_KMIN, _KMAX = -260, 300         # powers of ten in the table: 10**k for k = 16 - d


def _pow10_tables() -> tuple[np.ndarray, ...]:
    ks = range(_KMIN, _KMAX + 1)
    hi = np.empty(len(ks))
    lo = np.empty(len(ks))
    for i, k in enumerate(ks):
        exact = Fraction(10) ** k
        hi[i] = float(exact)
        lo[i] = float(exact - Fraction(hi[i]))
    c = _SPLIT * hi
    hh = c - (c - hi)
    return hi, lo, hh, hi - hh


_P10_HI, _P10_LO, _P10_HH, _P10_HL = _pow10_tables()
_FAST_MIN, _FAST_MAX = 1e-250, 1e270
#: '0000'..'9999' as 4-byte words (memory order = text order on any endianness)
_DIGITS4 = np.frombuffer(b"".join(b"%04d" % i for i in range(10000)), dtype=np.uint32)

_W = 1 + 5 + 17 + 1 + 17 + 5 + 1        # bytes of the frame of one value
_I, _DOT, _F, _E, _SEP = 6, 23, 24, 41, 46
_SCI = 21                                # layout index of scientific notation; 0..20: positional d = -4..16


def _mask_table() -> np.ndarray:
    mt = np.zeros((22, 18, _W), dtype=bool)
    for case in range(22):
        for nsig in range(1, 18):
            m = mt[case, nsig]
            m[_SEP] = True
            if case < _SCI:
                d = case - 4
                if d < 0:                                   # 0.000ddd
                    m[1:1 + 2 + (-d - 1)] = True
                    m[_F:_F + nsig] = True
                else:                                       # ddd[.ddd]
                    m[_I:_I + d + 1] = True
                    if nsig > d + 1:
                        m[_DOT] = True
                        m[_F + d + 1:_F + nsig] = True
            else:                                           # d[.ddd]e+dd[d]
                m[_I] = True
                if nsig > 1:
                    m[_DOT] = True
                    m[_F + 1:_F + nsig] = True
                m[_E:_E + 5] = True                         # hundreds digit of the exponent: cleared if < 100
    return mt


_MASKS = _mask_table()
_FRAME_HEAD = np.frombuffer(b"-0.000", dtype=np.uint8)


def _mantissas(ax: np.ndarray, fast: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(D, d) with ax = D * 10**(d - 16), D the rounded 17-digit mantissa, where fast (else unused)."""
    a = np.where(fast, ax, 1.0)             # 1.0 stands in for the others: in range at once
    d = np.floor(np.log10(a)).astype(np.int64)
    D = np.empty(a.shape, dtype=np.int64)
    idx: np.ndarray | None = None
    for _ in range(4):                      # log10 may be one off near powers of ten: redo those few
        aa = a if idx is None else a[idx]
        ki = 16 - _KMIN - (d if idx is None else d[idx])
        p = aa * _P10_HI[ki]                # p + lo = aa * 10**k, Dekker's exact product + tail
        c = _SPLIT * aa
        ah = c - (c - aa)
        al = aa - ah
        hh, hl = _P10_HH[ki], _P10_HL[ki]
        lo = (((ah * hh - p) + ah * hl + al * hh) + al * hl) + aa * _P10_LO[ki]
        # with d right, 1e16 <= p + lo < 1e17, p (>= 2**53) is an integer and lo a tail of a few units;
        # the decade is told from (p, lo) before rounding (the 1e-6 tolerance covers the table's own
        # error where aa * 10**k is exactly a power of ten)
        high = (p > 1e17) | ((p == 1e17) & (lo >= -1e-6))
        low = (p < 1e16) | ((p == 1e16) & (lo < -1e-6))
        v = p.astype(np.int64) + np.rint(lo).astype(np.int64)
        if idx is None:
            D = v
        else:
            D[idx] = v
        bad = np.flatnonzero(high | low)
        if bad.size == 0:
            break
        bad_global = bad if idx is None else idx[bad]
        d[bad_global] += np.where(high[bad], 1, -1)
        idx = bad_global
    else:  # pragma: no cover
        raise AssertionError("decimal exponent did not settle")
    top = np.flatnonzero(D == 10 ** 17)     # rounded up into the next decade
    if top.size:
        D[top] = 10 ** 16
        d[top] += 1
    return D, d


def _format_block(a: np.ndarray) -> bytes:
    n, ncol = a.shape
    x = a.ravel()
    N = x.size
    ax = np.abs(x)
    fast = (ax >= _FAST_MIN) & (ax < _FAST_MAX)
    D, d = _mantissas(ax, fast)
    neg = np.signbit(x)
    zero = ax == 0.0
    D[zero] = 0
    d[zero] = 0
    slow = np.flatnonzero(~(fast | zero))
    words: list[tuple[int, bytes]] = []
    for i in slow.tolist():                 # subnormals, extremes, inf, nan: exact Python digits
        v = float(ax[i])
        if math.isfinite(v):
            mant, exp = ("%.16e" % v).split("e")
            D[i] = int(mant.replace(".", ""))
            d[i] = int(exp)
        else:
            D[i] = 0
            d[i] = 2
            words.append((i, b"nan" if v != v else b"inf"))
            if v != v:
                neg[i] = False
    # the 17 digits: a leading digit and four 4-digit groups
    q1 = D // 10 ** 12
    r = D - q1 * 10 ** 12
    q2 = r // 10 ** 8
    r -= q2 * 10 ** 8
    q3 = r // 10 ** 4
    q4 = r - q3 * 10 ** 4
    lead = q1 // 10 ** 4
    g = np.empty((N, 5), dtype=np.uint32)
    g[:, 1] = _DIGITS4[q1 - lead * 10 ** 4]
    g[:, 2] = _DIGITS4[q2]
    g[:, 3] = _DIGITS4[q3]
    g[:, 4] = _DIGITS4[q4]
    digits = g.view(np.uint8).reshape(N, 20)[:, 3:]
    digits[:, 0] = lead.astype(np.uint8) + 48
    for i, w in words:
        digits[i, :3] = np.frombuffer(w, dtype=np.uint8)
    nsig = 17 - np.argmax(digits[:, ::-1] != 48, axis=1)
    nsig[zero] = 1
    frame = np.empty((N, _W), dtype=np.uint8)
    frame[:, :_I] = _FRAME_HEAD
    frame[:, _I:_I + 17] = digits
    frame[:, _DOT] = 46
    frame[:, _F:_F + 17] = digits
    ad = np.abs(d)
    frame[:, _E] = 101
    frame[:, _E + 1] = np.where(d < 0, 45, 43)
    frame[:, _E + 2] = ad // 100 + 48
    frame[:, _E + 3] = (ad // 10) % 10 + 48
    frame[:, _E + 4] = ad % 10 + 48
    sep = frame.reshape(n, ncol, _W)[:, :, _SEP]
    sep[:] = 44
    sep[:, -1] = 10
    layout = np.where((d >= -4) & (d <= 16), d + 4, _SCI)
    keep = _MASKS[layout, nsig]
    keep[:, 0] = neg
    keep[:, _E + 2] &= ad >= 100
    return frame.ravel()[keep.ravel()].tobytes()


def format_rows(data: np.ndarray, block_values: int = 16384) -> bytes:
    """CSV text (bytes) of a 2-D array: one line per row, each value as ``'%.17g' % value``.

    Byte-identical to ``"".join(",".join("%.17g" % v for v in row) + "\\n" for row in data)``, so
    every float64 (signed zero included) reads back exactly; NaN is written ``nan``, infinities
    ``inf``/``-inf``. Works in blocks of about ``block_values`` values to stay in cache.
    """
    a = np.asarray(data, dtype=np.float64)
    if a.ndim != 2:
        raise ValueError(f"format_rows needs a 2-D array, got shape {a.shape}")
    n, ncol = a.shape
    if n == 0:
        return b""
    if ncol == 0:
        return b"\n" * n
    a = np.ascontiguousarray(a)
    step = max(1, block_values // ncol)
    if n <= step:
        return _format_block(a)
    return b"".join([_format_block(a[i:i + step]) for i in range(0, n, step)])


# ------------------------------------------------------------------------------------------------------
# sidecar and CSV reading
# ------------------------------------------------------------------------------------------------------
def json_default(obj: Any) -> Any:
    """``json.dumps(default=...)`` for the values trace meta may hold (numpy, paths, sets)."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (set, frozenset, tuple)):
        return list(obj)
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    return str(obj)


def _write_sidecar(csv_path: str | os.PathLike, columns: Sequence[str], units: dict[str, str],
                   meta: dict, rows: int, complete: bool) -> None:
    side = sidecar_path(csv_path)
    doc = {"format": _FORMAT_NAME, "version": _FORMAT_VERSION, "columns": list(columns),
           "units": dict(units), "meta": meta, "rows": int(rows), "complete": bool(complete)}
    text = json.dumps(doc, indent=2, default=json_default, allow_nan=True) + "\n"
    tmp = side.with_name(side.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, side)


def _read_sidecar(csv_path: str | os.PathLike) -> dict:
    side = sidecar_path(csv_path)
    if not side.exists():
        return {}
    doc = json.loads(side.read_text(encoding="utf-8"))
    if not isinstance(doc, dict):
        raise ValueError(f"{side}: expected a JSON object")
    return doc


def _check_columns(columns: Iterable[str]) -> list[str]:
    cols = [str(c) for c in columns]
    if not cols:
        raise ValueError("a trace needs at least one column")
    for c in cols:
        if not c or c != c.strip() or any(ch in c for ch in ',"\r\n'):
            raise ValueError(f"column name {c!r}: must be non-empty, without surrounding blanks, "
                             "commas, quotes or line breaks")
    seen: set[str] = set()
    dup = [c for c in cols if c in seen or seen.add(c)]  # type: ignore[func-returns-value]
    if dup:
        raise ValueError(f"duplicate column names: {sorted(set(dup))}")
    return cols


# ------------------------------------------------------------------------------------------------------
# Trace
# ------------------------------------------------------------------------------------------------------
class Trace:
    """A recorded trace: ``data`` (rows x columns, float64) with column names, units and meta.

    Like python-control's ``TimeResponseData``, a result object: ``trace["Z.act"]`` is one signal
    (a view of its column), ``trace.t`` the time column, ``trace.plot()`` draws it.
    """

    def __init__(self, columns: Sequence[str], data: Any, units: dict[str, str] | None = None,
                 meta: dict | None = None, packed: bool = False):
        self.columns: list[str] = _check_columns(columns)
        self.packed = bool(packed)
        arr = np.asarray(data, dtype=np.float64)
        if arr.ndim == 1 and arr.size == 0:
            arr = arr.reshape(0, len(self.columns))
        if arr.ndim != 2 or arr.shape[1] != len(self.columns):
            raise ValueError(f"data of shape {arr.shape} does not fit {len(self.columns)} columns")
        self.data: np.ndarray = np.ascontiguousarray(arr)
        self.units: dict[str, str] = {c: str(u) for c, u in (units or {}).items() if c in self.columns}
        self.meta: dict = dict(meta or {})
        self._index = {c: i for i, c in enumerate(self.columns)}

    # --- access ---------------------------------------------------------------------------------------
    def __getitem__(self, column: str) -> np.ndarray:
        try:
            return self.data[:, self._index[column]]
        except KeyError:
            near = difflib.get_close_matches(str(column), self.columns, n=3)
            hint = f"; did you mean {', '.join(near)}?" if near else ""
            raise KeyError(f"no column {column!r} in the trace{hint}") from None

    def __contains__(self, column: object) -> bool:
        return column in self._index

    def __len__(self) -> int:
        return self.data.shape[0]

    @property
    def rows(self) -> int:
        return self.data.shape[0]

    @property
    def t(self) -> np.ndarray:
        """The time column ``t`` (falls back to the sample index when there is none)."""
        if "t" in self._index:
            return self["t"]
        return np.arange(self.rows, dtype=np.float64)

    time = t

    def unit(self, column: str) -> str:
        """The unit of a column ('' when unknown)."""
        return self.units.get(column, "")

    def __repr__(self) -> str:
        cols = ", ".join(self.columns[:6]) + (", ..." if len(self.columns) > 6 else "")
        return f"Trace({self.rows} rows x {len(self.columns)} columns: {cols})"

    def __eq__(self, other: object) -> bool:
        """Exact equality of columns, units, meta and data (NaN equals NaN, -0.0 differs from 0.0)."""
        if not isinstance(other, Trace):
            return NotImplemented
        if self.columns != other.columns or self.units != other.units or self.meta != other.meta:
            return False
        if self.data.shape != other.data.shape:
            return False
        a, b = self.data, other.data
        both_nan = np.isnan(a) & np.isnan(b)
        return bool(np.all(both_nan | (a.view(np.uint64) == b.view(np.uint64))))

    __hash__ = None  # type: ignore[assignment]

    # --- files ----------------------------------------------------------------------------------------
    def to_csv(self, path: str | os.PathLike) -> None:
        """Write the trace as CSV plus the ``<path>.meta.json`` sidecar (units, meta)."""
        path = Path(path)
        with open(path, "wb") as f:
            f.write((",".join(self.columns) + "\n").encode())
            step = 65536
            for i in range(0, self.rows, step):
                f.write(format_rows(self.data[i:i + step]))
        _write_sidecar(path, self.columns, self.units, self.meta, self.rows, True)

    @classmethod
    def from_csv(cls, path: str | os.PathLike) -> "Trace":
        """Load a trace CSV (and its sidecar, when present).

        A last line without its line break (a run killed while writing) is ignored.
        """
        path = Path(path)
        with open(path, "rb") as f:
            header = f.readline()
            if not header.endswith(b"\n"):
                raise ValueError(f"{path}: no complete header line")
            columns = header.decode("utf-8").rstrip("\r\n").split(",")
            body_start = f.tell()
            f.seek(0, os.SEEK_END)
            size = f.tell()
            complete = True
            if size > body_start:
                f.seek(size - 1)
                complete = f.read(1) == b"\n"
        ncol = len(columns)
        if size == body_start:
            data = np.empty((0, ncol))
        elif complete:
            data = np.loadtxt(path, delimiter=",", skiprows=1, dtype=np.float64, ndmin=2,
                              encoding="utf-8")
        else:
            with open(path, "r", encoding="utf-8", newline="") as f:
                f.readline()
                lines = (line for line in f if line.endswith("\n"))
                data = np.loadtxt(lines, delimiter=",", dtype=np.float64, ndmin=2)
            if data.size == 0:
                data = np.empty((0, ncol))
        if data.shape[1] != ncol:
            raise ValueError(f"{path}: rows have {data.shape[1]} values, the header names {ncol} columns")
        side = _read_sidecar(path)
        units = side.get("units") or {}
        meta = side.get("meta") or {}
        return cls(columns, data, units=units, meta=meta)

    # --- plot -----------------------------------------------------------------------------------------
    def plot(self, path: str | os.PathLike | None = None, signals: list[str] | None = None,
             title: str | None = None):
        """Stacked subplots over time (see :func:`distctrl.trace.plot.plot_trace`); returns the Figure."""
        return plot_trace(self, path=path, signals=signals, title=title)


# ------------------------------------------------------------------------------------------------------
# TraceRecorder
# ------------------------------------------------------------------------------------------------------
class TraceRecorder:
    """Records one row per cycle; streams float64 chunks to CSV and/or keeps them for a :class:`Trace`.

    ``append(row)`` takes ONE tuple (or list/array) of ``len(columns)`` numbers. It is a closure that
    appends the row to a Python list and calls :meth:`flush` when ``chunk_rows`` rows are buffered,
    so memory stays flat without any help from the caller (cost: one list append and one length
    check, ~50 ns over a bare ``list.append``). A loop that wants the last few nanoseconds can use
    ``append_raw`` (the bare bound ``list.append``) and call :meth:`tick` now and then (it flushes
    when a chunk is full); :meth:`flush` and :meth:`close` take the rows either way.

    A malformed row (wrong length, not numbers) raises ``ValueError`` at the flush that meets it;
    the row is dropped, every other row is kept. :meth:`close` never raises for such rows (it warns).

    ``packed=True``: rows are given already packed, ``recorder.pack(*numbers)`` (bytes of
    ``len(columns)`` native float64). A producer that packs each row at once keeps no Python floats
    alive between flushes: for the simulator's row of ~25 numbers that is ~0.5 µs a cycle less than
    buffering tuples (their floats leave the CPU caches before the flush packs them).

    ``max_rows``: a ring buffer like a scope's: only the last ``max_rows`` rows are kept, and the CSV
    is written at :meth:`close` (it holds those rows; the sidecar's meta says how many were dropped).
    ``keep_at_most``: the kept :class:`Trace` (not the CSV) is thinned to at most this many rows by
    doubling the stride whenever it would grow beyond (every row ``i`` with ``i % stride == 0`` is
    kept): enough for a plot or a report of a run of any length, in bounded memory.

    A file that cannot be written raises ``OSError`` naming the CSV path.
    """

    def __init__(self, columns: list[str], units: dict[str, str] | None = None,
                 csv_path: str | os.PathLike | None = None, keep: bool = True, chunk_rows: int = 65536,
                 meta: dict | None = None, packed: bool = False, max_rows: int | None = None,
                 keep_at_most: int | None = None):
        self.columns: list[str] = _check_columns(columns)
        self.packed = bool(packed)
        self.units: dict[str, str] = {c: str(u) for c, u in (units or {}).items() if c in self.columns}
        self.meta: dict = dict(meta or {})
        self.keep = bool(keep)
        chunk_rows = int(chunk_rows)
        if chunk_rows < 1:
            raise ValueError(f"chunk_rows must be >= 1, got {chunk_rows}")
        self.chunk_rows = chunk_rows
        if max_rows is not None and int(max_rows) < 1:
            raise ValueError(f"max_rows must be >= 1, got {max_rows}")
        if keep_at_most is not None and int(keep_at_most) < 2:
            raise ValueError(f"keep_at_most must be >= 2, got {keep_at_most}")
        self.max_rows = None if max_rows is None else int(max_rows)
        self.keep_at_most = None if keep_at_most is None else int(keep_at_most)
        self.stride = 1                     # with keep_at_most: every stride-th row is kept
        self._kept = 0
        self.csv_path: Path | None = Path(csv_path) if csv_path is not None else None
        self._ncol = len(self.columns)
        self._pack = struct.Struct(f"={self._ncol}d").pack
        #: packs one row (``len(columns)`` numbers) into what ``append`` takes with ``packed=True``
        self.pack = self._pack
        self._row_bytes = 8 * self._ncol
        self._buf: list = []
        self._chunks: list[np.ndarray] = []
        self._flushed = 0
        self._closed = False
        self._trace: Trace | None = None
        self._file = None
        self._good_pos = 0
        if self.csv_path is not None:
            with self._naming_the_file():
                self.csv_path.parent.mkdir(parents=True, exist_ok=True)
                _write_sidecar(self.csv_path, self.columns, self.units, self.meta, 0, False)
                self._file = open(self.csv_path, "wb")
                self._file.write((",".join(self.columns) + "\n").encode())
                self._file.flush()
                self._good_pos = self._file.tell()
        #: the bare ``list.append`` of the row buffer: call :meth:`tick` yourself to bound memory
        self.append_raw: Callable[[Any], None] = self._buf.append
        self.append: Callable[[Any], None] = self._make_append()

    @contextlib.contextmanager
    def _naming_the_file(self):
        """Re-raise an OSError of the CSV or its sidecar with the CSV's path (a full disk names none)."""
        try:
            yield
        except OSError as exc:
            if exc.filename is None:
                raise OSError(exc.errno, exc.strerror or str(exc), str(self.csv_path)) from exc
            raise

    def _make_append(self) -> Callable[[Any], None]:
        def append(row, _append=self._buf.append, _len=len, _buf=self._buf, _limit=self.chunk_rows,
                   _flush=self.flush):
            _append(row)
            if _len(_buf) >= _limit:
                _flush()
        return append

    # --- state ----------------------------------------------------------------------------------------
    @property
    def rows(self) -> int:
        """Rows recorded so far (flushed and buffered)."""
        return self._flushed + len(self._buf)

    @property
    def buffered_rows(self) -> int:
        """Rows appended but not yet flushed."""
        return len(self._buf)

    @property
    def kept_rows(self) -> int:
        """Rows held in float64 chunks (0 with ``keep=False``, except the ring buffer's rows)."""
        return sum(c.shape[0] for c in self._chunks)

    @property
    def closed(self) -> bool:
        return self._closed

    def tick(self) -> None:
        """Flush if a full chunk is buffered (for callers of ``append_raw``)."""
        if len(self._buf) >= self.chunk_rows:
            self.flush()

    # --- flushing -------------------------------------------------------------------------------------
    def flush(self) -> None:
        """Turn the buffered rows into a float64 chunk, write it to the CSV (if any), keep it (if keep)."""
        buf = self._buf
        if not buf:
            return
        if self._closed:
            n = len(buf)
            del buf[:]
            raise RuntimeError(f"{n} rows appended after close() were not recorded")
        n = len(buf)
        try:
            if self.packed:
                packed = b"".join(buf)
                if len(packed) != n * self._row_bytes:
                    raise ValueError("a packed row of the wrong length")
            else:
                # struct packs the tuples at C speed (about twice np.fromiter) and checks each row's length
                packed = b"".join(itertools.starmap(self._pack, buf))
        except (struct.error, ValueError, TypeError, OverflowError):
            self._flush_bad(buf)
            return
        self._take(np.frombuffer(packed, dtype=np.float64).reshape(n, self._ncol), n)

    def _take(self, arr: np.ndarray, n: int) -> None:
        """Write and keep the first n buffered rows, converted to arr; then drop them from the buffer."""
        f = self._file
        if f is not None and self.max_rows is None:
            text = format_rows(arr)
            with self._naming_the_file():
                if f.tell() != self._good_pos:   # an earlier write was interrupted: cut its partial rows
                    f.seek(self._good_pos)
                    f.truncate()
                f.write(text)
                f.flush()
                pos = f.tell()
            self._good_pos = pos
        first = self._flushed
        # no calls (and so no signal handlers) between these two stores: buffer and count agree
        del self._buf[:n]
        self._flushed += n
        if self.max_rows is not None:
            self._keep_ring(arr)
        elif self.keep:
            if self.keep_at_most is not None:
                self._keep_thinned(arr, first)
            else:
                self._chunks.append(arr)

    def _keep_ring(self, arr: np.ndarray) -> None:
        self._chunks.append(arr)
        self._kept += arr.shape[0]
        if self._kept >= 2 * self.max_rows:          # trim now and then: amortised O(1) per row
            self._chunks = [np.concatenate(self._chunks)[-self.max_rows:]]
            self._kept = self.max_rows

    def _keep_thinned(self, arr: np.ndarray, first: int) -> None:
        stride = self.stride
        part = arr[(-first) % stride::stride]
        self._chunks.append(part)
        self._kept += part.shape[0]
        while self._kept > self.keep_at_most:
            # kept rows are those with i % stride == 0, from row 0 on: every other one has i % 2·stride == 0
            kept = np.concatenate(self._chunks)[::2]
            self._chunks = [kept]
            self._kept = kept.shape[0]
            self.stride *= 2

    @property
    def dropped_rows(self) -> int:
        """Rows the ring buffer (``max_rows``) has dropped so far."""
        return 0 if self.max_rows is None else max(0, self._flushed - self.max_rows)

    def _row_bytes_of(self, row) -> bytes:
        """One buffered row as packed bytes; raises for a malformed one."""
        if self.packed:
            if not isinstance(row, (bytes, bytearray)) or len(row) != self._row_bytes:
                raise ValueError("not a packed row")
            return row
        return self._pack(*row)

    def _flush_bad(self, buf: list) -> None:
        """Take the rows before the first malformed one, drop that one and raise ValueError."""
        one = self._row_bytes_of
        for i, row in enumerate(buf):
            try:
                one(row)
            except (struct.error, ValueError, TypeError, OverflowError):
                break
        else:  # pragma: no cover - only if the rows changed under us: all good now
            n = len(buf)
            self._take(np.frombuffer(b"".join(map(one, buf)), dtype=np.float64).reshape(n, self._ncol), n)
            return
        if i:
            self._take(np.frombuffer(b"".join(map(one, buf[:i])), dtype=np.float64).reshape(i, self._ncol), i)
        bad = buf[0]
        index = self._flushed
        del buf[0]
        shown = repr(bad)
        if len(shown) > 200:
            shown = shown[:200] + "..."
        raise ValueError(f"trace row {index} is not {self._ncol} numbers ({shown}); the row was dropped")

    # --- closing --------------------------------------------------------------------------------------
    def close(self, complete: bool = True) -> Trace | None:
        """Flush, finish the CSV and sidecar; return the kept :class:`Trace` (None with keep=False).

        ``complete=False``: the recording was cut short (e.g. Ctrl-C); the file is whole up to its last
        row, but the sidecar says ``"complete": false`` so tools know the run did not end there.
        Idempotent: later calls return the same result. Safe in ``finally`` and signal handlers.
        """
        if self._closed:
            return self._trace
        problems: list[str] = []
        ring = None
        try:
            while self._buf:
                try:
                    self.flush()
                except ValueError as exc:
                    problems.append(str(exc))
        finally:
            self._closed = True
            if self.max_rows is not None:
                ring = np.concatenate(self._chunks)[-self.max_rows:] if self._chunks \
                    else np.empty((0, self._ncol))
                self._chunks = [ring]
                self.meta["ring_buffer_rows"] = self.max_rows
                self.meta["dropped_rows"] = self.dropped_rows
            if self.stride > 1:
                self.meta["kept_every"] = self.stride
            f, self._file = self._file, None
            if f is not None:
                with self._naming_the_file():
                    try:
                        if ring is not None:            # the scope's last rows, written once
                            f.seek(self._good_pos)
                            f.truncate()
                            step = 65536
                            for i in range(0, ring.shape[0], step):
                                f.write(format_rows(ring[i:i + step]))
                            f.flush()
                            self._good_pos = f.tell()
                        elif f.tell() != self._good_pos:
                            f.seek(self._good_pos)
                            f.truncate()
                    finally:
                        f.close()
                    rows = ring.shape[0] if ring is not None else self._flushed
                    _write_sidecar(self.csv_path, self.columns, self.units, self.meta, rows, bool(complete))
            if self.keep:
                chunks, self._chunks = self._chunks, []
                data = np.concatenate(chunks) if chunks else np.empty((0, self._ncol))
                self._trace = Trace(self.columns, data, units=self.units, meta=self.meta)
        for p in problems:
            warnings.warn(p, RuntimeWarning, stacklevel=2)
        return self._trace

    def __enter__(self) -> "TraceRecorder":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        where = f" -> {self.csv_path}" if self.csv_path else ""
        state = "closed" if self._closed else "open"
        return f"TraceRecorder({len(self.columns)} columns, {self.rows} rows, {state}{where})"
