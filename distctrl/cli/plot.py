"""``distctrl plot TRACE``: a scope-style plot of a saved trace, with state bands and error markers
(:func:`distctrl.trace.plot_file.plot_trace_file`; docs/workbench-report.md)."""
from __future__ import annotations

from pathlib import Path

import click

from ..errors import DistCtrlError
from ..errors.files import PLOT_SUFFIXES
from ..trace.plot_file import plot_trace_file
from .common import Finite, check_output, emit_json, fail, output_error_text

#: what -o may be called (matplotlib's formats by suffix; .jpg is JPEG)
OUTPUT_SUFFIXES = (*PLOT_SUFFIXES, ".jpg", ".jpeg")


# ------------------------------------------------------------------------------------------------------
# the command
# ------------------------------------------------------------------------------------------------------
def _split_signals(value: str | None) -> list[str] | None:
    if value is None:
        return None
    return [s.strip() for s in value.split(",") if s.strip()]


@click.command("plot")
@click.argument("trace_csv", metavar="TRACE", type=click.Path(dir_okay=False))
@click.option("--signals", help="Comma-separated columns to plot (one panel per unit); default: the "
              "standard panels (positions, distance-control signals, distance).")
@click.option("--from", "t_from", type=Finite(min=0.0), default=None, help="Start of the time window [s].")
@click.option("--to", "t_to", type=Finite(min=0.0), default=None, help="End of the time window [s].")
@click.option("-o", "--output", "out", type=click.Path(dir_okay=False),
              help="Output file (.png, .svg, .pdf, .jpg); default: TRACE with the suffix .png.")
@click.option("--errors", "errors_path", type=click.Path(dir_okay=False),
              help="JSON of 'distctrl run --json' whose errors/warnings are marked (default: the "
              "trace sidecar's meta, if it lists them).")
@click.option("--title", default=None, help="Figure title (default: the trace's program/scenario).")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object saying what was written (trace, output, format, bytes, signals, window).")
def plot(trace_csv: str, signals: str | None, t_from: float | None, t_to: float | None, out: str | None,
         errors_path: str | None, title: str | None, as_json: bool) -> None:
    """Plot a saved trace TRACE (.csv with its sidecar, or .parquet, as `distctrl run --trace` writes
    them) scope-style: signals over time, state bands, error markers.

    Exit code 0 when the plot was written, 1 for a missing file, an unknown signal (the message
    names the closest column), an empty time window, an unsupported output format or an output
    that cannot be written (the message names it and why).
    """
    names = _split_signals(signals)
    check_output(out, "plot", OUTPUT_SUFFIXES)
    try:
        path = plot_trace_file(trace_csv, out, names, t_from, t_to, errors_path, title)
    except DistCtrlError as exc:
        fail(str(exc))
    except OSError as exc:
        fail(output_error_text(exc, out if out is not None else str(Path(trace_csv).with_suffix(".png")), "plot"))
    if as_json:
        fmt = path.suffix.lstrip(".").lower()
        emit_json({"command": "plot", "trace": str(trace_csv), "output": str(path),
                   "format": "jpeg" if fmt == "jpg" else fmt, "bytes": path.stat().st_size,
                   "signals": names, "from_s": t_from, "to_s": t_to, "title": title})
        return
    click.echo(f"wrote {path}")

