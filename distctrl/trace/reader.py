"""Reading a trace that ``distctrl run --trace`` wrote, whichever format: the one reader of ``plot``,
``identify`` and ``filters --recording``.

* :func:`is_parquet`: a Parquet file (its magic bytes ``PAR1``, whatever its name);
* :func:`is_trace_file`: a distctrl trace: a Parquet file, or a CSV with its ``.meta.json`` sidecar;
* :func:`load_trace`: the :class:`~distctrl.trace.Trace` of either (Parquet through
  :mod:`distctrl.trace.parquet`, which needs pyarrow).
"""
from __future__ import annotations

import os
from pathlib import Path

from .parquet import from_parquet
from .recorder import Trace, sidecar_path

__all__ = ["is_parquet", "is_trace_file", "load_trace"]

#: the first (and last) four bytes of every Parquet file
PARQUET_MAGIC = b"PAR1"


def is_parquet(path: str | os.PathLike) -> bool:
    """True when ``path`` is a Parquet file (by its magic bytes, so a misnamed one is found too)."""
    try:
        with open(path, "rb") as f:
            return f.read(4) == PARQUET_MAGIC
    except OSError:
        return False


def is_trace_file(path: str | os.PathLike) -> bool:
    """True for a distctrl trace: a Parquet file or a CSV beside its ``.meta.json`` sidecar."""
    return is_parquet(path) or sidecar_path(path).exists()


def load_trace(path: str | os.PathLike) -> Trace:
    """The trace in ``path``: Parquet (``run --trace x.parquet``) or CSV with its sidecar.

    Raises ``ValueError`` or ``OSError`` for a CSV that cannot be read, and
    :class:`~distctrl.trace.parquet.ParquetError` (a DistCtrlError) for a Parquet file that
    cannot (pyarrow missing, not numeric columns).
    """
    if is_parquet(path):
        return from_parquet(Path(path))
    return Trace.from_csv(path)
