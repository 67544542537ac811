"""Traces as Parquet files: ``to_parquet(trace, path)`` and ``from_parquet(path) -> Trace``.

One float64 column per trace column, in order. The units and the meta travel in the Parquet schema
metadata under the key ``distctrl.trace`` (JSON: ``{"format": "distctrl-trace", "version": 1,
"columns": [...], "units": {...}, "meta": {...}}``, the same document as the CSV sidecar), and each
field carries its unit in its own metadata (``unit``), so other tools (pandas, polars, DuckDB) see
them too. Values round-trip bit for bit (NaN, infinities and -0.0 included).

pyarrow is optional and imported only when called; without it the functions raise
:class:`~distctrl.errors.DistCtrlError` naming the ``[parquet]`` extra that installs it. See
docs/workbench-report.md.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from ..errors import DistCtrlError
from .recorder import Trace, json_default

__all__ = ["to_parquet", "from_parquet", "ParquetError", "METADATA_KEY"]

#: key of the distctrl document in the Parquet schema metadata
METADATA_KEY = b"distctrl.trace"
_FORMAT_NAME = "distctrl-trace"
_FORMAT_VERSION = 1


class ParquetError(DistCtrlError):
    """pyarrow is missing, or a Parquet file is not a readable trace."""


def _pyarrow():
    try:
        # the [parquet] extra, loaded when a Parquet trace is read or written: CSV traces work without it
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError as exc:
        raise ParquetError("Parquet traces need pyarrow, which is not installed: pip install "
                           f"'distctrl[parquet]' ({exc})") from None
    return pa, pq


def require_pyarrow() -> None:
    """Raise ParquetError (naming the [parquet] extra) unless Parquet traces can be written."""
    _pyarrow()




def to_parquet(trace: "Trace", path: str | os.PathLike, *, compression: str = "zstd") -> Path:
    """Write ``trace`` to a Parquet file (parents created); returns the path.

    ``compression``: any codec pyarrow knows (``"zstd"`` default, ``"snappy"``, ``"none"``, ...).
    """
    pa, pq = _pyarrow()
    path = Path(path)
    doc = {"format": _FORMAT_NAME, "version": _FORMAT_VERSION, "columns": list(trace.columns),
           "units": dict(trace.units), "meta": trace.meta, "rows": int(trace.rows)}
    text = json.dumps(doc, default=json_default, allow_nan=True)
    fields = [pa.field(c, pa.float64(), nullable=True,
                       metadata={b"unit": trace.units[c].encode("utf-8")} if c in trace.units else None)
              for c in trace.columns]
    schema = pa.schema(fields, metadata={METADATA_KEY: text.encode("utf-8")})
    data = np.ascontiguousarray(trace.data)
    arrays = [pa.array(np.ascontiguousarray(data[:, i]), type=pa.float64())
              for i in range(len(trace.columns))]
    table = pa.Table.from_arrays(arrays, schema=schema)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        pq.write_table(table, path, compression=None if compression == "none" else compression)
    except (OSError, ValueError, pa.ArrowException) as exc:
        raise ParquetError(f"{path}: cannot write the Parquet trace: {exc}") from None
    return path


def from_parquet(path: str | os.PathLike) -> "Trace":
    """Read a Parquet trace written by :func:`to_parquet` (or any Parquet file of numeric columns).

    Units and meta come from the schema metadata; without it (a foreign file) the units come from the
    fields' ``unit`` metadata and the meta is empty. Nulls become NaN.
    """
    pa, pq = _pyarrow()
    path = Path(path)
    if not path.is_file():
        raise ParquetError(f"{path}: no such Parquet file")
    try:
        table = pq.read_table(path)
    except (OSError, ValueError, pa.ArrowException) as exc:
        raise ParquetError(f"{path}: cannot read as Parquet: {exc}") from None
    schema = table.schema
    columns = list(schema.names)
    md = schema.metadata or {}
    units: dict[str, str] = {}
    meta: dict = {}
    if METADATA_KEY in md:
        try:
            doc = json.loads(md[METADATA_KEY].decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ParquetError(f"{path}: the {METADATA_KEY.decode()} metadata is not JSON: {exc}") from None
        if not isinstance(doc, dict) or doc.get("format") != _FORMAT_NAME:
            raise ParquetError(f"{path}: the {METADATA_KEY.decode()} metadata is not a "
                               f"{_FORMAT_NAME} document")
        units = {str(k): str(v) for k, v in (doc.get("units") or {}).items()}
        meta = doc.get("meta") or {}
    else:
        for f in schema:
            if f.metadata and b"unit" in f.metadata:
                units[f.name] = f.metadata[b"unit"].decode("utf-8")
    cols = []
    for name, col in zip(columns, table.columns):
        kind = col.type
        if not (pa.types.is_floating(kind) or pa.types.is_integer(kind) or pa.types.is_boolean(kind)):
            raise ParquetError(f"{path}: column {name!r} is {col.type}, not numeric")
        if col.null_count:
            col = col.cast(pa.float64()).fill_null(float("nan"))
        cols.append(np.asarray(col.to_numpy(), dtype=np.float64))
    data = np.column_stack(cols) if cols else np.empty((table.num_rows, 0))
    try:
        return Trace(columns, data, units=units, meta=meta)
    except ValueError as exc:
        raise ParquetError(f"{path}: not a trace: {exc}") from None
