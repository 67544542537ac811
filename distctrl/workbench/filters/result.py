"""One filter on one signal as a result (:class:`FilterResult`: ``to_dict``, ``to_csv``, ``plot``) and
the overlay of several on the raw signal (:func:`plot_overlay`, the documents' Figs. 10-17).

Part of :mod:`distctrl.workbench.filters` (docs/workbench-filters.md); the package face re-exports every name.
"""
from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ...base.kinds import FilterType
from ...control.filters import FilterConfig
from ...trace.plot import MAX_POINTS, envelope
from ..plotfiles import check_plot_suffix
from .signals import _check_edges
from .spec import KEY_ORDER, KEYS_BY_TYPE, WorkbenchError

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure


@dataclass(frozen=True)
class FilterResult:
    """One filter on one signal: the output and its metrics (NaN where not measurable).

    ``noise_rms`` [mm]; ``delay_s`` / ``dead_time_s``: time from the first (rising) edge until the
    output has made 50 % / 10 % of the step; ``overshoot_mm`` beyond the top level in the step's
    direction (0 if none), ``overshoot_pct`` in % of the step. ``t``, ``signal`` and ``edges`` are
    what :func:`compare` ran it on (s, mm, s), so that the result plots itself (:meth:`plot`) and
    writes its time series (:meth:`to_csv`); None for a result built by hand without them.
    """

    config: FilterConfig
    label: str
    output: np.ndarray
    noise_rms: float
    delay_s: float
    dead_time_s: float
    overshoot_mm: float
    overshoot_pct: float
    t: np.ndarray | None = field(default=None, repr=False, compare=False)
    signal: np.ndarray | None = field(default=None, repr=False, compare=False)
    edges: tuple[float, ...] | None = field(default=None, repr=False, compare=False)

    def to_dict(self) -> dict:
        """This config's entry of ``distctrl filters --json``: label, filter type, the parameters the
        type uses, and the metrics with their units in the names (NaN where not measurable)."""
        c = self.config
        used = KEYS_BY_TYPE.get(c.filter_type, ())
        params = {k: getattr(c, k) for k in KEY_ORDER if k in used}
        if c.filter_type == FilterType.DEFAULT:
            params["n_cycles"] = c.effective_n
        return {"label": self.label, "filter_type": c.filter_type.name, "params": params,
                "noise_rms_mm": float(self.noise_rms), "delay_s": float(self.delay_s),
                "dead_time_s": float(self.dead_time_s), "overshoot_mm": float(self.overshoot_mm),
                "overshoot_pct": float(self.overshoot_pct)}


    def _signal(self) -> tuple[np.ndarray, np.ndarray]:
        if self.t is None or self.signal is None:
            raise WorkbenchError(f"{self.label}: the result holds no signal; allowed: a result of compare()")
        return self.t, self.signal

    def plot(self, path: str | os.PathLike | None = None, title: str | None = None,
             ylabel: str = "distance [mm]") -> "Figure":
        """The raw signal with this filter's output (:func:`plot_overlay` of this one result, titled with
        its label); saved too with ``path`` (.png, .svg, .pdf)."""
        t, x = self._signal()
        return plot_overlay(t, x, [self], path, edges=self.edges, title=self.label if title is None else title,
                            ylabel=ylabel)

    def to_csv(self, path: str | os.PathLike) -> Path:
        """The time series as CSV: ``t_s``, ``signal_mm`` (the raw input) and ``output_mm`` (this filter's
        output), one row per sample, numbers written so that they read back exactly."""
        t, x = self._signal()
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        with open(p, "w", newline="", encoding="utf-8") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(("t_s", "signal_mm", "output_mm"))
            w.writerows((repr(float(a)), repr(float(b)), repr(float(c))) for a, b, c in zip(t, x, self.output))
        return p

def check_plot_path(path: str | os.PathLike) -> Path:
    return check_plot_suffix(path, WorkbenchError)


def plot_overlay(t, signal, results: Sequence[FilterResult], path: str | os.PathLike | None = None,
                 edges: Sequence[float] | None = None, title: str | None = "Sensor filters compared",
                 ylabel: str = "distance [mm]") -> "Figure":
    """Raw signal (light grey) with every filter output overlaid, like the documents' Figs. 10-17.

    Top panel: the whole signal, the edges as vertical dashed lines. With edges a second panel zooms
    on the first (rising) edge: from a third of the window before it to three times the 75th
    percentile of the 50 % delays (at least 40 cycles) after it. Returns the Figure (Agg canvas, no pyplot); with
    ``path`` it is saved too, the format by suffix (.png, .svg, .pdf).
    """
    # matplotlib is imported here only: it stays off the import path of the cycle core and the CLI
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if path is not None:
        path = check_plot_path(path)
    tt = np.asarray(t, dtype=np.float64)
    x = np.asarray(signal, dtype=np.float64)
    ed = _check_edges(tt, edges) if edges is not None and len(edges) else []
    fig = Figure(figsize=(13.0, 7.5 if ed else 4.6), layout="constrained")
    FigureCanvasAgg(fig)
    if ed:
        ax_all, ax_zoom = fig.subplots(2, 1, gridspec_kw={"height_ratios": [1.1, 1.0]})
    else:
        ax_all, ax_zoom = fig.subplots(1, 1), None
    colors = [f"C{i % 10}" for i in range(len(results))]

    xs, ys = envelope(tt, x, MAX_POINTS)
    ax_all.plot(xs, ys, color="0.78", linewidth=0.8, label="raw signal", zorder=1)
    for r, c in zip(results, colors):
        xs, ys = envelope(tt, r.output, MAX_POINTS)
        ax_all.plot(xs, ys, color=c, linewidth=1.1, label=r.label, zorder=2)
    axes = [ax_all] + ([ax_zoom] if ax_zoom is not None else [])
    for ax in axes:
        for i, e in enumerate(ed):
            ax.axvline(e, color="0.3", linestyle="--", linewidth=0.8, zorder=0,
                       label="obstacle edge" if (i == 0 and ax is ax_all) else "_nolegend_")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.4)
    ax_all.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small", borderaxespad=0.0)
    if ax_zoom is not None:
        T = float(np.median(np.diff(tt)))
        delays = [r.delay_s for r in results if math.isfinite(r.delay_s)]
        post = max(40 * T, 3.0 * float(np.percentile(delays, 75)) if delays else 0.0)
        lo, hi = ed[0] - post / 3.0, min(ed[0] + post, ed[1] if len(ed) > 1 else tt[-1])
        sel = (tt >= lo) & (tt <= hi)
        ax_zoom.plot(tt[sel], x[sel], color="0.78", linewidth=0.8, marker=".", markersize=2, label="raw signal")
        for r, c in zip(results, colors):
            ax_zoom.plot(tt[sel], r.output[sel], color=c, linewidth=1.3, label=r.label)
        ax_zoom.set_xlim(lo, hi)
        ax_zoom.set_title("zoom on the first (rising) edge", fontsize="medium", loc="left")
    if title:
        fig.suptitle(str(title))
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
    return fig
