"""Evaluate many parameter sets of one scenario in chunks: in-process or on a dask.distributed cluster.

:class:`Evaluator` holds the recorded scenario (:class:`~distctrl.batch.closed_loop.LoopInputs`)
and where the work runs:

* ``mode="local"``: in this process, a sweep's chunks one per core side by side on one numba thread
  each (where numba's threading layer allows it), other work one chunk after the other on all cores
  (:meth:`Evaluator._run_local`); a chunk that raises is retried up to ``retries`` times;
* ``mode="cluster"`` (the default): an embedded ``LocalCluster(n_workers=os.cpu_count(),
  threads_per_worker=1, processes=True)`` started on entry and closed on exit, or, with
  ``scheduler="tcp://host:8786"``, a ``Client`` of an existing cluster (not closed).

Each chunk (at most ``chunk_size`` sets, fewer for long runs so a chunk's traces stay within
``chunk_bytes``) is the pure function :func:`evaluate_chunk` of the recorded inputs (without the
scenario object) and the packed rows, submitted with ``retries``: an exception is retried, and a
chunk whose worker dies is rescheduled by dask on another worker; only that chunk is lost. Progress
is a rich bar on stderr when it is a terminal.

The result is a :class:`SweepResult`: a column table (plain lists, no pandas) with the swept
parameters, the metrics of :mod:`distctrl.tuning.metrics`, the objective ``cost`` and the
controller error of each set; ``write()`` saves CSV or Parquet (pyarrow).
"""
from __future__ import annotations

import csv
import dataclasses
import functools
import hashlib
import io
import logging
import math
import os
import re
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from ..base.kinds import FilterType
from ..errors import DistCtrlError
from ..workbench.tables import render_table
from .metrics import METRIC_NAMES, METRIC_UNITS, compute_metrics, cost, limits_from_packed, wanted_distance
from .columns import COLUMN_FIELDS, check_columns, full_column
from .space import D_TV_NOTE, NC_WORDS, build_sets, d_tv_applies, filter_fields

__all__ = ["Evaluator", "SweepResult", "evaluate", "evaluate_chunk", "evaluate_points_chunk", "TuningRunError",
           "PARAM_COLUMNS", "plot_sweep"]

#: the parameter columns of every result table (AxisParameters fields)
PARAM_COLUMNS = tuple(NC_WORDS)
DEFAULT_CHUNK = 256
DEFAULT_CHUNK_BYTES = 256 * 2**20
#: the most blocks (``chunk_size`` sets each) one chunk of :meth:`Evaluator.evaluate_points` runs
MAX_TASK_BLOCKS = 64
#: dask settings of the embedded LocalCluster (not of a cluster given with ``scheduler``): its scheduler and
#: workers share the machine's cores with the chunks they run, and dask's defaults wake them 50-100 times a
#: second (the 20 ms event-loop tick, the workers' 10 ms statistical profiler of the running task, 100-500 ms
#: monitors): about 1 CPU-s per 10 s with nothing to do, and with 2 workers on 2 cores each task ran about 7 %
#: longer than on 1 worker (bench/bench_sweep.py, docs/tuning.md). With these the dashboard still shows tasks,
#: memory and progress, but no profile of the running code.
EMBEDDED_CLUSTER_CONFIG = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "500ms",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "500ms",
}
#: FilterType value -> name, indexable by an array of values (DEFAULT = -1 is the last entry)
_FILTER_NAMES = np.array([FilterType(v).name if v in {int(t) for t in FilterType} else str(v)
                          for v in list(range(max(FilterType) + 1)) + [-1]], dtype=object)


class TuningRunError(DistCtrlError, RuntimeError):
    """A sweep could not run (cluster unreachable, a chunk failed after its retries, ...)."""


# ----------------------------------------------------------------------------- the chunk function

def _hold(value):
    """Identity: a cluster task whose result is ``value`` (see Evaluator._hold_inputs)."""
    return value


def slim_inputs(inputs):
    """``inputs`` without the scenario object and parameters: what a worker needs (arrays only)."""
    return dataclasses.replace(inputs, scenario=None, params=None, notes=[])


def evaluate_chunk(inputs, packed: np.ndarray, cycles: int | None, metric_options: dict,
                   threads: int | None = None) -> dict[str, np.ndarray]:
    """Run the kernel for the packed rows and return their metrics (a pure function of its arguments)."""
    # numba (the [batch] extra) loads only when a batch runs
    from ..batch.closed_loop import numba_threads, run_batch

    with numba_threads(threads):             # the kernel's and the metrics pass's threads
        res = run_batch(inputs, packed, cycles=cycles, return_errors=True)
        return _measure(inputs, packed, res, wanted_distance(inputs, res[1].shape[1]), metric_options)


def _measure(inputs, packed: np.ndarray, res, wanted, metric_options: dict) -> dict[str, np.ndarray]:
    """The metrics of a kernel run ``res`` = ``(offset, distance, errors)`` of the rows ``packed``, and the
    cycle and ID of each set's first error."""
    offset, distance, errors = res
    m = compute_metrics(offset, distance, wanted, inputs.cycle_time, inputs.k_on, limits_from_packed(packed),
                        **metric_options)
    m["error_cycle"] = errors[:, 0].copy()
    m["error_id"] = errors[:, 1].copy()
    return m


def chunk_bounds(n: int, block: int, parts: int, side_by_side: int = 1) -> list[tuple[int, int]]:
    """``(start, stop)`` of the chunks of ``n`` points: about ``parts`` chunks, each at least a block and at most
    MAX_TASK_BLOCKS blocks (a chunk's filter rows and table parts stay tens of MB; 64 blocks of 256 sets are
    about 2 s of kernel on one core).

    ``side_by_side`` threads taking the chunks in turn (:meth:`Evaluator._chunks_side_by_side`): chunks 2 ..
    ``side_by_side`` are shorter, by 1/side_by_side of a chunk each, so that every thread's chunks end a
    fraction of a chunk after the previous thread's. At its end a chunk formats its rows of the table and the
    thread's next chunk checks its points: Python, which holds the GIL. Chunks of one length ended together
    on both threads, and each thread then waited for the other's Python at every chunk (a 10 000-set sweep
    used 1.0-1.4 of its 2 cores there, 20-40 ms per boundary)."""
    size = max(block, min(-(-n // max(parts, 1)), MAX_TASK_BLOCKS * block))
    sizes = [size] + [max(1, size - size * i // side_by_side) for i in range(1, max(side_by_side, 1))]
    out, a = [], 0
    while a < n:
        b = min(n, a + (sizes[len(out)] if len(out) < len(sizes) else size))
        out.append((a, b))
        a = b
    return out


class _PointChunk:
    """A slice of points, the index of its first point and the most sets run at once (len(): its size, for
    the progress bar)."""

    def __init__(self, points, start: int, block: int):
        self.points = points
        self.start = start
        self.block = block

    def __len__(self) -> int:
        return self.points.n


def _probe_of(inputs, base):
    """The probe's (increments per mm, reference offset) of the base set (None: the distance sensor)."""
    # numba (the [batch] extra) loads only when a batch runs
    from ..batch.closed_loop import SENSOR_PROBE, _probe_constants
    from ..batch.layout import PL_SENSOR

    return _probe_constants(inputs, base) if inputs.plant[PL_SENSOR] == SENSOR_PROBE else None


_LOCAL = threading.local()


def _outputs(n_sets: int, n: int):
    """Trace arrays for ``n_sets`` rows of ``n`` cycles: the first rows of arrays reused from block to block in
    this process, made again only for more rows or another length (fresh memory costs page faults:
    docs/batch.md; a chunk's shorter last block takes the first rows). Per calling thread of a worker that
    runs several tasks at once."""
    got = getattr(_LOCAL, "out", None)
    if got is None or got[0].shape[1] != n or got[0].shape[0] < n_sets:
        got = _LOCAL.out = (np.empty((n_sets, n)), np.empty((n_sets, n)))
    return got[0][:n_sets], got[1][:n_sets]


def _side_by_side_cores() -> int:
    """numba's thread count, where its threading layer runs parallel kernels called from several threads at
    once (tbb, omp; not workqueue, which aborts the process); else 1."""
    # numba (the [batch] extra) loads only when a batch runs
    import numba

    try:
        layer = numba.threading_layer()
    except ValueError:                      # no parallel kernel has run yet: not known
        return 1
    return numba.get_num_threads() if layer in ("tbb", "omp") else 1


class _CheckedChunk:
    """A chunk's points after the check: ``index`` (the kept points, in the chunk), ``rejected``
    ``(point, message)`` and ``pack()``, the packed rows of the kept points."""

    def __init__(self, index: np.ndarray, rejected: list, pack):
        self.index = index
        self.rejected = rejected
        self.pack = pack


def check_points_chunk(inputs, chunk: "_PointChunk", base, probe) -> _CheckedChunk:
    """Check and design a chunk's points (columns: :func:`~distctrl.tuning.columns.check_columns`; what the
    columns do not cover, set by set through :func:`~distctrl.tuning.space.build_sets`): the first half of
    :func:`evaluate_points_chunk`, which a local sweep runs for the next chunk while this one runs."""
    # numba (the [batch] extra) loads only when a batch runs
    from ..batch.closed_loop import pack_columns, pack_sets

    pts = chunk.points
    checked = check_columns(base, pts, inputs.cycle_time)
    if checked is not None:
        kept, fc, rejected = checked

        def pack():
            return pack_columns(inputs, base, kept.cols, kept.present, fc, probe=probe)
        return _CheckedChunk(kept.index, rejected, pack)
    points = pts.to_points()                 # what the columns do not cover: set by set
    sets, kept_points, rejected = build_sets(base, points, inputs.cycle_time)
    ids = {id(p): i for i, p in enumerate(points)}

    def pack():
        return pack_sets(inputs, sets, probe=probe)
    return _CheckedChunk(np.array([ids[id(p)] for p in kept_points], dtype=np.int64), rejected, pack)


def evaluate_points_chunk(inputs, chunk: "_PointChunk", cycles: int | None, metric_options: dict,
                          threads: int | None, base, probe, csv_options: dict | None = None,
                          checked: _CheckedChunk | None = None) -> dict:
    """Check, design, pack, run and measure one chunk of points (a pure function of its arguments; on a
    cluster it runs on the worker, which gets only the points' columns), ``chunk.block`` sets at a time
    (their traces in arrays reused from block to block): the metrics of the kept points,
    ``_kept`` their indices, ``_rejected`` ``(point, message)`` of the others, ``_kernel_s`` the time in
    the kernel and the metrics pass, ``_task_s`` the whole chunk's. ``checked``: the chunk's
    :func:`check_points_chunk`, when done already. ``csv_options`` (``osc_weight``, ``cost_weights``): also
    ``_csv``, the chunk's rows of the table as :meth:`SweepResult.to_csv` writes them (:func:`csv_rows` of
    :func:`points_table`), made here beside the other chunks' kernels instead of all at once when the table
    is written (a local sweep's 10 000 rows took 0.08 s to format, on one core).

    Block after block, each on all of ``threads``: the kernel, then the metrics pass and the two FFTs
    (:func:`~distctrl.tuning.metrics.compute_metrics`). Running the next block's kernel in a second thread
    while this block's metrics were taken was tried (until issue 27's last step): on two cores the two
    stages then share them, and it was no faster than one after the other (2.11 s against 2.06 s, the
    best of six 10 000-set sweeps each, docs/tuning.md)."""
    t_task = time.perf_counter()
    # numba (the [batch] extra) loads only when a batch runs
    from ..batch.closed_loop import numba_threads, run_batch
    from ..batch.soa import kernel_order

    if checked is None:
        checked = check_points_chunk(inputs, chunk, base, probe)
    index = checked.index
    out = {"_kept": index + chunk.start, "_rejected": checked.rejected}
    n = inputs.n_cycles if cycles is None else int(cycles)
    wanted = wanted_distance(inputs, n)
    kernel_s = 0.0
    parts = []
    packed_all = checked.pack()
    order = kernel_order(packed_all)
    with numba_threads(threads):
        for a in range(0, len(index), chunk.block):
            b = min(a + chunk.block, len(index))
            packed = packed_all[order[a:b]]
            t0 = time.perf_counter()
            res = run_batch(inputs, packed, cycles=cycles, return_errors=True, out=_outputs(b - a, n))
            parts.append(_measure(inputs, packed, res, wanted, metric_options))
            kernel_s += time.perf_counter() - t0
    if parts:
        back = np.empty_like(order)
        back[order] = np.arange(len(order))
        out.update({k: np.concatenate([p[k] for p in parts])[back] for k in parts[0]})
    else:
        out["failed"] = np.zeros(0, dtype=bool)
    if csv_options is not None and parts:
        out["_csv"] = csv_rows(points_table(base, chunk.points.take(index), out, **csv_options))
    out["_kernel_s"] = kernel_s
    out["_task_s"] = time.perf_counter() - t_task
    return out


# ----------------------------------------------------------------------------- results

class SweepResult:
    """A table: ``columns`` (names) and ``data`` (name -> numpy array or list), one row per set."""

    def __init__(self, data: dict[str, object], params: list | None = None, rejected: list | None = None,
                 info: dict | None = None, csv_body: str | None = None):
        self.data = {k: (v if isinstance(v, list) else np.asarray(v)) for k, v in data.items()}
        self.params = params or []
        self.rejected = rejected or []
        self.info = info or {}
        # the CSV rows of this table made beforehand (evaluate_points), with the digest of the table they
        # were made from: written only while the table is the same (a column changed in place is not)
        self._csv_body = (_digest(self.data), csv_body) if csv_body is not None else None

    @property
    def columns(self) -> list[str]:
        return list(self.data)

    def __len__(self) -> int:
        return len(next(iter(self.data.values()))) if self.data else 0

    def __getitem__(self, name: str):
        return self.data[name]

    def rows(self) -> list[dict]:
        """The table as a list of dicts (plain Python values)."""
        out = []
        for i in range(len(self)):
            out.append({k: _plain(v[i]) for k, v in self.data.items()})
        return out

    def order(self, key: str = "cost") -> np.ndarray:
        """Row indices sorted by ``key`` ascending (NaN / inf last)."""
        v = np.asarray(self.data[key], dtype=np.float64)
        return np.argsort(np.where(np.isnan(v), np.inf, v), kind="stable")

    def best(self, key: str = "cost") -> int:
        return int(self.order(key)[0])

    def concat(self, other: "SweepResult") -> "SweepResult":
        cols = [c for c in self.data if c in other.data]
        data = {}
        for c in cols:
            a, b = self.data[c], other.data[c]
            data[c] = (list(a) + list(b)) if isinstance(a, list) or isinstance(b, list) else np.concatenate([a, b])
        return SweepResult(data, self.params + other.params, self.rejected + other.rejected, dict(self.info))

    def to_csv(self, path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        made = self._csv_body
        body = made[1] if made is not None and made[0] == _digest(self.data) else csv_rows(self.data)
        with open(path, "w", newline="") as fh:
            csv.writer(fh).writerow(self.columns)
            fh.write(body)
        return path

    def to_parquet(self, path) -> Path:
        try:
            # pyarrow (the [parquet] extra): only for a Parquet table
            import pyarrow as pa
            import pyarrow.parquet as pq
        except ImportError:
            raise TuningRunError("Parquet results need pyarrow, which is not installed: pip install "
                                 "'distctrl[parquet]' (or write a .csv)") from None
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {c: pa.array([_plain(x) for x in v]) for c, v in self.data.items()}
        pq.write_table(pa.table(arrays), path)
        return path

    def write(self, path) -> Path:
        """CSV, or Parquet for a ``.parquet`` / ``.pq`` name."""
        if str(path).lower().endswith((".parquet", ".pq")):
            return self.to_parquet(path)
        return self.to_csv(path)

    def units(self) -> dict:
        """The unit of every column that has one (metrics: :data:`~distctrl.tuning.metrics.METRIC_UNITS`;
        parameters: internal units)."""
        units = {"i_tn": "s", "d_tv": "s", "low_pass_filter_fg_f0": "Hz", "v_max": "mm/s", "a_max": "mm/s²"}
        return {c: units.get(c) or METRIC_UNITS.get(c) for c in self.data if units.get(c) or METRIC_UNITS.get(c)}

    def best_rows(self, n: int = 10, key: str = "cost") -> list[dict]:
        """The best ``n`` rows by ``key`` as dicts: the parameters the row's filter uses and every metric."""
        out = []
        for i in self.order(key)[:n]:
            i = int(i)
            ft = _plain(self.data["filter_type"][i]) if "filter_type" in self.data else None
            used = set(filter_fields(FilterType[ft])) if isinstance(ft, str) and ft in FilterType.__members__ else None
            row = {}
            for c, v in self.data.items():
                if c in PARAM_COLUMNS and c not in ("kp", "i_tn", "d_tv", "filter_type") and used is not None \
                        and c not in used:
                    continue
                row[c] = _plain(v[i])
            if "d_tv" in row and "kp" in row and not d_tv_applies(row["kp"]):
                row["d_tv"] = None                 # no D part at kp >= 1: not a value that matters
            out.append(row)
        return out

    def notes(self, n: int | None = None, key: str = "cost") -> list[str]:
        """Notes on the best ``n`` rows (all with None): :data:`~distctrl.tuning.space.D_TV_NOTE` when one of
        them has kp >= 1 and d_tv is a column."""
        if "kp" not in self.data or "d_tv" not in self.data or not len(self):
            return []
        rows = self.order(key)[:n] if n is not None else range(len(self))
        return [D_TV_NOTE] if any(not d_tv_applies(self.data["kp"][int(i)]) for i in rows) else []

    def render(self, n: int = 10, key: str = "cost", plain: bool = False, title: str | None = None) -> str:
        """The best ``n`` rows as a text table."""
        params = [c for c in PARAM_COLUMNS if c in self.data and len(set(map(str, self.data[c]))) > 1] \
            or [c for c in ("kp", "filter_type") if c in self.data]
        mets = ["cost", "rms_error", "max_error", "overshoot", "osc_index", "hf_rms", "offset_hf_rms",
                "settle_time_50um", "sat_share"]
        cols = params + [m for m in mets if m in self.data]

        rows = []
        for i in self.order(key)[:n]:
            ft = _plain(self.data["filter_type"][i]) if "filter_type" in self.data else None
            used = set(filter_fields(FilterType[ft])) if isinstance(ft, str) and ft in FilterType.__members__ else None
            # a filter parameter the row's filter does not use is "-", not a value that does nothing
            inert = {"d_tv"} if "kp" in self.data and not d_tv_applies(self.data["kp"][i]) else set()
            rows.append(["-" if (c in PARAM_COLUMNS and c not in ("kp", "i_tn", "d_tv", "filter_type")
                                 and used is not None and c not in used) or c in inert else
                         (_fmt_param(self.data[c][i]) if c in PARAM_COLUMNS else _fmt(self.data[c][i]))
                         for c in cols])
        units = self.units()
        heads = [f"{c} [{units[c]}]" if c in units else c for c in cols]
        text = render_table(heads, rows, title=title, plain=plain)
        if "d_tv" in cols:
            text += "".join(f"note: {s}\n" for s in self.notes(n, key))
        return text

    def to_dict(self, top: int = 10, key: str = "rms_error") -> dict:
        """What ``distctrl sweep --json`` prints of the result: the ranking ``metric``, the sets, cycles,
        seconds and throughput (set-cycles per second), how it ran (mode, workers), the best ``top``
        rows (:meth:`best_rows`), the units and the notes."""
        info = self.info
        sets, cycles, seconds = info.get("sets", len(self)), info.get("cycles"), info.get("seconds")
        rate = sets * cycles / max(seconds, 1e-9) if cycles is not None and seconds is not None else None
        return {"metric": key, "sets": sets, "cycles": cycles, "seconds": seconds, "set_cycles_per_s": rate,
                "mode": info.get("mode"), "workers": info.get("workers"), "best": self.best_rows(top, key=key),
                "units": self.units(), "notes": self.notes(top, key=key)}

    def plot(self, path=None, metric: str = "rms_error"):
        """A heatmap of ``metric`` over the two swept parameters with the most values (the best value
        over the others), or parallel coordinates when fewer than two numeric parameters vary or the
        grid is irregular. A Figure on an Agg canvas, saved to ``path`` when given."""
        # matplotlib is imported here only: it stays off the import path of the batch kernel and the CLI
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        fig = Figure(figsize=(9, 6), constrained_layout=True)
        FigureCanvasAgg(fig)
        ax = fig.subplots()
        varied = [c for c in PARAM_COLUMNS if c in self.data and len(set(map(str, self[c]))) > 1]
        numeric = [c for c in varied if c != "filter_type"]
        counts = {c: len(set(map(str, self[c]))) for c in numeric}
        two = sorted(numeric, key=lambda c: -counts[c])[:2]
        if len(two) == 2 and counts[two[0]] * counts[two[1]] <= len(self) and counts[two[0]] <= 60 \
                and counts[two[1]] <= 60:
            self._heatmap(fig, ax, two, metric)
        else:
            self._parallel(fig, ax, varied or ["kp"], metric)
        if path is not None:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            fig.savefig(path, dpi=110)
        return fig

    def _heatmap(self, fig, ax, two: list[str], metric: str) -> None:
        y = np.asarray(self[metric], dtype=float)
        xs = np.unique(np.asarray(self[two[0]], dtype=float))
        ys = np.unique(np.asarray(self[two[1]], dtype=float))
        grid = np.full((len(ys), len(xs)), np.nan)
        xi = np.searchsorted(xs, np.asarray(self[two[0]], dtype=float))
        yi = np.searchsorted(ys, np.asarray(self[two[1]], dtype=float))
        for a, b, v in zip(yi, xi, y):
            if np.isfinite(v) and not (grid[a, b] <= v):
                grid[a, b] = v
        im = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis")
        ax.set_xticks(range(len(xs)), [f"{v:.4g}" for v in xs], rotation=60, fontsize=7)
        ax.set_yticks(range(len(ys)), [f"{v:.4g}" for v in ys], fontsize=7)
        ax.set_xlabel(two[0])
        ax.set_ylabel(two[1])
        fig.colorbar(im, ax=ax, label=f"{metric} (best over the other parameters)")
        ax.set_title(f"{metric} over {two[0]} x {two[1]} ({len(self)} sets)")

    def _parallel(self, fig, ax, cols: list[str], metric: str) -> None:
        # matplotlib is imported here only (see plot)
        from matplotlib import colormaps
        from matplotlib.cm import ScalarMappable
        from matplotlib.colors import Normalize

        y = np.asarray(self[metric], dtype=float)
        mat = []
        for c in cols + [metric]:
            v = self[c]
            if c == "filter_type":
                names = sorted(set(v))
                v = [names.index(x) for x in v]
            v = np.asarray(v, dtype=float)
            lo, hi = np.nanmin(v[np.isfinite(v)]) if np.isfinite(v).any() else 0, \
                np.nanmax(v[np.isfinite(v)]) if np.isfinite(v).any() else 1
            mat.append((v - lo) / (hi - lo) if hi > lo else np.zeros_like(v))
        mat = np.asarray(mat)
        finite = np.isfinite(y)
        order = np.argsort(np.where(finite, y, np.inf))[::-1]
        # viridis: the smallest metric (the best set) is dark purple, the largest yellow; the best sets
        # are drawn last, on top (the order above is worst first)
        cmap = colormaps["viridis"]
        ylo, yhi = (np.min(y[finite]), np.max(y[finite])) if finite.any() else (0, 1)
        for i in order:
            c = cmap((y[i] - ylo) / (yhi - ylo) if finite[i] and yhi > ylo else 0.0) if finite[i] else "lightgray"
            ax.plot(range(len(cols) + 1), mat[:, i], color=c, lw=0.6, alpha=0.6)
        ax.set_xticks(range(len(cols) + 1), cols + [metric], fontsize=8)
        ax.set_ylabel("normalised value")
        fig.colorbar(ScalarMappable(Normalize(ylo, yhi if yhi > ylo else ylo + 1), cmap), ax=ax,
                     label=f"{metric} (dark = smaller = better)")
        ax.set_title(f"parallel coordinates, colour = {metric} ({len(self)} sets; dark = better)")
        _separate_tick_labels(fig, ax)


def _separate_tick_labels(fig, ax) -> None:
    """The x tick labels (the parallel coordinates' axis names) laid out so that none overlaps another, as
    matplotlib's renderer measures them: as they are, else every other one a row lower, else vertical
    (new-user audit R5: a random sweep's ten names ran into one string)."""
    renderer = fig.canvas.get_renderer()

    def overlapping() -> bool:
        fig.draw_without_rendering()                    # the constrained layout, as saved
        boxes = [t.label1.get_window_extent(renderer) for t in ax.xaxis.get_major_ticks()]
        return any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])

    if not overlapping():
        return
    ticks = ax.xaxis.get_major_ticks()
    row = max(t.label1.get_window_extent(renderer).height for t in ticks) * 72.0 / fig.dpi   # points
    for t in ticks[1::2]:
        t.set_pad(t.get_pad() + 1.2 * row)
    if overlapping():
        for t in ticks[1::2]:
            t.set_pad(t.get_pad() - 1.2 * row)
        ax.tick_params(axis="x", labelrotation=90)


def _plain(x):
    if isinstance(x, FilterType):
        return x.name
    if isinstance(x, np.generic):
        return x.item()
    return x


def csv_rows(data: dict) -> str:
    """The rows of a table (name -> column) as :meth:`SweepResult.to_csv` writes them below the header (the
    csv module's: a float as its repr, NaN and None as an empty field, a field with a comma, a quote or a line
    break quoted, ``\r\n`` after each row)."""
    cols = [_csv_column(v) for v in data.values()]
    if len(cols) < 2 or any(_CSV_SPECIAL.search(f) for c, v in zip(cols, data.values()) if _is_text(v) for f in c):
        # a text field to quote, or one column (an empty field alone on its row is written ""): the csv module
        buf = io.StringIO()
        csv.writer(buf).writerows(zip(*cols))
        return buf.getvalue()
    # no field to quote (numbers and names): the same text joined directly, a third faster than the csv
    # module (the fields are made once, column by column: a local sweep's 10 000 rows took 0.08 s on one core)
    return "".join([",".join(row) + "\r\n" for row in zip(*cols)])


#: what the csv module's QUOTE_MINIMAL quotes a field for (the delimiter, the quote, a line break)
_CSV_SPECIAL = re.compile(r'[,"\r\n]')


def _is_text(v) -> bool:
    """Whether a column's fields can hold text (a list, an object or string array) rather than numbers."""
    return isinstance(v, list) or v.dtype.kind in "OUS"


def _digest(data: dict) -> bytes:
    """A digest of a table's names and values (about a millisecond for 10 000 rows of 21 columns)."""
    h = hashlib.blake2b(digest_size=16)
    for k, v in data.items():
        h.update(k.encode() + b"\0")
        if isinstance(v, list):
            h.update(repr(v).encode())
        else:
            a = np.ascontiguousarray(v)
            h.update(f"{a.dtype.str}{a.shape}".encode())
            h.update(a.tobytes() if a.dtype.kind != "O" else repr(a.tolist()).encode())
    return h.digest()


def metric_columns(m: dict, osc_weight: float = 1.0, cost_weights: dict | None = None) -> dict:
    """The metric columns of a result table: ``cost`` (:func:`~distctrl.tuning.metrics.cost`), the metrics,
    ``failed`` and the first error's cycle and ID."""
    data = {"cost": cost(m, osc_weight, **(cost_weights or {}))}
    for name in METRIC_NAMES:
        data[name] = m[name]
    data["failed"] = m["failed"]
    data["error_cycle"] = m["error_cycle"]
    data["error_id"] = m["error_id"]
    return data


def points_table(base, sel, m: dict, osc_weight: float = 1.0, cost_weights: dict | None = None) -> dict:
    """The table of points ``sel`` (:class:`~distctrl.tuning.space.PointColumns`) over ``base`` with their
    metrics ``m``: the parameter columns, then :func:`metric_columns`."""
    data: dict[str, object] = {}
    for f in PARAM_COLUMNS:
        col = full_column(base, sel, f)
        data[f] = _FILTER_NAMES[col].tolist() if f == "filter_type" else col
    data.update(metric_columns(m, osc_weight, cost_weights))
    return data


def _csv_column(v) -> list[str]:
    """A column's CSV fields as text, what the csv module writes for each value (``_csv(_plain(x))``): a float
    as its repr, a NaN or None as an empty field, anything else as ``str``; by the column's type."""
    if isinstance(v, list):
        return [_csv(_plain(x)) for x in v]
    vals = v.tolist()
    if v.dtype.kind == "f":
        out = list(map(repr, vals))
        for i in np.flatnonzero(np.isnan(v)).tolist():
            out[i] = ""
        return out
    if v.dtype.kind in "iub":
        return list(map(str, vals))
    return [_csv(_plain(x)) for x in vals]


def _csv(x) -> str:
    if isinstance(x, float):
        return "" if math.isnan(x) else repr(x)
    return "" if x is None else str(x)


def _fmt_param(x) -> str:
    """A parameter value as used, in the shortest form that reads back as the same float (0.9, 1234.5)."""
    x = _plain(x)
    if isinstance(x, float) and math.isfinite(x):
        return repr(x)
    return _fmt(x)


def _fmt(x) -> str:
    x = _plain(x)
    if isinstance(x, float):
        if math.isnan(x):
            return "-"
        if math.isinf(x):
            return "inf"
        return f"{x:.4g}"
    return str(x)


# ----------------------------------------------------------------------------- evaluator

def _progress_wanted(progress) -> bool:
    if progress is not None:
        return bool(progress)
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


class Evaluator:
    """Evaluates parameter sets of one recorded scenario; a context manager (see the module docstring).

    ``metric_options``: keyword arguments of :func:`~distctrl.tuning.metrics.compute_metrics`
    (``skip``, ``band``, ``hold``, ``f_osc``); ``osc_weight``: weight of ``hf_rms`` in ``cost``.
    ``chunk_fn``: the chunk function (default :func:`evaluate_chunk`; tests substitute a flaky one).
    """

    def __init__(self, inputs, *, mode: str = "cluster", scheduler: str | None = None,
                 n_workers: int | None = None, chunk_size: int = DEFAULT_CHUNK,
                 chunk_bytes: int = DEFAULT_CHUNK_BYTES, retries: int = 2, progress: bool | None = None,
                 cycles: int | None = None, metric_options: dict | None = None, osc_weight: float = 1.0,
                 chunk_fn=None, threads: int | None = None, log=None, cost_weights: dict | None = None):
        if scheduler:
            mode = "cluster"
        if mode not in ("local", "cluster"):
            raise TuningRunError(f"mode {mode!r}: 'local' or 'cluster'")
        self.inputs = inputs
        self.mode = mode
        self.scheduler = scheduler
        self.n_workers = n_workers or os.cpu_count() or 1
        self.cycles = cycles
        n = inputs.n_cycles if cycles is None else int(cycles)
        self.n_cycles = n
        self.chunk_size = max(1, min(int(chunk_size), int(chunk_bytes // (16 * max(n, 1))) or 1))
        self.retries = int(retries)
        self.progress = _progress_wanted(progress)
        self.metric_options = dict(metric_options or {})
        self.osc_weight = osc_weight
        self.chunk_fn = chunk_fn or evaluate_chunk
        self.threads = threads
        self._slim = slim_inputs(inputs)
        self._client = None
        self._cluster = None
        self._remote_inputs = None
        self.stats = {"sets": 0, "set_cycles": 0, "seconds": 0.0, "chunks": 0, "retried": 0, "compile_s": 0.0}
        self.log = log or (lambda message: None)
        self.cost_weights = dict(cost_weights or {})
        self._opening = None           # the thread that opens the cluster (open(wait=False))
        self._open_error = None
        self._kernels_ready = False

    # -- lifecycle
    def __enter__(self) -> "Evaluator":
        self.open(wait=False)
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def open(self, wait: bool = True) -> None:
        """Start the cluster (cluster mode). ``wait=False``: in a background thread, so that the caller
        prepares its parameter sets meanwhile; :meth:`evaluate` waits for it."""
        if self.mode != "cluster":
            return
        if self._opening is None and self._client is None:
            self._open_error = None
            self._opening = threading.Thread(target=self._open_now, name="distctrl-cluster-start", daemon=True)
            self._opening.start()
        if wait:
            self._wait_open()

    def _wait_open(self) -> None:
        if self._opening is not None:
            self._opening.join()
            self._opening = None
        if self._open_error is not None:
            exc, self._open_error = self._open_error, None
            raise exc

    def _open_now(self) -> None:
        try:
            self._open_cluster()
        except BaseException as exc:          # noqa: BLE001 - raised again in the caller's thread
            self._open_error = exc

    def _open_cluster(self) -> None:
        try:
            # dask.distributed (the [batch] extra, seconds of import): only for a cluster sweep
            import dask
            from distributed import Client, LocalCluster
        except ImportError:
            raise TuningRunError("cluster mode needs dask.distributed: pip install 'dask[distributed]' "
                                 "(or use --local)") from None
        try:
            if self.scheduler:
                self._client = Client(self.scheduler, timeout="20s")
            else:
                # while the servers are made: they read their timers then, and each nanny hands this
                # config to the worker process it spawns (and to a worker it restarts)
                with dask.config.set(EMBEDDED_CLUSTER_CONFIG):
                    self._cluster = LocalCluster(n_workers=self.n_workers, threads_per_worker=1, processes=True,
                                                 dashboard_address=":0", silence_logs=logging.ERROR)
                    self._client = Client(self._cluster)
        except OSError as exc:
            self.close()
            raise TuningRunError(f"cannot reach the dask scheduler {self.scheduler or '(local)'}: {exc}") from None
        self._remote_inputs = self._hold_inputs()

    def _hold_inputs(self):
        """The recorded inputs as a cluster value that survives losing any worker. Scattered data
        cannot be recovered when the workers holding it die (a death then cancelled every chunk);
        the result of a task is recomputed from the task, which the scheduler keeps."""
        return self._client.submit(_hold, self._slim, pure=False)

    def close(self) -> None:
        if self._opening is not None and self._opening is not threading.current_thread():
            try:
                self._wait_open()
            except Exception:                 # noqa: BLE001 - closing anyway
                pass
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None
        self._remote_inputs = None

    def set_inputs(self, inputs) -> None:
        """Evaluate further sets on another recording (e.g. a perturbed scenario); same cluster."""
        self.inputs = inputs
        self.n_cycles = inputs.n_cycles if self.cycles is None else int(self.cycles)
        self._slim = slim_inputs(inputs)
        if self._client is not None:
            self._remote_inputs = self._hold_inputs()

    # -- work
    def evaluate(self, param_sets, points: list[dict] | None = None, *, description: str = "sweep") -> SweepResult:
        """Metrics of every set (a list of AxisParameters); ``points``: what each set changes (for the
        table; default: the tuning fields of the sets)."""
        # numba (the [batch] extra) loads only when a batch runs
        from ..batch.closed_loop import pack_sets

        param_sets = list(param_sets)
        if not param_sets:
            return SweepResult(self._table([], [], {}))
        packed = pack_sets(self.inputs, param_sets)
        return self._evaluate_packed(packed, lambda m: self._table(param_sets, points, m), param_sets, description)

    def evaluate_points(self, base, points, *, description: str = "sweep") -> SweepResult:
        """:meth:`evaluate` of the sets ``base`` with the values of ``points`` (a
        :class:`~distctrl.tuning.columns.PointColumns`), checked, designed, packed, run and measured chunk by
        chunk where the chunks run (:func:`evaluate_points_chunk`: on the workers of a cluster), so that only
        the points' columns travel (issue 27). The points a check refuses are left out of the table and
        listed in ``result.rejected`` as ``(point, message)``, in order; ``result.info["kept"]``: the indices
        of the points in the table. The same table as :meth:`evaluate` of what
        :func:`~distctrl.tuning.space.build_sets` keeps (tests/tuning/test_runner.py)."""
        if set(points.cols) - COLUMN_FIELDS:
            raise TuningRunError(f"evaluate_points: fields {sorted(set(points.cols) - COLUMN_FIELDS)} are not "
                                 "evaluated as columns (use evaluate)")
        n = points.n
        if not n:
            return SweepResult(self._table([], [], {}))
        block = self.chunk_size
        self.prepare_kernels()
        # a cluster's tasks: about eight per worker (load balance: the last task's tail), in this process
        # about eight chunks (the progress bar's steps). Every chunk runs its points block by block (the
        # traces of a block at a time); in this process the chunks run side by side where they can (_run_local)
        side = self._local_cores() if self.mode == "local" else 1
        bounds = chunk_bounds(n, block, 8 if self.mode == "local" else 8 * self.n_workers, side)
        chunks = [_PointChunk(points.take(np.arange(a, b)), a, block) for a, b in bounds]
        probe = _probe_of(self.inputs, base)
        t0 = time.perf_counter()
        extra = (base, probe)
        if self.mode == "local":
            parts = self._run_local(chunks, description, evaluate_points_chunk, extra, ahead=check_points_chunk,
                                    options={"csv_options": {"osc_weight": self.osc_weight,
                                                             "cost_weights": self.cost_weights}})
        else:
            self.open()
            parts = self._run_cluster(chunks, description, evaluate_points_chunk, extra)
        kept = np.concatenate([p.pop("_kept") for p in parts])
        rejected = [r for p in parts for r in p.pop("_rejected")]
        for p in parts:
            self.stats["kernel_s"] = self.stats.get("kernel_s", 0.0) + float(p.pop("_kernel_s"))
            self.stats["task_s"] = self.stats.get("task_s", 0.0) + float(p.pop("_task_s"))
        parts = [p for p in parts if len(p["failed"])]
        texts = [p.pop("_csv", None) for p in parts]
        n_sets = len(kept)
        info = self._account(n_sets, time.perf_counter() - t0, len(chunks))
        if not n_sets:
            return SweepResult(self._table([], [], {}), rejected=rejected, info={"kept": kept})
        merged = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        table = points_table(base, points.take(kept), merged, self.osc_weight, self.cost_weights)
        # the chunks' rows of the CSV, in order (a local sweep made them beside the kernels)
        body = "".join(texts) if all(t is not None for t in texts) else None
        return SweepResult(table, params=[], rejected=rejected, info={**info, "kept": kept}, csv_body=body)

    def _evaluate_packed(self, packed, table, params, description) -> SweepResult:
        n_sets = len(packed)
        chunks = [packed[i:i + self.chunk_size] for i in range(0, len(packed), self.chunk_size)]
        self.prepare_kernels(packed[:1])
        t0 = time.perf_counter()
        if self.mode == "local":
            parts = self._run_local(chunks, description)
        else:
            self.open()
            parts = self._run_cluster(chunks, description)
        merged = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        info = self._account(n_sets, time.perf_counter() - t0, len(chunks))
        return SweepResult(table(merged), params=params, info=info)

    def _account(self, n_sets: int, seconds: float, n_chunks: int) -> dict:
        """Add an evaluation to :attr:`stats`; its result's ``info``."""
        self.stats["sets"] += n_sets
        self.stats["set_cycles"] += n_sets * self.n_cycles
        self.stats["seconds"] += seconds
        self.stats["chunks"] += n_chunks
        return {"seconds": seconds, "sets": n_sets, "cycles": self.n_cycles, "mode": self.mode,
                "workers": self.n_workers if self.mode == "cluster" else 1}

    def prepare_kernels(self, packed_one=None) -> None:
        """Compile the batch kernels once, before the sets run, and say so (the first use on a machine,
        or after a change of distctrl's sources, takes tens of seconds; afterwards the kernels load
        from numba's disk cache, :mod:`distctrl.batch.jitcache`). In local mode and with the embedded
        cluster this process compiles them (the workers, on the same machine, then load them from the
        cache); with ``scheduler`` the workers compile on their first chunk, which is only announced."""
        if self._kernels_ready:
            return
        self._kernels_ready = True
        # numba (the [batch] extra) loads only when a batch runs
        from ..batch.jitcache import cache_dir, is_cached
        from ..batch.warm import run_signatures

        entry, argtypes = run_signatures()[0]          # the closed loop's kernel, as run_batch calls it
        if is_cached(entry, argtypes):
            if self.mode == "local" and not entry.signatures:
                # load the cached code now (about 0.5 s), so that the sweep's time is the sweep's
                # numba (the [batch] extra) loads only when a batch runs
                from ..batch.closed_loop import pack_sets, run_batch

                packed = packed_one if packed_one is not None and len(packed_one) else \
                    pack_sets(self.inputs, [self.inputs.params])
                run_batch(self.inputs, packed, cycles=min(8, self.n_cycles), threads=self.threads)
            return
        where = cache_dir(entry) or "memory only (no writable cache folder)"
        if self.scheduler:
            self.log("note: the workers compile the batch kernels on their first chunk if they have not "
                     "yet (about 30 s per machine, cached on disk afterwards)")
            return
        # numba (the [batch] extra) loads only when a batch runs
        from ..batch.closed_loop import pack_sets, run_batch

        packed = packed_one if packed_one is not None and len(packed_one) else pack_sets(self.inputs,
                                                                                         [self.inputs.params])
        # numba (the [batch] extra) loads only when a batch runs
        from ..batch.warm import COMPILING, announced

        text = COMPILING.format(where=where)
        t0 = time.perf_counter()
        status = None
        if self.progress:
            # rich (0.1 s of import): only where a table or progress bar is printed
            from rich.console import Console

            status = Console(stderr=True).status(text)
            status.start()
        elif not announced():           # the command said it already, first thing (audit R17)
            self.log(text)
        try:
            run_batch(self.inputs, packed, cycles=min(8, self.n_cycles), threads=self.threads)
        finally:
            if status is not None:
                status.stop()
        dt = time.perf_counter() - t0
        self.stats["compile_s"] += dt
        self.log(f"compiled in {dt:.1f} s")

    def _table(self, sets, points, m) -> dict:
        data: dict[str, object] = {}
        for f in PARAM_COLUMNS:
            vals = [getattr(p, f) for p in sets]
            data[f] = [v.name for v in vals] if f == "filter_type" else np.asarray(vals)
        if sets:
            data.update(self._metric_columns(m))
        return data

    def _metric_columns(self, m) -> dict:
        return metric_columns(m, self.osc_weight, self.cost_weights)

    def _bar(self, total: int, description: str):
        if not self.progress:
            return None
        # rich (0.1 s of import): only where a table or progress bar is printed
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

        bar = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                       TextColumn("sets"), TimeRemainingColumn(), console=Console(stderr=True), transient=True)
        bar.start()
        bar.add_task(description, total=total)
        return bar

    def _run_local(self, chunks, description, fn=None, extra=None, ahead=None, options=None) -> list[dict]:
        """``fn(inputs, chunk, cycles, metric_options, threads, *extra, **options)`` of every chunk (default:
        chunk_fn), in this process.

        With ``ahead`` (the first part of ``fn``, checking a chunk's points: ``ahead(inputs, chunk, *extra)``,
        handed to ``fn`` as ``checked=``) and all cores wanted (``threads`` None), where numba runs parallel
        kernels from two threads at once (threading layers tbb and omp): one chunk per core side by side,
        each on one numba thread (:meth:`_chunks_side_by_side`). Otherwise one chunk after the other on all
        cores, the next chunk checked in a second thread meanwhile (:meth:`_chunks_in_turn`)."""
        fn = fn or self.chunk_fn
        extra = tuple(extra or ())
        if options:
            fn = functools.partial(fn, **options)
        bar = self._bar(sum(len(c) for c in chunks), description)
        try:
            cores = self._local_cores() if ahead is not None and len(chunks) > 1 else 1
            if cores > 1:
                return self._chunks_side_by_side(chunks, fn, extra, cores, bar)
            return self._chunks_in_turn(chunks, fn, extra, ahead, bar)
        finally:
            if bar is not None:
                bar.stop()

    def _local_cores(self) -> int:
        """How many chunks run side by side in this process (:meth:`_chunks_side_by_side`): numba's threads
        where its threading layer allows it and no ``threads`` is given, else 1."""
        return _side_by_side_cores() if self.threads is None else 1

    def _chunk(self, fn, chunk, extra, threads, checked=None) -> dict:
        """``fn`` of one chunk, retried up to ``retries`` times (a retry runs it whole: ``checked`` only first)."""
        for attempt in range(self.retries + 1):
            try:
                kw = {"checked": checked} if checked is not None and attempt == 0 else {}
                return fn(self._slim, chunk, self.cycles, self.metric_options, threads, *extra, **kw)
            except Exception as exc:          # noqa: BLE001 - retried, then reported
                if attempt == self.retries:
                    raise TuningRunError(f"a chunk of {len(chunk)} sets failed after {self.retries} "
                                         f"retries: {type(exc).__name__}: {exc}") from exc
                self.stats["retried"] += 1
        raise AssertionError("unreachable")

    def _chunks_side_by_side(self, chunks, fn, extra, cores: int, bar) -> list[dict]:
        """One chunk per core at a time, each whole (checked, run and measured) on one numba thread: no
        barrier between the kernel's threads, the metrics pass and the FFTs of a block, and one chunk's
        check (Python, holding the GIL) beside the other's kernel. On two cores a 10 000-set sweep took
        0.71-0.73 s against 0.74 s for one chunk after the other on both (docs/tuning.md)."""
        with ThreadPoolExecutor(cores, thread_name_prefix="distctrl-chunk") as pool:
            futures = [pool.submit(self._chunk, fn, c, extra, 1) for c in chunks]
            try:
                for f, c in zip(futures, chunks):
                    f.result()
                    if bar is not None:
                        bar.advance(0, len(c))
            except BaseException:
                for f in futures:
                    f.cancel()
                raise
        return [f.result() for f in futures]

    def _chunks_in_turn(self, chunks, fn, extra, ahead, bar) -> list[dict]:
        """One chunk after the other on all cores; with ``ahead``, the next chunk's points are checked in a
        second thread meanwhile (Python and numpy, mostly holding the GIL, which the kernel and the FFTs do not:
        it fills what they leave of the cores instead of running alone); a failed check ahead is redone by
        the chunk's own ``fn``."""
        parts = []
        pool = ThreadPoolExecutor(1, thread_name_prefix="distctrl-check") if ahead and len(chunks) > 1 else None
        try:
            upcoming = pool.submit(ahead, self._slim, chunks[0], *extra) if pool else None
            for k, c in enumerate(chunks):
                checked = None
                if upcoming is not None:
                    try:
                        checked = upcoming.result()
                    except Exception:                 # noqa: BLE001 - fn checks again and reports it
                        checked = None
                    upcoming = pool.submit(ahead, self._slim, chunks[k + 1], *extra) if k + 1 < len(chunks) else None
                parts.append(self._chunk(fn, c, extra, self.threads, checked))
                if bar is not None:
                    bar.advance(0, len(c))
        finally:
            if pool is not None:
                pool.shutdown(wait=True, cancel_futures=True)
        return parts

    def _run_cluster(self, chunks, description, fn=None, extra=None) -> list[dict]:
        # dask.distributed (the [batch] extra, seconds of import): only for a cluster sweep
        from distributed import as_completed

        fn = fn or self.chunk_fn
        extra = tuple(extra or ())
        client = self._client
        threads = self.threads if self.threads is not None else (1 if not self.scheduler else None)
        futures = [client.submit(fn, self._remote_inputs, c, self.cycles, self.metric_options,
                                 threads, *extra, retries=self.retries, pure=False) for c in chunks]
        index = {f.key: i for i, f in enumerate(futures)}
        running = {f.key: f for f in futures}
        done = as_completed(futures)
        del futures
        parts: list = [None] * len(chunks)
        bar = self._bar(sum(len(c) for c in chunks), description)
        try:
            for fut in done:
                i = index[fut.key]
                try:
                    parts[i] = fut.result()
                except Exception as exc:              # noqa: BLE001
                    for f in running.values():
                        f.cancel()
                    raise TuningRunError(f"chunk {i} ({len(chunks[i])} sets) failed after {self.retries} "
                                         f"retries: {type(exc).__name__}: {exc}") from exc
                # fetched: release it at once, so a worker dying later does not make dask recompute it
                running.pop(fut.key).release()
                del fut
                if bar is not None:
                    bar.advance(0, len(chunks[i]))
        finally:
            if bar is not None:
                bar.stop()
        return parts


def evaluate(inputs, param_sets, points=None, **options) -> SweepResult:
    """One-shot :class:`Evaluator`: open, evaluate ``param_sets``, close."""
    with Evaluator(inputs, **options) as ev:
        return ev.evaluate(param_sets, points)


def plot_sweep(result: SweepResult, path=None, metric: str = "rms_error"):
    """:meth:`SweepResult.plot` (kept as a function for its callers)."""
    return result.plot(path, metric)
