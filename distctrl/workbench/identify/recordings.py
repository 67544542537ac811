"""``distctrl identify``, the recordings: plain CSV, distctrl traces, TwinCAT Scope CSV export."""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...errors import DistCtrlError
from ...trace import Trace, is_trace_file, load_trace, sidecar_path
from ..filters.recording import _TIME_UNITS, _VALUE_UNITS, _pick_column, _read_plain_csv, _unit_factor
from .common import MIN_SAMPLES, MIN_SECONDS, IdentifyError


@dataclass(frozen=True)
class Signals:
    """One recording in s and mm: time, command (set position), actual (motor encoder), sensor.

    ``actual_at``: when the actual column of a row is sampled: ``"start"`` of the cycle (TwinCAT:
    the input mapping before the task runs) or ``"end"`` (distctrl traces: the drive's position
    after the cycle). ``source``: ``"trace"``, ``"scope"`` or ``"csv"``.
    """

    t: np.ndarray
    command: np.ndarray
    actual: np.ndarray
    sensor: np.ndarray
    cycle_time: float
    path: str
    columns: tuple[str, str, str]
    source: str
    actual_at: str
    #: a distctrl trace's ``<axis>.dc.state`` column (None: the recording has none) and the cycles in
    #: which distance control was closing the loop in it (ACTIVE, TURNING_OFF, ACTIVE_CONST_DIST)
    state_column: str | None = None
    closed_loop_cycles: int = 0

    @property
    def duration(self) -> float:
        return self.t.size * self.cycle_time


_SCOPE_KEYS = {"Name", "SymbolName", "SymbolComment", "NetId", "NetID", "Port", "IndexGroup", "IndexOffset",
               "Data-Type", "SampleTime[ms]", "SymbolBased", "VariableSize", "Offset", "ScaleFactor", "BitMask",
               "Unit", "Unit ScaleFactor", "Unit Offset", "StartTime", "EndTime", "File", "Comment"}


def _read_text(p: Path) -> str:
    try:
        return p.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        return p.read_text(encoding="latin-1")


def _is_number(cell: str) -> bool:
    try:
        float(cell)
        return True
    except ValueError:
        return False


def _delimiter(lines: list[str]) -> str:
    """The separator of a Scope export: the one whose count is the same on most of the last lines
    (';' before TAB before ',' on a tie: on a TAB file with decimal commas ',' counts the same)."""
    tail = [ln for ln in lines if ln.strip()][-20:]
    best, best_score = ",", -1.0
    for d in (";", "\t", ","):
        counts = [ln.count(d) for ln in tail]
        mode = max(set(counts), key=counts.count)
        if mode == 0:
            continue
        score = counts.count(mode) / len(counts)
        if score > best_score:
            best, best_score = d, score
    return best


def is_scope_export(text_head: str) -> bool:
    """A TwinCAT Scope CSV export starts with metadata rows ``Name<sep>...`` (the Scope project),
    and has a ``Name`` row per channel before the data."""
    lines = [ln for ln in text_head.splitlines() if ln.strip()]
    if not lines:
        return False
    first = lines[0].lstrip('"').split(";")[0].split("\t")[0].split(",")[0].strip().strip('"')
    return first in ("Name", "File", "StartTime") and sum(
        1 for ln in lines[:60] if ln.strip().strip('"').split(";")[0].split("\t")[0].split(",")[0].strip('"')
        in _SCOPE_KEYS) >= 2


def _read_scope_csv(p: Path, text: str) -> tuple[list[str], list[list[str]], int, dict[str, str], dict]:
    """A TwinCAT Scope CSV export: (column names, data rows, line of the first data row, time column
    of each value column, info).

    Layout (TE13xx Scope View "Export in csv", TC3ScopeExportTool): rows of key/value metadata (the
    project: Name, File, StartTime/EndTime), then per channel a block of ``key<sep>value`` pairs side
    by side (Name, SymbolName, NetId, Port, SampleTime[ms], Data-Type, ...), then the data: each group
    of channels with the same sample time has its own time column (ms since the start of the export,
    or FILETIME ticks with "Full Timestamp") followed by its value columns. The ``Name`` row marks a
    group's time column with the key itself. Separator ``;``, TAB or ``,``; with ``;`` or TAB the
    decimal mark may be a comma. A trailing ``EOF`` row is skipped.
    """
    lines = text.splitlines()
    delim = _delimiter(lines)
    cells = [[c.strip().strip('"') for c in ln.split(delim)] if ln.strip() else [] for ln in lines]
    comma = delim != "," and any("," in c for row in cells[-20:] for c in row)

    def num(c: str) -> bool:
        return bool(c) and _is_number(c.replace(",", ".") if comma else c)

    data_i = None
    for i, row in enumerate(cells):
        filled = [c for c in row if c]
        if len(filled) >= 2 and all(num(c) for c in filled) and row[0] not in _SCOPE_KEYS:
            nxt = next((r for r in cells[i + 1:] if r), None)
            if nxt is None or all(num(c) for c in nxt if c) or nxt[0].upper() == "EOF":
                data_i = i
                break
    if data_i is None:
        raise IdentifyError(f"{p}: a TwinCAT Scope export without numeric data rows; export the recording "
                            "again (Scope View: Export -> CSV)")
    width = len(cells[data_i])
    meta: dict[str, list[str]] = {}
    for row in cells[:data_i]:
        if row and row[0] in _SCOPE_KEYS and len(row) >= width - 1:
            meta[row[0]] = row + [""] * (width - len(row))         # the last (channel) block wins
    names_row = meta.get("Name")
    symbols = meta.get("SymbolName")
    if names_row is None:
        header = next((r for r in reversed(cells[:data_i]) if r and not all(num(c) for c in r if c)), None)
        if header is None:
            raise IdentifyError(f"{p}: no row with the channel names before the data")
        names_row = header
    names: list[str] = []
    time_of: dict[str, str] = {}
    current_time = None
    groups = 0
    for j in range(width):
        c = names_row[j] if j < len(names_row) else ""
        if c == "Name" or (j == 0 and names_row is not meta.get("Name")):
            groups += 1
            current_time = "Time" if groups == 1 else f"Time ({groups})"
            names.append(current_time)
            continue
        name = c or f"column {j + 1}"
        if name in names:
            name = f"{name} ({j + 1})"
        names.append(name)
        if current_time is not None:
            time_of[name] = current_time
        if symbols is not None and j < len(symbols) and symbols[j] and symbols[j] != "SymbolName":
            time_of.setdefault(f"symbol:{symbols[j]}", name)
    body = []
    for row in cells[data_i:]:
        if not row:
            continue
        if row[0].upper() == "EOF":
            break
        body.append([c.replace(",", ".") for c in row] if comma else row)
    info = {"separator": {"\t": "TAB"}.get(delim, delim), "decimal": "," if comma else ".",
            "groups": groups, "sample_time_ms": (meta.get("SampleTime[ms]") or [None, None])[1]}
    return names, body, data_i + 1, time_of, info


def _column(p: Path, body: list[list[str]], j: int, name: str, first_line: int) -> np.ndarray:
    out = np.empty(len(body))
    for i, row in enumerate(body):
        try:
            out[i] = float(row[j])
        except (ValueError, IndexError):
            cell = row[j] if j < len(row) else ""
            raise IdentifyError(f"{p}:{first_line + i}: column {name!r}: {cell!r} is not a number; allowed: "
                                "decimal numbers in every row (record all signals at the same sample time)") from None
    return out


def load_signals(path: str | os.PathLike, *, time: str | None = None, command: str, actual: str, sensor: str,
                 time_unit: str | None = None, value_unit: str = "mm", sensor_unit: str | None = None,
                 mm_per_increment: float | None = None, actual_at: str = "auto") -> Signals:
    """One recording, converted to s and mm.

    ``time``: the time column (default: ``t`` for a trace, the channels' own time column for a
    Scope export, the first column of a plain CSV). ``time_unit``: s, ms or us (default: the
    trace's unit; ms for a Scope export, as it writes them; s for a plain CSV). ``value_unit``:
    mm, um or inc (with ``mm_per_increment``) for command and actual; ``sensor_unit`` for the sensor
    (default: ``value_unit``). ``actual_at``: ``start``/``end``/``auto`` (auto: end for a trace,
    start otherwise).
    """
    p = Path(path)
    if not p.is_file():
        raise IdentifyError(f"{p}: no such file; expected a CSV recording (header row, one row per cycle)")
    vf = _unit_factor(p, "value", value_unit, _VALUE_UNITS, mm_per_increment)
    sf = _unit_factor(p, "sensor", sensor_unit or value_unit, _VALUE_UNITS, mm_per_increment)
    tf = None if time_unit is None else _unit_factor(p, "time", time_unit, _TIME_UNITS)
    wanted = {"command": command, "actual": actual, "sensor": sensor}
    filetime = False
    if is_trace_file(p):                 # a CSV with its sidecar, or Parquet (distctrl run --trace x.parquet)
        source = "trace"
        try:
            trace = load_trace(p)
        except (ValueError, OSError, DistCtrlError) as exc:
            raise IdentifyError(f"{p}: not a readable distctrl trace: {exc}") from None
        cols = list(trace.columns)
        time = time or ("t" if "t" in trace else cols[0])
        idx = {k: _col_index(p, cols, v, k) for k, v in wanted.items()}
        ti = _col_index(p, cols, time, "time")
        raw = {k: trace.data[:, i] for k, i in idx.items()}
        raw_t = trace.data[:, ti]
        state_column, closed = _closed_loop_cycles(cols, trace.data, command)
        if tf is None:
            tf = _unit_factor(p, f"time column {time!r} has a", trace.unit(time) or "s", _TIME_UNITS)
        units = {k: trace.unit(v) for k, v in wanted.items()}
        if units["command"] or units["actual"]:
            vf = _unit_factor(p, f"column {command!r} has a", units["command"] or units["actual"], _VALUE_UNITS,
                              mm_per_increment)
        if units["sensor"]:
            sf = _unit_factor(p, f"column {sensor!r} has a", units["sensor"], _VALUE_UNITS, mm_per_increment)
        first_line = 2
    else:
        state_column, closed = None, 0
        text = _read_text(p)
        if not text.strip():
            raise IdentifyError(f"{p}: empty file; expected a header row and one row per cycle")
        if is_scope_export(text[:20000]):
            source = "scope"
            names, body, first_line, time_of, _info = _read_scope_csv(p, text)
            # a channel may be named by its Scope name or its SymbolName
            for k, v in list(wanted.items()):
                if v not in names and f"symbol:{v}" in time_of:
                    wanted[k] = time_of[f"symbol:{v}"]
            idx = {k: _col_index(p, names, v, k) for k, v in wanted.items()}
            if time is None:
                tcols = [time_of.get(wanted[k]) for k in wanted]
                if None in tcols:
                    raise IdentifyError(f"{p}: no time column for {wanted[list(wanted)[tcols.index(None)]]!r}; "
                                        "name it with --time")
                first = _column(p, [r for r in body if any(c.strip() for c in r)], names.index(tcols[0]),
                                tcols[0], first_line)
                for other in set(tcols) - {tcols[0]}:
                    col = _column(p, [r for r in body if any(c.strip() for c in r)], names.index(other), other,
                                  first_line)
                    if col.shape != first.shape or not np.allclose(col, first, rtol=0, atol=1e-9 * max(1.0, abs(first).max())):
                        raise IdentifyError(f"{p}: the channels {', '.join(map(repr, wanted.values()))} are in "
                                            "time groups with different time stamps in the Scope export; record them "
                                            "at the same sample time (the interpolation cycle) or name the time "
                                            "column with --time")
                time = tcols[0]
            ti = _col_index(p, names, time, "time")
            if tf is None:
                tf = 1e-3                                        # Scope exports ms since the start
                filetime = True
        else:
            source = "csv"
            names, body, first_line = _read_plain_csv(p)
            idx = {k: _col_index(p, names, v, k) for k, v in wanted.items()}
            ti = _col_index(p, names, time, "time") if time is not None else 0
            time = names[ti]
            if tf is None:
                tf = 1.0
        body = [r for r in body if any(c.strip() for c in r)]
        raw = {k: _column(p, body, j, names[j], first_line) for k, j in idx.items()}
        raw_t = _column(p, body, ti, names[ti], first_line)
        wanted = {k: names[j] for k, j in idx.items()}
    n = raw_t.size
    for k, v in raw.items():
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise IdentifyError(f"{p}:{first_line + bad[0]}: column {wanted[k]!r} is not finite; allowed: finite "
                                "numbers in every row")
    if filetime and n and raw_t[0] > 1e14:                      # "Full Timestamp": FILETIME, 100 ns ticks
        raw_t = (raw_t - raw_t[0]) * 1e-4                          # -> ms
    t = raw_t * tf
    if n < 2:
        raise IdentifyError(f"{p}: recording too short: {n} samples; record at least {MIN_SECONDS:g} s at the "
                            "interpolation cycle")
    dt = np.diff(t)
    back = np.flatnonzero(~(dt > 0.0))
    if back.size:
        raise IdentifyError(f"{p}:{first_line + back[0] + 1}: time column {time!r} is not strictly increasing; "
                            "allowed: one row per cycle in time order")
    T = float(np.median(dt))
    spread = float(np.max(np.abs(dt - T))) / T
    if spread > 0.01:
        i = int(np.argmax(np.abs(dt - T)))
        raise IdentifyError(f"{p}:{first_line + i + 1}: non-uniform time base: the sample interval is "
                            f"{dt[i] * 1e3:.6g} ms there, the median {T * 1e3:.6g} ms (allowed: within 1 %); record "
                            "every cycle (Scope: the task's cycle time as sample time, no gaps)")
    if n < MIN_SAMPLES or n * T < MIN_SECONDS:
        raise IdentifyError(f"{p}: recording too short: {n} samples ({n * T:.3g} s); record at least "
                            f"{MIN_SECONDS:g} s and {MIN_SAMPLES} cycles (steps: 5 s, chirp: 20 s, ramp: 20 s)")
    if actual_at not in ("auto", "start", "end"):
        raise IdentifyError(f"actual_at {actual_at!r}; allowed: auto, start, end")
    at = ("end" if source == "trace" else "start") if actual_at == "auto" else actual_at
    return Signals(t=t - t[0], command=raw["command"] * vf, actual=raw["actual"] * vf, sensor=raw["sensor"] * sf,
                   cycle_time=T, path=str(p), columns=(wanted["command"], wanted["actual"], wanted["sensor"]),
                   source=source, actual_at=at, state_column=state_column, closed_loop_cycles=closed)


#: HLI states in which distance control closes the loop (docs/trace.md: 1 ACTIVE, 3 TURNING_OFF,
#: 4 ACTIVE_CONST_DIST); FREEZE holds the offset and the dry runs do not move the axis
CLOSED_LOOP_STATES = (1, 3, 4)


def _closed_loop_cycles(cols: list[str], data: np.ndarray, command: str) -> tuple[str | None, int]:
    """The trace's distance control state column of the command's axis (``Z.cmd`` -> ``Z.dc.state``; the
    only ``*.dc.state`` column otherwise) and the cycles in which it closed the loop."""
    axis = command.split(".")[0]
    name = f"{axis}.dc.state"
    if name not in cols:
        states = [c for c in cols if c.endswith(".dc.state")]
        if len(states) != 1:
            return None, 0
        name = states[0]
    state = data[:, cols.index(name)]
    return name, int(np.isin(np.round(state), CLOSED_LOOP_STATES).sum())


def _col_index(p, columns: list[str], name: str, what: str) -> int:
    try:
        return _pick_column(p, columns, name, what)
    except DistCtrlError as exc:
        raise IdentifyError(str(exc)) from None
