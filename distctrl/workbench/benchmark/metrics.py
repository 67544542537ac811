"""The benchmark's figures of one run (docs/benchmark.md "Figures"), from a :class:`~.contestants.Track`
and its plate. Every contestant is measured by the same code; the true distance is the nozzle's Z
minus the plate's surface under the nozzle's X/Y (``d``), the error ``e = d - set``. A figure that does
not apply or cannot be computed is None (JSON null).

* ``steady_mean_mm`` / ``steady_sd_mm`` / ``steady_max_mm`` (max |e|) over the *steady window*: the
  nozzle in a plain zone of the plate (no void or corner within the footprint), ``settle_s`` of travel
  past the zone's start, the path at 99 % of the feed or more; ``steady_cycles`` its length;
* ``drive_lag_mm``: what the Z drive's lag alone costs there, ``-(1 - ff) / kv`` times the mean rate at
  which the surface under the nozzle rises (``-v tan(a) / kv`` on a ramp of angle a without
  feed-forward); ``beyond_lag_mm`` = steady mean minus that;
* ``void_excursion_mm``: the deepest the nozzle went below the set height over the sheet (the sheet
  without its voids) while over a void (hole, kerf, beyond the edge): ``max(sheet + set - z)``, at
  least 0;
* ``min_feature_distance_mm``: the least nozzle height above the sheet (voids closed) in the void and
  corner zones after the path started;
* ``approach_undershoot_mm``: ``max(0, set - min d)`` from the select to the path's start;
  ``approach_time_s``: from the select until ``|e| <= in_position_mm`` holds ``in_position_hold_s``;
* ``collisions``: entries of the nozzle into the surface (``d < 0``); ``min_distance_mm`` the least
  ``d`` after the select; ``time_below_half_s`` over metal (no void under the nozzle) with
  ``d < set / 2`` after the select;
* ``locks_at_feed``: entries into FREEZE (a process function's hold) while the path runs at the feed
  (``settle_s`` before and after) and no void or corner is near the nozzle: false locks (None for a
  contestant without such a state).
"""
from __future__ import annotations

import math

import numpy as np

from ...sim.surface import surface_from_config
from .contestants import Track
from .suite import Plate, RunSpec

__all__ = ["measure", "FIGURES", "FIGURE_UNITS"]

FIGURE_UNITS = {"steady_mean_mm": "mm", "steady_sd_mm": "mm", "steady_max_mm": "mm",
                "steady_cycles": "cycles",
                "drive_lag_mm": "mm", "beyond_lag_mm": "mm", "void_excursion_mm": "mm",
                "min_feature_distance_mm": "mm", "approach_undershoot_mm": "mm", "approach_time_s": "s",
                "collisions": "", "min_distance_mm": "mm", "time_below_half_s": "s", "locks_at_feed": ""}
FIGURES = tuple(FIGURE_UNITS)


def _f(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def _held_from(ok: np.ndarray, hold: int) -> int | None:
    """First index from which ``ok`` holds ``hold`` entries in a row (None: never)."""
    run = 0
    for i, good in enumerate(ok):
        run = run + 1 if good else 0
        if run >= hold:
            return i - hold + 1
    return None


def measure(track: Track, spec: RunSpec, plate: Plate) -> dict:
    p = spec.params
    T = p.cycle_time
    end = len(track.z) if track.k_end is None else track.k_end + 1
    x, y, z = track.x[:end], track.y[:end], track.z[:end]       # to the path's end: the deselect follows
    n = len(z)
    out: dict = dict.fromkeys(FIGURES)
    out["collisions"] = 0
    if n < 2 or track.k_select is None:
        return out
    set_mm = spec.set_mm
    true = surface_from_config(plate.surface).height_array(x, y) * np.ones(n)
    sheet = surface_from_config(plate.sheet).height_array(x, y) * np.ones(n)
    d = z - true
    e = d - set_mm
    k_sel = track.k_select
    k_mov = track.k_motion if track.k_motion is not None else n
    idx = np.arange(n)
    after_sel = idx >= k_sel
    moving = idx >= k_mov
    v_feed = spec.feed * 1000.0 / 60.0
    speed = np.hypot(np.diff(x, prepend=x[0]), np.diff(y, prepend=y[0])) / T
    at_feed = speed >= 0.99 * v_feed
    steady = np.zeros(n, dtype=bool)
    for zone in plate.steady:
        shifted = type(zone)(zone.kind, zone.lo + v_feed * p.settle_s, zone.hi, zone.r)
        steady |= shifted.mask(x, y)
    steady &= at_feed & moving
    out["steady_cycles"] = int(steady.sum())
    if steady.sum() >= 10:
        es = e[steady]
        out["steady_mean_mm"] = _f(es.mean())
        out["steady_sd_mm"] = _f(es.std())
        out["steady_max_mm"] = _f(np.abs(es).max())
        rate = np.diff(sheet, prepend=sheet[0]) / T
        lag = -(1.0 - spec.feedforward) / p.kv * float(rate[steady].mean())
        out["drive_lag_mm"] = _f(lag)
        out["beyond_lag_mm"] = _f(es.mean() - lag)
    void = np.zeros(n, dtype=bool)
    for zone in plate.voids:
        void |= zone.mask(x, y)
    void &= moving
    if plate.voids:
        out["void_excursion_mm"] = _f(max(0.0, float(np.max(sheet[void] + set_mm - z[void])))) if void.any() \
            else None
    feature = void.copy()
    for zone in plate.corners:
        feature |= zone.mask(x, y) & moving
    if feature.any():
        out["min_feature_distance_mm"] = _f(np.min(z[feature] - sheet[feature]))
    approach = after_sel & (idx < k_mov)
    if approach.any():
        out["approach_undershoot_mm"] = _f(max(0.0, set_mm - float(d[approach].min())))
    hold = max(1, int(round(p.in_position_hold_s / T)))
    k_in = _held_from(np.abs(e[k_sel:]) <= p.in_position_mm, hold)
    out["approach_time_s"] = None if k_in is None else _f(k_in * T)
    below = d < 0.0
    out["collisions"] = int(np.count_nonzero(below[1:] & ~below[:-1]) + int(below[0]))
    out["min_distance_mm"] = _f(d[after_sel].min())
    metal = np.abs(true - sheet) < 1e-9
    out["time_below_half_s"] = _f(np.count_nonzero(after_sel & metal & (d < set_mm / 2)) * T)
    if track.held is not None:
        # at the feed from settle_s before to after (the X/Y drives lag the path): a block's end, where the
        # corner lock holds, is no false lock
        w = max(1, int(round(p.settle_s / T)))
        slow = np.concatenate(([0], np.cumsum(~at_feed)))
        steady_feed = slow[np.minimum(idx + w, n)] - slow[np.maximum(idx - w, 0)] == 0
        corner = np.zeros(n, dtype=bool)
        for zone in plate.corners:
            corner |= zone.mask(x, y)
        held = track.held[:end] & steady_feed & moving & ~void & ~corner
        out["locks_at_feed"] = int(np.count_nonzero(held[1:] & ~held[:-1]))
    return out
