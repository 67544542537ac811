"""Per-cycle trace recording, CSV export/load and plotting (docs/trace.md).

``TraceRecorder`` records one row of floats per cycle (``append``), streams float64 chunks to a CSV
file and/or keeps them; ``close()`` returns a ``Trace`` (columns, units, data, meta) that can be
saved (``to_csv``), loaded (``Trace.from_csv``) and drawn (``plot``, matplotlib imported lazily).
"""
from .reader import is_parquet, is_trace_file, load_trace
from .recorder import HLI_STATE_NAMES, Trace, TraceRecorder, format_rows, sidecar_path

__all__ = ["Trace", "TraceRecorder", "format_rows", "sidecar_path", "HLI_STATE_NAMES", "load_trace",
           "is_trace_file", "is_parquet"]
