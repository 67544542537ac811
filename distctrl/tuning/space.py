"""The search space of the tuning tools: filter and PID settings of one distance-controlled axis.

A *point* is a plain ``dict`` ``{field: value}`` over :class:`~distctrl.params.axis.AxisParameters`
fields (internal units: s, Hz). :func:`parse_grid` turns a ``--grid`` text into the points of a
grid, :func:`random_sample` draws points at random, :func:`to_params` / :func:`build_sets` turn
points into validated parameter sets (``base.replace(**point)`` plus the checks only the cycle
time can make, e.g. the low-pass cut-off below Nyquist). Every value is checked against the
documented range of its parameter (docs/parameters.md); a problem raises :class:`SpaceError`
naming the key, the value and what is allowed.

Grid syntax (``distctrl sweep --grid``)::

    kp=0.1:1.0:10,d_tv=0,0.01,0.02,filter_type=MOVING_AVERAGE,n_cycles=4,8,16

``name=a:b:n`` is ``n`` values from ``a`` to ``b`` (both included, linear), ``name=a:b:n:log``
the same on a log scale (range values are rounded to the parameter's resolution,
:data:`REAL_RESOLUTION`: ``kp=0.1:1.5:8`` gives 0.9, not 0.8999999999999999); ``name=v1,v2,...`` a
list (kept as typed). A comma followed by ``name=`` starts the next
parameter. Names are the field names or the NC words (``kp``, ``i_tn``, ``d_tv``, ``filter_type``,
``n_cycles``, ``smoothing_factor``/``smooth_fact``, ``kalman_sigma``, ``order``, ``fg_f0``).
"""
from __future__ import annotations

import dataclasses
import itertools
import math
import re
from dataclasses import dataclass

import numpy as np

from ..base.kinds import FILTER_TYPE_NAMES, FilterType
from ..batch.design import check_cycle_time, design_many, filter_coefficients, filter_config
from ..control.controller import AxisDistanceController
from ..control.filters import FILTER_KINDS
from ..errors import DistCtrlError, ParameterError
from ..params.axis import AxisParameters, check_internal
from ..params.table import BY_FIELD, BY_NC_WORD, short_key_fields

__all__ = ["SpaceError", "Dim", "DEFAULT_SPACE", "ALIASES", "NC_WORDS", "canonical", "parse_grid",
           "grid_points", "random_sample", "to_params", "build_sets", "point_label", "filter_fields",
           "REAL_RESOLUTION", "resolution", "round_value", "round_point", "D_NO_EFFECT_KP", "D_TV_NOTE",
           "d_tv_applies", "drop_inert_d_tv", "PointColumns", "random_columns", "round_column"]


class SpaceError(DistCtrlError, ValueError):
    """A grid text, a search-space value or a combination of values that is not allowed."""


#: names accepted in a grid -> AxisParameters field (the parameter table's short keys; the limiter
#: settings v_max, a_max, optimized_scheduling may be swept too, not part of the default tuning space)
ALIASES = {**short_key_fields()}
#: AxisParameters field -> NC DIST_CTRL word (from the parameter table; this order is the column order
#: of sweep results)
_NC_WORD_ORDER = ("kp", "i_tn", "d_tv", "filter_type", "n_cycles", "smoothing_factor", "kalman_sigma",
                  "low_pass_filter_order", "low_pass_filter_fg_f0")
NC_WORDS = {s.field: s.nc_word for s in sorted(
    BY_NC_WORD.values(), key=lambda s: _NC_WORD_ORDER.index(s.field) if s.field in _NC_WORD_ORDER else 99)}
_INT_FIELDS = {"n_cycles", "low_pass_filter_order"}
_BOOL_FIELDS = {"optimized_scheduling"}


def canonical(name: str) -> str:
    """The AxisParameters field of a grid name (``order`` -> ``low_pass_filter_order``)."""
    key = name.strip().lower()
    if key not in ALIASES:
        raise SpaceError(f"unknown sweep parameter {name!r}; allowed: {', '.join(sorted(ALIASES))}")
    return ALIASES[key]


def filter_fields(filter_type: FilterType) -> tuple[str, ...]:
    """The filter parameters a filter type uses (the others do not change the law)."""
    return FILTER_KINDS[FilterType(filter_type)].fields


@dataclass(frozen=True)
class Dim:
    """One dimension of the search space: ``kind`` "float", "log" (float, log-uniform), "int", "choice".

    ``zero_share``: for "log" dimensions whose 0 means "off" (i_tn, d_tv), the share of random
    points that get exactly 0.
    """

    field: str
    kind: str
    lo: float = 0.0
    hi: float = 0.0
    choices: tuple = ()
    zero_share: float = 0.0

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        if self.kind == "choice":
            return np.asarray(self.choices, dtype=object)[rng.integers(0, len(self.choices), n)]
        if self.kind == "int":
            return rng.integers(int(self.lo), int(self.hi) + 1, n)
        if self.kind == "log":
            x = np.exp(rng.uniform(math.log(self.lo), math.log(self.hi), n))
        else:
            x = rng.uniform(self.lo, self.hi, n)
        if self.zero_share:
            x[rng.random(n) < self.zero_share] = 0.0
        return x

    def clip(self, value: float) -> float:
        if self.kind == "int":
            return int(min(max(round(value), self.lo), self.hi))
        if self.kind == "choice":
            return value
        lo = 0.0 if self.zero_share else self.lo
        return float(min(max(value, lo), self.hi))


#: the default tuning space: inside the documented ranges, narrowed to what makes sense for a
#: distance control at 1 ms (kp in (0, 2], n_cycles 0..99, i_tn 0..50 s, d_tv 0..2 s documented)
DEFAULT_SPACE: tuple[Dim, ...] = (
    Dim("filter_type", "choice", choices=tuple(t for t, k in FILTER_KINDS.items() if k.tunable)),
    Dim("n_cycles", "int", 1, 32),
    Dim("smoothing_factor", "float", 0.05, 1.0),
    Dim("kalman_sigma", "log", 1.0, 1000.0),
    Dim("low_pass_filter_order", "int", 1, 6),
    Dim("low_pass_filter_fg_f0", "log", 5.0, 200.0),     # further clipped below Nyquist per scenario
    Dim("kp", "float", 0.05, 2.0),
    Dim("i_tn", "log", 0.005, 2.0, zero_share=0.5),
    Dim("d_tv", "log", 0.0002, 0.05, zero_share=0.3),
)


# ----------------------------------------------------------------------------- the D part at kp >= 1

#: from this kp on the D part has no room and no effect: the law saturates its per-cycle gain at
#: 0.3·(1 − kp) (:func:`distctrl.control.law.derivative_gain`, docs/control-law.md "The D part"), so
#: every d_tv gives the same run. The tools neither vary d_tv there nor report a value for it.
D_NO_EFFECT_KP = 1.0
D_TV_NOTE = ("d_tv: not applicable at kp >= 1 (the D part has no effect there, docs/control-law.md); "
             "such sets are run once, with D_TV 0")


def d_tv_applies(kp) -> bool:
    """Whether D_TV changes anything at this kp (kp < :data:`D_NO_EFFECT_KP`)."""
    return float(kp) < D_NO_EFFECT_KP


def drop_inert_d_tv(points: list[dict]) -> tuple[list[dict], int]:
    """``points`` with d_tv set to 0 where kp >= 1 and the duplicates this makes removed (the first kept,
    order kept); returns ``(points, number removed)``. Points without both kp and d_tv are kept as they are."""
    out, seen, merged = [], set(), 0
    for p in points:
        if "kp" in p and "d_tv" in p and not d_tv_applies(p["kp"]):
            p = dict(p, d_tv=0.0)
        key = tuple((k, v.name if isinstance(v, FilterType) else v) for k, v in p.items())
        if key in seen:
            merged += 1
            continue
        seen.add(key)
        out.append(p)
    return out, merged


# ----------------------------------------------------------------------------- resolution

#: the steps the tuner gives its REAL64 parameters (internal units), so that what it prints is what an
#: engineer types into the list and the NC block: gains and the smoothing factor to 0.001, times to
#: 0.1 ms (a tenth of a 1 ms cycle: finer steps do not change the per-cycle gains measurably), the
#: Kalman sigma to 0.1, the low-pass cut-off to 0.1 Hz. Integer parameters keep the list's own step
#: (one interface unit, e.g. 1 µm/s of v_max). The list and the NC accept more digits; nobody needs them.
REAL_RESOLUTION = {"kp": 0.001, "i_tn": 0.0001, "d_tv": 0.0001, "smoothing_factor": 0.001,
                   "kalman_sigma": 0.1, "low_pass_filter_fg_f0": 0.1}
_INTEGER_TYPES = ("SGN32", "UNS32", "UNS16")


def resolution(field: str) -> float | None:
    """The step a tuned value of ``field`` is rounded to (internal units), None: not rounded."""
    if field in REAL_RESOLUTION:
        return REAL_RESOLUTION[field]
    spec = BY_FIELD.get(field)
    if spec is not None and spec.type in _INTEGER_TYPES:
        return float(spec.scale)
    return None


def round_value(field: str, value):
    """``value`` rounded to :func:`resolution` (kept inside an open lower bound: kp never rounds to 0)."""
    if isinstance(value, (bool, np.bool_, FilterType)) or field in _INT_FIELDS or field in _BOOL_FIELDS:
        return value
    step = resolution(field)
    if step is None:
        return value
    v = float(value)
    r = round(round(v / step) * step, 10)
    spec = BY_FIELD.get(field)
    if spec is not None and spec.lo_open and spec.lo is not None and r <= spec.lo * spec.scale and v > r:
        r = round(r + step, 10)
    return r


def round_point(point: dict) -> dict:
    """Every value of ``point`` rounded (:func:`round_value`)."""
    return {k: round_value(k, v) for k, v in point.items()}


# ----------------------------------------------------------------------------- values

def _check_value(field: str, value, where: str):
    """Convert ``value`` to the field's type and check its documented range (SpaceError if not)."""
    spec = BY_FIELD[field]
    try:
        if field == "filter_type":
            v = value if isinstance(value, FilterType) else FilterType.parse(str(value))
            if v == FilterType.PASS:
                raise ValueError("PASS is internal")
        elif field in _BOOL_FIELDS:
            v = bool(int(float(value)))
        elif field in _INT_FIELDS:
            f = float(value)
            if not f.is_integer():
                raise ValueError(f"{value!r} is not an integer")
            v = int(f)
        else:
            v = float(value)
    except (TypeError, ValueError) as exc:
        allowed = ", ".join(FILTER_TYPE_NAMES) if field == "filter_type" else spec.range_text()
        raise SpaceError(f"{where}: {field} = {value!r} is not valid ({exc}); allowed: {allowed}") from None
    try:
        check_internal(spec, v)
    except ParameterError as exc:
        raise SpaceError(f"{where}: {exc}") from None
    return v


def _num(text: str, where: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise SpaceError(f"{where}: {text!r} is not a number") from None


def _expand(field: str, items: list[str], where: str) -> list:
    """The values of one grid entry: a range ``a:b:n[:log]`` or a list."""
    if len(items) == 1 and ":" in items[0]:
        parts = items[0].split(":")
        if len(parts) not in (3, 4) or (len(parts) == 4 and parts[3].strip().lower() not in ("log", "lin")):
            raise SpaceError(f"{where}: range {items[0]!r} must be a:b:n or a:b:n:log")
        a, b = _num(parts[0], where), _num(parts[1], where)
        nf = _num(parts[2], where)
        if not nf.is_integer() or nf < 1:
            raise SpaceError(f"{where}: the number of values n in {items[0]!r} must be a positive integer")
        n = int(nf)
        log = len(parts) == 4 and parts[3].strip().lower() == "log"
        if log and (a <= 0 or b <= 0):
            raise SpaceError(f"{where}: a log range needs positive ends, not {items[0]!r}")
        raw = np.geomspace(a, b, n) if log else np.linspace(a, b, n)
        if field in _INT_FIELDS:
            vals = list(dict.fromkeys(int(round(x)) for x in raw))
        else:
            vals = _round_range(field, [float(x) for x in raw])
    else:
        vals = [x.strip() for x in items]
        if any(not x for x in vals):
            raise SpaceError(f"{where}: empty value in {','.join(items)!r}")
    return list(dict.fromkeys(_check_value(field, v, where) for v in vals))


def _round_range(field: str, vals: list[float]) -> list[float]:
    """The values of a range rounded to the parameter's resolution (:func:`round_value`), so that a
    sweep uses and prints 0.9, not the 0.8999999999999999 of ``linspace``. A range finer than the
    resolution would lose values by that: it is rounded to 10 significant digits instead (which
    removes the binary artefacts and keeps every value)."""
    rounded = [round_value(field, v) for v in vals]
    if len(set(rounded)) == len(set(vals)):
        return rounded
    return [float(f"{v:.10g}") for v in vals]


_ENTRY_RE = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=(.*)$")


def parse_grid(text: str) -> dict[str, list]:
    """``"kp=0.1:1.0:10,d_tv=0,0.01,filter_type=MOVING_AVERAGE"`` -> ``{field: [values]}`` (in order).

    Every value is converted and checked against its documented range.
    """
    if not text or not text.strip():
        raise SpaceError("empty grid; expected e.g. 'kp=0.1:1.0:10,n_cycles=4,8,16'")
    entries: list[tuple[str, list[str]]] = []
    for tok in text.split(","):
        m = _ENTRY_RE.match(tok)
        if m:
            entries.append((m.group(1), [m.group(2)]))
        elif not entries:
            raise SpaceError(f"grid {text!r}: expected name=values at the start, not {tok!r}")
        else:
            entries[-1][1].append(tok)
    grid: dict[str, list] = {}
    for name, items in entries:
        field = canonical(name)
        where = f"grid entry {name}"
        if field in grid:
            raise SpaceError(f"{where}: {field} is given twice")
        grid[field] = _expand(field, items, where)
    return grid


def grid_points(grid: dict[str, list]) -> list[dict]:
    """The cartesian product of a parsed grid as points (the last name varies fastest)."""
    names = list(grid)
    return [dict(zip(names, combo)) for combo in itertools.product(*(grid[n] for n in names))]


def random_sample(n: int, seed: int = 0, space: tuple[Dim, ...] = DEFAULT_SPACE, *,
                  cycle_time: float | None = None) -> list[dict]:
    """``n`` random points of ``space``; each point sets only the filter parameters its filter type uses.

    With ``cycle_time`` the low-pass cut-off is kept below 0.45 / cycle_time (Nyquist margin); at kp >= 1
    d_tv is 0 (:data:`D_NO_EFFECT_KP`). Values are rounded to :func:`resolution` (what the tuner prints is what
    it evaluated).
    Drawn for all points at once (:func:`random_columns`).
    """
    return random_columns(n, seed, space, cycle_time=cycle_time).to_points()


# ----------------------------------------------------------------------------- points as columns

#: decimal steps whose rounding :func:`round_column` does without Python (k / 10**d, see there)
_DECIMAL_STEPS = {0.1: 10.0, 0.01: 100.0, 0.001: 1000.0, 0.0001: 10000.0}
#: above this magnitude round(x, 10) may no longer be the decimal k / 10**d: rounded in Python
_FAST_ROUND_LIMIT = 1e5


@dataclass
class PointColumns:
    """``n`` points as columns: ``cols`` field -> values (in the points' key order), ``present`` field ->
    bool mask of the points that set the field (None: all do)."""

    n: int
    cols: dict
    present: dict
    index: np.ndarray | None = None       # the points' numbers in the list they were taken from (take)

    def mask(self, field: str) -> np.ndarray:
        m = self.present.get(field)
        return np.ones(self.n, dtype=bool) if m is None else m

    def take(self, idx) -> "PointColumns":
        """The points ``idx`` (an index array or a bool mask), in that order."""
        idx = np.asarray(idx)
        n = int(idx.sum()) if idx.dtype == bool else len(idx)
        base = np.arange(self.n) if self.index is None else self.index
        return PointColumns(n, {f: v[idx] for f, v in self.cols.items()},
                            {f: (None if m is None else m[idx]) for f, m in self.present.items()}, base[idx])

    def to_points(self) -> list[dict]:
        """The points as dicts (Python int / float / FilterType values, the fields in column order)."""
        names = list(self.cols)
        values = []
        for f in names:
            v = self.cols[f].tolist()
            if f == "filter_type":
                members = {int(t): t for t in FilterType}
                v = [members[c] for c in v]
            values.append(v)
        masks = [self.present.get(f) for f in names]
        if all(m is None for m in masks):
            return [dict(zip(names, row)) for row in zip(*values)]
        masks = [[True] * self.n if m is None else m.tolist() for m in masks]
        out = []
        for i in range(self.n):
            out.append({f: v[i] for f, v, m in zip(names, values, masks) if m[i]})
        return out

    def point(self, i: int) -> dict:
        """Point ``i`` as a dict (for messages)."""
        return self.take(np.array([i])).to_points()[0]


def round_column(field: str, x: np.ndarray) -> np.ndarray:
    """:func:`~distctrl.tuning.space.round_value` of every value of a float column.

    ``round(round(v / step) * step, 10)`` for a decimal step ``10**-d`` is the double nearest to the
    decimal ``k / 10**d`` (k = round(v / step), half to even as Python's round): the product is within a
    few units of the last place of it, far inside the 10th decimal for values below 1e5, and IEEE
    division of the exact integers k and 10**d is correctly rounded. Other steps, larger values: Python."""
    step = resolution(field)
    if step is None or field in _INT_FIELDS or field in _BOOL_FIELDS:
        return x
    x = np.asarray(x, dtype=np.float64)
    scale = _DECIMAL_STEPS.get(step)
    if scale is None or not len(x) or not np.all(np.abs(x) < _FAST_ROUND_LIMIT):
        return np.fromiter((round_value(field, float(v)) for v in x), dtype=np.float64, count=len(x))
    k = np.rint(x / step)
    r = k / scale
    spec = BY_FIELD.get(field)
    if spec is not None and spec.lo_open and spec.lo is not None:
        up = (r <= spec.lo * spec.scale) & (x > r)
        r = np.where(up, (k + 1.0) / scale, r)
    return r


def random_columns(n: int, seed: int = 0, space=None, *, cycle_time: float | None = None) -> PointColumns:
    """:func:`~distctrl.tuning.space.random_sample` as columns: the same points, drawn for all at once."""
    space = DEFAULT_SPACE if space is None else space
    if n < 0:
        raise SpaceError(f"random sample size {n}: must be >= 0")
    rng = np.random.default_rng(seed)
    dims = {d.field: d for d in space}
    draws = {}
    for f, d in dims.items():                # the same stream, the same order as Dim.sample
        if f == "filter_type" and d.kind == "choice":
            # Dim.sample's draw (the index of a choice), as the filter types' values, without objects
            codes = np.array([int(FilterType(c)) for c in d.choices], dtype=np.int64)
            draws[f] = codes[rng.integers(0, len(d.choices), n)]
        else:
            draws[f] = d.sample(rng, n)
    cols: dict = {}
    present: dict = {}
    ft = draws["filter_type"] if "filter_type" in dims else None
    for f, d in dims.items():
        v = draws[f]
        if f == "filter_type":
            v = ft
        elif d.kind == "choice":
            raise SpaceError(f"random_columns: a choice dimension other than filter_type ({f})")
        elif d.kind == "int":
            v = np.asarray(v, dtype=np.int64)
        else:
            v = np.asarray(v, dtype=np.float64)
        mask = None
        if f in NC_WORDS and f not in ("kp", "i_tn", "d_tv", "filter_type") and ft is not None:
            users = [int(t) for t, k in FILTER_KINDS.items() if f in k.fields]
            mask = np.isin(ft, users)
        if f == "low_pass_filter_fg_f0" and cycle_time:
            v = np.minimum(v, 0.45 / cycle_time)                 # (min(v, c): v unless c < v)
        cols[f] = v
        present[f] = mask
    if "kp" in cols and "d_tv" in cols:
        inert = ~(round_column("kp", cols["kp"]) < D_NO_EFFECT_KP)    # not d_tv_applies(round_value(kp))
        cols["d_tv"] = np.where(inert, 0.0, cols["d_tv"])         # no D part at kp >= 1
    for f in cols:
        if f != "filter_type" and dims[f].kind != "int":
            cols[f] = round_column(f, cols[f])
    return PointColumns(n, cols, present)


# ----------------------------------------------------------------------------- points -> sets

def point_label(point: dict) -> str:
    """``kp=0.5 n_cycles=8 filter_type=MOVING_AVERAGE`` (for messages and tables)."""
    parts = []
    for k, v in point.items():
        if isinstance(v, FilterType):
            v = v.name
        elif isinstance(v, float):
            v = f"{v:.6g}"
        parts.append(f"{k}={v}")
    return " ".join(parts)


def to_params(base: AxisParameters, point: dict, cycle_time: float | None = None) -> AxisParameters:
    """``base.replace(**point)`` validated; with ``cycle_time`` also the checks of the controller
    (the low-pass cut-off below Nyquist). Raises :class:`SpaceError` naming the point."""
    try:
        p = base.replace(**point)
        if cycle_time is not None:
            AxisDistanceController(p, cycle_time)
    except (ParameterError, ValueError, TypeError) as exc:
        raise SpaceError(f"parameter set {point_label(point)} is not valid: {exc}") from None
    return p


def build_sets(base: AxisParameters, points: list[dict], cycle_time: float | None = None
               ) -> tuple[list[AxisParameters], list[dict], list[tuple[dict, str]]]:
    """Valid sets, their points, and the rejected ``(point, message)`` pairs.

    What :func:`to_params` does per point, for all points at once (issue 27): the values of every
    swept field are checked against the parameter table (:func:`distctrl.params.axis.check_internal`'s
    rule, vectorised), the filters are designed once per distinct configuration
    (:func:`distctrl.batch.design.filter_coefficients`), and a set is ``base`` with the point's values,
    without a controller per set. A point the vectorised check does not pass (or a field it does not
    cover: the sensor window, software limits, axis type, values of other types) goes through
    :func:`to_params`, so the sets and the messages are those of :func:`to_params`."""
    points = list(points)
    fast = _fast_ok(base, points)
    if cycle_time is not None:
        try:
            check_cycle_time(cycle_time)
        except (ParameterError, ValueError, TypeError):
            fast[:] = False
    if cycle_time is not None and fast.any():
        # every distinct low-pass at once (vectorised over the cut-offs): the loop below finds them cached
        design_many((filter_config(_with(base, pt)) for pt, ok in zip(points, fast) if ok), cycle_time)
    sets, kept, rejected = [], [], []
    for pt, ok in zip(points, fast):
        if ok:
            p = _with(base, pt)
            if cycle_time is not None:
                try:
                    filter_coefficients(filter_config(p), cycle_time)
                except (ParameterError, ValueError, TypeError) as exc:
                    rejected.append((pt, f"parameter set {point_label(pt)} is not valid: {exc}"))
                    continue
            sets.append(p)
            kept.append(pt)
            continue
        try:
            sets.append(to_params(base, pt, cycle_time))
            kept.append(pt)
        except SpaceError as exc:
            rejected.append((pt, str(exc)))
    return sets, kept, rejected


def _with(base: AxisParameters, pt: dict) -> AxisParameters:
    """``base`` with the point's (checked) values, without running the checks again."""
    p = object.__new__(AxisParameters)
    p.__dict__.update(base.__dict__)
    p.__dict__.update(pt)
    return p


#: fields whose checks involve other fields (AxisParameters.__post_init__) or convert values: per point
_CROSS_FIELDS = frozenset({"min_pos", "max_pos", "tolerance", "sw_limit_min", "sw_limit_max", "axis_type"})



def in_table_range(spec, x: np.ndarray, rotary: bool) -> np.ndarray:
    """Which of the values ``x`` (in the NC's units, floats) the parameter table's ``spec`` accepts: one of
    its choices, or within its bounds (open or closed, a closed bound with a relative slack of 1e-9 for
    the unit conversion), as the table's check says for a single value. NaN is refused."""
    good = np.isfinite(x)
    with np.errstate(invalid="ignore"):
        iv = x / spec.scale_for(rotary)
        slack = 1e-9 * np.maximum(1.0, np.abs(iv))
        if spec.choices:
            good &= np.isin(iv, np.asarray(spec.choices, dtype=np.float64))
        else:
            if spec.lo is not None:
                good &= (iv > spec.lo) if spec.lo_open else (iv >= spec.lo - slack)
            if spec.hi is not None:
                good &= (iv < spec.hi) if spec.hi_open else (iv <= spec.hi + slack)
    return good

def _fast_ok(base: AxisParameters, points: list[dict]) -> np.ndarray:
    """Per point: every value passes check_internal's rule for its field (vectorised over the points)."""
    n = len(points)
    ok = np.ones(n, dtype=bool)
    names = {f.name for f in dataclasses.fields(AxisParameters) if f.init}
    fields: dict[str, list] = {}
    for i, pt in enumerate(points):
        for f, v in pt.items():
            fields.setdefault(f, []).append((i, v))
    rotary = base.rotary
    for f, items in fields.items():
        idx = np.fromiter((i for i, _ in items), dtype=np.int64, count=len(items))
        spec = BY_FIELD.get(f)
        if f not in names or spec is None or f in _CROSS_FIELDS or (spec.type == "STRING" and f != "filter_type"):
            ok[idx] = False
            continue
        if f == "filter_type":
            good = np.fromiter((isinstance(v, FilterType) and v != FilterType.PASS for _, v in items), dtype=bool,
                               count=len(items))
            ok[idx[~good]] = False
            continue
        allowed = (int, float, bool) if spec.type == "BOOLEAN" else (int, float)
        typed = np.fromiter((type(v) in allowed for _, v in items), dtype=bool, count=len(items))
        x = np.fromiter((float(v) if t else np.nan for (_, v), t in zip(items, typed)), dtype=np.float64,
                        count=len(items))
        good = typed & np.isfinite(x)
        if spec.type == "BOOLEAN":
            with np.errstate(invalid="ignore"):
                iv = x / spec.scale_for(rotary)
            good &= (iv == 0.0) | (iv == 1.0)
        else:
            good &= in_table_range(spec, x, rotary)
        ok[idx[~good]] = False
    return ok
