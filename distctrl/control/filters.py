"""Sensor filters (SPEC §4, P-AXIS-00782): configuration, design and a small filter object.

The per-sample law lives in :mod:`distctrl.control.law`; this module turns a configuration into
the flat coefficient buffer the law uses (designing the Butterworth low-pass once, with scipy.signal.butter's numbers: :mod:`distctrl.control.butter`) and
offers :class:`SensorFilter`, a filterpy-style object with public state for use on its own
(workbench, tests, a user's own loop).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..base.kinds import FilterType
from ..errors import ParameterError
from ..params.table import BY_FIELD, ParamSpec
from . import law


@dataclass(frozen=True)
class FilterParam:
    """A filter parameter as the parameter table declares it (params/table.py, the only range table):
    its :class:`FilterConfig` field is the spec's canonical short key (``order`` for
    ``low_pass_filter_order``); ``symbol`` names the value in range texts."""

    field: str                   # AxisParameters field (ParamSpec.field)
    symbol: str = "value"
    range_override: str = ""     # a range the table cannot state (fg_f0: below Nyquist, depends on the cycle time)

    @property
    def spec(self) -> ParamSpec:
        return BY_FIELD[self.field]

    @property
    def name(self) -> str:
        """The FilterConfig field and canonical short key."""
        return self.spec.short_keys[0]

    @property
    def keys(self) -> tuple[str, ...]:
        """Every accepted spelling: the short keys, then the AxisParameters field."""
        return tuple(dict.fromkeys((*self.spec.short_keys, self.field)))

    def allowed(self) -> str:
        """The documented range as text: ``0..6`` for a closed integer range, else e.g. ``0 < value <= 1``."""
        s = self.spec
        if s.integer and s.lo is not None and s.hi is not None and not (s.lo_open or s.hi_open):
            return f"{s.lo:g}..{s.hi:g}"
        return s.range_text(self.symbol)

    def range_label(self) -> str:
        """The range with its parameter ID, as the filter specs' messages give it, e.g.
        ``integer 0 <= n < 100 (P-AXIS-00413)``."""
        s = self.spec
        text = self.range_override or ("integer " if s.integer else "") + self.allowed()
        return f"{text} ({s.id})"

    def check(self, value) -> None:
        """Raise ParameterError (ID, field, value, range) unless ``value`` lies in the documented range."""
        s = self.spec
        ok = value == value and s.check(value) and (not s.integer or int(value) == value)   # NaN: not ok
        if not ok:
            text = ("integer " if s.integer and ".." not in self.allowed() else "") + self.allowed()
            raise ParameterError(f"{s.id} {s.field} = {value!r} out of range; allowed: {text}",
                                 param_id=s.id, value=value, allowed=self.allowed())


#: the filter parameters, in FilterConfig order (fg_f0's range depends on the cycle time: Nyquist)
FILTER_PARAMS: dict[str, FilterParam] = {p.name: p for p in (
    FilterParam("n_cycles", symbol="n"), FilterParam("smoothing_factor"), FilterParam("kalman_sigma"),
    FilterParam("low_pass_filter_order"),
    FilterParam("low_pass_filter_fg_f0", range_override="0 < value < Nyquist = 1/(2 cycle time) Hz"))}


@dataclass(frozen=True, slots=True)
class FilterConfig:
    """Filter type and its parameters (P-AXIS-00782, 00413, 00784, 00783, 00507, 00508)."""

    filter_type: FilterType = FilterType.DEFAULT
    n_cycles: int = 4                 # P-AXIS-00413, 0 <= n < 100
    smoothing_factor: float = 0.7     # P-AXIS-00784, 0 < alpha <= 1
    kalman_sigma: float = 4.0         # P-AXIS-00783, 1..10000
    order: int = 4                    # P-AXIS-00507, 0..6
    fg_f0: float = 25.0               # P-AXIS-00508, Hz

    def check(self, cycle_time: float) -> None:
        """Raise ParameterError unless the configuration is usable at this cycle time."""
        if not isinstance(self.filter_type, FilterType) or self.filter_type == FilterType.PASS:
            raise ParameterError(f"filter type {self.filter_type!r} not allowed", param_id="P-AXIS-00782")
        for name in ("n_cycles", "smoothing_factor", "kalman_sigma", "order"):
            FILTER_PARAMS[name].check(getattr(self, name))
        if self.filter_type == FilterType.LOWPASS and self.order > 0:
            nyquist = 0.5 / cycle_time
            if not (0.0 < self.fg_f0 < nyquist):
                raise ParameterError(
                    f"P-AXIS-00508 low_pass_filter_fg_f0 = {self.fg_f0!r} Hz out of range for cycle time {cycle_time} s; "
                    f"allowed: 0 < fg_f0 < {nyquist:g} Hz (Nyquist)", param_id="P-AXIS-00508",
                    value=self.fg_f0, allowed=f"0 < value < {nyquist:g}")

    @property
    def kind(self) -> "FilterKind":
        """The descriptor of this filter type (:data:`FILTER_KINDS`)."""
        return FILTER_KINDS[self.filter_type]

    @property
    def effective_kind(self) -> int:
        """The law's filter code after DEFAULT and the pass-through cases are resolved."""
        return self.kind.code(self)

    @property
    def effective_n(self) -> int:
        return 4 if self.filter_type == FilterType.DEFAULT else int(self.n_cycles)

    def label(self) -> str:
        return self.kind.label(self)


#: Kalman filters: process variance q per cycle, the unit in which ``kalman_sigma`` (the measurement
#: variance, P-AXIS-00783) is given (SPEC §4)
KALMAN_PROCESS_VARIANCE = 1.0


def expo_weights(n: int, alpha: float) -> np.ndarray:
    """EXPO_MEAN weights of the last ``n`` values (n >= 2), **oldest first** (SPEC §4, P-AXIS-00784):
    the newest has exactly ``alpha``; the n-1 older values share ``1 - alpha`` with geometric
    weights ``rho^k`` (age k = 1 .. n-1, rho = 1 - alpha), so they sum to 1, a smaller alpha smooths
    more (FCT-M3 §4.2.1) and alpha -> 0 tends to the mean of the older values (docs/control-law.md)."""
    if n < 2:
        return np.ones(max(n, 1))
    age = np.arange(n - 1, 0, -1, dtype=np.float64)          # ages n-1 .. 1, oldest first
    rho = 1.0 - alpha
    older = np.power(rho, age - 1.0)
    older *= (1.0 - alpha) / older.sum() if older.sum() > 0.0 else 0.0
    weights = np.empty(n)                 # [older..., alpha]: np.r_ cost more than the rest (a sweep designs
    weights[:-1] = older                  # thousands of these)
    weights[-1] = alpha
    return weights


@dataclass(frozen=True)
class KalmanDesign:
    """The constants of a Kalman filter (SPEC §4) for ``n`` measurements and ``sigma``.

    ``coefficients`` (oldest first) give the prediction of the current measurement as a linear
    combination of the last n measurements: the (weighted) least-squares line through them,
    evaluated at the current cycle. ``prediction_variance`` is the variance of that prediction for
    measurements of unit variance (least-squares theory: the sum of the squared coefficients); the
    prior variance is ``P- = prediction_variance * sigma + q`` (the uncertainty of a prediction from n
    measurements of variance sigma, plus the process variance q of one cycle), the gain
    ``K = P- / (P- + sigma)`` and the posterior variance ``P = (1 - K) P-``.
    """

    coefficients: np.ndarray
    prediction_variance: float
    p_prior: float
    gain: float
    p_posterior: float


def kalman_design(kind: int, n: int, alpha: float, sigma: float,
                  q: float = KALMAN_PROCESS_VARIANCE) -> KalmanDesign:
    """Design the Kalman filter ``kind`` (``law.KALMAN_MA`` or ``law.KALMAN_EXPO``) for n >= 2."""
    w = np.full(n, 1.0 / n) if kind == law.KALMAN_MA else expo_weights(n, alpha)
    t = np.arange(n, dtype=np.float64)            # cycle of each measurement, oldest first
    t_now = float(n)                              # the current cycle, one after the newest
    t_mean = float(np.dot(w, t))
    spread = float(np.dot(w, (t - t_mean) ** 2))
    if spread > 1e-12:
        c = w * (1.0 + (t - t_mean) * (t_now - t_mean) / spread)
    else:                                         # all weight on one value (alpha = 1): no slope
        c = w.copy()
    v = float(np.dot(c, c))
    p_prior = v * sigma + q
    gain = p_prior / (p_prior + sigma)
    return KalmanDesign(c, v, p_prior, gain, (1.0 - gain) * p_prior)


def design_coefficients(config: FilterConfig, cycle_time: float, lowpass=None) -> list[float]:
    """The law's coefficient buffer ``fc`` for a configuration (designs the low-pass with
    :func:`distctrl.control.butter.butter_lowpass`). ``lowpass``: the LOWPASS design ``(sos, zi)``
    of this configuration when designed already (many at once, :mod:`distctrl.batch.design`)."""
    config.check(cycle_time)
    fc = [0.0] * law.FC_LEN
    kind = config.effective_kind
    n = config.effective_n
    alpha = float(config.smoothing_factor)
    fc[law.FC_KIND] = float(kind)
    fc[law.FC_N] = float(n)
    fc[law.FC_INV_N] = 1.0 / n if n > 0 else 0.0     # (n = 0: PASS, the mean is not used)
    fc[law.FC_ALPHA] = alpha
    fc[law.FC_SIGMA] = float(config.kalman_sigma)
    # rho^n, sum_(k<n) rho^k = (1 - rho^n)/alpha and beta = alpha/(1 - rho^(n-1)) (rho = 1 - alpha) via
    # log1p/expm1: exact also for a tiny alpha, where the older values' weights become uniform
    # (sum -> n, beta -> 1/(n-1)) instead of a 0/0
    log_rho = math.log1p(-alpha) if alpha < 1.0 else -math.inf
    fc[law.FC_DECAY_N] = math.exp(n * log_rho)
    fc[law.FC_WSUM] = 1.0
    design = FILTER_KINDS[FilterType(kind)].design
    if design is _design_lowpass and lowpass is not None:
        _put_lowpass(fc, *lowpass)
    elif design is not None:
        design(config, fc, cycle_time)
    return fc


# ------------------------------------------------------------------------------------------------------
# the filter types, each described once
# ------------------------------------------------------------------------------------------------------
def _design_expo(config: FilterConfig, fc: list[float], cycle_time: float) -> None:
    n, alpha = int(fc[law.FC_N]), fc[law.FC_ALPHA]
    log_rho = math.log1p(-alpha) if alpha < 1.0 else -math.inf
    fc[law.FC_WSUM] = -math.expm1(n * log_rho) / alpha
    fc[law.FC_EXPO_OLDER] = alpha / -math.expm1((n - 1) * log_rho)


def _design_kalman(config: FilterConfig, fc: list[float], cycle_time: float) -> None:
    n = int(fc[law.FC_N])
    kd = kalman_design(int(fc[law.FC_KIND]), n, fc[law.FC_ALPHA], float(config.kalman_sigma))
    fc[law.FC_GAIN] = kd.gain
    fc[law.FC_P_PRIOR] = kd.p_prior
    fc[law.FC_PRED:law.FC_PRED + n] = [float(v) for v in kd.coefficients]


def _design_lowpass(config: FilterConfig, fc: list[float], cycle_time: float) -> None:
    from .butter import butter_lowpass   # scipy.signal.butter's numbers without scipy (issue 27)

    sos, zi = butter_lowpass(int(config.order), float(config.fg_f0), 1.0 / cycle_time)
    _put_lowpass(fc, sos[0], zi[0])     # zi: steady state for a unit input, seeding causes no jump


def _put_lowpass(fc: list[float], sos, zi) -> None:
    fc[law.FC_NSEC] = float(len(sos))
    for s, row in enumerate(sos):
        fc[law.FC_SOS + 6 * s: law.FC_SOS + 6 * s + 6] = [float(v) for v in row]
        fc[law.FC_ZI + 2 * s] = float(zi[s, 0])
        fc[law.FC_ZI + 2 * s + 1] = float(zi[s, 1])


def _poly_pass(fc):
    return [1.0], [1.0]


def _poly_mean(fc):
    return [fc[law.FC_INV_N]] * int(fc[law.FC_N]), [1.0]


def _poly_expo(fc):
    alpha, beta, rho = fc[law.FC_ALPHA], fc[law.FC_EXPO_OLDER], 1.0 - fc[law.FC_ALPHA]
    return [alpha] + [beta * rho ** k for k in range(1, int(fc[law.FC_N]))], [1.0]


def _poly_kalman(fc):
    n, gain = int(fc[law.FC_N]), fc[law.FC_GAIN]
    pred = fc[law.FC_PRED:law.FC_PRED + n]          # oldest first: pred[n-1] weighs x_(-1)
    return [gain] + [(1.0 - gain) * pred[n - m] for m in range(1, n + 1)], [1.0]


def _poly_lowpass(fc):
    b, a = np.array([1.0]), np.array([1.0])
    for s in range(int(fc[law.FC_NSEC])):
        o = law.FC_SOS + 6 * s
        b = np.convolve(b, fc[o:o + 3])
        a = np.convolve(a, fc[o + 3:o + 6])
    return [float(v) for v in b], [float(v) for v in a]


def _code_windowed(c: FilterConfig) -> int:
    """Filters over the last n_cycles values: n <= 1 passes the value through."""
    return law.PASS if c.n_cycles <= 1 else int(c.filter_type)


def _code_expo(c: FilterConfig) -> int:
    return law.PASS if c.n_cycles <= 1 or c.smoothing_factor >= 1.0 else law.EXPO_MEAN


def _label_windowed(c: FilterConfig) -> str:
    extra = "".join(f", {p}={getattr(c, p):g}" for p in c.kind.params if p != "n_cycles")
    return f"{c.filter_type.name}(n_cycles={c.n_cycles}{extra})"


@dataclass(frozen=True)
class FilterKind:
    """One filter type, described once (SPEC §4): what control, workbench, tuning and margins read.

    * ``params``: the :class:`FilterConfig` fields (= short keys, :data:`FILTER_PARAMS`) that change
      the law; the others have no effect (a filter spec naming one is an error, tuning does not vary it);
    * ``code(config)``: the law's filter code in force (DEFAULT and the pass-through cases resolved);
    * ``design(config, fc, cycle_time)``: fills this kind's part of the coefficient buffer (after the
      common part of :func:`design_coefficients`), None when it needs nothing more;
    * ``polynomials(fc)``: its transfer function ``(b, a)`` in ``z^-1`` as the law computes it, for
      the margins (None: no linear model, e.g. an order statistic);
    * ``example``: its spec in the workbench's default comparison (``distctrl filters``), if any;
    * ``tunable``: one of the choices of the default tuning space.

    A new filter type: a branch in :func:`distctrl.control.law.filter_step` (and a code constant),
    a member of :class:`~distctrl.base.kinds.FilterType` and a descriptor here.
    """

    type: FilterType
    params: tuple[str, ...]
    code: Callable[[FilterConfig], int]
    label: Callable[[FilterConfig], str] = _label_windowed
    design: Callable[[FilterConfig, list, float], None] | None = None
    polynomials: Callable[[list], tuple[list, list]] | None = None
    example: str = ""
    tunable: bool = True

    @property
    def fields(self) -> tuple[str, ...]:
        """The AxisParameters fields of :attr:`params` (``order`` -> ``low_pass_filter_order``)."""
        return tuple(FILTER_PARAMS[p].field for p in self.params)


#: every filter type, in FilterType order (the tuning space's choices keep this order)
FILTER_KINDS: dict[FilterType, FilterKind] = {k.type: k for k in (
    FilterKind(FilterType.DEFAULT, (), lambda c: law.MOVING_AVERAGE,
               label=lambda c: "DEFAULT(MOVING_AVERAGE n=4)", tunable=False),
    FilterKind(FilterType.PASS, (), lambda c: law.PASS, polynomials=_poly_pass, tunable=False),
    FilterKind(FilterType.MOVING_AVERAGE, ("n_cycles",), _code_windowed, polynomials=_poly_mean,
               example="MOVING_AVERAGE:n_cycles=20,30"),
    FilterKind(FilterType.EXPO_MEAN, ("n_cycles", "smoothing_factor"), _code_expo, design=_design_expo,
               polynomials=_poly_expo, example="EXPO_MEAN:n_cycles=30,smoothing_factor=0.3"),
    FilterKind(FilterType.LOWPASS, ("order", "fg_f0"), lambda c: law.LOWPASS if c.order > 0 else law.PASS,
               label=lambda c: f"LOWPASS(order={c.order}, fg_f0={c.fg_f0:g} Hz)", design=_design_lowpass,
               polynomials=_poly_lowpass, example="LOWPASS:order=2,fg_f0=30"),
    FilterKind(FilterType.KALMAN_MA, ("n_cycles", "kalman_sigma"), _code_windowed, design=_design_kalman,
               polynomials=_poly_kalman, example="KALMAN_MA:n_cycles=20,30,kalman_sigma=4,1000"),
    FilterKind(FilterType.KALMAN_EXPO, ("n_cycles", "smoothing_factor", "kalman_sigma"), _code_windowed,
               design=_design_kalman, polynomials=_poly_kalman,
               example="KALMAN_EXPO:n_cycles=30,smoothing_factor=0.3,kalman_sigma=1000"),
)}


class SensorFilter:
    """One configured sensor filter with public state (filterpy style).

    >>> f = SensorFilter(FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=3), cycle_time=0.001)
    >>> [f.step(x) for x in (3.0, 3.0, 6.0)]
    [3.0, 3.0, 4.0]

    The first sample seeds the history (no jump on activation). ``fc``, ``fs`` and ``buf`` are
    the law's buffers; :meth:`apply` runs a whole signal through a fresh copy.
    """

    def __init__(self, config: FilterConfig, cycle_time: float = 0.001):
        self.config = config
        self.cycle_time = float(cycle_time)
        self.fc = design_coefficients(config, self.cycle_time)
        self.fs = [0.0] * law.FS_LEN
        self.buf = [0.0] * law.MAX_N
        self.seeded = False

    def seed(self, x0: float) -> None:
        law.filter_seed(self.fc, self.fs, self.buf, float(x0))
        self.seeded = True

    def step(self, x: float) -> float:
        if not self.seeded:
            self.seed(x)
        return law.filter_step(self.fc, self.fs, self.buf, float(x))

    @property
    def last(self) -> float:
        return self.fs[law.FS_LAST]

    def apply(self, signal) -> np.ndarray:
        """Filter a whole signal from a fresh start (seeded with its first sample)."""
        fresh = SensorFilter(self.config, self.cycle_time)
        return np.fromiter((fresh.step(x) for x in np.asarray(signal, dtype=float)), dtype=float,
                           count=len(signal))
