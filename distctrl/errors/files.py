"""The name of an output file checked before any work: its suffix decides its format (a plot's PNG/SVG/PDF,
a table's CSV/Parquet), so a suffix the writer does not know is refused at the edge, in one line naming
the file and the suffixes allowed (docs/cli.md), never after a long run."""
from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from . import DistCtrlError

__all__ = ["PLOT_SUFFIXES", "TABLE_SUFFIXES", "check_suffix"]

#: what plots are saved as (matplotlib picks the format by the suffix)
PLOT_SUFFIXES = (".png", ".svg", ".pdf")
#: what traces and result tables are written as (CSV, or Parquet with pyarrow)
TABLE_SUFFIXES = (".csv", ".parquet")


def check_suffix(path: str | os.PathLike, what: str, allowed: Sequence[str],
                 error: type[DistCtrlError] = DistCtrlError) -> Path:
    """``path`` as a Path; raises ``error`` for a suffix not in ``allowed`` (lower case, with the dot):
    ``plot file 'f.bmp': suffix '.bmp' not supported; allowed: .png, .svg, .pdf``."""
    p = Path(path)
    if p.suffix.lower() not in allowed:
        raise error(f"{what} file {str(p)!r}: suffix {p.suffix or '(none)'!r} not supported; allowed: "
                    f"{', '.join(allowed)}")
    return p
