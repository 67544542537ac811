"""``distctrl identify``, the result: :class:`Identification` (the fitted plant) with the result face of
python-control's results: :meth:`~Identification.to_dict` (what ``--json`` prints) and
:meth:`~Identification.plot` (measured vs fitted, the report's figure)."""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .common import DRIVE_KEYS, SENSOR_KEYS, _mode

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

UNITS = {"kv": "1/s", "dead_time": "s", "feedforward": "- (velocity feed-forward 0..1)", "v_max": "mm/s",
         "a_max": "mm/s^2", "resonance_hz": "Hz", "damping": "-",
         "delay": "s", "noise_std": "mm", "characteristic": "[[true mm, reported mm], ...]"}


@dataclass
class Identification:
    """The fitted plant, fit quality and what could not be identified (``warnings``)."""

    cycle_time: float
    drive: dict
    sensor: dict
    fit: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    #: standard deviations of the identified figures: {"drive": {key: sd}, "sensor": {key: sd}}
    uncertainty: dict = field(default_factory=dict)
    #: the prediction error on recordings not used for the fit (``validate``), else None
    validation: dict | None = None
    recordings: list[dict] = field(default_factory=list)
    # for the report: per recording (t, X, S, Y) and model curves
    curves: dict = field(default_factory=dict)

    def to_dict(self, scenario: str | None = None, report: str | None = None) -> dict:
        """The ``distctrl identify --json`` object (:func:`result_json`); ``scenario`` and ``report``:
        the files ``--out`` wrote."""
        return result_json(self, scenario, report)

    def plot(self, path: str | os.PathLike | None = None) -> "Figure":
        """Measured vs fitted: per recording the actual and the sensor in time, the motor -> sensor
        frequency response (magnitude, phase) and the characteristic. A Figure on an Agg canvas (no
        pyplot), saved to ``path`` too when given."""
        # matplotlib is imported here only: it stays off the import path of the fit and the CLI
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        recs = self.curves.get("recs") or []
        rows = len(recs) + 1
        fig = Figure(figsize=(13, 3.0 * rows))
        FigureCanvasAgg(fig)
        axes = fig.subplots(rows, 2, squeeze=False)
        for i, r in enumerate(recs):
            self._plot_recording(axes[i], i, r)
        self._plot_frf(axes[-1][0])
        self._plot_characteristic(axes[-1][1])
        for row in axes[:-1]:
            for ax in row:
                ax.set_xlabel("s")
        fig.tight_layout()
        if path is not None:
            fig.savefig(path, dpi=90)
        return fig

    def _plot_recording(self, row, i: int, r) -> None:
        sims = self.curves.get("drive_sim") or []
        preds = self.curves.get("sensor_pred") or []
        ax = row[0]
        ax.plot(r.t, r.X, lw=0.8, label="actual (measured)")
        if i < len(sims):
            ax.plot(r.t, sims[i], lw=0.8, ls="--", label="drive model")
        ax.plot(r.t, r.S, lw=0.5, alpha=0.5, label="command")
        ax.set_title(f"{Path(r.sig.path).name}: motor", fontsize=9)
        ax.set_ylabel("mm")
        ax.legend(fontsize=7, loc="best")
        ax = row[1]
        ax.plot(r.t, r.Y, lw=0.6, label="sensor (measured)")
        if i < len(preds):
            ax.plot(r.t, preds[i], lw=0.8, ls="--", label="sensor model")
        ax.set_title(f"{Path(r.sig.path).name}: sensor (sign {self.extra.get('sensor_sign', 1):+.0f})", fontsize=9)
        ax.set_ylabel("mm")
        ax.legend(fontsize=7, loc="best")

    def _plot_frf(self, ax_m) -> None:
        fr = self.curves.get("frf_fit") or {}
        if fr.get("_points") is not None:
            f, H, _ = fr["_points"]
            g, tau, f0, zeta = fr["_model"]
            ff = np.linspace(f.min(), f.max(), 600)
            G = g * np.exp(-2j * np.pi * ff * tau) * (_mode(ff, f0, zeta) if f0 else 1.0)
            ax_m.semilogx(f, 20 * np.log10(np.abs(H)), ".", ms=3, label="|H| measured (coherent)")
            ax_m.semilogx(ff, 20 * np.log10(np.abs(G)), "-", lw=1, label="|H| model")
            ax_p = ax_m.twinx()
            ax_p.semilogx(f, np.degrees(np.unwrap(np.angle(H))), ".", ms=2, color="tab:green", label="phase measured")
            ax_p.semilogx(ff, np.degrees(np.unwrap(np.angle(G))), "-", lw=0.8, color="tab:red", label="phase model")
            ax_p.set_ylabel("phase [deg]")
            ax_m.set_xlabel("Hz")
            ax_m.set_ylabel("dB")
            ax_m.legend(fontsize=7, loc="lower left")
            ax_p.legend(fontsize=7, loc="upper right")
        ax_m.set_title("frequency response motor -> sensor", fontsize=9)

    def _plot_characteristic(self, ax_c) -> None:
        ch = self.sensor.get("characteristic")
        if ch:
            a = np.array(ch)
            ax_c.plot(a[:, 0], (a[:, 1] - a[:, 0]) * 1e3, "o-", ms=3)
            ax_c.set_xlabel("true distance [mm]")
            ax_c.set_ylabel("reported - true [um]")
        else:
            ax_c.text(0.5, 0.5, "characteristic not identified", ha="center", va="center", transform=ax_c.transAxes)
        ax_c.set_title("sensor characteristic", fontsize=9)


def result_json(res: Identification, scenario: str | None = None, report: str | None = None) -> dict:
    """The ``--json`` object: ``drive`` and ``sensor`` with exactly the keys of issue 15, the rest
    under other keys."""
    return {"drive": {k: res.drive.get(k) for k in DRIVE_KEYS},
            "sensor": {k: res.sensor.get(k) for k in SENSOR_KEYS},
            "uncertainty": uncertainty_json(res),
            "validation": res.validation,
            "units": UNITS, "cycle_time_s": res.cycle_time, "fit": res.fit, "details": res.extra,
            "recordings": res.recordings, "warnings": list(res.warnings), "scenario": scenario, "report": report}


def uncertainty_json(res: Identification) -> dict:
    """Standard deviations beside the pinned keys: ``drive`` and ``sensor`` with the same keys (same
    units; ``characteristic``: the largest standard deviation of a table point, mm), null where the
    figure is not identified."""
    u = res.uncertainty or {}
    drive = {k: (u.get("drive", {}).get(k) if res.drive.get(k) is not None else None) for k in DRIVE_KEYS}
    sensor = {k: (u.get("sensor", {}).get(k) if res.sensor.get(k) is not None else None) for k in SENSOR_KEYS}
    return {"drive": drive, "sensor": sensor, "kind": "standard deviation (statistical, from the fit's residuals)"}
