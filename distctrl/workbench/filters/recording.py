"""Sensor recordings for the filter workbench: :func:`load_recording` reads a plain CSV or a distctrl
trace CSV into a :class:`Recording` (s, mm).

Part of :mod:`distctrl.workbench.filters` (docs/workbench-filters.md); the package face re-exports every name.
"""
from __future__ import annotations

import csv
import difflib
import io
import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...errors import DistCtrlError
from ...trace import Trace, is_trace_file, load_trace
from .spec import RecordingError, RecordingWarning


_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}
_VALUE_UNITS = {"mm": 1.0, "um": 1e-3, "µm": 1e-3, "inc": None, "increments": None}


@dataclass(frozen=True)
class Recording:
    """A sensor recording in s and mm; ``cycle_time`` is its (median) sample interval."""

    t: np.ndarray
    values: np.ndarray
    cycle_time: float
    path: str
    time_column: str | None
    value_column: str
    warnings: tuple[str, ...] = field(default=())

    def __len__(self) -> int:
        return self.values.size


def _unit_factor(path, which: str, unit: str, table: dict, mm_per_increment: float | None = None) -> float:
    key = str(unit).strip()
    key = key.lower() if key not in ("µs", "µm") else key
    if key not in table:
        raise RecordingError(f"{path}: {which} unit {unit!r} not known; allowed: {', '.join(table)}")
    f = table[key]
    if f is None:  # increments
        if mm_per_increment is None or not (mm_per_increment > 0.0 and math.isfinite(mm_per_increment)):
            raise RecordingError(f"{path}: value unit {unit!r} needs mm_per_increment "
                                 f"(--mm-per-increment), a finite number > 0; got {mm_per_increment!r}")
        f = float(mm_per_increment)
    return f


def _pick_column(path, columns: list[str], name: str, what: str) -> int:
    if name in columns:
        return columns.index(name)
    near = difflib.get_close_matches(name, columns, n=3)
    hint = f"; did you mean {', '.join(near)}?" if near else ""
    raise RecordingError(f"{path}: no {what} column {name!r}{hint}; columns: {', '.join(columns)}")


def _read_plain_csv(path: Path) -> tuple[list[str], list[list[str]], int]:
    """Header names, rows of cells, and the line number of the first data row (1-based)."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        text = path.read_text(encoding="latin-1")
    lines = text.splitlines()
    first = next((i for i, line in enumerate(lines) if line.strip()), None)
    if first is None:
        raise RecordingError(f"{path}: empty file; expected a header row and one row per sample")
    head = lines[first]
    delim = ";" if ";" in head else ("\t" if "\t" in head else ",")
    rows = list(csv.reader(io.StringIO("\n".join(lines[first:])), delimiter=delim))
    header = [h.strip() for h in rows[0]]
    body = rows[1:]
    data_line = first + 2

    def numeric(cell: str) -> bool:
        try:
            float(cell.replace(",", ".") if delim != "," else cell)
            return True
        except ValueError:
            return False
    if header and all(numeric(h) for h in header if h):       # no header row: name the columns
        body = rows
        data_line = first + 1
        header = [f"column {i + 1}" for i in range(len(rows[0]))]
    if delim != ",":                                            # ';' or tab: allow a decimal comma
        body = [[c.replace(",", ".") for c in r] for r in body]
    return header, body, data_line


def _trace_columns(p: Path, time_column: str | None, value_column: str | None, tf: float, vf: float,
                   mm_per_increment: float | None) -> tuple:
    """``(raw_t, raw_v, time_column, value_column, tf, vf)`` of a distctrl trace: the value column by name
    (default the one ``*.dc.sensor``), time ``t``; the trace's own units win."""
    try:
        trace = load_trace(p)
    except (ValueError, OSError, DistCtrlError) as exc:
        raise RecordingError(f"{p}: not a readable distctrl trace: {exc}") from None
    cols = list(trace.columns)
    if value_column is None:
        # a run's trace has <axis>.dc.sensor, a `machine record` trace <axis>.sensor
        sensors = [c for c in cols if c.endswith(".dc.sensor")] or [c for c in cols if c.endswith(".sensor")]
        if len(sensors) != 1:
            example = f", e.g. {sensors[0]}" if sensors else ""
            raise RecordingError(f"{p}: name the value column (--value-column){example}; the trace's "
                                 f"columns: {', '.join(c for c in cols if c != 't')}")
        value_column = sensors[0]
    vi = _pick_column(p, cols, value_column, "value")
    if time_column is None and "t" in trace:
        time_column = "t"
    tu, vu = trace.unit(time_column) if time_column else "", trace.unit(value_column)
    if tu:
        tf = _unit_factor(p, f"time column {time_column!r} has a", tu, _TIME_UNITS)
    if vu:
        vf = _unit_factor(p, f"value column {value_column!r} has a", vu, _VALUE_UNITS, mm_per_increment)
    raw_v = trace.data[:, vi]
    raw_t = trace.data[:, _pick_column(p, cols, time_column, "time")] if time_column else None
    return raw_t, raw_v, time_column, value_column, tf, vf


def _plain_columns(p: Path, time_column: str | None, value_column: str | None, cycle_time: float | None) -> tuple:
    """``(raw_t, raw_v, time_column, value_column, first_line)`` of a plain CSV: the named columns, else the
    first two numeric ones (one value column alone with a cycle time)."""
    header, body, first_line = _read_plain_csv(p)
    width = len(header)
    for i, row in enumerate(body):
        if len(row) != width and any(c.strip() for c in row):
            raise RecordingError(f"{p}:{first_line + i}: {len(row)} cells, the header has {width} columns")
    body = [r for r in body if any(c.strip() for c in r)]

    def column(j: int, name: str) -> np.ndarray | None:
        out = np.empty(len(body))
        for i, row in enumerate(body):
            try:
                out[i] = float(row[j])
            except ValueError:
                if name:
                    raise RecordingError(f"{p}:{first_line + i}: column {name!r}: {row[j]!r} is not a "
                                         "number; allowed: decimal numbers") from None
                return None
        return out
    if time_column is not None:
        ti = _pick_column(p, header, time_column, "time")
    if value_column is not None:
        vi = _pick_column(p, header, value_column, "value")
    numeric = [j for j in range(width) if column(j, "") is not None]
    if time_column is None and value_column is None:
        if len(numeric) >= 2:
            ti, vi = numeric[0], numeric[1]
        elif len(numeric) == 1 and cycle_time:
            ti, vi = None, numeric[0]
        else:
            raise RecordingError(f"{p}: found {len(numeric)} numeric column(s) in {', '.join(header)}; "
                                 "allowed: a time and a value column (or one value column with a "
                                 "cycle time); name them with time_column/value_column")
    elif value_column is None:
        rest = [j for j in numeric if j != ti]
        if not rest:
            raise RecordingError(f"{p}: no numeric value column besides {time_column!r}; "
                                 f"columns: {', '.join(header)}")
        vi = rest[0]
    elif time_column is None:
        rest = [j for j in numeric if j != vi]
        if rest:
            ti = rest[0]
        elif cycle_time:
            ti = None
        else:
            raise RecordingError(f"{p}: no numeric time column besides {value_column!r}; columns: "
                                 f"{', '.join(header)}; allowed: name a time column or give a cycle time")
    value_column = header[vi]
    time_column = header[ti] if ti is not None else None
    raw_v = column(vi, value_column)
    raw_t = column(ti, time_column) if ti is not None else None
    return raw_t, raw_v, time_column, value_column, first_line


def load_recording(path: str | os.PathLike, time_column: str | None = None, value_column: str | None = None,
                   time_unit: str = "s", value_unit: str = "mm", mm_per_increment: float | None = None,
                   cycle_time: float | None = None) -> Recording:
    """A sensor recording from CSV: one column of time, one of values, converted to s and mm.

    Plain CSV: a header row, then one row per sample (``,`` separated; ``;`` or tab with a decimal
    comma also work). Without names the first two numeric columns are time and value. Units:
    ``time_unit`` s, ms or us; ``value_unit`` mm, um or inc (with ``mm_per_increment``). A file with
    a single numeric column and no ``time_column`` is taken as one sample per ``cycle_time``.

    A distctrl trace CSV (recognised by its ``.meta.json`` sidecar) is read with
    :meth:`Trace.from_csv`: time column ``t``, value column by name (default: the one ``*.dc.sensor``
    column, if there is exactly one); the trace's own units win over ``time_unit``/``value_unit``.

    The median sample interval becomes the cycle time; a :class:`RecordingWarning` is issued (and
    kept in ``Recording.warnings``) when an interval differs from it by more than 1 %: the filters
    run once per sample, as in the kernel's cycle, so the time axis is treated as uniform.
    """
    p = Path(path)
    if not p.is_file():
        raise RecordingError(f"{p}: no such file; expected a CSV recording (header row, one row per sample)")
    tf = _unit_factor(p, "time", time_unit, _TIME_UNITS)
    vf = _unit_factor(p, "value", value_unit, _VALUE_UNITS, mm_per_increment)
    if is_trace_file(p):                 # a CSV with its sidecar, or Parquet (distctrl run --trace x.parquet)
        raw_t, raw_v, time_column, value_column, tf, vf = _trace_columns(p, time_column, value_column, tf, vf,
                                                                         mm_per_increment)
        first_line = 2
    else:
        raw_t, raw_v, time_column, value_column, first_line = _plain_columns(p, time_column, value_column,
                                                                             cycle_time)
    n = raw_v.size
    if n < 3:
        raise RecordingError(f"{p}: {n} samples; allowed: at least 3")
    bad = np.flatnonzero(~np.isfinite(raw_v))
    if bad.size:
        raise RecordingError(f"{p}:{first_line + bad[0]}: column {value_column!r} is not finite "
                             f"({raw_v[bad[0]]!r}); allowed: finite numbers")
    values = raw_v * vf
    notes: list[str] = []
    if raw_t is None:
        if not (cycle_time and cycle_time > 0.0 and math.isfinite(cycle_time)):
            raise RecordingError(f"{p}: no time column; allowed: a cycle time > 0 s, got {cycle_time!r}")
        t = np.arange(n) * float(cycle_time)
        T = float(cycle_time)
    else:
        t = raw_t * tf
        bad = np.flatnonzero(~np.isfinite(t))
        if bad.size:
            raise RecordingError(f"{p}:{first_line + bad[0]}: time column {time_column!r} is not finite; "
                                 "allowed: finite numbers")
        dt = np.diff(t)
        back = np.flatnonzero(dt <= 0.0)
        if back.size:
            raise RecordingError(f"{p}:{first_line + back[0] + 1}: time column {time_column!r} is not strictly "
                                 f"increasing ({raw_t[back[0]]!r} -> {raw_t[back[0] + 1]!r}); allowed: one row per "
                                 "sample in time order")
        T = float(np.median(dt))
        spread = float(np.max(np.abs(dt - T))) / T
        if spread > 0.01:
            msg = (f"{p}: sample interval not uniform within 1 % (median {T * 1e3:.6g} ms, min "
                   f"{dt.min() * 1e3:.6g} ms, max {dt.max() * 1e3:.6g} ms); the filters run once per sample "
                   f"as in the kernel's cycle, with cycle time {T * 1e3:.6g} ms")
            notes.append(msg)
            warnings.warn(msg, RecordingWarning, stacklevel=2)
    return Recording(t=t, values=values, cycle_time=T, path=str(p), time_column=time_column,
                     value_column=value_column, warnings=tuple(notes))
