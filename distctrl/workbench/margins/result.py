"""The margins of one loop as a result: :class:`MarginResult` (``to_dict``, ``format_text``, ``plot``).

Part of :mod:`distctrl.workbench.margins` (docs/margins.md); the package face re-exports every name.
"""
from __future__ import annotations

import csv
import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..plotfiles import check_plot_suffix
from .model import POLE_TOLERANCE, LoopModel, MarginsError
from .text import _cycles, _hz, format_text

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure


def _finite(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


@dataclass(frozen=True)
class MarginResult:
    """Margins of one loop (python-control's ``stability_margins`` and the KP search).

    ``gain_margin`` (factor; < 1: unstable, the loop gain must fall by it) and ``gain_margin_db``,
    ``phase_margin_deg``, the frequencies in Hz (``phase_crossover_hz``: where the phase is -180 deg and
    the gain margin is read; ``gain_crossover_hz``: where |L| = 1 and the phase margin is read); None
    where a margin does not exist. ``kp_limit``: the KP at which the loop (with I and D as set, the D
    gain following KP as the core computes it) reaches the stability limit, searched up to
    :data:`KP_SEARCH_MAX`; ``limit_frequency_hz`` the oscillation there (the critical closed-loop pole).
    ``kp_times_gain_margin`` is KP x gain margin (equal to ``kp_limit`` when the D part is off).
    ``spectral_radius`` is the largest |z| of the closed loop's poles and ``pole_frequency_hz`` that
    pole's frequency: a small disturbance decays (or grows) by the factor |z| per cycle, oscillating
    at that frequency.
    """

    model: LoopModel
    gain_margin: float | None
    phase_margin_deg: float | None
    stability_margin: float | None
    phase_crossover_hz: float | None
    gain_crossover_hz: float | None
    spectral_radius: float
    pole_frequency_hz: float
    kp_limit: float | None
    limit_frequency_hz: float | None
    #: every crossing python-control found: (gain margin, phase crossover in Hz) and (phase margin in
    #: deg, gain crossover in Hz), lowest frequency first
    gain_margins: tuple[tuple[float, float], ...] = ()
    phase_margins: tuple[tuple[float, float], ...] = ()

    @property
    def stable(self) -> bool:
        return self.spectral_radius <= 1.0 + POLE_TOLERANCE

    @property
    def marginal(self) -> bool:
        """At the stability limit: the largest closed-loop pole on the unit circle (within 1e-6)."""
        return abs(self.spectral_radius - 1.0) <= 1e-6

    @property
    def gain_margin_db(self) -> float | None:
        gm = self.gain_margin
        return None if gm is None or gm <= 0.0 else 20.0 * math.log10(gm)

    @property
    def kp_times_gain_margin(self) -> float | None:
        return None if self.gain_margin is None else self.model.kp * self.gain_margin

    @property
    def verdict(self) -> str:
        if self.marginal:
            return "AT THE STABILITY LIMIT (a small disturbance oscillates without decaying)"
        if not self.stable:
            return "UNSTABLE (a small disturbance grows until the slope limiter or the drive limits it)"
        return "stable (a small disturbance decays)"

    def growth_per_cycle(self) -> float:
        return self.spectral_radius

    def to_dict(self) -> dict[str, Any]:
        """One JSON-ready object; units in the key names; None where a figure does not exist."""
        r = self.spectral_radius
        return {"scenario": self.model.scenario, "model": self.model.describe(),
                "stable": self.stable, "at_stability_limit": self.marginal,
                "verdict": self.verdict.split(" (")[0].lower(),
                "gain_margin": self.gain_margin, "gain_margin_db": self.gain_margin_db,
                "phase_margin_deg": self.phase_margin_deg, "stability_margin": self.stability_margin,
                "phase_crossover_hz": self.phase_crossover_hz, "gain_crossover_hz": self.gain_crossover_hz,
                "kp": self.model.kp, "kp_limit": self.kp_limit, "kp_times_gain_margin": self.kp_times_gain_margin,
                "limit_frequency_hz": self.limit_frequency_hz,
                "all_gain_margins": [{"gain_margin": g, "phase_crossover_hz": f} for g, f in self.gain_margins],
                "all_phase_margins": [{"phase_margin_deg": p, "gain_crossover_hz": f} for p, f in self.phase_margins],
                "closed_loop_pole_max_abs": r, "closed_loop_pole_hz": self.pole_frequency_hz,
                "closed_loop_growth_per_s": math.log(r) / self.model.cycle_time if r > 0 else None}

    # -- text -------------------------------------------------------------------------------------------
    def format_text(self) -> str:
        """The text ``distctrl margins`` prints (:func:`distctrl.workbench.margins.text.format_text`)."""
        return format_text(self)

    # -- table ------------------------------------------------------------------------------------------
    def to_csv(self, path: str | os.PathLike) -> Path:
        """The open loop's frequency response on the Bode plot's grid (0.1 Hz to 0.999 x the Nyquist
        frequency, 2000 points, logarithmic), factor by factor (:meth:`LoopModel.response`): ``f_hz``,
        ``re``, ``im``, ``magnitude_db``, ``phase_deg`` (unwrapped), numbers that read back exactly."""
        omega = _omega(self.model.cycle_time)
        resp = np.asarray(self.model.response(omega), dtype=complex).reshape(-1)
        with np.errstate(divide="ignore"):
            mag_db = 20.0 * np.log10(np.abs(resp))
        phase = np.degrees(np.unwrap(np.angle(resp)))
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        with open(p, "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(("f_hz", "re", "im", "magnitude_db", "phase_deg"))
            w.writerows(tuple(repr(float(v)) for v in row)
                        for row in zip(omega / (2.0 * math.pi), resp.real, resp.imag, mag_db, phase))
        return p

    # -- plot -------------------------------------------------------------------------------------------
    def plot(self, path: str | os.PathLike | None = None, nyquist: bool = True) -> "Figure":
        """Bode plot of the open loop (magnitude in dB, phase in deg over Hz up to the Nyquist frequency,
        the margins marked by python-control), and beside it the Nyquist plot. Returns the Figure (Agg
        canvas, no pyplot); with ``path`` it is saved too (.png, .svg, .pdf)."""
        # python-control (about 1 s of import): only where the loop model is built
        import control
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        if path is not None:
            path = check_plot_path(path)
        m = self.model
        T = m.cycle_time
        fig = Figure(figsize=(13.0 if nyquist else 8.5, 6.4), layout="constrained")
        FigureCanvasAgg(fig)
        if nyquist:
            grid = fig.add_gridspec(2, 2, width_ratios=(1.5, 1.0))
            ax_mag = fig.add_subplot(grid[0, 0])
            ax_ph = fig.add_subplot(grid[1, 0], sharex=ax_mag)
            ax_ny = fig.add_subplot(grid[:, 1])
        else:
            ax_mag, ax_ph = fig.subplots(2, 1, sharex=True)
        omega = _omega(T)
        # the response factor by factor (LoopModel.response), as analyse reads the margins from it
        resp = m.response(omega)
        loop = control.frd(resp, omega, dt=T, name="L")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            control.bode_plot(loop, omega, ax=np.array([[ax_mag], [ax_ph]]), Hz=True, dB=True, deg=True,
                              display_margins=True, title="", label="L(z)")
        ax_mag.set_ylabel("|L| [dB]")
        ax_ph.set_ylabel("phase of L [deg]")
        ax_ph.set_xlabel("frequency [Hz]")
        if self.limit_frequency_hz:
            for ax in (ax_mag, ax_ph):
                ax.axvline(self.limit_frequency_hz, color="C3", linestyle=":", linewidth=1.0)
        if nyquist:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                # the curve for positive and (mirrored) negative frequencies, clipped at |L| = 5 as
                # python-control's nyquist_plot does (it cannot draw frequency response data)
                mag = np.abs(resp)
                cur = np.where(mag > 5.0, resp / np.maximum(mag, 1e-300) * 5.0, resp)
                ax_ny.plot(cur.real, cur.imag, color="C0", label="L(z)")
                ax_ny.plot(cur.real, -cur.imag, color="C0", linestyle="--")
                ax_ny.plot(np.cos(np.linspace(0.0, 2.0 * math.pi, 361)), np.sin(np.linspace(0.0, 2.0 * math.pi, 361)),
                           color="grey", linewidth=0.8, linestyle=":")
                ax_ny.plot([-1.0], [0.0], marker="+", color="C3", markersize=12)
            ax_ny.set_xlim(-3.0, 1.5)
            ax_ny.set_ylim(-2.5, 2.5)
            ax_ny.set_aspect("equal", adjustable="box")
            ax_ny.set_xlabel("Re L")
            ax_ny.set_ylabel("Im L")
            ax_ny.set_title("Nyquist (zoom on -1)", fontsize="medium")
        gm = self.gain_margin
        head = (f"axis {m.axis} {m.mode}{' both encoders' if m.both_encoders else ''}, KP = {m.kp:g}, "
                f"{m.filter_label}, dead time {_cycles(m.dead_time_cycles)}, kv = {m.kv:g} 1/s")
        tail = (f"gain margin {'-' if gm is None else f'{gm:.3g} ({self.gain_margin_db:+.1f} dB)'}, "
                f"phase margin {'-' if self.phase_margin_deg is None else f'{self.phase_margin_deg:.1f} deg'}, "
                f"KP limit {'-' if self.kp_limit is None else f'{self.kp_limit:.3g}'} at "
                f"{_hz(self.limit_frequency_hz)} — {self.verdict.split(' (')[0].lower()}")
        fig.suptitle(f"Open loop of distance control: {head}\n{tail}", fontsize="medium")
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            fig.savefig(path, dpi=110)
        return fig


def _omega(T: float) -> np.ndarray:
    """The Bode plot's frequency grid (rad/s): 0.1 Hz to 0.999 x the Nyquist frequency, 2000 points."""
    w_lo = 2.0 * math.pi * 0.1
    return np.logspace(math.log10(w_lo), math.log10(math.pi / T * 0.999), 2000)


def check_plot_path(path: str | os.PathLike) -> Path:
    return check_plot_suffix(path, MarginsError)


