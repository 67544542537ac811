"""Traces as Parquet: moved to :mod:`distctrl.trace.parquet` (a trace format, read by the trace reader);
this name stays for code that imports it from here."""
from ..trace.parquet import METADATA_KEY, ParquetError, from_parquet, require_pyarrow, to_parquet

__all__ = ["METADATA_KEY", "ParquetError", "from_parquet", "require_pyarrow", "to_parquet"]
