"""What the workbench's plots may be saved as, checked before any work is done."""
from __future__ import annotations

import os
from pathlib import Path

from ..errors import DistCtrlError
from ..errors.files import PLOT_SUFFIXES, check_suffix

__all__ = ["PLOT_SUFFIXES", "check_plot_suffix"]


def check_plot_suffix(path: str | os.PathLike, error: type[DistCtrlError] = DistCtrlError) -> Path:
    """``path`` as a Path; raises ``error`` (naming the path and the allowed suffixes) for another suffix."""
    return check_suffix(path, "plot", PLOT_SUFFIXES, error)
