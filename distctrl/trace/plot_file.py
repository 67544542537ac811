"""A saved trace drawn to a file: :func:`plot_trace_file` (``distctrl plot TRACE``; docs/workbench-report.md)."""
from __future__ import annotations

import os
from pathlib import Path

from .plot import (OUTPUT_FORMATS, PlotError, add_event_markers, load_events, plot_trace, resolve_signals,
                   slice_trace)
from .reader import load_trace

__all__ = ["plot_trace_file"]

#: the resolution of the written figure (dpi)
_SAVE_DPI = 110


def plot_trace_file(trace_csv: str | os.PathLike, out: str | os.PathLike | None = None,
                    signals: list[str] | None = None, t0: float | None = None, t1: float | None = None,
                    errors_path: str | os.PathLike | None = None, title: str | None = None) -> Path:
    """Load a trace (a CSV with its sidecar, or the ``.parquet`` file ``distctrl run`` writes), draw it
    and save the figure; returns the output path.

    Default ``out``: the trace's path with the suffix ``.png``. Raises :class:`PlotError`.
    """
    src = Path(trace_csv)
    if not src.is_file():
        raise PlotError(f"{src}: no such trace file" if not src.exists() else f"{src}: not a file")
    try:
        trace = load_trace(src)               # CSV with its sidecar, or Parquet
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise PlotError(f"{src}: cannot read the trace: {exc}") from None
    sigs = resolve_signals(trace, signals, str(src)) if signals is not None else None
    if t0 is not None and t1 is not None and t1 <= t0:
        raise PlotError(f"--to ({t1:g}) must be after --from ({t0:g})")
    events = load_events(trace, errors_path)
    part = slice_trace(trace, t0, t1)
    if part.rows == 0:
        span = f"{trace.t[0]:g} .. {trace.t[-1]:g} s" if trace.rows else "no rows"
        raise PlotError(f"{src}: no rows between --from {t0} and --to {t1} (the trace covers {span})")
    out_path = Path(out) if out is not None else src.with_suffix(".png")
    fmt = out_path.suffix.lstrip(".").lower()
    fmt = "jpeg" if fmt == "jpg" else fmt
    if fmt not in OUTPUT_FORMATS:
        raise PlotError(f"{out_path}: the output must end in .png, .svg, .pdf, .jpg or .jpeg")
    heading = title
    if heading is None:
        heading = part.meta.get("title") or part.meta.get("program") or part.meta.get("scenario") or src.name
    fig = plot_trace(part, signals=sigs, title=str(heading))
    add_event_markers(fig, events, float(part.t[0]), float(part.t[-1]))
    out_path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_path, dpi=_SAVE_DPI, format=fmt)
    return out_path
