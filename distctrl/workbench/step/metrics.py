"""Step-response metrics of a run's offset response: :class:`StepMetrics`, :func:`measure`, and the
class a response falls in along the documents' method (``good``, ``damped``, ``oscillating``, ...).

Part of :mod:`distctrl.workbench.step` (docs/workbench-step.md); the package face re-exports every name.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .model import (BAND, LARGE_PCT, LIMITED_SHARE, NOISE_SIGMAS, RAPID_CROSSINGS, RECOGNISABLE_PCT, StepError,
                    _number)

if TYPE_CHECKING:  # pragma: no cover
    from ...trace import Trace


@dataclass(frozen=True)
class StepMetrics:
    """Step-response metrics of the offset response ``y(t) = o(t) - o(t_step-)`` (mm, s).

    * ``rise_time_s``: from 10 % to 90 % of the step (linear interpolation between cycles); ``None``
      when 90 % is never reached;
    * ``overshoot_mm`` / ``overshoot_pct``: the largest excursion beyond the reference (the step, plus
      the ramp if any), >= 0;
    * ``settling_time_s``: from the step until the response enters +-2 % of the reference and stays
      there to the end of the run; ``None`` (not settled) unless it stays inside for at least the
      last 10 % of the run after the step (so a limit cycle is not "settled" by chance);
    * ``steady_state_error_mm``: the permanent control deviation, averaged over the last 10 % of the
      run after the step, positive when the offset is short of the reference (in the direction of
      the step). From a distance-control trace it is the controller's own remaining error ``e``
      (SPEC §3: ``SET_DIST - filtered distance`` in CONST_DIST, ``filtered surface - SET_POS -
      offset`` in SET_POS), which is what the I part integrates; it equals ``reference - response``
      once the axis has settled on a step, but not on a ramp, where the offset runs ahead of the
      axis by the drive's following error. Without those columns: ``reference - response``;
    * ``oscillation``: zero crossings of the error (response - reference) after the first peak, a
      crossing counted once the error reaches beyond +-1 % of the step on the other side (2 crossings
      = 1 period); 0 without overshoot;
    * ``peak_time_s``: time of the largest excursion beyond the reference (``None`` without one);
    * ``band_mm``: the half-width of the settling band actually used: +-2 % of the step, or
      :data:`NOISE_SIGMAS` standard deviations of the offset's noise before the step where that is
      larger (``None`` from an old caller that built the metrics by hand);
    * ``limited_share``: the share (0..1) of the cycles from the step until it settled (the whole run
      after the step if it did not) in which the slope limiter changed the PID's offset step
      (``|u - v·T|``: P-AXIS-00415 v_max, P-AXIS-00416 a_max and its braking, the offset bounds);
      ``None`` when the trace lacks ``<axis>.dc.pre_limiter`` / ``<axis>.dc.sloped_delta``.
      :attr:`limiter_bound` (at least :data:`LIMITED_SHARE`): the limiter, not KP, shaped the response.
    """

    step_mm: float
    rise_time_s: float | None
    overshoot_mm: float
    overshoot_pct: float
    settling_time_s: float | None
    steady_state_error_mm: float
    oscillation: int
    peak_time_s: float | None = None
    band_mm: float | None = None
    limited_share: float | None = None

    @property
    def settled(self) -> bool:
        return self.settling_time_s is not None

    @property
    def limiter_bound(self) -> bool:
        """The slope limiter changed the PID's step in at least :data:`LIMITED_SHARE` of the transient."""
        return self.limited_share is not None and self.limited_share >= LIMITED_SHARE

    @property
    def band(self) -> float:
        """The settling band in mm (+-)."""
        return self.band_mm if self.band_mm is not None else BAND * abs(self.step_mm)

    @property
    def periods(self) -> int:
        """Oscillation periods after the first peak (two zero crossings each, rounded up)."""
        return (self.oscillation + 1) // 2

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["settled"] = self.settled
        d["band_mm"] = self.band
        d["limiter_bound"] = self.limiter_bound
        return d


def _first_crossing(tt: np.ndarray, y: np.ndarray, level: float) -> float | None:
    """The first time ``y`` reaches ``level`` from below (linear interpolation), None if never."""
    idx = np.flatnonzero(y >= level)
    if idx.size == 0:
        return None
    k = int(idx[0])
    if k == 0:
        return float(tt[0])
    y0, y1 = float(y[k - 1]), float(y[k])
    frac = (level - y0) / (y1 - y0) if y1 != y0 else 1.0
    return float(tt[k - 1] + frac * (tt[k] - tt[k - 1]))


def _trace_of(result: Any) -> "Trace":
    trace = getattr(result, "trace", result)
    if trace is None or not hasattr(trace, "columns"):
        raise StepError("measure: no trace; allowed: a RunResult with its trace kept, or a Trace")
    return trace


def _offset_column(trace: "Trace", column: str | None) -> str:
    if column is not None:
        if column not in trace:
            raise StepError(f"measure: no column {column!r} in the trace; allowed: one of "
                            f"{', '.join(c for c in trace.columns if c.endswith('offset')) or 'its columns'}")
        return column
    for c in trace.columns:
        if c.endswith(".dc.offset"):
            return c
    raise StepError("measure: the trace has no '<axis>.dc.offset' column; allowed: a trace of a run with "
                    "distance control, or name the column")


def _control_error(trace: "Trace", col: str) -> np.ndarray | None:
    """The controller's remaining error ``e`` per cycle (SPEC §3), NaN where it is not tracking:
    ``-target_deviation`` in ACTIVE_CONST_DIST (4), ``target_deviation - offset`` in ACTIVE (1,
    SET_POS; the offset before the cycle's update, i.e. the previous row's). None when the trace
    lacks the columns (e.g. a synthetic trace)."""
    if not col.endswith(".dc.offset"):
        return None
    ax = col[:-len(".dc.offset")]
    state_col, td_col = f"{ax}.dc.state", f"{ax}.dc.target_deviation"
    if state_col not in trace or td_col not in trace:
        return None
    state = np.asarray(trace[state_col])
    td = np.asarray(trace[td_col], dtype=np.float64)
    o = np.asarray(trace[col], dtype=np.float64)
    o_prev = np.concatenate((o[:1], o[:-1]))   # the row holds the offset after this cycle's update
    return np.where(state == 4, -td, np.where(state == 1, td - o_prev, np.nan))


def _baseline_and_band(trace: "Trace", col: str, y_all: np.ndarray, n_pre: int, T: float, step_mm: float,
                       band: float) -> tuple[float, float, float]:
    """``(baseline, band_mm, hysteresis)``: the offset before the step, the settling band in mm (+-2 % of
    the step, or :data:`NOISE_SIGMAS` x the offset's noise before the step where larger) and the swing
    that counts as a zero crossing (relative to the step)."""
    # the quiet time before the step: its second half, at most 0.5 s
    k_quiet = max(n_pre // 2, n_pre - int(round(0.5 / T))) if T > 0 else n_pre // 2
    quiet = y_all[k_quiet:n_pre]
    quiet = quiet[np.isfinite(quiet)]
    noise_mm = float(np.std(quiet)) if quiet.size >= 10 else 0.0
    if noise_mm > 1e-4 * abs(step_mm) and quiet.size >= 10:
        # a noisy offset: the mean of the quiet time (the last samples alone carry the noise)
        baseline = float(np.mean(quiet[-min(quiet.size, int(round(0.1 / T)) if T > 0 else 100):]))
    else:
        baseline = float(np.mean(y_all[max(0, n_pre - 10):n_pre]))
    # the band widens to the offset's noise, unless the limiter already acted before the step (a loop
    # that oscillates on its own is not noise: its swing must not count as settled)
    pre_limited = _limited_share(trace, col, k_quiet, None, T, stop=n_pre)
    if pre_limited is not None and pre_limited > 0.01:
        noise_mm = 0.0
    band_mm = max(band * abs(step_mm), NOISE_SIGMAS * noise_mm)
    # a swing counts beyond half the band on the other side, or beyond the noise band (noise alone
    # does not get there)
    hysteresis = max(band * abs(step_mm) / 2.0, NOISE_SIGMAS * noise_mm) / abs(step_mm)
    return baseline, band_mm, hysteresis


def measure(result: Any, t_step: float, step_mm: float, *, ramp_mm_s: float = 0.0, column: str | None = None,
            band: float = BAND) -> StepMetrics:
    """Step-response metrics (:class:`StepMetrics`) of a run (``RunResult``) or a :class:`Trace`.

    The response is the offset column (default: the first ``<axis>.dc.offset``) relative to its value
    just before ``t_step`` (the mean of up to 10 samples before it); the reference is ``step_mm``
    (plus ``ramp_mm_s`` times the time since the step). ``band`` is the settling band as a fraction of
    the step (0.02 = +-2 %).
    """
    trace = _trace_of(result)
    col = _offset_column(trace, column)
    step_mm = _number("step", step_mm, nonzero=True, allowed="a step != 0 in mm")
    t_step = _number("t_step", t_step, allowed="the time of the step in s")
    band = _number("band", band, lo=0.0, lo_open=True, hi=1.0, allowed="0 < band <= 1 (fraction of the step)")
    t = np.asarray(trace.t, dtype=np.float64)
    y_all = np.asarray(trace[col], dtype=np.float64)
    if t.size < 3:
        raise StepError(f"measure: the trace has {t.size} samples; allowed: a trace covering the step")
    T = float(np.median(np.diff(t)))
    pre = t < t_step - 0.5 * T
    n_pre = int(np.count_nonzero(pre))
    if n_pre == 0 or t.size - n_pre < 2:
        raise StepError(f"measure: t_step = {t_step:g} s is outside the trace ({t[0]:g} .. {t[-1]:g} s); "
                        f"allowed: a time with samples before and after it")
    baseline, band_mm, hysteresis = _baseline_and_band(trace, col, y_all, n_pre, T, step_mm, band)
    band = band_mm / abs(step_mm)
    tt = t[n_pre:] - t_step
    yn = (y_all[n_pre:] - baseline) / step_mm
    rn = 1.0 + ramp_mm_s * tt / step_mm
    err = yn - rn
    finite = np.isfinite(err)
    if not finite.all():  # a run that failed (NaN offsets are never written, but be safe)
        err = np.where(finite, err, np.inf)
        yn = np.where(finite, yn, 0.0)

    t10, t90 = _first_crossing(tt, yn, 0.1), _first_crossing(tt, yn, 0.9)
    rise = t90 - t10 if t10 is not None and t90 is not None else None

    peak = float(np.max(err))
    overshoot = peak if peak > 0 and math.isfinite(peak) else 0.0
    peak_time = float(tt[int(np.argmax(err))]) if overshoot > 0 else None

    n_final = max(1, err.size // 10)
    outside = np.flatnonzero(~(np.abs(err) <= band))
    if outside.size == 0:
        settling: float | None = 0.0
    elif outside[-1] >= err.size - n_final:   # must stay inside for (at least) the final 10 %
        settling = None
    else:
        k = int(outside[-1])
        e0, e1 = abs(float(err[k])), abs(float(err[k + 1]))
        frac = (e0 - band) / (e0 - e1) if math.isfinite(e0) and e0 != e1 else 1.0
        settling = float(tt[k] + min(max(frac, 0.0), 1.0) * (tt[k + 1] - tt[k]))

    sse = -float(np.mean(err[-n_final:])) * abs(step_mm)
    e_ctrl = _control_error(trace, col)
    if e_ctrl is not None:
        tail = e_ctrl[-n_final:]
        if np.isfinite(tail).all():
            sse = float(np.mean(tail)) * (1.0 if step_mm > 0 else -1.0)

    signs = np.sign(err[np.abs(err) > hysteresis])
    above = np.flatnonzero(signs > 0)
    oscillation = int(np.count_nonzero(signs[above[0] + 1:] != signs[above[0]:-1])) if above.size else 0

    limited = _limited_share(trace, col, n_pre, settling, T)
    return StepMetrics(step_mm=step_mm, rise_time_s=rise, overshoot_mm=overshoot * abs(step_mm),
                       overshoot_pct=overshoot * 100.0, settling_time_s=settling, steady_state_error_mm=sse,
                       oscillation=oscillation, peak_time_s=peak_time, band_mm=band_mm, limited_share=limited)


def _limited_share(trace: "Trace", col: str, n_pre: int, settling: float | None, T: float,
                   stop: int | None = None) -> float | None:
    """Share of the transient's cycles (from the step to the settling time, or to the end of the run)
    in which the limiter changed the PID's step: ``|u - v·T| > max(1 nm, 0.1 % of |u|)`` with ``u`` =
    ``<axis>.dc.pre_limiter`` (DIST_CTRL::delta_deviation_pre_limiter) and ``v·T`` =
    ``<axis>.dc.sloped_delta`` (DIST_CTRL_IFC::sloped_delta_deviation). None without those columns."""
    if not col.endswith(".dc.offset"):
        return None
    ax = col[:-len(".dc.offset")]
    u_col, v_col = f"{ax}.dc.pre_limiter", f"{ax}.dc.sloped_delta"
    if u_col not in trace or v_col not in trace:
        return None
    u = np.asarray(trace[u_col], dtype=np.float64)[n_pre:stop]
    vt = np.asarray(trace[v_col], dtype=np.float64)[n_pre:stop]
    if settling is not None:
        n = max(1, int(math.ceil(settling / T - 1e-9)) + 1) if T > 0 else u.size
        u, vt = u[:n], vt[:n]
    if u.size == 0:
        return None
    with np.errstate(invalid="ignore"):
        clipped = np.abs(u - vt) > np.maximum(1e-6, 1e-3 * np.abs(u))
    return float(np.count_nonzero(clipped)) / u.size

def _classify(m: StepMetrics) -> str:
    """``oscillating`` (more than 2 periods after the first peak, settled or not), ``deviation`` (a
    steady-state error beyond the band), ``slow`` (not settled, without those), ``damped`` (no
    recognisable overshoot), ``large`` (overshoot above 40 %) or ``good`` (a recognisable overshoot
    up to 40 %, rapidly decaying)."""
    if m.oscillation > RAPID_CROSSINGS:
        return "oscillating"
    if abs(m.steady_state_error_mm) > m.band:
        return "deviation"
    if not m.settled:
        return "slow"
    if m.overshoot_pct < RECOGNISABLE_PCT:
        return "damped"
    if m.overshoot_pct > LARGE_PCT:
        return "large"
    return "good"
