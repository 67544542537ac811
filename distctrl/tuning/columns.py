"""Parameter points as columns: a sweep's sets sampled, checked and packed without Python per set (issue 27).

A point of :mod:`distctrl.tuning.space` is a ``dict`` ``{field: value}``; 10 000 of them cost
seconds of Python per step (drawing, rounding, de-duplicating, checking, packing, writing the table)
beside a kernel that runs them in about one. :class:`PointColumns` holds the same points as one numpy
array per field and a mask of the points that set it (a point sets only the filter parameters its
filter type uses). :func:`random_columns` (in :mod:`distctrl.tuning.space`, which samples) draws them with
numpy over all points at once, from the same random stream in the same order as the per-point sampler did
(:func:`~distctrl.tuning.space.random_sample` now converts them), and rounds them as
:func:`~distctrl.tuning.space.round_value` does (tests compare the two over many seeds);
:func:`drop_inert_columns` is :func:`~distctrl.tuning.space.drop_inert_d_tv`, :func:`check_columns`
:func:`~distctrl.tuning.space.build_sets` over columns.

Values: float64 for REAL64 fields, int64 for integer fields, the filter type as its ``FilterType``
value (int64).
"""
from __future__ import annotations

import numpy as np

from ..base.kinds import FilterType
from ..batch.design import check_cycle_time, design_rows, unique_rows
from ..errors import ParameterError
from .space import (BY_FIELD, D_NO_EFFECT_KP, PointColumns, SpaceError, drop_inert_d_tv, in_table_range,
                    point_label, random_columns, round_column, to_params)

__all__ = ["PointColumns", "random_columns", "drop_inert_columns", "round_column", "columns_of", "check_columns",
           "full_column", "COLUMN_FIELDS"]


def drop_inert_columns(pc: PointColumns) -> tuple[PointColumns, int]:
    """:func:`~distctrl.tuning.space.drop_inert_d_tv` of columns: d_tv 0 where kp >= 1, and the
    duplicates this makes removed (the first kept, order kept)."""
    if not pc.n:
        return pc, 0
    cols = dict(pc.cols)
    if "kp" in cols and "d_tv" in cols:
        both = pc.mask("kp") & pc.mask("d_tv")
        cols["d_tv"] = np.where(both & ~(cols["kp"] < D_NO_EFFECT_KP), 0.0, np.asarray(cols["d_tv"], np.float64))
    pc = PointColumns(pc.n, cols, pc.present)
    if any(np.isnan(v[pc.mask(f)]).any() for f, v in cols.items() if v.dtype.kind == "f"):
        points, merged = drop_inert_d_tv(pc.to_points())
        return columns_of(points, list(cols)), merged
    # one row of float64 per point (absent: NaN, -0.0 as 0.0 as Python's == does), unique by bytes
    mat = np.empty((pc.n, len(cols)))
    for j, (f, v) in enumerate(cols.items()):
        mat[:, j] = np.where(pc.mask(f), np.asarray(v, dtype=np.float64) + 0.0, np.nan)
    first = _first_of_equal_rows(mat)
    if len(first) == pc.n:
        return pc, 0
    keep = np.sort(first)
    return pc.take(keep), pc.n - len(keep)


_H1 = np.uint64(0x9E3779B97F4A7C15)
_H2 = np.uint64(0xBF58476D1CE4E5B9)


def _first_of_equal_rows(mat: np.ndarray) -> np.ndarray:
    """The index of the first row of every group of equal rows of ``mat`` (bit for bit; no -0.0). Rows are
    grouped by a 64-bit hash of their bits, then every row is compared with its group's first row; a
    collision (a group of unequal rows) falls back to np.unique over the rows' bytes (several times
    slower: 1.3 s for 10^6 points)."""
    bits = np.ascontiguousarray(mat).view(np.uint64)
    h = np.zeros(len(mat), dtype=np.uint64)
    with np.errstate(over="ignore"):
        for j in range(mat.shape[1]):
            h = (h ^ bits[:, j]) * _H1
            h ^= h >> np.uint64(31)
            h *= _H2
    _, first, inv = np.unique(h, return_index=True, return_inverse=True)
    if np.array_equal(bits, bits[first[inv.reshape(-1)]]):
        return first
    rows = bits.view(np.dtype((np.void, 8 * mat.shape[1])))[:, 0]
    return np.unique(rows, return_index=True)[1]


def columns_of(points: list[dict], names: list | None = None) -> PointColumns | None:
    """Dict points as columns; None when they do not fit (a field with values of mixed or other types than
    int, float and FilterType, or points whose keys are not in one common order)."""
    n = len(points)
    if names is None:
        names = list(dict.fromkeys(f for p in points for f in p))
    order = {f: j for j, f in enumerate(names)}
    cols, present = {}, {}
    for p in points:
        idx = [order.get(f, -1) for f in p]
        if -1 in idx or idx != sorted(idx):
            return None
    for f in names:
        mask = np.fromiter((f in p for p in points), dtype=bool, count=n)
        vals = [p[f] for p in points if f in p]
        kinds = {type(v) for v in vals}
        if kinds == {FilterType}:
            col = np.fromiter((int(v) for v in vals), dtype=np.int64, count=len(vals))
        elif kinds == {int}:
            col = np.fromiter(vals, dtype=np.int64, count=len(vals))
        elif kinds == {float}:
            col = np.fromiter(vals, dtype=np.float64, count=len(vals))
        elif not vals:
            return None
        else:
            return None
        full = np.zeros(n, dtype=col.dtype)
        full[mask] = col
        cols[f] = full
        present[f] = None if mask.all() else mask
    return PointColumns(n, cols, present)


#: the fields the columnar check and packing take from columns (distctrl.batch.closed_loop.PACKED_COLUMN_FIELDS)
COLUMN_FIELDS = frozenset({"kp", "i_tn", "d_tv", "filter_type", "n_cycles", "smoothing_factor", "kalman_sigma",
                           "low_pass_filter_order", "low_pass_filter_fg_f0", "v_max", "a_max"})
#: the filter configuration's fields, in FilterConfig's order
_FILTER_FIELDS = ("filter_type", "n_cycles", "smoothing_factor", "kalman_sigma", "low_pass_filter_order",
                  "low_pass_filter_fg_f0")


def full_column(base, pc: PointColumns, field: str) -> np.ndarray:
    """The value of ``field`` in every set: the point's where it sets it, else ``base``'s."""
    b = getattr(base, field)
    b = int(b) if isinstance(b, FilterType) else b
    if field not in pc.cols:
        return np.full(pc.n, b, dtype=np.asarray(b).dtype)
    m = pc.present.get(field)
    c = pc.cols[field]
    return c if m is None else np.where(m, c, np.asarray(b, dtype=c.dtype))


def check_columns(base, pc: PointColumns, cycle_time: float):
    """:func:`~distctrl.tuning.space.build_sets` for columns: ``(kept points, their filter coefficient rows
    (n_kept, law.FC_LEN), rejected [(point, message)])`` with the same sets, rows and messages, checked per
    field over the columns (the parameter table's ranges) and designed per distinct filter
    (:func:`distctrl.batch.design.design_rows`). None when the columns hold a field outside
    :data:`COLUMN_FIELDS` or of another type than ``base``'s, or a point fails the vectorised check but
    :func:`~distctrl.tuning.space.to_params` accepts it: the caller then takes the per-set way."""
    if set(pc.cols) - COLUMN_FIELDS:
        return None
    for f, c in pc.cols.items():
        b = getattr(base, f)
        want = "i" if isinstance(b, (int, FilterType)) and not isinstance(b, bool) else "f"
        if c.dtype.kind != want or isinstance(b, bool):
            return None
    try:
        check_cycle_time(cycle_time)
    except (ParameterError, ValueError, TypeError):
        return None
    n = pc.n
    bad = np.zeros(n, dtype=bool)
    rotary = base.rotary
    for f, c in pc.cols.items():
        m = pc.mask(f)
        if f == "filter_type":
            good = np.isin(c, [int(t) for t in FilterType if t != FilterType.PASS])
        else:
            good = in_table_range(BY_FIELD[f], c.astype(np.float64), rotary)
        bad |= m & ~good
    rejected: dict = {}
    for i in np.nonzero(bad)[0].tolist():
        pt = pc.point(i)
        try:
            to_params(base, pt, cycle_time)
        except SpaceError as exc:
            rejected[i] = (pt, str(exc))
            continue
        return None                       # the per-set check accepts what this one refuses
    good_rows = np.nonzero(~bad)[0]
    cfg = np.stack([full_column(base, pc, f)[good_rows].astype(np.float64) for f in _FILTER_FIELDS], axis=1)
    uniq, inv = unique_rows(cfg)
    fc_u, errors = design_rows(*(uniq[:, j] for j in range(len(_FILTER_FIELDS))), cycle_time)
    failed = np.zeros(len(uniq), dtype=bool)
    failed[list(errors)] = True
    for r in np.nonzero(failed[inv])[0].tolist():
        i = int(good_rows[r])
        pt = pc.point(i)
        rejected[i] = (pt, f"parameter set {point_label(pt)} is not valid: {errors[int(inv[r])]}")
    keep_rows = good_rows[~failed[inv]]
    fc = fc_u[inv[~failed[inv]]]
    kept = pc.take(keep_rows)
    kept.index = keep_rows                # the kept points' numbers in ``pc``
    return kept, fc, [rejected[i] for i in sorted(rejected)]
