"""The filter comparison as text and tables: the metrics table (:func:`format_table`), the results CSV
(:func:`write_results_csv`) and the entries of ``distctrl filters --json`` (:func:`results_dicts`).

Part of :mod:`distctrl.workbench.filters` (docs/workbench-filters.md); the package face re-exports every name.
"""
from __future__ import annotations

import csv
import math
import os
from pathlib import Path
from typing import Sequence

from ...base.kinds import FilterType
from ..tables import render_table
from .result import FilterResult
from .spec import KEY_ORDER, KEYS_BY_TYPE


def _fmt(v: float, spec: str) -> str:
    return "-" if v is None or not math.isfinite(v) else format(v, spec)


TABLE_COLUMNS = ("filter", "noise RMS [mm]", "delay 50 % [ms]", "dead time 10 % [ms]", "overshoot [mm]",
                 "overshoot [%]")


def format_table(results: Sequence[FilterResult], title: str | None = None, plain: bool = False) -> str:
    """The metrics as a text table (rich, no colour; ``plain=True``: fixed-width ASCII)."""
    rows = [(r.label, _fmt(r.noise_rms, ".4f"), _fmt(r.delay_s * 1e3, ".2f"), _fmt(r.dead_time_s * 1e3, ".2f"),
             _fmt(r.overshoot_mm, ".3f"), _fmt(r.overshoot_pct, ".1f")) for r in results]
    return render_table(TABLE_COLUMNS, rows, title, plain)


RESULT_CSV_COLUMNS = ("label", "filter_type", "n_cycles", "smoothing_factor", "kalman_sigma", "order", "fg_f0",
                      "noise_rms_mm", "delay_s", "dead_time_s", "overshoot_mm", "overshoot_pct")


def write_results_csv(results: Sequence[FilterResult], path: str | os.PathLike) -> None:
    """One row per config: its parameters (empty where they have no effect) and metrics (empty
    where NaN)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)

    def num(v: float) -> str:
        return "" if v is None or not math.isfinite(v) else repr(float(v))
    with open(p, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(RESULT_CSV_COLUMNS)
        for r in results:
            c = r.config
            used = KEYS_BY_TYPE.get(c.filter_type, ())
            params = {k: (repr(getattr(c, k)) if k in used else "") for k in KEY_ORDER}
            if c.filter_type == FilterType.DEFAULT:
                params["n_cycles"] = str(c.effective_n)
            w.writerow([r.label, c.filter_type.name, *params.values(), num(r.noise_rms), num(r.delay_s),
                        num(r.dead_time_s), num(r.overshoot_mm), num(r.overshoot_pct)])


def results_dicts(results: Sequence[FilterResult]) -> list[dict]:
    """One dict per config (``distctrl filters --json``): label, filter type, the parameters the type
    uses, and the metrics with their units in the names (NaN where not measurable)."""
    return [r.to_dict() for r in results]
