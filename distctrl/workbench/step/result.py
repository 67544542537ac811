"""One setting's step response as a result (:class:`StepResult`: ``to_dict``, ``plot``, ``to_csv``) and
the overlaid plot of several (:func:`plot_steps`).

Part of :mod:`distctrl.workbench.step` (docs/workbench-step.md); the package face re-exports every name.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple, Sequence

import numpy as np

from ...trace.plot import MAX_POINTS, envelope
from ..plotfiles import check_plot_suffix
from .metrics import StepMetrics, _classify, _offset_column
from .model import BAND, StepError, StepSetting

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ...trace import Trace


class StepResult(NamedTuple):
    """One setting's run: unpacks as ``(setting, metrics, trace)``. ``trace.meta`` holds ``step``
    (t_step, step_mm, ramp_mm_s, mode, column), ``errors`` and ``warnings`` of the run."""

    setting: StepSetting
    metrics: StepMetrics
    trace: "Trace"

    def to_dict(self) -> dict:
        """This setting's row of ``distctrl step --json``: its words, metrics (s, mm, %), class,
        limiter reach, errors and warnings."""
        info = self.trace.meta.get("step", {})
        s = self.setting
        return {"setting": {"kp": s.kp, "i_tn_s": s.i_tn, "d_tv_s": s.d_tv, "label": s.label, "kind": s.kind},
                "metrics": self.metrics.to_dict(), "class": _classify(self.metrics),
                "limiter": {"v_max_mm_s": info.get("v_max"), "a_max_mm_s2": info.get("a_max"),
                            "linear_step_mm": info.get("linear_step_mm")},
                "errors": list(_errors_of(self)),
                "warnings": list(self.trace.meta.get("warnings") or []) if hasattr(self.trace, "meta") else []}

    def plot(self, path: str | os.PathLike | None = None, title: str | None = None) -> "Figure":
        """The offset response (:func:`plot_steps` of this one result); saved too with ``path``."""
        return plot_steps([self], path, title)

    def to_csv(self, path: str | os.PathLike) -> None:
        """The run's trace as CSV with its ``.meta.json`` sidecar (units, meta) (:meth:`distctrl.trace.Trace.to_csv`)."""
        self.trace.to_csv(path)


def _errors_of(r: StepResult) -> list:
    return (r.trace.meta.get("errors") if hasattr(r.trace, "meta") else None) or []


#: the step plot's time axis: this many times the slowest settling time of the responses that settle ...
SETTLE_VIEW = 4.0
#: ... but at least this long (s)
MIN_VIEW_S = 0.02


def check_plot_path(path: str | os.PathLike) -> Path:
    return check_plot_suffix(path, StepError)


def _curves(results: Sequence[StepResult]) -> tuple[list[tuple], float]:
    """Per result ``(n, x, y, label, settles, settling_time_s)`` (x from just before the step, y
    relative to the offset before it) and the last time after the step."""
    curves, t_end = [], 0.0
    for n, r in enumerate(results):
        info = r.trace.meta.get("step", {})
        t_step = float(info.get("t_step", 0.0))
        col = info.get("column") or _offset_column(r.trace, None)
        t = np.asarray(r.trace.t, dtype=np.float64)
        y = np.asarray(r.trace[col], dtype=np.float64)
        T = float(np.median(np.diff(t))) if t.size > 1 else 0.001
        pre = int(np.count_nonzero(t < t_step - 0.5 * T))
        baseline = float(np.mean(y[max(0, pre - 10):pre])) if pre else float(y[0])
        x = t - t_step
        keep = x >= -min(0.05, t_step)
        settles = r.metrics.settled
        label = r.setting.label + ("" if settles else " (does not settle)")
        curves.append((n, x[keep], y[keep] - baseline, label, settles, r.metrics.settling_time_s))
        t_end = max(t_end, float(x[-1]))
    return curves, t_end


def _draw_panel(panel: "Axes", curves: list[tuple], t_hi: float, step_mm: float, ramp: float, main: bool) -> None:
    """The responses up to ``t_hi``, the reference (step plus ramp) and the band; labels on the main panel."""
    for n, x, y, label, settles, _ in curves:
        sel = x <= t_hi + 1e-12
        xs, ys = envelope(x[sel], y[sel], MAX_POINTS)
        panel.plot(xs, ys, color=f"C{n % 10}", linewidth=1.2 if settles else 0.8,
                   linestyle="-" if settles else ":", label=label if main else "_nolegend_")
    xr = np.array([0.0, t_hi])
    ref = step_mm + ramp * xr
    band = BAND * abs(step_mm)
    panel.plot([-0.05, 0.0, 0.0], [0.0, 0.0, step_mm], color="0.25", linestyle="--", linewidth=0.9,
               label="_nolegend_")
    panel.plot(xr, ref, color="0.25", linestyle="--", linewidth=0.9,
               label=(f"step {step_mm:g} mm" + (f" + ramp {ramp:g} mm/s" if ramp else "")) if main
               else "_nolegend_")
    panel.plot(xr, ref + band, color="0.55", linestyle="--", linewidth=0.7,
               label=f"±{BAND * 100:.0f} % band" if main else "_nolegend_")
    panel.plot(xr, ref - band, color="0.55", linestyle="--", linewidth=0.7, label="_nolegend_")
    panel.set_xlim(-min(0.05, 0.25 * t_hi), t_hi)
    panel.grid(True, alpha=0.4)
    panel.set_ylabel("offset response [mm]")


def plot_steps(results: Sequence[StepResult], path: str | os.PathLike | None = None,
               title: str | None = None) -> "Figure":
    """The offset responses overlaid: x ``t − t_step [s]``, y ``offset response [mm]``, one line per
    setting (labelled ``KP=.. I_TN=.. D_TV=..``), the step level (plus ramp) and the ±2 % band dashed.

    Returns the Figure (Agg canvas, no pyplot); with ``path`` it is saved too, the format by suffix
    (.png, .svg, .pdf).
    """
    # matplotlib is imported here only: it stays off the import path of the cycle core and the CLI
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if not results:
        raise StepError("plot_steps: no results; allowed: the list run_steps returns")
    if path is not None:
        path = check_plot_path(path)
    info0 = results[0].trace.meta.get("step", {})
    step_mm = float(info0.get("step_mm", results[0].metrics.step_mm))
    ramp = float(info0.get("ramp_mm_s", 0.0))
    curves, t_end = _curves(results)
    # the time axis from the responses that settle (audit R1: a limit cycle drawn over the whole run hid
    # responses that settle in milliseconds): SETTLE_VIEW x the slowest settling time; a response that
    # does not settle says so in the legend, and a second panel shows the whole run
    settling = [c[5] for c in curves if c[4] and c[5] is not None]
    zoom = bool(settling) and len(settling) < len(curves)
    t_view = min(t_end, max(SETTLE_VIEW * max(settling), MIN_VIEW_S)) if settling else t_end
    if zoom and t_view < 0.5 * t_end:
        fig = Figure(figsize=(10.0, 7.6), layout="constrained")
        FigureCanvasAgg(fig)
        ax, whole = fig.subplots(2, 1, height_ratios=(3, 1.3))
    else:
        fig = Figure(figsize=(10.0, 5.6), layout="constrained")
        FigureCanvasAgg(fig)
        ax, whole = fig.subplots(1, 1), None
        t_view = t_end if not settling else t_view
    _draw_panel(ax, curves, t_view, step_mm, ramp, main=True)
    if whole is not None:
        _draw_panel(whole, curves, t_end, step_mm, ramp, main=False)
    ax.set_xlabel("t − t_step [s]")
    ax.legend(loc="best", fontsize="small")
    if whole is not None:
        ax.set_title(f"the first {t_view * 1e3:.0f} ms ({SETTLE_VIEW:g} x the slowest settling time)",
                     fontsize="medium")
        whole.set_title("the whole run: dotted = does not settle", fontsize="medium")
        whole.set_xlabel("t − t_step [s]")
    mode = info0.get("mode")
    fig.suptitle(title if title is not None else
                 f"Distance-control step response ({mode + ', ' if mode else ''}step {step_mm:g} mm)")
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
    return fig
