"""Filter workbench: compare sensor-filter configurations on a recorded or synthetic signal.

The documents (FCT-M3 ch. 4, Figs. 9-17) show the filters on one test: a sensor crosses an
obstacle about 2.8 mm high with distance control disabled, and the raw and filtered sensor data are
overlaid. This module reproduces that test offline for any set of :class:`FilterConfig`:

* :func:`parse_filter_spec` turns the CLI text ``MOVING_AVERAGE:n_cycles=10,20,40`` into configs,
* :func:`obstacle_signal` is the documents' synthetic test signal (seeded noise),
* :func:`load_recording` reads a sensor recording (plain CSV or a distctrl trace CSV),
* :func:`compare` runs every filter (:meth:`SensorFilter.apply`, the cycle core's own law) and
  measures noise RMS, delay (50 %), dead time (10 %) and overshoot,
* :func:`format_table` and :func:`plot_overlay` present the result (docs/workbench-filters.md).

Nothing here touches the cycle path; errors are :class:`WorkbenchError` (a ``DistCtrlError``)
whose messages name the spec, file, line or column and what is allowed.
"""
from __future__ import annotations

import csv
import difflib
import io
import itertools
import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..base.kinds import FILTER_TYPE_NAMES, FilterType
from ..control.filters import FILTER_KINDS, FILTER_PARAMS, FilterConfig, SensorFilter
from ..errors import DistCtrlError, ParameterError
from ..trace import Trace, is_trace_file, load_trace, sidecar_path
from ..trace.plot import MAX_POINTS, envelope
from .plotfiles import PLOT_SUFFIXES, check_plot_suffix  # noqa: F401  (PLOT_SUFFIXES: part of the API)
from .tables import render_table

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = [
    "WorkbenchError", "FilterSpecError", "RecordingError", "WorkbenchWarning", "RecordingWarning",
    "FilterResult", "Recording", "DEFAULT_SPECS", "SPEC_SYNTAX",
    "parse_filter_spec", "parse_filter_specs", "default_configs", "obstacle_signal", "load_recording",
    "find_edges", "compare", "signal_noise_rms", "warmup_samples", "format_table", "write_results_csv",
    "check_plot_path", "plot_overlay",
]


# ------------------------------------------------------------------------------------------------------
# errors
# ------------------------------------------------------------------------------------------------------
class WorkbenchError(DistCtrlError, ValueError):
    """Bad input to a workbench tool (spec text, file, column, unit, edge time, output path)."""


class FilterSpecError(WorkbenchError):
    """A filter spec (``TYPE:key=value,...``) that cannot be parsed or is out of range."""


class RecordingError(WorkbenchError):
    """A sensor recording that cannot be read: names the file, line or column and what is allowed."""


class WorkbenchWarning(UserWarning):
    """A usable input with a flaw the result depends on (reported, not fatal)."""


class RecordingWarning(WorkbenchWarning):
    """A usable recording with a flaw (e.g. a sample interval that is not uniform within 1 %)."""


# ------------------------------------------------------------------------------------------------------
# filter specs
# ------------------------------------------------------------------------------------------------------
SPEC_SYNTAX = ("TYPE[:key=value[,value...][,key=value[,value...]...]], e.g. MOVING_AVERAGE:n_cycles=10,20,40 "
               "or KALMAN_MA:n_cycles=30,kalman_sigma=100,1000; several specs separated by ';'")

#: accepted key spellings -> FilterConfig field (the parameter table's short keys and the kernel's parameter names)
KEY_ALIASES: dict[str, str] = {k: p.name for p in FILTER_PARAMS.values() for k in p.keys}

#: the keys that have an effect, per filter type (a key that does nothing is an error, not silence)
KEYS_BY_TYPE: dict[FilterType, tuple[str, ...]] = {t: k.params for t, k in FILTER_KINDS.items()
                                                   if t != FilterType.PASS}

_INT_KEYS = {p.name for p in FILTER_PARAMS.values() if p.spec.integer}
_RANGES = {p.name: p.range_label() for p in FILTER_PARAMS.values()}

#: the comparison ``distctrl filters`` runs without a SPEC: each filter kind's example
#: (control/filters.FILTER_KINDS) in this order, the documents' example values (FCT-M3 §4.1 n 20, §4.2 n 30 alpha 0.3, §4.3 order 2 at 30 Hz, §4.4 n 30 sigma 1000, §4.5, §9.3 n 20
#: sigma 1000) and the default sigma 4, so the plain filters and the Kalman filters of the same n
#: (shorter dead time, overshoot growing with n and sigma) are side by side
_COMPARISON_ORDER = (FilterType.MOVING_AVERAGE, FilterType.KALMAN_MA, FilterType.EXPO_MEAN,
                     FilterType.KALMAN_EXPO, FilterType.LOWPASS)
DEFAULT_SPECS: tuple[str, ...] = tuple(
    FILTER_KINDS[t].example for t in sorted(FILTER_KINDS, key=lambda t: _COMPARISON_ORDER.index(t)
                                            if t in _COMPARISON_ORDER else len(_COMPARISON_ORDER))
    if FILTER_KINDS[t].example)


def _keys_text(ft: FilterType) -> str:
    keys = KEYS_BY_TYPE[ft]
    if not keys:
        return "none (DEFAULT is the moving average with n = 4)"
    out = []
    for k in keys:
        aliases = [a for a, c in KEY_ALIASES.items() if c == k and a != k]
        out.append(k + (f" (alias {', '.join(aliases)})" if aliases else ""))
    return ", ".join(out)


def _convert(spec: str, key: str, text: str) -> float | int:
    try:
        value = float(text)
    except ValueError:
        raise FilterSpecError(f"filter spec {spec!r}: {key} = {text!r} is not a number; "
                              f"allowed: {_RANGES[key]}") from None
    if not math.isfinite(value):
        raise FilterSpecError(f"filter spec {spec!r}: {key} = {text!r} is not finite; allowed: {_RANGES[key]}")
    if key in _INT_KEYS:
        if value != int(value):
            raise FilterSpecError(f"filter spec {spec!r}: {key} = {text!r} is not an integer; "
                                  f"allowed: {_RANGES[key]}")
        return int(value)
    return value


def _check_config(spec: str, cfg: FilterConfig, cycle_time: float | None) -> None:
    if cfg.filter_type == FilterType.LOWPASS and cfg.order > 0 and not cfg.fg_f0 > 0.0:
        raise FilterSpecError(f"filter spec {spec!r}: fg_f0 = {cfg.fg_f0:g} out of range; allowed: {_RANGES['fg_f0']}")
    try:
        # without a cycle time only the Nyquist bound is left open (checked again when the filter is built)
        cfg.check(cycle_time if cycle_time else 1e-300)
    except ParameterError as exc:
        raise FilterSpecError(f"filter spec {spec!r}: {exc}") from None


def _parse_one(spec: str, cycle_time: float | None) -> list[FilterConfig]:
    name, sep, rest = spec.partition(":")
    try:
        ft = FilterType.parse(name)
    except ValueError:
        raise FilterSpecError(f"filter spec {spec!r}: unknown filter type {name.strip()!r}; allowed: "
                              f"{', '.join(FILTER_TYPE_NAMES)}; syntax: {SPEC_SYNTAX}") from None
    allowed = KEYS_BY_TYPE[ft]
    values: dict[str, list] = {}
    if sep:
        if not rest.strip():
            raise FilterSpecError(f"filter spec {spec!r}: nothing after ':'; allowed keys for {ft.name}: "
                                  f"{_keys_text(ft)}; syntax: {SPEC_SYNTAX}")
        current: str | None = None
        for tok in rest.split(","):
            tok = tok.strip()
            if "=" in tok:
                raw_key, _, tok = tok.partition("=")
                key = raw_key.strip().lower()
                canon = KEY_ALIASES.get(key)
                if canon is None:
                    near = difflib.get_close_matches(key, list(KEY_ALIASES), n=1)
                    hint = f" (did you mean {near[0]}?)" if near else ""
                    raise FilterSpecError(f"filter spec {spec!r}: unknown key {raw_key.strip()!r}{hint}; "
                                          f"allowed keys for {ft.name}: {_keys_text(ft)}")
                if canon not in allowed:
                    raise FilterSpecError(f"filter spec {spec!r}: key {raw_key.strip()!r} has no effect on "
                                          f"{ft.name}; allowed keys for {ft.name}: {_keys_text(ft)}")
                if canon in values:
                    raise FilterSpecError(f"filter spec {spec!r}: key {canon!r} given twice; list several "
                                          f"values after one key: {canon}=v1,v2")
                values[canon] = []
                current = canon
                tok = tok.strip()
            elif current is None:
                raise FilterSpecError(f"filter spec {spec!r}: value {tok!r} before any key; syntax: {SPEC_SYNTAX}")
            if not tok:
                raise FilterSpecError(f"filter spec {spec!r}: empty value for {current}; allowed: {_RANGES[current]}")
            values[current].append(_convert(spec, current, tok))
    keys = [k for k in allowed if k in values]
    configs = []
    for combo in itertools.product(*(values[k] for k in keys)):
        cfg = FilterConfig(ft, **dict(zip(keys, combo)))
        _check_config(spec, cfg, cycle_time)
        configs.append(cfg)
    return configs


def parse_filter_spec(text: str, cycle_time: float | None = None) -> list[FilterConfig]:
    """Configs of one spec text: ``TYPE[:key=v1[,v2...][,key=v...]]`` (several specs joined by ``;``).

    A value list continues until the next ``key=``; keys with several values expand into their
    cartesian product, e.g. ``KALMAN_MA:n_cycles=30,kalman_sigma=100,1000`` gives two configs.
    Unnamed parameters keep the :class:`FilterConfig` defaults. Keys: ``n_cycles``,
    ``smoothing_factor`` (``smooth_fact``), ``kalman_sigma`` (``sigma``), ``order``
    (``low_pass_filter_order``), ``fg_f0`` (``low_pass_filter_fg_f0``), each only where it has an
    effect. With ``cycle_time`` the low-pass cut-off is also checked against Nyquist.
    Raises :class:`FilterSpecError` naming the spec and what is allowed.
    """
    if not isinstance(text, str) or not text.strip():
        raise FilterSpecError(f"empty filter spec {text!r}; syntax: {SPEC_SYNTAX}")
    configs: list[FilterConfig] = []
    for part in text.split(";"):
        if part.strip():
            configs.extend(_parse_one(part.strip(), cycle_time))
    if not configs:
        raise FilterSpecError(f"empty filter spec {text!r}; syntax: {SPEC_SYNTAX}")
    return configs


def parse_filter_specs(texts: Sequence[str], cycle_time: float | None = None) -> list[FilterConfig]:
    """All configs of several spec texts, in order."""
    return [cfg for text in texts for cfg in parse_filter_spec(text, cycle_time)]


def default_configs(cycle_time: float | None = None) -> list[FilterConfig]:
    """The default comparison (:data:`DEFAULT_SPECS`): 9 configs."""
    return parse_filter_specs(DEFAULT_SPECS, cycle_time)


# ------------------------------------------------------------------------------------------------------
# signals
# ------------------------------------------------------------------------------------------------------
def obstacle_signal(cycle_time: float = 0.001, *, height: float = 2.8, level: float = 0.0,
                    flat_before: float = 0.5, top: float = 0.5, flat_after: float = 0.5,
                    ramp_time: float = 0.0, noise_std: float = 0.05, seed: int | None = 1
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The documents' filter test (FCT-M3 ch. 4): a sensor crossing an obstacle ``height`` mm high.

    Flat (``flat_before`` s at ``level``), rising edge, top (``top`` s at ``level + height``),
    falling edge, flat (``flat_after`` s), sampled every ``cycle_time`` s, plus Gaussian noise of
    standard deviation ``noise_std`` mm from ``numpy.random.default_rng(seed)``.

    Returns ``(t, values, edges)``; ``edges`` holds the times of the rising and the falling edge.
    With ``ramp_time = 0`` (default) the edges are steps: the signal has its new level from the edge
    sample on. With ``ramp_time > 0`` each edge is a linear ramp and the edge time is the ramp's
    middle (where the raw signal has made half the step). ``height`` is signed: the default +2.8
    rises like the sensor data in the documents' figures; a distance sensor at a standoff whose
    distance drops over the obstacle is ``level=5, height=-2.8`` (the metrics follow the sign).
    """
    T = float(cycle_time)
    if not (T > 0.0 and math.isfinite(T)):
        raise WorkbenchError(f"cycle_time = {cycle_time!r}; allowed: a finite number > 0 s")
    for name, v in (("flat_before", flat_before), ("top", top), ("flat_after", flat_after)):
        if not (v > 0.0 and math.isfinite(v)):
            raise WorkbenchError(f"{name} = {v!r} s; allowed: a finite number > 0")
    if not (ramp_time >= 0.0 and ramp_time < top and math.isfinite(ramp_time)):
        raise WorkbenchError(f"ramp_time = {ramp_time!r} s; allowed: 0 <= ramp_time < top ({top!r} s)")
    if not (noise_std >= 0.0 and math.isfinite(noise_std)):
        raise WorkbenchError(f"noise_std = {noise_std!r} mm; allowed: a finite number >= 0")
    i1 = int(round(flat_before / T))
    i2 = i1 + int(round(top / T))
    n = i2 + int(round(flat_after / T))
    k = np.arange(n, dtype=np.float64)
    if ramp_time > 0.0:
        r = ramp_time / T
        profile = np.clip((k - i1) / r + 0.5, 0.0, 1.0) - np.clip((k - i2) / r + 0.5, 0.0, 1.0)
    else:
        profile = (k >= i1).astype(np.float64) - (k >= i2).astype(np.float64)
    t = k * T
    values = level + height * profile
    if noise_std > 0.0:
        values = values + np.random.default_rng(seed).normal(0.0, noise_std, n)
    return t, values, np.array([i1 * T, i2 * T])


# ------------------------------------------------------------------------------------------------------
# recordings
# ------------------------------------------------------------------------------------------------------
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
        try:
            trace = load_trace(p)
        except (ValueError, OSError, DistCtrlError) as exc:
            raise RecordingError(f"{p}: not a readable distctrl trace: {exc}") from None
        cols = list(trace.columns)
        if value_column is None:
            sensors = [c for c in cols if c.endswith(".dc.sensor")]
            if len(sensors) != 1:
                raise RecordingError(f"{p}: name the value column (--value-column), e.g. "
                                     f"{sensors[0] if sensors else 'Z.dc.sensor'}; columns: {', '.join(cols)}")
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
        first_line = 2
    else:
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


# ------------------------------------------------------------------------------------------------------
# metrics
# ------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FilterResult:
    """One filter on one signal: the output and its metrics (NaN where not measurable).

    ``noise_rms`` [mm]; ``delay_s`` / ``dead_time_s``: time from the first (rising) edge until the
    output has made 50 % / 10 % of the step; ``overshoot_mm`` beyond the top level in the step's
    direction (0 if none), ``overshoot_pct`` in % of the step.
    """

    config: FilterConfig
    label: str
    output: np.ndarray
    noise_rms: float
    delay_s: float
    dead_time_s: float
    overshoot_mm: float
    overshoot_pct: float

    def to_dict(self) -> dict:
        """This config's entry of ``distctrl filters --json``: label, filter type, the parameters the
        type uses, and the metrics with their units in the names (NaN where not measurable)."""
        c = self.config
        used = KEYS_BY_TYPE.get(c.filter_type, ())
        params = {k: getattr(c, k) for k in KEY_ORDER if k in used}
        if c.filter_type == FilterType.DEFAULT:
            params["n_cycles"] = c.effective_n
        return {"label": self.label, "filter_type": c.filter_type.name, "params": params,
                "noise_rms_mm": float(self.noise_rms), "delay_s": float(self.delay_s),
                "dead_time_s": float(self.dead_time_s), "overshoot_mm": float(self.overshoot_mm),
                "overshoot_pct": float(self.overshoot_pct)}


def warmup_samples(config: FilterConfig, cycle_time: float) -> int:
    """Samples skipped before measuring noise: max(n, 50); for the low-pass n is one period of fg."""
    n = config.effective_n
    if config.filter_type == FilterType.LOWPASS:
        n = int(math.ceil(1.0 / (config.fg_f0 * cycle_time))) if config.order > 0 and config.fg_f0 > 0 else 0
    return max(int(n), 50)


def _median_window(warmup: int) -> int:
    return 4 * int(warmup) + 1


def _rms_about_mean(x: np.ndarray) -> float:
    if x.size < 10:
        return math.nan
    return float(np.sqrt(np.mean((x - x.mean()) ** 2)))


def signal_noise_rms(y: np.ndarray, t: np.ndarray, edges: Sequence[float] | None = None, warmup: int = 50,
                     median_window: int | None = None) -> float:
    """Noise RMS [mm] of a signal: about its mean on the flat part before the first edge (after
    ``warmup`` samples); without edges, of the signal minus its moving median (window
    ``median_window``, default ``4 warmup + 1``) after ``warmup`` samples. NaN if < 10 samples remain."""
    y = np.asarray(y, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    if edges is not None and len(edges):
        i_edge = int(np.searchsorted(t, float(min(edges)), side="left"))
        return _rms_about_mean(y[warmup:i_edge])
    from scipy.ndimage import median_filter

    w = median_window or _median_window(warmup)
    rest = y - median_filter(y, size=int(w), mode="nearest")
    return _rms_about_mean(rest[warmup:] + 0.0) if rest.size > warmup else math.nan


def _levels(x: np.ndarray, i1: int, i2: int) -> tuple[float, float]:
    """Base (median before the edge) and top (median of the middle 80 % between the edges)."""
    base = float(np.median(x[:i1]))
    m = (i2 - i1) // 10
    seg = x[i1 + m:i2 - m] if i2 - i1 - 2 * m >= 1 else x[i1:i2]
    return base, float(np.median(seg))


def _crossing(y: np.ndarray, t: np.ndarray, edge: float, i1: int, i2: int, base: float, step: float,
              fraction: float) -> float:
    """Time from ``edge`` until ``y`` has made ``fraction`` of ``step`` (linear between samples)."""
    z = (y[i1:i2] - base) / step
    hit = np.flatnonzero(z >= fraction)
    if not hit.size:
        return math.nan
    j = int(hit[0])
    if j == 0:
        return float(t[i1] - edge)
    z0, z1 = z[j - 1], z[j]
    frac = (fraction - z0) / (z1 - z0) if z1 != z0 else 1.0
    return float(t[i1 + j - 1] + frac * (t[i1 + j] - t[i1 + j - 1]) - edge)


def _check_edges(t: np.ndarray, edges) -> list[float] | None:
    if edges is None:
        return None
    out = sorted(float(e) for e in edges)
    if not out:
        return None
    for e in out:
        if not (math.isfinite(e) and t[0] < e <= t[-1]):
            raise WorkbenchError(f"edge time {e!r} s outside the signal; allowed: {t[0]:g} < edge <= {t[-1]:g} s")
    return out


def compare(signal, t, configs: Sequence[FilterConfig], cycle_time: float | None = None,
            edges: Sequence[float] | None = None) -> list[FilterResult]:
    """Run each config over ``signal`` (sampled at ``t``) and measure it.

    The filter is the cycle core's own (:meth:`SensorFilter.apply`: fresh, seeded with the first
    sample). ``cycle_time`` defaults to the median sample interval. Metrics (SPEC §4, docs):

    * noise RMS: on the flat part before the first edge, after a warm-up of
      :func:`warmup_samples` (max(n, 50)); without edges, the output minus its moving median
      (one window, ``4 * max(warm-up) + 1`` samples, for all configs so they compare),
    * delay / dead time: from the first edge until the output has made 50 % / 10 % of the step,
    * overshoot: the largest excursion beyond the top level between the first and the second edge.

    Base and top level are the medians of the raw signal before the first edge and between the
    edges (its middle 80 %; up to the end if there is one edge only). Without edges, or when the
    level changes by no more than 5 times the raw noise RMS at the first edge (then with a
    :class:`WorkbenchWarning`), the step metrics are NaN. Overshoot on a noisy signal includes
    the output's remaining noise.
    """
    x = np.asarray(signal, dtype=np.float64).ravel()
    tt = np.asarray(t, dtype=np.float64).ravel()
    if x.size != tt.size:
        raise WorkbenchError(f"signal has {x.size} samples, t has {tt.size}; allowed: equal lengths")
    if x.size < 3:
        raise WorkbenchError(f"signal has {x.size} samples; allowed: at least 3")
    if not np.all(np.isfinite(x)) or not np.all(np.isfinite(tt)):
        raise WorkbenchError("signal or t contains NaN or infinite values; allowed: finite numbers")
    if cycle_time is None:
        cycle_time = float(np.median(np.diff(tt)))
    if not (cycle_time > 0.0 and math.isfinite(cycle_time)):
        raise WorkbenchError(f"cycle_time = {cycle_time!r}; allowed: a finite number > 0 s")
    ed = _check_edges(tt, edges)
    warm = [warmup_samples(c, cycle_time) for c in configs]
    median_window = _median_window(max(warm, default=50))
    step_ctx = None
    if ed:
        e1 = ed[0]
        i1 = int(np.searchsorted(tt, e1, side="left"))
        i2 = int(np.searchsorted(tt, ed[1], side="left")) if len(ed) > 1 else x.size
        if i1 < 1 or i2 - i1 < 2:
            raise WorkbenchError(f"edges {ed} leave no flat part before or no top after the first edge; "
                                 "allowed: at least 1 sample before and 2 between the edges")
        base, top = _levels(x, i1, i2)
        step = top - base
        raw_noise = float(np.std(x[:i1]))
        if abs(step) > 5.0 * raw_noise and step != 0.0:
            step_ctx = (e1, i1, i2, base, top, step)
        else:
            warnings.warn(f"no step at the edge t = {e1:g} s: the level changes by {step:.4g} mm, the raw noise "
                          f"RMS before it is {raw_noise:.4g} mm; delay, dead time and overshoot need a change "
                          "of more than 5 noise RMS (check the edge times)", WorkbenchWarning, stacklevel=2)
    results = []
    for cfg, w in zip(configs, warm):
        try:
            y = SensorFilter(cfg, cycle_time).apply(x)
        except ParameterError as exc:
            raise FilterSpecError(f"{cfg.label()}: {exc}") from None
        noise = signal_noise_rms(y, tt, ed, w, median_window)
        delay = dead = os_mm = os_pct = math.nan
        if step_ctx is not None:
            e1, i1, i2, base, top, step = step_ctx
            delay = _crossing(y, tt, e1, i1, i2, base, step, 0.5)
            dead = _crossing(y, tt, e1, i1, i2, base, step, 0.1)
            os_mm = max(0.0, float(np.max((y[i1:i2] - top) * math.copysign(1.0, step))))
            os_pct = 100.0 * os_mm / abs(step)
        results.append(FilterResult(cfg, cfg.label(), y, noise, delay, dead, os_mm, os_pct))
    return results


def find_edges(t, values, window: int = 21) -> list[float]:
    """Estimate the obstacle edges of a recording: the largest level change and, after it, the
    largest change back (each more than 8 noise RMS). Times where the moving median makes half of
    the change; [] if there is no clear edge. A helper for ``--edge auto``; check it on the plot."""
    from scipy.ndimage import median_filter

    x = np.asarray(values, dtype=np.float64)
    tt = np.asarray(t, dtype=np.float64)
    w = int(window) | 1
    k = w // 2
    if x.size < 4 * w:
        return []
    m = median_filter(x, size=w, mode="nearest")
    resid = x - m
    noise = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
    d = np.zeros_like(x)
    d[k:-k] = m[2 * k:] - m[:-2 * k]
    thresh = max(8.0 * noise, 1e-12)

    def locate(i: int) -> float:
        a, b = max(i - k, 0), min(i + k, x.size - 1)
        z = (m[a:b + 1] - m[a]) / (m[b] - m[a])
        j = int(np.flatnonzero(z >= 0.5)[0])
        return float(tt[a + j])
    i1 = int(np.argmax(np.abs(d)))
    if abs(d[i1]) <= thresh:
        return []
    found = [i1]
    back = -math.copysign(1.0, d[i1]) * d             # the change back, anywhere but at the first one
    back[max(i1 - w, 0):i1 + w + 1] = -np.inf
    j = int(np.argmax(back))
    if back[j] > max(thresh, 0.5 * abs(d[i1])):
        found.append(j)
    return [locate(i) for i in sorted(found)]


# ------------------------------------------------------------------------------------------------------
# presentation
# ------------------------------------------------------------------------------------------------------
def _fmt(v: float, spec: str) -> str:
    return "-" if v is None or not math.isfinite(v) else format(v, spec)


TABLE_COLUMNS = ("filter", "noise RMS [mm]", "delay 50 % [ms]", "dead time 10 % [ms]", "overshoot [mm]",
                 "overshoot [%]")


def format_table(results: Sequence[FilterResult], title: str | None = None, plain: bool = False) -> str:
    """The metrics as a text table (rich, no colour; ``plain=True``: fixed-width ASCII)."""
    rows = [(r.label, _fmt(r.noise_rms, ".4f"), _fmt(r.delay_s * 1e3, ".2f"), _fmt(r.dead_time_s * 1e3, ".2f"),
             _fmt(r.overshoot_mm, ".3f"), _fmt(r.overshoot_pct, ".1f")) for r in results]
    return render_table(TABLE_COLUMNS, rows, title, plain)


RESULT_CSV_COLUMNS = ("label", "filter_type", "n_cycles", "smoothing_factor", "kalman_sigma", "order", "fg_f0",
                      "noise_rms_mm", "delay_s", "dead_time_s", "overshoot_mm", "overshoot_pct")


KEY_ORDER = ("n_cycles", "smoothing_factor", "kalman_sigma", "order", "fg_f0")


def write_results_csv(results: Sequence[FilterResult], path: str | os.PathLike) -> None:
    """One row per config: its parameters (empty where they have no effect) and metrics (empty
    where NaN)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)

    def num(v: float) -> str:
        return "" if v is None or not math.isfinite(v) else repr(float(v))
    with open(p, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(RESULT_CSV_COLUMNS)
        for r in results:
            c = r.config
            used = KEYS_BY_TYPE.get(c.filter_type, ())
            params = {k: (repr(getattr(c, k)) if k in used else "") for k in KEY_ORDER}
            if c.filter_type == FilterType.DEFAULT:
                params["n_cycles"] = str(c.effective_n)
            w.writerow([r.label, c.filter_type.name, *params.values(), num(r.noise_rms), num(r.delay_s),
                        num(r.dead_time_s), num(r.overshoot_mm), num(r.overshoot_pct)])


def results_dicts(results: Sequence[FilterResult]) -> list[dict]:
    """One dict per config (``distctrl filters --json``): label, filter type, the parameters the type
    uses, and the metrics with their units in the names (NaN where not measurable)."""
    return [r.to_dict() for r in results]




def check_plot_path(path: str | os.PathLike) -> Path:
    return check_plot_suffix(path, WorkbenchError)


def plot_overlay(t, signal, results: Sequence[FilterResult], path: str | os.PathLike | None = None,
                 edges: Sequence[float] | None = None, title: str | None = "Sensor filters compared",
                 ylabel: str = "distance [mm]") -> "Figure":
    """Raw signal (light grey) with every filter output overlaid, like the documents' Figs. 10-17.

    Top panel: the whole signal, the edges as vertical dashed lines. With edges a second panel zooms
    on the first (rising) edge: from a third of the window before it to three times the 75th
    percentile of the 50 % delays (at least 40 cycles) after it. Returns the Figure (Agg canvas, no pyplot); with
    ``path`` it is saved too, the format by suffix (.png, .svg, .pdf).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if path is not None:
        path = check_plot_path(path)
    tt = np.asarray(t, dtype=np.float64)
    x = np.asarray(signal, dtype=np.float64)
    ed = _check_edges(tt, edges) if edges is not None and len(edges) else []
    fig = Figure(figsize=(13.0, 7.5 if ed else 4.6), layout="constrained")
    FigureCanvasAgg(fig)
    if ed:
        ax_all, ax_zoom = fig.subplots(2, 1, gridspec_kw={"height_ratios": [1.1, 1.0]})
    else:
        ax_all, ax_zoom = fig.subplots(1, 1), None
    colors = [f"C{i % 10}" for i in range(len(results))]

    xs, ys = envelope(tt, x, MAX_POINTS)
    ax_all.plot(xs, ys, color="0.78", linewidth=0.8, label="raw signal", zorder=1)
    for r, c in zip(results, colors):
        xs, ys = envelope(tt, r.output, MAX_POINTS)
        ax_all.plot(xs, ys, color=c, linewidth=1.1, label=r.label, zorder=2)
    axes = [ax_all] + ([ax_zoom] if ax_zoom is not None else [])
    for ax in axes:
        for i, e in enumerate(ed):
            ax.axvline(e, color="0.3", linestyle="--", linewidth=0.8, zorder=0,
                       label="obstacle edge" if (i == 0 and ax is ax_all) else "_nolegend_")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.4)
    ax_all.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small", borderaxespad=0.0)
    if ax_zoom is not None:
        T = float(np.median(np.diff(tt)))
        delays = [r.delay_s for r in results if math.isfinite(r.delay_s)]
        post = max(40 * T, 3.0 * float(np.percentile(delays, 75)) if delays else 0.0)
        lo, hi = ed[0] - post / 3.0, min(ed[0] + post, ed[1] if len(ed) > 1 else tt[-1])
        sel = (tt >= lo) & (tt <= hi)
        ax_zoom.plot(tt[sel], x[sel], color="0.78", linewidth=0.8, marker=".", markersize=2, label="raw signal")
        for r, c in zip(results, colors):
            ax_zoom.plot(tt[sel], r.output[sel], color=c, linewidth=1.3, label=r.label)
        ax_zoom.set_xlim(lo, hi)
        ax_zoom.set_title("zoom on the first (rising) edge", fontsize="medium", loc="left")
    if title:
        fig.suptitle(str(title))
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
    return fig
