"""What the workbench's plots may be saved as, checked before any work is done."""
from __future__ import annotations

import os
from pathlib import Path

from ..errors import DistCtrlError

#: the suffixes the step, filter and margin plots are written as (matplotlib picks the format by it)
PLOT_SUFFIXES = (".png", ".svg", ".pdf")


def check_plot_suffix(path: str | os.PathLike, error: type[DistCtrlError] = DistCtrlError) -> Path:
    """``path`` as a Path; raises ``error`` (naming the path and the allowed suffixes) for another suffix."""
    p = Path(path)
    if p.suffix.lower() not in PLOT_SUFFIXES:
        raise error(f"plot file {str(p)!r}: suffix {p.suffix or '(none)'!r} not supported; allowed: "
                    f"{', '.join(PLOT_SUFFIXES)}")
    return p
