"""``distctrl identify``: the plant (drive and sensor) fitted to recordings of the real machine.

A recording is a CSV at the interpolation cycle with four signals: time, the set position sent to
the drive (*command*), the motor encoder (*actual*) and the height sensor (*sensor*). Three kinds of
file load (docs/identify.md): a plain CSV with a header row, a distctrl trace (docs/trace.md, with
its ``.meta.json`` sidecar) and a TwinCAT Scope CSV export (metadata rows before the data, ``;``,
TAB or ``,`` separated, decimal comma possible, one time column per group of channels).

The model (the one ``distctrl run`` simulates, docs/sim-models.md, in continuous time)::

    command --(dead time)--> P loop kv, |v| <= v_max, |dv/dt| <= a_max --> motor x (actual column)
    motor --(mode f0, zeta: e'' = -w0^2 e - 2 zeta w0 e' - x'')--> nozzle n = x + e
    sensor = sign * characteristic(n(t - delay) - surface) + noise

and the classic tools fit it:

* drive: the one-step equation of the sampled P loop, ``x_{k+1} - x_k = (1 - exp(-kv T)) (c_k - x_k)``
  with ``c_k`` the command delayed by the dead time (fractional, interpolated), by robust least
  squares (:func:`scipy.optimize.least_squares`, soft-L1) on a grid of dead times, then refined;
  ``v_max`` and ``a_max`` from the samples where the loop demands more than the motor does;
* resonance and sensor delay: the frequency response motor -> sensor ``H = Pxy / Pxx``
  (:func:`scipy.signal.csd`, :func:`scipy.signal.welch`, averaged over the recordings) fitted by
  complex least squares with ``g * M(f0, zeta) * exp(-j 2 pi f delay)``, weighted by the coherence;
* characteristic and noise: the quasi-static samples (a slow ramp, settled holds) against the motor
  encoder, in bins of the true distance (local linear fits: the bin's value and its residual noise).

A figure that the recordings cannot determine is ``None`` with a warning that says what to record.
Errors are :class:`IdentifyError` (a ``DistCtrlError``) whose message names the file, the column or
what to record.
"""
from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import DistCtrlError
from ..sim.physics import limit_velocity
from .filters import _TIME_UNITS, _VALUE_UNITS, _pick_column, _read_plain_csv, _unit_factor

__all__ = ["IdentifyError", "IdentifyWarning", "Signals", "Identification", "load_signals", "identify",
           "result_json", "format_summary", "write_scenario", "write_report", "MIN_SECONDS"]


class IdentifyError(DistCtrlError, ValueError):
    """Invalid recordings or options for ``identify`` (exit code 1)."""


class IdentifyWarning(UserWarning):
    """A figure that could not be identified, or a doubt about one."""


#: shortest recording identify accepts (s)
MIN_SECONDS = 1.0
#: and in samples
MIN_SAMPLES = 200
#: what to record, quoted in the messages (docs/identify.md)
RECORD_STEPS = ("steps of the set position of 0.2-0.5 mm (0.5 s apart, sensor not saturated, "
                "distance control off)")
RECORD_LARGE_STEP = ("a step large enough that the axis reaches its velocity limit (several mm, "
                     "at a safe height above the sheet)")
RECORD_CHIRP = ("a chirp of the set position 1-150 Hz, 0.02-0.05 mm amplitude, 20 s, above the sheet")
RECORD_RAMP = ("a slow ramp of the set position (0.2-0.5 mm/s) over the sensor's range, with the "
               "sensor over a flat sheet")
RECORD_STANDSTILL = "1 s or more at standstill above the sheet"


# ------------------------------------------------------------------------------------------------------
# recordings
# ------------------------------------------------------------------------------------------------------
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
    from ..trace import Trace, sidecar_path

    p = Path(path)
    if not p.is_file():
        raise IdentifyError(f"{p}: no such file; expected a CSV recording (header row, one row per cycle)")
    vf = _unit_factor(p, "value", value_unit, _VALUE_UNITS, mm_per_increment)
    sf = _unit_factor(p, "sensor", sensor_unit or value_unit, _VALUE_UNITS, mm_per_increment)
    tf = None if time_unit is None else _unit_factor(p, "time", time_unit, _TIME_UNITS)
    wanted = {"command": command, "actual": actual, "sensor": sensor}
    filetime = False
    if sidecar_path(p).exists():
        source = "trace"
        try:
            trace = Trace.from_csv(p)
        except (ValueError, OSError) as exc:
            raise IdentifyError(f"{p}: not a readable distctrl trace: {exc}") from None
        cols = list(trace.columns)
        time = time or ("t" if "t" in trace else cols[0])
        idx = {k: _col_index(p, cols, v, k) for k, v in wanted.items()}
        ti = _col_index(p, cols, time, "time")
        raw = {k: trace.data[:, i] for k, i in idx.items()}
        raw_t = trace.data[:, ti]
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
                   source=source, actual_at=at)


def _col_index(p, columns: list[str], name: str, what: str) -> int:
    try:
        return _pick_column(p, columns, name, what)
    except DistCtrlError as exc:
        raise IdentifyError(str(exc)) from None


# ------------------------------------------------------------------------------------------------------
# identification
# ------------------------------------------------------------------------------------------------------
DRIVE_KEYS = ("kv", "dead_time", "v_max", "a_max", "resonance_hz", "damping")
SENSOR_KEYS = ("delay", "noise_std", "characteristic")
#: longest dead time / sensor delay searched (s)
MAX_DELAY = 0.03
#: quasi-static samples (characteristic, noise): motor slower than this (mm/s) ...
QS_VELOCITY = 5.0
#: ... and command acceleration below this (mm/s^2) for the settling window before the sample
QS_ACCELERATION = 20.0
#: characteristic bins (mm of true distance)
CHAR_BIN = 0.25
#: Welch segment length (samples) of the frequency response
NPERSEG = 2048


@dataclass
class _Rec:
    """A recording on the motor's time base: X[k] is the motor at the row's time t[k]."""

    sig: Signals
    X: np.ndarray          # motor (mm)
    S: np.ndarray          # command (mm)
    Y: np.ndarray          # sensor, sign-corrected (mm, grows with the distance)
    t: np.ndarray


@dataclass
class Identification:
    """The fitted plant, fit quality and what could not be identified (``warnings``)."""

    cycle_time: float
    drive: dict
    sensor: dict
    fit: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    recordings: list[dict] = field(default_factory=list)
    # for the report: per recording (t, X, S, Y) and model curves
    curves: dict = field(default_factory=dict)


def _warn(res_warnings: list[str], text: str) -> None:
    res_warnings.append(text)
    warnings.warn(text, IdentifyWarning, stacklevel=3)


def _prepare(sig: Signals, sign: float) -> _Rec:
    if sig.actual_at == "end":           # the row's actual is the motor one cycle later
        X, S, Y, t = sig.actual[:-1], sig.command[1:], sig.sensor[1:], sig.t[1:]
    else:
        X, S, Y, t = sig.actual, sig.command, sig.sensor, sig.t
    return _Rec(sig=sig, X=np.asarray(X, float), S=np.asarray(S, float), Y=sign * np.asarray(Y, float), t=t)


def _delayed(x: np.ndarray, shift: float) -> np.ndarray:
    """x at the fractional index k - shift (linear interpolation; the first value before the start)."""
    idx = np.arange(x.size, dtype=float) - shift
    return np.interp(idx, np.arange(x.size, dtype=float), x)


def _drive_rows(recs: Sequence[_Rec], theta: float, T: float):
    """Regressor z = c(theta) - X, response dX and the previous dX of every recording, concatenated."""
    zs, ys, ps = [], [], []
    skip = int(math.ceil(MAX_DELAY / T)) + 2
    for r in recs:
        c = _delayed(r.S, theta / T)
        dX = np.diff(r.X)
        z = (c - r.X)[:-1]
        zs.append(z[skip:])
        ys.append(dX[skip:])
        ps.append(dX[skip - 1:-1])
    return np.concatenate(zs), np.concatenate(ys), np.concatenate(ps)


def _robust_alpha(z: np.ndarray, y: np.ndarray, scale: float | None = None) -> tuple[float, float, float]:
    """y = alpha z on the samples the linear loop explains: alpha first as the median of y/z over the
    moving samples (free of the leverage of the limited ones), then least squares on the samples
    within 4 scales. Returns alpha, the truncated-quadratic cost and the median |residual|."""
    mv = np.abs(z) > 1e-3
    if int(mv.sum()) < 10:
        return 0.0, math.inf, math.inf
    a0 = float(np.median(y[mv] / z[mv]))
    r = y - a0 * z
    med = float(np.median(np.abs(r[mv])))
    s = scale if scale is not None else max(1.4826 * med, 1e-7)
    inl = np.abs(r) <= 4.0 * s
    den = float(np.dot(z[inl], z[inl]))
    alpha = float(np.dot(z[inl], y[inl])) / den if den > 0 else a0
    q = ((y - alpha * z) / s) ** 2
    return alpha, float(np.sum(np.minimum(q, 16.0))), med


def _limits(recs, T: float, alpha: float, theta: float, scale: float):
    """v_max and a_max (None if never reached) from the samples where the P loop demands more than
    the motor does, and the number of such samples."""
    z, y, yp = _drive_rows(recs, theta, T)
    v, vp, vd = y / T, yp / T, alpha * z / T
    dv, dvd = v - vp, vd - vp
    sv = 3.0 * scale / T + 1e-9                     # velocity noise
    sat_v = (np.abs(vd) > 1.15 * np.abs(v) + 5 * sv) & (np.sign(vd) == np.sign(v)) & \
            (np.abs(dv) < 0.05 * np.abs(v) + 3 * sv) & (np.abs(v) > 10 * sv)
    sat_a = (np.abs(dvd) > 1.15 * np.abs(dv) + 5 * sv) & (np.sign(dvd) == np.sign(dv)) & \
            (np.abs(dv) > 10 * sv) & ~sat_v
    v_max = float(np.median(np.abs(v[sat_v]))) if int(sat_v.sum()) >= 3 else None
    a_max = float(np.percentile(np.abs(dv[sat_a]), 90)) / T if int(sat_a.sum()) >= 3 else None
    return v_max, a_max, int(sat_v.sum()), int(sat_a.sum())


def _limited_cost(recs, T: float, theta: float, scale: float, alpha: float, v_max, a_max) -> float:
    """The truncated quadratic cost of the one-step prediction with the limits (the measured previous
    velocity bounds the change): a limited start is explained, a motion before the command is not."""
    z, y, yp = _drive_rows(recs, theta, T)
    vhat = alpha * z / T
    if v_max is not None:
        vhat = np.clip(vhat, -v_max, v_max)
    if a_max is not None:
        vp = yp / T
        vhat = np.clip(vhat, vp - a_max * T, vp + a_max * T)
    q = ((y - vhat * T) / scale) ** 2
    return float(np.sum(np.minimum(q, 16.0)))


def _fit_drive(recs: Sequence[_Rec], T: float, res: Identification) -> dict:
    from scipy.optimize import minimize_scalar

    out = {"kv": None, "dead_time": None, "v_max": None, "a_max": None}
    moving = sum(float(np.ptp(r.S)) for r in recs)
    if moving <= 0.0:
        return out
    # pass 1: least median of the residual over the moving samples, on a grid of dead times
    coarse = np.arange(0.0, MAX_DELAY + 1e-12, T)
    med = np.array([_robust_alpha(*_drive_rows(recs, th, T)[:2])[2] for th in coarse])
    if not np.isfinite(med).any():
        _warn(res.warnings, f"kv and dead time: the axis hardly moves in these recordings; record {RECORD_STEPS}")
        return out
    scale = max(1.4826 * float(np.min(med)), 1e-7)
    res.extra["drive_equation_scale_mm"] = scale
    # pass 2: the linear loop's truncated quadratic cost: a first dead time, and the limits there
    costs = np.array([_robust_alpha(*_drive_rows(recs, th, T)[:2], scale)[1] for th in coarse])
    theta = float(coarse[int(np.argmin(costs))])
    alpha = _robust_alpha(*_drive_rows(recs, theta, T)[:2], scale)[0]
    grid = np.arange(0.0, MAX_DELAY + 1e-12, 0.25 * T)
    v_max, a_max, _, _ = _limits(recs, T, alpha, theta, scale)
    # pass 3: with the limits in the one-step prediction (an acceleration-limited start no longer
    # looks like a longer dead time), on the grid near the first dead time, then refined; the
    # smallest of equal costs (the per-cycle velocity of the model cannot tell a continuous start
    # within the cycle: the cost can be flat over a cycle)
    for _ in range(2):
        win = grid[np.abs(grid - theta) <= 8 * T + 1e-12]
        costs_w = np.array([_limited_cost(recs, T, th, scale, alpha, v_max, a_max) for th in win])
        i = int(np.flatnonzero(costs_w <= costs_w.min() * (1 + 1e-9))[0])
        theta = float(win[i])
        lo, hi = win[max(i - 1, 0)], win[min(i + 1, win.size - 1)]
        if hi > lo:
            opt = minimize_scalar(lambda th: _limited_cost(recs, T, th, scale, alpha, v_max, a_max),
                                  bounds=(lo, hi), method="bounded", options={"xatol": 0.005 * T})
            if opt.fun < costs_w[i] * (1 - 1e-9):
                theta = float(opt.x)
        alpha = _robust_alpha(*_drive_rows(recs, theta, T)[:2], scale)[0]
        best = _limited_cost(recs, T, theta, scale, alpha, v_max, a_max)
        v_max, a_max, n_v, n_a = _limits(recs, T, alpha, theta, scale)
    # identifiability of the dead time: the cost must rise 2-3 ms away from the optimum (a ramp
    # alone trades dead time against kv; steps or a chirp separate them)
    near = [_limited_cost(recs, T, th, scale, alpha, v_max, a_max) for th in (theta - 0.003, theta - 0.002,
                                                                               theta + 0.002, theta + 0.003)
            if 0.0 <= th <= MAX_DELAY]
    sharp = bool(near) and min(near) > 1.05 * best
    # and command transients well above the encoder's noise (a ramp's kink is not enough)
    jumps = sum(int(np.sum(np.abs(np.diff(r.S, 2)) > max(200.0 * scale, 1e-3))) for r in recs)
    res.extra["drive_command_transients"] = jumps
    sharp = sharp and jumps >= 3
    res.extra["drive_dead_time_cost_ratio"] = (min(near) / best) if near and best > 0 else None
    if not (0.0 < alpha < 1.0) or not sharp:
        _warn(res.warnings, "kv and dead time: not identifiable from these recordings (the command has no "
                            f"fast transients); record {RECORD_STEPS}")
        return out
    out["kv"], out["dead_time"] = -math.log1p(-alpha) / T, theta
    out["v_max"], out["a_max"] = v_max, a_max
    if v_max is None:
        _warn(res.warnings, "v_max: the velocity limit was not reached in these recordings; record "
                            f"{RECORD_LARGE_STEP}")
    if a_max is None:
        _warn(res.warnings, "a_max: the acceleration limit was not reached in these recordings; record "
                            f"{RECORD_LARGE_STEP} (or steps of 1-2 mm)")
    res.extra["drive_samples_velocity_limited"] = n_v
    res.extra["drive_samples_acceleration_limited"] = n_a
    return out


def simulate_drive(S: np.ndarray, x0: float, T: float, kv: float, dead_time: float, v_max: float | None,
                   a_max: float | None) -> np.ndarray:
    """The fitted drive on a command (the model of :func:`identify`, sampled): motor positions at the
    rows' times."""
    alpha = -math.expm1(-kv * T)
    kv_d = alpha / T
    c = _delayed(S, dead_time / T).tolist()
    vm = math.inf if v_max is None else v_max
    dvm = math.inf if a_max is None else a_max * T
    out = [0.0] * len(c)
    x = x0
    v = 0.0
    for k in range(len(c)):
        out[k] = x
        v = limit_velocity(kv_d * (c[k] - x), vm, v, dvm)     # the simulator's drive limits
        x += v * T
    return np.array(out)


def _mode(f: np.ndarray, f0: float, zeta: float) -> np.ndarray:
    """Motor -> nozzle: (w0^2 + 2 zeta w0 s) / (s^2 + 2 zeta w0 s + w0^2) at s = j 2 pi f."""
    s = 2j * np.pi * f
    w0 = 2.0 * np.pi * f0
    return (w0 * w0 + 2 * zeta * w0 * s) / (s * s + 2 * zeta * w0 * s + w0 * w0)


def _frf(recs: Sequence[_Rec], T: float):
    from scipy.signal import csd, welch

    fs = 1.0 / T
    lengths = [r.X.size for r in recs]
    nper = NPERSEG if max(lengths) >= 2 * NPERSEG else max(256, 2 ** int(math.log2(max(lengths) // 2)))
    Pxx = Pyy = Pxy = None
    f = None
    for r in recs:
        if r.X.size < nper:
            continue
        kw = dict(fs=fs, nperseg=nper, detrend="linear")
        f, pxx = welch(r.X, **kw)
        _, pyy = welch(r.Y, **kw)
        _, pxy = csd(r.X, r.Y, **kw)
        w = r.X.size / nper
        Pxx = pxx * w if Pxx is None else Pxx + pxx * w
        Pyy = pyy * w if Pyy is None else Pyy + pyy * w
        Pxy = pxy * w if Pxy is None else Pxy + pxy * w
    if f is None:
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        H = Pxy / Pxx
        coh = np.abs(Pxy) ** 2 / (Pxx * Pyy)
    return f, H, np.nan_to_num(coh), nper


def _fit_frf(f, H, coh, T: float, res: Identification) -> dict:
    from scipy.optimize import least_squares

    out = {"resonance_hz": None, "damping": None, "delay": None, "gain": None}
    df = f[1] - f[0]
    sel = (f > 1.5 * df) & (f <= 0.45 / T) & (coh >= 0.6) & np.isfinite(H)
    if int(sel.sum()) < 8:
        _warn(res.warnings, "sensor delay and resonance: the motor -> sensor response is not coherent at any "
                            f"frequency; record {RECORD_CHIRP}")
        return out
    fs_, Hs, cs = f[sel], H[sel], np.clip(coh[sel], 0.0, 0.999)
    w = np.sqrt(cs / (1.0 - cs))
    f_hi = float(fs_.max())
    out["band_hz"] = [float(fs_.min()), f_hi]
    mag = np.abs(Hs)
    g0 = float(np.median(mag[: max(3, mag.size // 10)]))
    low = fs_ <= min(30.0, max(fs_[2], 0.3 * f_hi))
    ph = np.unwrap(np.angle(Hs / np.sign(g0 or 1.0)))
    tau0 = float(-np.polyfit(fs_[low], ph[low], 1)[0] / (2 * np.pi)) if int(low.sum()) >= 3 else 0.0
    tau0 = min(max(tau0, 0.0), MAX_DELAY)

    def resid(model):
        r = w * (model / Hs - 1.0)
        return np.concatenate([r.real, r.imag])

    def rigid(p):
        return resid(p[0] * np.exp(-2j * np.pi * fs_ * p[1]))

    fr = least_squares(rigid, [g0, tau0], bounds=([-np.inf, -0.005], [np.inf, MAX_DELAY]), x_scale=[abs(g0) or 1.0, T])
    best = {"cost": float(fr.cost), "g": float(fr.x[0]), "tau": float(fr.x[1]), "f0": None, "zeta": None, "x": fr}
    ratio = mag / abs(g0) if g0 else mag
    ipk = int(np.argmax(ratio))
    if ratio[ipk] > 1.3 and 0 < ipk < fs_.size - 1:
        f00 = float(fs_[ipk])

        def resonant(p):
            return resid(p[0] * _mode(fs_, math.exp(p[2]), math.exp(p[3])) * np.exp(-2j * np.pi * fs_ * p[1]))

        starts = [(f00, min(max(0.5 / ratio[ipk], 0.01), 0.5)), (f00, 0.1), (f00, 0.3)]
        for f_init, z_init in starts:
            try:
                fm = least_squares(resonant, [g0, fr.x[1], math.log(f_init), math.log(z_init)],
                                   bounds=([-np.inf, -0.005, math.log(fs_.min()), math.log(0.003)],
                                           [np.inf, MAX_DELAY, math.log(0.5 / T), math.log(1.0)]),
                                   x_scale=[abs(g0) or 1.0, T, 0.1, 0.3])
            except ValueError:
                continue
            if fm.cost < best["cost"]:
                best = {"cost": float(fm.cost), "g": float(fm.x[0]), "tau": float(fm.x[1]),
                        "f0": math.exp(fm.x[2]), "zeta": math.exp(fm.x[3]), "x": fm}
    rigid_cost = float(fr.cost)
    f0 = best["f0"]
    accepted = (f0 is not None and best["cost"] < 0.5 * rigid_cost and int((fs_ > 1.2 * f0).sum()) >= 3
                and int((fs_ < 0.8 * f0).sum()) >= 3)
    if not accepted:
        best = {"cost": rigid_cost, "g": float(fr.x[0]), "tau": float(fr.x[1]), "f0": None, "zeta": None, "x": fr}
        if f_hi < 100.0:
            _warn(res.warnings, f"resonance_hz, damping: the recordings excite the axis coherently only up to "
                                f"{f_hi:.0f} Hz and show no resonance there; record {RECORD_CHIRP}")
        else:
            _warn(res.warnings, f"resonance_hz, damping: no resonance between motor and nozzle up to {f_hi:.0f} Hz "
                                "(a rigid drive fits: the scenario keeps resonance_hz = 0)")
    # the delay's uncertainty from the Jacobian
    J = best["x"].jac
    try:
        cov = np.linalg.pinv(J.T @ J) * (2 * best["cost"] / max(J.shape[0] - J.shape[1], 1))
        tau_sd = float(math.sqrt(max(cov[1, 1], 0.0)))
    except (np.linalg.LinAlgError, ValueError):
        tau_sd = math.inf
    if tau_sd <= 0.3e-3:
        out["delay"] = max(best["tau"], 0.0)
    else:
        _warn(res.warnings, f"sensor delay: uncertain by {tau_sd * 1e3:.2g} ms with this excitation; record "
                            f"{RECORD_CHIRP}")
    out.update(resonance_hz=best["f0"], damping=best["zeta"], gain=best["g"])
    model = best["g"] * np.exp(-2j * np.pi * fs_ * best["tau"])
    if best["f0"] is not None:
        model = model * _mode(fs_, best["f0"], best["zeta"])
    err = np.linalg.norm(w * (model - Hs)) / max(np.linalg.norm(w * Hs), 1e-300)
    out["frf_fit_percent"] = float(100.0 * (1.0 - err))
    out["delay_sd"] = tau_sd
    out["_model"] = (best["g"], best["tau"], best["f0"], best["zeta"])
    out["_points"] = (fs_, Hs, cs)
    return out


def nozzle_from_motor(X: np.ndarray, T: float, f0: float | None, zeta: float | None) -> np.ndarray:
    """The nozzle the fitted mode makes of the motor positions (continuous model, bilinear)."""
    if not f0:
        return X.copy()
    from scipy.signal import cont2discrete, lfilter

    w0 = 2 * math.pi * f0
    num, den = [2 * zeta * w0, w0 * w0], [1.0, 2 * zeta * w0, w0 * w0]
    b, a, _ = cont2discrete((num, den), T, method="bilinear")
    b = np.ravel(b)
    from scipy.signal import lfilter_zi

    zi = lfilter_zi(b, a) * X[0]
    return lfilter(b, a, X, zi=zi)[0]


def _quasi_static(r: _Rec, T: float, settle: float) -> np.ndarray:
    """Samples where the nozzle equals the motor: slow motor, and no command acceleration for
    ``settle`` seconds before (a slow ramp, a settled hold)."""
    acc = np.zeros_like(r.S)
    acc[1:-1] = np.abs(np.diff(r.S, 2)) / (T * T)
    dyn = (acc > QS_ACCELERATION).astype(np.int64)
    n = int(round(settle / T))
    cs = np.concatenate([[0], np.cumsum(dyn)])
    k = np.arange(r.S.size)
    recent = cs[k + 1] - cs[np.maximum(k + 1 - n, 0)]
    v = np.zeros_like(r.X)
    v[1:] = np.abs(np.diff(r.X)) / T
    ok = (recent == 0) & (v <= QS_VELOCITY) & (k >= n)
    return ok


def _characteristic(recs: Sequence[_Rec], T: float, delay: float, settle: float, surface: float | None,
                    calibrated_at: float | None, gain: float | None, res: Identification) -> dict:
    xs, ys = [], []
    for r in recs:
        ok = _quasi_static(r, T, settle)
        Xd = _delayed(r.X, delay / T)
        xs.append(Xd[ok])
        ys.append(r.Y[ok])
    x, y = np.concatenate(xs), np.concatenate(ys)
    out = {"characteristic": None, "noise_std": None, "quasi_static_samples": int(x.size)}
    if x.size < 200:
        _warn(res.warnings, f"noise_std and characteristic: too few quasi-static samples ({x.size}); record "
                            f"{RECORD_STANDSTILL} and {RECORD_RAMP}")
        return out
    edges = np.arange(math.floor(x.min() / CHAR_BIN) * CHAR_BIN, x.max() + CHAR_BIN, CHAR_BIN)
    which = np.digitize(x, edges)
    pts, resid, slopes = [], [], []
    for b in np.unique(which):
        m = which == b
        if int(m.sum()) < 30:
            continue
        xb, yb = x[m], y[m]
        span = float(np.ptp(xb))
        if span >= 0.2 * CHAR_BIN:
            c = 0.5 * (edges[b - 1] + edges[b]) if 0 < b < edges.size else float(np.mean(xb))
            c = min(max(c, float(xb.min())), float(xb.max()))
            p = np.polyfit(xb - c, yb, 1)
            pts.append((c, float(p[1])))
            slopes.append(float(p[0]))
            resid.append(yb - np.polyval(p, xb - c))
        else:
            pts.append((float(np.mean(xb)), float(np.mean(yb))))
            resid.append(yb - np.mean(yb))
    if resid:
        rr = np.concatenate(resid)
        std = float(np.sqrt(np.mean(rr * rr)))
        g = abs(gain) if gain else (abs(float(np.median(slopes))) if slopes else 1.0)
        out["noise_std"] = std / (g or 1.0)
        out["noise_samples"] = int(rr.size)
    pts.sort()
    out["points_motor"] = pts
    if not pts:
        return out
    px = np.array([p[0] for p in pts])
    py = np.array([p[1] for p in pts])
    if surface is None and calibrated_at is None:
        _warn(res.warnings, "characteristic: the zero of the true distance is unknown; give the surface height "
                            "in the motor encoder's coordinates (--surface Z: the actual position where the nozzle "
                            "touches the sheet) or the distance where the sensor reads true (--calibrated-at D)")
        return out
    if surface is None:
        if not (py.min() <= calibrated_at <= py.max()) or px.size < 2 or np.any(np.diff(py) <= 0):
            _warn(res.warnings, f"characteristic: the sensor never read {calibrated_at:g} mm on a monotonic part "
                                f"of the recordings; record {RECORD_RAMP}")
            return out
        surface = float(np.interp(calibrated_at, py, px)) - calibrated_at
    true = px - surface
    if px.size < 2 or float(np.ptp(true)) < 0.5:
        _warn(res.warnings, f"characteristic: the recordings cover only {float(np.ptp(true)):.2f} mm of distance "
                            f"quasi-statically; record {RECORD_RAMP}")
        return out
    out["characteristic"] = [[round(float(a), 6), round(float(b), 6)] for a, b in zip(true, py)]
    out["surface"] = surface
    return out


def _sign(recs: Sequence[_Rec]) -> float:
    cov = 0.0
    for r in recs:
        cov += float(np.dot(r.X - r.X.mean(), r.sig.sensor[-r.X.size:] - r.sig.sensor[-r.X.size:].mean()))
    return -1.0 if cov < 0.0 else 1.0


def identify(signals: Sequence[Signals], *, sensor_sign: float | None = None, surface: float | None = None,
             calibrated_at: float | None = None) -> Identification:
    """Fit the drive and the sensor to the recordings (see the module docstring).

    ``sensor_sign``: +1 if the sensor reads nozzle - surface (a distance), -1 if surface - nozzle
    (encoder 2, s = -d); None: detected from the correlation with the motor. ``surface``: the
    surface height in the actual column's coordinates (fixes the zero of the true distance for the
    characteristic); ``calibrated_at``: instead, the distance (mm) at which the sensor reads true.
    """
    if not signals:
        raise IdentifyError("no recording given")
    T = signals[0].cycle_time
    for s in signals[1:]:
        if abs(s.cycle_time - T) > 0.01 * T:
            raise IdentifyError(f"{s.path}: cycle {s.cycle_time * 1e3:.6g} ms, {signals[0].path}: {T * 1e3:.6g} ms; "
                                "record every file at the same (interpolation) cycle")
    moving = [s for s in signals if np.ptp(s.command) > 0.0]
    if not moving:
        raise IdentifyError("excitation too poor: the command does not move in any recording; record "
                            f"{RECORD_STEPS}, {RECORD_CHIRP} and {RECORD_RAMP} (docs/identify.md)")
    res = Identification(cycle_time=T, drive={k: None for k in DRIVE_KEYS}, sensor={k: None for k in SENSOR_KEYS})
    recs0 = [_prepare(s, 1.0) for s in signals]
    sign = _sign(recs0) if sensor_sign is None else float(sensor_sign)
    recs = [_prepare(s, sign) for s in signals]
    res.extra["sensor_sign"] = sign
    res.extra["sensor_reads"] = "nozzle - surface (distance)" if sign > 0 else "surface - nozzle (encoder 2)"
    # drive
    drive = _fit_drive(recs, T, res)
    res.drive.update(drive)
    if all(drive[k] is None for k in ("kv", "v_max", "a_max")) and np.ptp(np.concatenate([r.S for r in recs])) < 1e-3:
        raise IdentifyError("excitation too poor: the command moves less than 1 um; record "
                            f"{RECORD_STEPS}, {RECORD_CHIRP} and {RECORD_RAMP}")
    # sensor path: frequency response motor -> sensor
    frf = _frf(recs, T)
    fr = _fit_frf(*frf[:3], T, res) if frf is not None else {"resonance_hz": None, "damping": None, "delay": None,
                                                             "gain": None}
    if frf is None:
        _warn(res.warnings, f"sensor delay and resonance: recordings too short for a frequency response; record "
                            f"{RECORD_CHIRP}")
    res.drive["resonance_hz"] = fr.get("resonance_hz")
    res.drive["damping"] = fr.get("damping")
    res.sensor["delay"] = fr.get("delay")
    # quasi-static: characteristic and noise
    settle = 0.3
    if res.drive["kv"]:
        settle = max(settle, 5.0 / res.drive["kv"])
    if res.drive["resonance_hz"]:
        settle = max(settle, 5.0 / (2 * math.pi * res.drive["resonance_hz"] * res.drive["damping"]))
    settle = min(settle, 2.0)
    delay = res.sensor["delay"] if res.sensor["delay"] is not None else (fr.get("_model") or (0, 0))[1]
    ch = _characteristic(recs, T, delay or 0.0, settle, surface, calibrated_at, fr.get("gain"), res)
    res.sensor["noise_std"] = ch["noise_std"]
    res.sensor["characteristic"] = ch["characteristic"]
    if ch["noise_std"] is None and not any("noise_std" in w for w in res.warnings):
        _warn(res.warnings, f"noise_std: no quasi-static samples; record {RECORD_STANDSTILL}")
    res.extra.update({"sensor_gain": fr.get("gain"), "surface_mm": ch.get("surface"),
                      "frequency_band_hz": fr.get("band_hz"), "sensor_delay_sd_s": fr.get("delay_sd"),
                      "quasi_static_samples": ch.get("quasi_static_samples"), "settle_s": settle,
                      "noise_samples": ch.get("noise_samples")})
    _fit_quality(recs, T, res, fr, ch)
    res.recordings = [{"path": s.path, "source": s.source, "samples": int(s.t.size), "duration_s": s.duration,
                       "columns": {"command": s.columns[0], "actual": s.columns[1], "sensor": s.columns[2]},
                       "actual_sampled_at": s.actual_at, "cycle_time_s": s.cycle_time} for s in signals]
    res.curves["recs"] = recs
    res.curves["frf"] = frf
    res.curves["frf_fit"] = fr
    res.curves["char_points"] = ch.get("points_motor")
    return res


def _fit_quality(recs, T, res: Identification, fr: dict, ch: dict) -> None:
    d = res.drive
    fit = res.fit
    sims = []
    if d["kv"] is not None:
        errs, fits = [], []
        for r in recs:
            xh = simulate_drive(r.S, float(r.X[0]), T, d["kv"], d["dead_time"], d["v_max"], d["a_max"])
            e = r.X - xh
            errs.append(float(np.sqrt(np.mean(e * e))))
            den = float(np.linalg.norm(r.X - r.X.mean()))
            fits.append(float(100.0 * (1.0 - np.linalg.norm(e) / den)) if den > 0 else None)
            sims.append(xh)
        fit["drive_rms_mm"] = errs
        fit["drive_fit_percent"] = fits
    res.curves["drive_sim"] = sims
    fit["frf_fit_percent"] = fr.get("frf_fit_percent")
    model = fr.get("_model")
    preds = []
    if model is not None:
        g, tau, f0, zeta = model
        errs = []
        for r in recs:
            n = nozzle_from_motor(r.X, T, f0, zeta)
            nd = _delayed(n, max(tau, 0.0) / T)
            pts = ch.get("points_motor")
            if ch.get("characteristic") is not None and pts:
                yh = np.interp(nd, [p[0] for p in pts], [p[1] for p in pts])
            else:
                yh = g * nd
                yh = yh + float(np.median(r.Y - yh))
            preds.append(yh)
            e = r.Y - yh
            errs.append(float(np.sqrt(np.mean(e * e))))
        fit["sensor_rms_mm"] = errs
    res.curves["sensor_pred"] = preds


# ------------------------------------------------------------------------------------------------------
# output: JSON, summary, scenario TOML, report
# ------------------------------------------------------------------------------------------------------
UNITS = {"kv": "1/s", "dead_time": "s", "v_max": "mm/s", "a_max": "mm/s^2", "resonance_hz": "Hz", "damping": "-",
         "delay": "s", "noise_std": "mm", "characteristic": "[[true mm, reported mm], ...]"}


def result_json(res: Identification, scenario: str | None = None, report: str | None = None) -> dict:
    """The ``--json`` object: ``drive`` and ``sensor`` with exactly the keys of issue 15, the rest
    under other keys."""
    return {"drive": {k: res.drive.get(k) for k in DRIVE_KEYS},
            "sensor": {k: res.sensor.get(k) for k in SENSOR_KEYS},
            "units": UNITS, "cycle_time_s": res.cycle_time, "fit": res.fit, "details": res.extra,
            "recordings": res.recordings, "warnings": list(res.warnings), "scenario": scenario, "report": report}


def _fmt(v, scale=1.0, spec=".4g", unit=""):
    return "-" if v is None else f"{v * scale:{spec}} {unit}".rstrip()


def format_summary(res: Identification) -> str:
    d, s = res.drive, res.sensor
    ch = s["characteristic"]
    lines = [f"identified at cycle {res.cycle_time * 1e3:g} ms from {len(res.recordings)} recording(s)",
             "drive:",
             f"  kv            {_fmt(d['kv'], unit='1/s')}",
             f"  dead time     {_fmt(d['dead_time'], 1e3, '.3g', 'ms')}",
             f"  v_max         {_fmt(d['v_max'], unit='mm/s')}",
             f"  a_max         {_fmt(d['a_max'], unit='mm/s^2')}",
             f"  resonance     {_fmt(d['resonance_hz'], unit='Hz')}",
             f"  damping       {_fmt(d['damping'], spec='.3g')}",
             "sensor:" + f" ({res.extra.get('sensor_reads', '')})",
             f"  delay         {_fmt(s['delay'], 1e3, '.3g', 'ms')}",
             f"  noise std     {_fmt(s['noise_std'], 1e3, '.3g', 'um')}",
             "  characteristic " + ("-" if ch is None else
                                    f"{len(ch)} points, true {ch[0][0]:.3f} .. {ch[-1][0]:.3f} mm, "
                                    f"reported - true {min(b - a for a, b in ch) * 1e3:+.1f} .. "
                                    f"{max(b - a for a, b in ch) * 1e3:+.1f} um"),
             "fit quality:"]
    f = res.fit
    if f.get("drive_fit_percent"):
        lines.append("  drive (actual, simulated from the command): " + ", ".join(
            f"{_fmt(p, spec='.1f', unit='%')} (RMS {_fmt(e, 1e3, '.3g', 'um')})"
            for p, e in zip(f["drive_fit_percent"], f["drive_rms_mm"])))
    if f.get("frf_fit_percent") is not None:
        band = res.extra.get("frequency_band_hz") or [math.nan, math.nan]
        lines.append(f"  motor -> sensor frequency response: {f['frf_fit_percent']:.1f} % "
                     f"(coherent {band[0]:.1f} .. {band[1]:.1f} Hz)")
    if f.get("sensor_rms_mm"):
        lines.append("  sensor (predicted from the actual): RMS " + ", ".join(
            _fmt(e, 1e3, ".3g", "um") for e in f["sensor_rms_mm"]))
    return "\n".join(lines) + "\n"


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise IdentifyError(f"cannot write {v!r} to TOML")
        return repr(v)
    if isinstance(v, str):
        if "\n" in v:
            return '"""\n' + v.replace("\\", "\\\\").replace('"""', '\\"\\"\\"') + '"""'
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise IdentifyError(f"cannot write {type(v).__name__} to TOML")


def _toml_key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else _toml_value(k)


def toml_text(doc: dict, comments: dict | None = None) -> str:
    """A TOML document of the scenario subset: plain keys, tables, tables of tables, arrays of tables."""
    comments = comments or {}
    out: list[str] = []

    def table(prefix: str, d: dict) -> None:
        plain = {k: v for k, v in d.items() if not isinstance(v, dict) and not _is_table_array(v)}
        if prefix and (plain or not d):
            out.append(f"\n[{prefix}]")
        for k, v in plain.items():
            c = comments.get(f"{prefix}.{k}" if prefix else k)
            out.append(f"{_toml_key(k)} = {_toml_value(v)}" + (f"    # {c}" if c else ""))
        for k, v in d.items():
            if isinstance(v, dict):
                table(f"{prefix}.{_toml_key(k)}" if prefix else _toml_key(k), v)
            elif _is_table_array(v):
                for item in v:
                    out.append(f"\n[[{prefix + '.' if prefix else ''}{_toml_key(k)}]]")
                    for kk, vv in item.items():
                        out.append(f"{_toml_key(kk)} = {_toml_value(vv)}")
    table("", doc)
    return "\n".join(out).lstrip("\n") + "\n"


def _is_table_array(v) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


DEFAULT_PROGRAM = """%IDENTIFIED
; the fitted plant: CONST_DIST 1 mm over a sheet with a 0.5 mm step at X 150
N10 G90 G0 X0 Y0 Z{z0:g}
N20 Z[DIST_CTRL ON CONST_DIST SET_DIST=1 SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]
N30 G1 X300 F6000
N40 Z[DIST_CTRL OFF]
N50 G0 Z{z1:g}
N60 M30
"""

DEFAULT_LIST = """# Z axis: distance control on, a distance sensor as a V.E. variable (written by distctrl identify;
# tune kp, d_tv and the filter with distctrl tune/step/margins on the fitted plant)
lr_param.distance_control_on        1
kenngr.distc.max_deviation          80000     # [0.1 um] 8 mm
kenngr.distc.v_max                  100000    # [um/s] 100 mm/s
kenngr.distc.a_max                  10000     # [mm/s^2]
kenngr.distc.max_act_value_change   10000000  # [um/s]
kenngr.distc.max_pos                100000    # [0.1 um] +10 mm
kenngr.distc.min_pos                -100000   # [0.1 um] -10 mm
kenngr.distc.filter_type            MOVING_AVERAGE
kenngr.distc.n_cycles               4
kenngr.distc.kp                     0.05      # conservative: tune it on the fitted plant
"""


def fitted_axis(res: Identification) -> tuple[dict, list[str]]:
    """The scenario's axis keys of the fitted drive (only the identified ones) and notes."""
    T = res.cycle_time
    d = res.drive
    keys: dict = {}
    notes: list[str] = []
    if d["kv"] is not None:
        # the simulator's drive integrates x += kv (c - x) T: the same pole as the continuous kv
        keys["kv"] = float(-math.expm1(-d["kv"] * T) / T)
        keys["bus_delay_cycles"] = int(round(d["dead_time"] / T))
    if d["v_max"] is not None:
        keys["v_max"] = float(d["v_max"])
    if d["a_max"] is not None:
        keys["a_max"] = float(d["a_max"])
    if d["resonance_hz"] is not None:
        if d["resonance_hz"] <= 1.0 / (4.0 * T):
            keys["resonance_hz"] = float(d["resonance_hz"])
            keys["damping"] = float(min(max(d["damping"], 1e-4), 1.0))
        else:
            notes.append(f"resonance {d['resonance_hz']:.1f} Hz above 1/(4T) = {0.25 / T:g} Hz: not written")
    return keys, notes


def fitted_sensor(res: Identification, range_max: float = 10.0) -> dict:
    """The scenario's sensor keys of the fitted sensor."""
    T = res.cycle_time
    s = res.sensor
    keys: dict = {}
    if s["delay"] is not None:
        keys["delay_cycles"] = int(round(s["delay"] / T))
    if s["noise_std"] is not None:
        keys["noise_std"] = float(s["noise_std"])
    ch = s["characteristic"]
    if ch is not None and len(ch) >= 2:
        pts = [list(p) for p in ch if 0.0 < p[0] < range_max]
        if len(pts) >= 2:
            # extended linearly from the end segments to 0 and range_max: the simulator holds the
            # end values beyond the table
            (x0, y0), (x1, y1) = pts[0], pts[1]
            (xa, ya), (xb, yb) = pts[-2], pts[-1]
            head = [[0.0, round(y0 - x0 * (y1 - y0) / (x1 - x0), 6)]]
            tail = [[float(range_max), round(yb + (range_max - xb) * (yb - ya) / (xb - xa), 6)]]
            keys["characteristic"] = head + pts + tail
    return keys


def _absolute_paths(doc: dict, base: Path) -> None:
    def fix(d: dict, key: str) -> None:
        v = d.get(key)
        if isinstance(v, str) and v and not os.path.isabs(v):
            d[key] = str((base / v).resolve())
    fix(doc, "program")
    for ax in (doc.get("axes") or {}).values():
        if isinstance(ax, dict):
            fix(ax, "params")
    if isinstance(doc.get("channel"), dict):
        fix(doc["channel"], "params")
    for feat in ((doc.get("surface") or {}).get("features") or []):
        if isinstance(feat, dict):
            fix(feat, "file")


def write_scenario(res: Identification, out_dir: str | os.PathLike, template: str | os.PathLike | None = None,
                   axis: str = "Z", name: str = "fitted.toml") -> tuple[Path, list[str]]:
    """The fitted machine and sensor as a complete scenario TOML in ``out_dir`` (with its parameter
    list when no template is given). Returns the path and notes (what was not written)."""
    import tomllib

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    axis_keys, notes = fitted_axis(res)
    if template is not None:
        tp = Path(template)
        try:
            doc = tomllib.loads(tp.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError) as exc:
            raise IdentifyError(f"--template {tp}: cannot read: {getattr(exc, 'strerror', None) or exc}") from None
        except tomllib.TOMLDecodeError as exc:
            raise IdentifyError(f"--template {tp}: not valid TOML: {exc}") from None
        _absolute_paths(doc, tp.resolve().parent)
        sensor = doc.get("sensor")
        if not isinstance(sensor, dict):
            raise IdentifyError(f"--template {tp}: no [sensor] table; the template must have a sensor")
        axis = sensor.get("axis", axis)
        axes = doc.setdefault("axes", {})
        if axis not in axes:
            raise IdentifyError(f"--template {tp}: no [axes.{axis}] (the sensor's axis)")
        doc["name"] = f"{doc.get('name', tp.stem)} (plant fitted by distctrl identify)"
    else:
        z0 = 31.5
        doc = {"name": "Plant fitted by distctrl identify: CONST_DIST 1 mm over a sheet with a 0.5 mm step",
               "cycle_time": float(f"{res.cycle_time:.9g}"), "duration": 5.0,
               "program_text": DEFAULT_PROGRAM.format(z0=z0, z1=z0 + 8.5),
               "axes": {"X": {"start": 0.0, "v_max": 500.0, "a_max": 5000.0}, "Y": {"start": 0.0},
                        axis: {"params": "z_axis.lis", "start": z0}},
               "surface": {"base": 30.0, "features": [{"type": "step", "axis": "X", "at": 150.0, "height": 0.5}]},
               "sensor": {"axis": axis, "kind": "distance", "variable": "SENSOR", "range_max": 10.0, "seed": 1}}
        (out / "z_axis.lis").write_text(DEFAULT_LIST, encoding="utf-8")
        sensor = doc["sensor"]
    if abs(float(doc.get("cycle_time", 0.001)) - res.cycle_time) > 1e-3 * res.cycle_time:
        notes.append(f"the template's cycle_time {doc.get('cycle_time', 0.001)} s differs from the recordings' "
                     f"{res.cycle_time:g} s: cycle_time set to the recordings'")
        doc["cycle_time"] = float(f"{res.cycle_time:.9g}")
    doc["axes"][axis].update(axis_keys)
    skeys = fitted_sensor(res, float(sensor.get("range_max", 10.0)))
    if sensor.get("kind") == "encoder" and "characteristic" in skeys:
        skeys.pop("characteristic")
        notes.append("characteristic not written: the template's sensor is an encoder-2 probe (linear)")
    sensor.update(skeys)
    comments = {f"axes.{axis}.kv": f"1/s (identified {res.drive['kv']:.4g} 1/s continuous; the same pole per cycle)"
                if res.drive["kv"] is not None else None,
                f"axes.{axis}.bus_delay_cycles": f"dead time {res.drive['dead_time'] * 1e3:.3g} ms"
                if res.drive["dead_time"] is not None else None,
                "sensor.delay_cycles": f"delay {res.sensor['delay'] * 1e3:.3g} ms" if res.sensor["delay"] is not None
                else None}
    path = out / name
    head = (f"# written by distctrl identify from {', '.join(Path(r['path']).name for r in res.recordings)}\n"
            "# keys not identified keep the template's values (or the defaults, docs/scenarios.md)\n")
    path.write_text(head + toml_text(doc, comments), encoding="utf-8")
    return path, notes


def plot_identification(res: Identification, path: str | os.PathLike) -> None:
    """Measured vs fitted: per recording the actual and the sensor in time, the motor -> sensor
    frequency response (magnitude, phase) and the characteristic."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    recs = res.curves.get("recs") or []
    sims = res.curves.get("drive_sim") or []
    preds = res.curves.get("sensor_pred") or []
    rows = len(recs) + 1
    fig, axes = plt.subplots(rows, 2, figsize=(13, 3.0 * rows), squeeze=False)
    for i, r in enumerate(recs):
        ax = axes[i][0]
        ax.plot(r.t, r.X, lw=0.8, label="actual (measured)")
        if i < len(sims):
            ax.plot(r.t, sims[i], lw=0.8, ls="--", label="drive model")
        ax.plot(r.t, r.S, lw=0.5, alpha=0.5, label="command")
        ax.set_title(f"{Path(r.sig.path).name}: motor", fontsize=9)
        ax.set_ylabel("mm")
        ax.legend(fontsize=7, loc="best")
        ax = axes[i][1]
        ax.plot(r.t, r.Y, lw=0.6, label="sensor (measured)")
        if i < len(preds):
            ax.plot(r.t, preds[i], lw=0.8, ls="--", label="sensor model")
        ax.set_title(f"{Path(r.sig.path).name}: sensor (sign {res.extra.get('sensor_sign', 1):+.0f})", fontsize=9)
        ax.set_ylabel("mm")
        ax.legend(fontsize=7, loc="best")
    ax_m, ax_c = axes[-1][0], axes[-1][1]
    fr = res.curves.get("frf_fit") or {}
    if fr.get("_points") is not None:
        f, H, _ = fr["_points"]
        g, tau, f0, zeta = fr["_model"]
        ff = np.linspace(f.min(), f.max(), 600)
        G = g * np.exp(-2j * np.pi * ff * tau) * (_mode(ff, f0, zeta) if f0 else 1.0)
        ax_m.semilogx(f, 20 * np.log10(np.abs(H)), ".", ms=3, label="|H| measured (coherent)")
        ax_m.semilogx(ff, 20 * np.log10(np.abs(G)), "-", lw=1, label="|H| model")
        ax_p = ax_m.twinx()
        ax_p.semilogx(f, np.degrees(np.unwrap(np.angle(H))), ".", ms=2, color="tab:green", label="phase measured")
        ax_p.semilogx(ff, np.degrees(np.unwrap(np.angle(G))), "-", lw=0.8, color="tab:red", label="phase model")
        ax_p.set_ylabel("phase [deg]")
        ax_m.set_xlabel("Hz")
        ax_m.set_ylabel("dB")
        ax_m.legend(fontsize=7, loc="lower left")
        ax_p.legend(fontsize=7, loc="upper right")
    ax_m.set_title("frequency response motor -> sensor", fontsize=9)
    ch = res.sensor.get("characteristic")
    if ch:
        a = np.array(ch)
        ax_c.plot(a[:, 0], (a[:, 1] - a[:, 0]) * 1e3, "o-", ms=3)
        ax_c.set_xlabel("true distance [mm]")
        ax_c.set_ylabel("reported - true [um]")
    else:
        ax_c.text(0.5, 0.5, "characteristic not identified", ha="center", va="center", transform=ax_c.transAxes)
    ax_c.set_title("sensor characteristic", fontsize=9)
    for row in axes[:-1]:
        for ax in row:
            ax.set_xlabel("s")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def write_report(res: Identification, out_dir: str | os.PathLike, scenario: str | None = None) -> Path:
    """``report.html`` (the figure embedded, the values with units, the fit quality, the warnings)
    and ``identify.png`` in ``out_dir``."""
    import base64
    import html

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    png = out / "identify.png"
    plot_identification(res, png)
    img = base64.b64encode(png.read_bytes()).decode("ascii")
    j = result_json(res, scenario=scenario)
    rows = "".join(f"<tr><td>drive.{k}</td><td>{html.escape(str(v))}</td><td>{html.escape(UNITS[k])}</td></tr>"
                   for k, v in j["drive"].items())
    rows += "".join(f"<tr><td>sensor.{k}</td><td>{html.escape(str(v))}</td><td>{html.escape(UNITS[k])}</td></tr>"
                    for k, v in j["sensor"].items())
    warn = "".join(f"<li>{html.escape(w)}</li>" for w in res.warnings) or "<li>none</li>"
    page = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>distctrl identify</title>
<style>body{{font-family:sans-serif;margin:2em}} td,th{{border:1px solid #ccc;padding:2px 6px}}
table{{border-collapse:collapse}} pre{{background:#f6f6f6;padding:1em}}</style></head><body>
<h1>distctrl identify</h1>
<p>Recordings: {html.escape(', '.join(r['path'] for r in res.recordings))}; cycle {res.cycle_time * 1e3:g} ms.
Scenario: {html.escape(str(scenario or '-'))}</p>
<h2>Identified plant</h2><table><tr><th>figure</th><th>value</th><th>unit</th></tr>{rows}</table>
<h2>Fit quality</h2><pre>{html.escape(format_summary(res))}</pre>
<h2>Warnings</h2><ul>{warn}</ul>
<h2>Measured vs fitted</h2><img alt="measured vs fitted" src="data:image/png;base64,{img}" style="max-width:100%">
</body></html>
"""
    page_path = out / "report.html"
    page_path.write_text(page, encoding="utf-8")
    return page_path
