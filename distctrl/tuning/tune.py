"""Auto-tuning of the filter and PID settings of one distance-controlled axis.

:func:`tune` runs, on one :class:`~distctrl.tuning.runner.Evaluator` (an embedded dask cluster,
an existing one, or in-process):

1. **coarse sweep**: the scenario's own parameters plus ``coarse_share * budget`` random points of
   the search space (:data:`~distctrl.tuning.space.DEFAULT_SPACE`);
2. **local refinement**: a parallel pattern (coordinate) search around the best ``top`` distinct
   points: per round every point's neighbours (each continuous or integer parameter one step up
   and down, the filter type fixed) are evaluated in one batch; a point moves to its best
   neighbour if that is better, otherwise its step is halved; until the budget is used up;
3. the objective is :func:`~distctrl.tuning.metrics.cost` = ``rms_error + osc_weight * hf_rms``
   (the oscillation penalty), ``inf`` for a set that raises a controller error;
4. **robustness**: the chosen set and the scenario's own set are re-run on perturbed copies of
   the scenario (probe noise x2, surface amplitude x1.5, Z drive kv x0.7); the report gives for
   each the cost, the degradation against the nominal run and the margin = the share of the
   improvement over the scenario's own set that is left under the perturbation.

Only sets that meet the **margin constraint** (:mod:`distctrl.tuning.robust`: gain and phase margin at
every crossing, on the plant and its variants within identify's tolerances) are chosen; random points
that miss it get the largest KP that meets it.

Output: :class:`TuneResult` with the chosen :class:`~distctrl.params.axis.AxisParameters`,
its kernel parameter list (:func:`~distctrl.params.format_list`, changed values only), an NC
block ``Z[DIST_CTRL KP=.. I_TN=.. D_TV=.. FILTER_TYPE=.. N_CYCLES=..]`` and a before/after plot
(:func:`plot_before_after`).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..base.kinds import FilterType
from ..errors import DistCtrlError
from ..params import format_list
from ..params.axis import AxisParameters
from ..sim.surface import Surface
from ..workbench.margins import analyse, loop_model, model_from_parts
from ..workbench.tables import render_table
from .metrics import CHATTER_WEIGHT, METRIC_NAMES, METRIC_UNITS, SAT_WEIGHT, wanted_distance
from .robust import DEFAULT_ALLOWANCE, KP_FLOOR, MIN_GAIN_MARGIN, MIN_PHASE_MARGIN_DEG, MarginConstraint, PlantAllowance
from .runner import Evaluator, SweepResult
from .simfallback import FINALISTS, kernel_proxy, sim_evaluate
from .space import (D_TV_NOTE, DEFAULT_SPACE, NC_WORDS, Dim, SpaceError, build_sets, d_tv_applies, drop_inert_d_tv,
                    filter_fields, random_sample, resolution, round_point, round_value, to_params)

__all__ = ["TuneResult", "tune", "nc_block", "param_list", "perturbed_scenarios", "ScaledSurface",
           "plot_before_after", "PERTURBATIONS"]

#: (name, description) of the robustness checks
PERTURBATIONS = (("noise x2", "probe noise_std x2"), ("surface x1.5", "surface amplitude x1.5"),
                 ("kv x0.7", "Z drive kv x0.7"))
_TUNED = ("kp", "i_tn", "d_tv")


# ----------------------------------------------------------------------------- output formats

def _fmt(v) -> str:
    if isinstance(v, FilterType):
        return v.name
    if isinstance(v, (bool, np.bool_)):
        return str(int(v))
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    return f"{float(v):.6g}"


def nc_block(params: AxisParameters, axis: str = "Z") -> str:
    """``Z[DIST_CTRL KP=.. I_TN=.. D_TV=.. FILTER_TYPE=.. N_CYCLES=..]`` (+ the words the filter uses)."""
    words = [f"KP={_fmt(params.kp)}", f"I_TN={_fmt(params.i_tn)}", f"D_TV={_fmt(params.d_tv)}",
             f"FILTER_TYPE={params.filter_type.name}"]
    if params.filter_type != FilterType.DEFAULT:
        used = filter_fields(params.filter_type)
        if "n_cycles" in used:
            words.append(f"N_CYCLES={params.n_cycles}")
        for f in used:
            if f != "n_cycles":
                words.append(f"{NC_WORDS[f]}={_fmt(getattr(params, f))}")
    return f"{axis}[DIST_CTRL {' '.join(words)}]"


def param_list(params: AxisParameters) -> str:
    """The kernel list of ``params``, only the values that differ from the defaults."""
    return format_list(params, only_changed=True)


# ----------------------------------------------------------------------------- perturbations

class ScaledSurface(Surface):
    """A surface whose features are scaled: ``base + factor * (surface - base)``."""

    def __init__(self, surface: Surface, factor: float):
        super().__init__(surface.base, surface.features)
        self._inner = surface
        self._factor = float(factor)

    def height(self, x: float, y: float = 0.0) -> float:
        return self.base + self._factor * (self._inner.height(x, y) - self.base)

    def height_array(self, xs, ys=0.0):
        return self.base + self._factor * (self._inner.height_array(xs, ys) - self.base)

    def gradient(self, x: float, y: float = 0.0):
        gx, gy = self._inner.gradient(x, y)
        return self._factor * gx, self._factor * gy


def perturbed_scenarios(scenario, axis: str, noise: float = 2.0, surface: float = 1.5, kv: float = 0.7):
    """``[(name, scenario)]``: copies of ``scenario`` with the probe noise, the surface amplitude and
    the drive kv of ``axis`` scaled (the scenario is edited, then recorded again by ``prepare``)."""
    sc = scenario
    out = []
    out.append((PERTURBATIONS[0][0], dataclasses.replace(
        sc, sensor=dataclasses.replace(sc.sensor, noise_std=sc.sensor.noise_std * noise))))
    out.append((PERTURBATIONS[1][0], dataclasses.replace(sc, surface=ScaledSurface(sc.surface, surface))))
    axes = dict(sc.axes)
    axes[axis] = dataclasses.replace(axes[axis], kv=axes[axis].kv * kv)
    out.append((PERTURBATIONS[2][0], dataclasses.replace(sc, axes=axes)))
    return out


# ----------------------------------------------------------------------------- search

def _refine_dims(ft: FilterType, space: tuple[Dim, ...], cycle_time: float) -> list[Dim]:
    used = set(_TUNED) | set(filter_fields(ft))
    dims = []
    for d in space:
        if d.field in used and d.kind != "choice":
            if d.field == "low_pass_filter_fg_f0":
                d = dataclasses.replace(d, hi=min(d.hi, 0.45 / cycle_time))
            dims.append(d)
    return dims


def _neighbours(point: dict, dims: list[Dim], scale: float) -> list[dict]:
    out = []
    for d in dims:
        v = point.get(d.field)
        if v is None or (d.field == "d_tv" and not d_tv_applies(point.get("kp", 0.0))):
            continue                   # no D part at kp >= 1: d_tv is no dimension to spend budget on
        cands = []
        if d.field == "kp" and v < d.lo:
            # a KP the margin constraint lowered below the space (robust.MarginConstraint.fit_kp): steps by a
            # factor, down to the floor
            f = 2.0 ** scale
            for c in (max(v / f, KP_FLOOR), min(v * f, d.hi)):
                c = round_value(d.field, c)
                if c != v:
                    out.append(dict(point, kp=c))
            continue
        if d.kind == "float":
            step = scale * 0.15 * (d.hi - d.lo)
            cands = [v - step, v + step]
        elif d.kind == "int":
            step = max(1, int(round(scale * (d.hi - d.lo) / 4)))
            cands = [v - step, v + step]
        elif d.kind == "log":
            f = 2.0 ** scale
            if v == 0:
                cands = [d.lo]
            else:
                cands = [v / f, v * f]
                if d.zero_share and v / f < d.lo:
                    cands.append(0.0)
        for c in cands:
            c = d.clip(c)
            if d.kind == "log" and 0 < c < d.lo and not d.zero_share:
                c = d.lo
            c = round_value(d.field, c)
            if c != v:
                q = dict(point)
                q[d.field] = c
                if "d_tv" in q and not d_tv_applies(q.get("kp", 0.0)):
                    q["d_tv"] = 0.0
                out.append(q)
    return out


def _key(point: dict) -> tuple:
    return tuple(sorted((k, round(float(v), 9) if not isinstance(v, FilterType) else v.name)
                        for k, v in point.items()))


def _point_of(p: AxisParameters) -> dict:
    pt = {f: getattr(p, f) for f in _TUNED}
    pt["filter_type"] = p.filter_type
    for f in filter_fields(p.filter_type):
        pt[f] = getattr(p, f)
    return pt


@dataclass
class TuneResult:
    """What :func:`tune` found (see the module docstring)."""

    axis: str
    base: AxisParameters
    best: AxisParameters
    base_metrics: dict
    best_metrics: dict
    sweep: SweepResult
    robustness: list[dict] = field(default_factory=list)
    evaluations: int = 0
    seconds: float = 0.0
    stats: dict = field(default_factory=dict)
    #: the search's best set before rounding and its metrics (``best`` is rounded to the resolutions of
    #: :func:`~distctrl.tuning.space.resolution` and ``best_metrics`` come from a run of that set)
    unrounded: AxisParameters | None = None
    unrounded_metrics: dict = field(default_factory=dict)
    cost_weights: dict = field(default_factory=dict)
    #: the linearised loop's margins on the plant tuned on (:func:`stability`), tuned and scenario's set
    stability: dict = field(default_factory=dict)
    base_stability: dict = field(default_factory=dict)
    #: the margin constraint (:mod:`distctrl.tuning.robust`): what was required, on which plants, the worst
    #: margins of the tuned and the scenario's set, how many sets it changed or dropped; {} when off
    margin_constraint: dict = field(default_factory=dict)
    #: the closed-loop inputs tuned on and the cycles replayed (what :meth:`plot` runs again); None for a
    #: result built by hand
    inputs: object = field(default=None, repr=False, compare=False)
    cycles: int | None = None
    #: when the tuned set changes the filter: the best evaluated set that keeps the scenario's filter (only
    #: kp, i_tn, d_tv, v_max, a_max differ: what ``machine write`` can put into a machine over the CNC
    #: objects), its metrics, and how it was found; None / {} otherwise
    objects: AxisParameters | None = None
    objects_metrics: dict = field(default_factory=dict)
    objects_note: str = ""
    #: the best evaluated set by cost without the margin constraint (``best`` when the constraint is off)
    unconstrained: AxisParameters | None = None
    unconstrained_metrics: dict = field(default_factory=dict)
    #: set when the kernel does not model the scenario's sensor exactly and the reported sets ran on the
    #: scalar simulation (:mod:`distctrl.tuning.simfallback`): what was done
    fallback_note: str = ""

    @property
    def param_list(self) -> str:
        return param_list(self.best)

    @property
    def nc_block(self) -> str:
        return nc_block(self.best, self.axis)

    @property
    def margin(self) -> float | None:
        """The smallest margin over the perturbations (1 = the full improvement kept, <= 0 = none); None
        when there is no improvement over the scenario's set to keep (or no perturbation ran)."""
        vals = [r["margin"] for r in self.robustness
                if r["margin"] is not None and math.isfinite(r["margin"])]
        return min(vals) if vals else None

    @property
    def changes_filter(self) -> bool:
        """True when the tuned set's filter (type and the parameters it uses) differs from the scenario's."""
        return _filter_of(self.best) != _filter_of(self.base)

    @property
    def worse_than_current(self) -> bool:
        """True when the recommended set tracks worse than the scenario's (current) set in the nominal run:
        an rms_error more than :data:`WORSE_RMS_REL` larger, or a larger cost."""
        return _worse(self.best_metrics, self.base_metrics)

    @property
    def worse_reason(self) -> str | None:
        """Why the recommended set is reported worse than the current one: which figure is worse, what the
        cost (the figure tune minimises) did, why the set was still recommended, and what the margin
        constraint cost (the best evaluated set without it); None when it is not worse."""
        if not self.worse_than_current:
            return None
        b, t = self.base_metrics, self.best_metrics
        rms = f"{_num(b.get('rms_error'))} -> {_num(t.get('rms_error'))} mm"
        costs = f"{_num(b.get('cost'))} -> {_num(t.get('cost'))} mm"
        formula = _cost_formula(self.cost_weights)
        mc = self.margin_constraint or {}
        applied = bool(mc) and "error" not in mc
        misses = applied and not (mc.get("scenario_params") or {}).get("ok", True)
        missed = (f"the current set misses the margin constraint ({mc['scenario_params_text']})"
                  if misses else "")
        if not _worse({"cost": t.get("cost")}, {"cost": b.get("cost")}):
            others = ", ".join(f"{n} {_num(b.get(n))} -> {_num(t.get(n))}"
                               + (" mm" if METRIC_UNITS.get(n) == "mm" else "")
                               for n in _cost_terms(self.cost_weights))
            out = (f"its rms_error is worse ({rms}), but tune minimises the cost ({formula}, "
                   f"docs/tuning.md), and that improved ({costs}): the cost's other terms ({others}), "
                   "weighted, fell by more than rms_error rose")
            if missed:
                out += f"; besides, {missed}"
        else:
            rms_worse = _worse({"rms_error": t.get("rms_error")}, {"rms_error": b.get("rms_error")})
            minimised = f"the figure tune minimises ({formula}, docs/tuning.md)"
            out = (f"its rms_error is worse ({rms}) and so is its cost, {minimised}: {costs}; " if rms_worse
                   else f"its cost, {minimised}, is worse: {costs}; ")
            if missed and mc.get("met"):
                out += (f"{missed}, so it is not recommended, and the best evaluated set that meets it costs "
                        "more than the current set")
            else:
                out += ("rounding the tuned values to what the list and the NC take made it worse than the "
                        f"current set (cost before rounding {_num(self.unrounded_metrics.get('cost'))} mm)")
                out += f"; besides, {missed}" if missed else ""
        u, um = self.unconstrained, self.unconstrained_metrics
        if not applied:
            out += "; no margin constraint was applied"
        elif u is None or not um or u == self.best:
            out += ("; the margin constraint cost nothing: the best evaluated set by cost, with it or "
                    f"without it, is the recommended set (rms_error {_num(t.get('rms_error'))} mm, cost "
                    f"{_num(t.get('cost'))} mm)")
        else:
            who = "the current set" if u == self.base else "an evaluated set that misses it"
            out += (f"; cost of the constraint: the best set without it ({who}) has rms_error "
                    f"{_num(um.get('rms_error'))} mm, cost {_num(um.get('cost'))} mm, against "
                    f"{_num(t.get('rms_error'))} mm, {_num(t.get('cost'))} mm with it")
        return out

    @property
    def _worse_advice(self) -> str:
        """The report's advice after :attr:`worse_reason`."""
        if not _worse({"cost": self.best_metrics.get("cost")}, {"cost": self.base_metrics.get("cost")}):
            return "It is recommended for its lower cost; keep the current set if rms_error alone matters."
        u = self.unconstrained
        if u is not None and u != self.best:
            return "Keep the current set unless you need what the constraint buys."
        return "Keep the current set."

    def tuned_values(self, params: AxisParameters | None = None) -> dict:
        """The tuned parameters as plain values (internal units: s, Hz): kp, i_tn, d_tv, filter_type
        and the filter's own parameters."""
        p = params if params is not None else self.best
        out = {}
        for k, v in _point_of(p).items():
            out[k] = v.name if isinstance(v, FilterType) else (int(v) if isinstance(v, (int, np.integer))
                                                                and not isinstance(v, bool) else float(v))
        if not d_tv_applies(p.kp):
            out["d_tv"] = None                 # no D part at kp >= 1 (the list and the NC block carry 0)
        return out

    @property
    def notes(self) -> list[str]:
        """:data:`~distctrl.tuning.space.D_TV_NOTE` when the scenario's or the tuned kp is >= 1."""
        return [D_TV_NOTE] if not (d_tv_applies(self.best.kp) and d_tv_applies(self.base.kp)) else []

    def to_dict(self) -> dict:
        """One JSON-able object (``distctrl tune --json``)."""
        def metrics(m: dict) -> dict:
            return {n: _plain(m.get(n)) for n in ["cost"] + list(METRIC_NAMES) + ["failed"] if n in m}

        return {"axis": self.axis, "evaluations": self.evaluations, "seconds": self.seconds,
                "cost_weights": dict(self.cost_weights), "metric_units": dict(METRIC_UNITS),
                "resolution": {k: resolution(k) for k in self.tuned_values()},
                "scenario_params": {"values": self.tuned_values(self.base), "metrics": metrics(self.base_metrics),
                                    "stability": dict(self.base_stability) or None},
                "tuned": {"values": self.tuned_values(), "metrics": metrics(self.best_metrics),
                          "stability": dict(self.stability) or None,
                          "unrounded_values": self.tuned_values(self.unrounded) if self.unrounded is not None else None,
                          "unrounded_metrics": metrics(self.unrounded_metrics)},
                "robustness": [{k: _plain(v) for k, v in r.items()} for r in self.robustness],
                "margin": _plain(self.margin), "param_list": self.param_list, "nc_block": self.nc_block,
                "margin_constraint": dict(self.margin_constraint) or None, "notes": self.notes,
                "worse_than_current": self.worse_than_current, "worse_reason": self.worse_reason,
                "unconstrained": None if self.unconstrained is None else {
                    "values": self.tuned_values(self.unconstrained),
                    "metrics": metrics(self.unconstrained_metrics)},
                "changes_filter": self.changes_filter,
                "objects_set": None if self.objects is None else {
                    "values": self.tuned_values(self.objects), "metrics": metrics(self.objects_metrics),
                    "param_list": param_list(self.objects), "note": self.objects_note},
                "objects_note": self.objects_note or None,
                "evaluated_by": "simulation" if self.fallback_note else "kernel",
                "fallback_note": self.fallback_note or None}

    def plot(self, path=None, title: str | None = None):
        """The distance error and the offset over time with the scenario's and the tuned parameters
        (:func:`plot_before_after` on the inputs tuned on); a Figure on an Agg canvas, saved to ``path``."""
        if self.inputs is None:
            raise DistCtrlError("this TuneResult holds no inputs to run again; allowed: a result of tune()")
        return plot_before_after(self.inputs, self.base, self.best, path, cycles=self.cycles, title=title)

    def to_csv(self, path) -> Path:
        """The table of every evaluated set (:meth:`SweepResult.to_csv <distctrl.tuning.runner.SweepResult.to_csv>`)."""
        return self.sweep.to_csv(path)

    def report(self, plain: bool = True) -> str:
        names = ["cost"] + list(METRIC_NAMES)
        rows = [[n, METRIC_UNITS.get(n, "-"), _num(self.base_metrics.get(n)), _num(self.best_metrics.get(n))]
                for n in names]
        out = []
        if self.worse_than_current:
            out.append("WARNING: the recommended set tracks WORSE than the current one "
                       f"({self.worse_reason}). " + self._worse_advice)
        if self.fallback_note:
            out.append(f"note: {self.fallback_note}")
        out += [f"evaluated {self.evaluations} parameter sets in {self.seconds:.1f} s",
               render_table(["metric", "unit", "scenario params", "tuned"], rows, title="nominal scenario",
                            plain=plain)]
        if self.unrounded is not None:
            steps = ", ".join(f"{k} {resolution(k):g}" for k in self.tuned_values() if resolution(k) is not None)
            out.append(f"tuned values rounded to what one types into the list and the NC ({steps}) and run "
                       f"again: the table shows that run (cost before rounding "
                       f"{_num(self.unrounded_metrics.get('cost'))} mm)")
        out.extend(_stability_lines(self.stability, self.base_stability))
        out.extend(_constraint_lines(self.margin_constraint))
        sat = self.best_metrics.get("sat_share")
        if sat is not None and math.isfinite(float(sat)) and float(sat) > 0.1:
            out.append(f"warning: the tuned set runs at the limiter (P-AXIS-00415/00416) {float(sat):.0%} of the "
                       "time; raise --sat-weight")
        if self.robustness:
            rrows = [[r["name"], _num(r["base_cost"]), _num(r["best_cost"]), _num(r["best_rms"]),
                      f"{r['degradation']:.2f}x" if math.isfinite(r["degradation"]) else "-",
                      f"{r['margin']:.0%}" if math.isfinite(r["margin"]) else "-",
                      "FAILED" if r["failed"] else "ok"] for r in self.robustness]
            out.append(render_table(["perturbation", "cost scen.", "cost tuned", "rms tuned", "degradation",
                                     "margin", "state"], rrows, title="robustness", plain=plain))
            if self.margin is None:
                out.append("margin: none to give: the tuned set is no improvement over the scenario's set "
                           "(degradation: cost perturbed / cost nominal of the tuned set)")
            else:
                out.append(f"margin: {self.margin:.0%} of the improvement is kept in the worst perturbation "
                           "(degradation: cost perturbed / cost nominal of the tuned set)")
        out.extend(f"note: {n}" for n in self.notes)
        out.extend(self._objects_lines())
        out.append("# axis parameter list (changed values)\n" + self.param_list)
        out.append("; NC block\n" + self.nc_block)
        return "\n".join(out) + "\n"


    def _objects_lines(self) -> list[str]:
        """The lines on tuned-objects.lis (when the tuned set changes the filter)."""
        if not self.changes_filter:
            return []
        if self.objects is None:
            return [f"note: the tuned set changes the filter ({_filter_text(self.base)} -> "
                    f"{_filter_text(self.best)}), which is not writable over the CNC objects; "
                    + (self.objects_note or "no set that keeps the filter was found")]
        m, b = self.objects_metrics, self.best_metrics
        vals = ", ".join(f"{k} {_fmt(getattr(self.objects, k))}" for k in _TUNED)
        return [f"note: the tuned set changes the filter ({_filter_text(self.base)} -> "
                f"{_filter_text(self.best)}), which `machine write` cannot put into a machine over the CNC "
                "objects (it goes into the CNC's parameter list). tuned-objects.lis holds the best evaluated "
                f"set that keeps the scenario's filter: {vals}: rms_error {_num(m.get('rms_error'))} mm, "
                f"cost {_num(m.get('cost'))} mm (the tuned set: "
                f"{_num(b.get('rms_error'))} mm, {_num(b.get('cost'))} mm; the current set: "
                f"{_num(self.base_metrics.get('rms_error'))} mm, {_num(self.base_metrics.get('cost'))} mm)"
                + (f"; {self.objects_note}" if self.objects_note else "")]

    @property
    def objects_list(self) -> str | None:
        """The kernel list of :attr:`objects` (tuned-objects.lis), None when there is none."""
        return None if self.objects is None else param_list(self.objects)


#: what ``machine write`` can write over the CNC objects (the rest of a set goes into the parameter list)
OBJECT_FIELDS = ("kp", "i_tn", "d_tv", "v_max", "a_max")


def _filter_of(p: AxisParameters) -> tuple:
    return (p.filter_type,) + tuple(getattr(p, f) for f in filter_fields(p.filter_type))


def _filter_text(p: AxisParameters) -> str:
    used = filter_fields(p.filter_type)
    return p.filter_type.name + ("" if not used else
                                 " " + ", ".join(f"{f} {_fmt(getattr(p, f))}" for f in used))


#: the cost's terms after rms_error: (weight's key in cost_weights, metric); docs/tuning.md "cost ="
_COST_TERMS = (("osc_weight", "hf_rms"), ("overshoot_weight", "overshoot"), ("sat_weight", "sat_share"),
               ("chatter_weight", "offset_hf_rms"))


def _cost_terms(weights: dict) -> list[str]:
    """The metrics the cost adds to rms_error with a weight other than 0."""
    return [m for k, m in _COST_TERMS if weights.get(k)]


def _cost_formula(weights: dict) -> str:
    """``cost = rms_error + 1 * hf_rms + 0.05 * sat_share + ...`` with the weights of this tune."""
    return "cost = " + " + ".join(["rms_error"] + [f"{weights[k]:g} * {m}" for k, m in _COST_TERMS
                                                    if weights.get(k)])


def _worse(tuned: dict, current: dict) -> bool:
    def f(m, k):
        v = m.get(k)
        return None if v is None or not math.isfinite(float(v)) else float(v)

    for k, rel in (("rms_error", WORSE_RMS_REL), ("cost", 1e-6)):
        t, c = f(tuned, k), f(current, k)
        if t is not None and c is not None and t > c * (1.0 + rel):
            return True
    return False


#: the tuned set "tracks worse" when its rms_error exceeds the current set's by more than this share (or its
#: cost exceeds it at all): a cost that weighs chatter may trade a hair of rms_error for much less chatter
WORSE_RMS_REL = 0.005


def stability(scenario, params: AxisParameters) -> dict:
    """Gain and phase margin of ``params`` on the scenario's plant: the linearised loop of
    ``distctrl margins`` (:mod:`distctrl.workbench.margins`: drive kv, bus delay, resonance, sensor delay
    and gain of the scenario) with the list ``params`` (in CONST_DIST or the mode of the first select).
    ``{"error": text}`` where the margins cannot be computed (e.g. a 3D scenario)."""
    try:
        m = loop_model(scenario)
        r = analyse(model_from_parts(params, m.cycle_time, axis=m.axis, mode=m.mode, kv=m.kv,
                                     feedforward=m.feedforward, bus_delay_cycles=m.bus_delay_cycles,
                                     sensor_delay_cycles=m.sensor_delay_cycles, sensor_gain=m.sensor_gain,
                                     scenario=m.scenario, kp_source="tuned list", notes=m.notes,
                                     resonance_hz=m.resonance_hz, damping=m.damping))
    except DistCtrlError as exc:
        return {"error": str(exc)}
    d = r.to_dict()
    return {k: _plain(d[k]) for k in ("stable", "verdict", "gain_margin", "gain_margin_db", "phase_crossover_hz",
                                      "phase_margin_deg", "gain_crossover_hz", "kp", "kp_limit",
                                      "closed_loop_pole_max_abs")}


def _stability_lines(tuned: dict, base: dict) -> list[str]:
    """The report's lines on the margins (``distctrl margins`` of the tuned plant)."""
    def one(s: dict) -> str:
        if not s:
            return "-"
        if "error" in s:
            return f"not computed ({s['error']})"
        gm, db, pm = s.get("gain_margin"), s.get("gain_margin_db"), s.get("phase_margin_deg")
        parts = [s["verdict"]]
        parts.append(f"gain margin {gm:.3g} ({db:+.1f} dB) at {_hz_text(s.get('phase_crossover_hz'))}"
                     if gm is not None and db is not None else "gain margin - (no phase crossover)")
        parts.append(f"phase margin {pm:.1f} deg at {_hz_text(s.get('gain_crossover_hz'))}"
                     if pm is not None else "phase margin - (no gain crossover)")
        return ", ".join(parts)

    if not tuned and not base:
        return []
    return ["margins on the plant tuned on (distctrl margins, linearised loop):",
            f"  tuned:           {one(tuned)}", f"  scenario params: {one(base)}"]


def _constraint_lines(mc: dict) -> list[str]:
    """The report's lines on the margin constraint (:mod:`distctrl.tuning.robust`)."""
    if not mc:
        return []
    if "error" in mc:
        return [f"margin constraint: not applied ({mc['error']})"]
    out = [f"margin constraint: {mc['description']}:",
           f"  tuned:           {mc['tuned_text']}", f"  scenario params: {mc['scenario_params_text']}"]
    if mc["kp_lowered"] or mc["dropped"]:
        out.append(f"  {mc['kp_lowered']} random sets had their KP lowered to meet it, {mc['dropped']} could not "
                   f"meet it even at KP {KP_FLOOR:g} (dropped), {mc['neighbours_dropped']} refinement steps "
                   "left it (not run)")
    if not mc["met"]:
        out.append("warning: no evaluated set met the margin constraint; the tuned set is the best by cost and "
                   "its margins are above. Do not use it on the machine without checking it (distctrl margins)")
    return out


def _hz_text(f) -> str:
    return f"{f:.3g} Hz" if f is not None else "- Hz"


def _num(x) -> str:
    if x is None:
        return "-"
    if isinstance(x, (bool, np.bool_)):
        return str(bool(x))
    x = float(x)
    if math.isnan(x):
        return "-"
    if math.isinf(x):
        return "inf"
    return f"{x:.4g}"


def _plain(x):
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None           # no NaN or inf in the JSON: null
    if isinstance(x, FilterType):
        return x.name
    return x


def _row(res: SweepResult, i: int) -> dict:
    return {k: (v[i] if not isinstance(v, list) else v[i]) for k, v in res.data.items()}


def _meet(constraint, counts: dict, sets_in: list, pts_in: list, lower: bool) -> tuple[list, list]:
    """The sets that meet the margin constraint (all without one); with ``lower`` a set that misses it gets
    the largest KP that meets it (dropped if even the floor does not). ``counts`` tallies what changed."""
    if constraint is None:
        return sets_in, pts_in
    out_s, out_p = [], []
    for st, pt in zip(sets_in, pts_in):
        if lower:
            q = constraint.fit_kp(st)
            if q is None:
                counts["dropped"] += 1
                continue
            if q.kp != st.kp:
                counts["kp_lowered"] += 1
                st, pt = q, dict(pt, kp=q.kp)
        elif not constraint.ok(st):
            counts["neighbours_dropped"] += 1
            continue
        out_s.append(st)
        out_p.append(pt)
    return out_s, out_p


def _coarse(ev, base: AxisParameters, constraint, n_coarse: int, seed: int, space: tuple[Dim, ...], T: float,
            meet, say) -> tuple[SweepResult, list, list]:
    """The coarse sweep: the scenario's set and ``n_coarse`` random points (KP lowered to meet the margin
    constraint, duplicates merged). Returns the result, the points (the scenario's first) and whether each
    set meets the constraint."""
    pts = random_sample(n_coarse, seed, space, cycle_time=T)
    sets, pts, rejected = build_sets(base, pts, T)
    sets, pts = meet(sets, pts, lower=True)
    dedup = {}
    for st, pt in zip(sets, pts):                       # lowering KP can make two points one
        dedup.setdefault(_key(pt), (st, pt))
    sets, pts = [v[0] for v in dedup.values()], [v[1] for v in dedup.values()]
    base_ok = constraint is None or constraint.ok(base)
    sets = [base] + sets
    pts = [_point_of(base)] + pts
    say(f"coarse sweep: {len(sets)} sets ({len(rejected)} rejected)")
    res = ev.evaluate(sets, pts, description="coarse")
    feasible = [base_ok] + [True] * (len(sets) - 1)    # every other set meets the constraint
    return res, list(pts), feasible


def _refine(ev, base: AxisParameters, res: SweepResult, all_pts: list, feasible: list, seen: set, used: int,
            budget: int, top: int, space: tuple[Dim, ...], T: float, meet, say) -> tuple[SweepResult, int]:
    """Pattern search around the ``top`` best feasible distinct points of ``res`` until the budget is used
    or every step has shrunk below 1/64: each round evaluates the unseen neighbours, moves a start to a
    better neighbour or halves its step. Appends to ``all_pts``, ``feasible`` and ``seen``; returns the
    grown result and the sets used."""
    order = res.order("cost")
    starts, starts_ft = [], []
    for i in order:
        if not math.isfinite(res["cost"][i]):
            break
        if not feasible[i]:
            continue
        p = all_pts[i]
        starts.append([p, float(res["cost"][i]), 1.0])
        starts_ft.append(p["filter_type"])
        if len(starts) >= top:
            break
    rounds = 0
    while used < budget and starts and any(s[2] > 1 / 64 for s in starts):
        cand, owner = [], []
        for j, (p, c, scale) in enumerate(starts):
            if scale <= 1 / 64:
                continue
            for q in _neighbours(p, _refine_dims(p["filter_type"], space, T), scale):
                k = _key(q)
                if k not in seen:
                    seen.add(k)
                    cand.append(q)
                    owner.append(j)
        if not cand:
            for s in starts:
                s[2] /= 2
            continue
        room = budget - used
        cand, owner = cand[:room], owner[:room]
        sets_r, kept, rej = build_sets(base, cand, T)
        sets_r, kept = meet(sets_r, kept, lower=False)
        ok = {_key(q) for q in kept}
        owner = [o for q, o in zip(cand, owner) if _key(q) in ok]
        if not sets_r:
            for s in starts:
                s[2] /= 2
            used += len(cand)
            continue
        r = ev.evaluate(sets_r, kept, description=f"refine {rounds + 1}")
        used += len(cand)
        res = res.concat(r)
        all_pts += kept
        feasible += [True] * len(kept)
        costs = np.asarray(r["cost"], dtype=float)
        for j, s in enumerate(starts):
            mine = [i for i, o in enumerate(owner) if o == j]
            if not mine:
                s[2] /= 2
                continue
            b = min(mine, key=lambda i: costs[i])
            if costs[b] < s[1]:
                s[0], s[1] = kept[b], float(costs[b])
            else:
                s[2] /= 2
        rounds += 1
        say(f"refine round {rounds}: best cost {min(s[1] for s in starts):.5g} mm ({used}/{budget} sets)")
    return res, used


def _robustness(ev, scenario, inputs, cycles: int | None, base: AxisParameters, best: AxisParameters,
                base_metrics: dict, best_metrics: dict) -> list[dict]:
    """The scenario's and the tuned set on each perturbed scenario (:func:`perturbed_scenarios`): their
    costs, the degradation and the share of the improvement kept (``margin``); ``ev`` is left on ``inputs``."""
    from ..batch.closed_loop import prepare  # numba (the [batch] extra) loads only when a batch runs

    rob = []
    for name, sc in perturbed_scenarios(scenario, inputs.axis):
        try:
            pin = prepare(sc, cycles)
        except Exception as exc:          # noqa: BLE001 - reported, not fatal
            rob.append({"name": name, "base_cost": math.nan, "best_cost": math.nan, "best_rms": math.nan,
                        "degradation": math.nan, "margin": math.nan, "failed": True, "note": str(exc)})
            continue
        ev.set_inputs(pin)
        rr = ev.evaluate([base, best], description=name)
        bc, tc = float(rr["cost"][0]), float(rr["cost"][1])
        gain_nom = float(base_metrics["cost"]) - float(best_metrics["cost"])
        margin = (bc - tc) / gain_nom if gain_nom > 0 and math.isfinite(bc) and math.isfinite(tc) else \
            (math.nan if gain_nom <= 0 else -math.inf)
        rob.append({"name": name, "base_cost": bc, "best_cost": tc, "best_rms": float(rr["rms_error"][1]),
                    "degradation": tc / float(best_metrics["cost"]) if best_metrics["cost"] > 0 else math.nan,
                    "margin": margin, "failed": bool(rr["failed"][1])})
    ev.set_inputs(inputs)
    return rob


def _constraint_report(constraint: MarginConstraint, best: AxisParameters, base: AxisParameters, met: bool,
                       counts: dict) -> dict:
    """What ``TuneResult.margin_constraint`` holds: the requirement, the plants, the worst margins of the
    tuned and the scenario's set, and how many sets the constraint changed or dropped."""
    ct, cb = constraint.check(best), constraint.check(base)
    return {"description": constraint.describe(), "min_gain_margin": constraint.min_gain_margin,
            "min_phase_margin_deg": constraint.min_phase_margin_deg, "allowance": constraint.allowance.to_dict(),
            "plants": len(constraint.plants), "met": bool(met and ct.ok),
            "tuned": {k: _plain(v) for k, v in ct.to_dict().items()},
            "scenario_params": {k: _plain(v) for k, v in cb.to_dict().items()},
            "tuned_text": constraint.check_text(ct), "scenario_params_text": constraint.check_text(cb),
            "binding": ct.binding, **counts}


def tune(scenario, *, budget: int = 400, seed: int = 0, cycles: int | None = None, coarse_share: float = 0.6,
         top: int = 3, osc_weight: float = 1.0, space: tuple[Dim, ...] = DEFAULT_SPACE,
         robustness: bool = True, evaluator: Evaluator | None = None, log=None, sat_weight: float | None = None,
         chatter_weight: float | None = None, margin_constraint: bool = True,
         min_gain_margin: float = MIN_GAIN_MARGIN, min_phase_margin: float = MIN_PHASE_MARGIN_DEG,
         allowance: PlantAllowance = DEFAULT_ALLOWANCE, **evaluator_options) -> TuneResult:
    """Tune the scenario's distance-controlled axis (module docstring). ``budget``: parameter sets to
    evaluate in the search (the re-run of the rounded set and the robustness runs come on top: 1, and 2
    per perturbation). ``sat_weight`` / ``chatter_weight``: the chatter terms of
    :func:`~distctrl.tuning.metrics.cost` (default :data:`~distctrl.tuning.metrics.SAT_WEIGHT`,
    :data:`~distctrl.tuning.metrics.CHATTER_WEIGHT`). ``margin_constraint``: only sets with at least
    ``min_gain_margin`` and ``min_phase_margin`` (deg) on the scenario's plant and its variants within
    ``allowance`` are chosen (:mod:`distctrl.tuning.robust`; random points get their KP lowered to meet it).
    ``evaluator_options``
    go to :class:`Evaluator` (``mode``, ``scheduler``, ``n_workers``, ``progress`` ...)."""
    import time

    from ..batch.closed_loop import prepare  # numba (the [batch] extra) loads only when a batch runs
    from ..sim.scenario import Scenario, load_scenario

    say = log or (lambda msg: None)
    t0 = time.perf_counter()
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    # a sensor the kernel does not model (the capacitive footprint): search on a point sensor, choose and
    # report on the scalar simulation (simfallback)
    kernel_scenario, fallback_note = kernel_proxy(scenario)
    if fallback_note:
        say(f"note: {fallback_note}")
    inputs = prepare(kernel_scenario, cycles)
    T = inputs.cycle_time
    base = inputs.params
    constraint, mc = None, {}
    if margin_constraint:
        try:
            constraint = MarginConstraint(loop_model(scenario), min_gain_margin=min_gain_margin,
                                          min_phase_margin_deg=min_phase_margin, allowance=allowance)
        except DistCtrlError as exc:
            mc = {"error": str(exc)}
    counts = {"kp_lowered": 0, "dropped": 0, "neighbours_dropped": 0}

    def meet(sets_in: list, pts_in: list, lower: bool) -> tuple[list, list]:
        return _meet(constraint, counts, sets_in, pts_in, lower)

    own = evaluator is None
    ev = evaluator or Evaluator(inputs, cycles=cycles, osc_weight=osc_weight, log=log, **evaluator_options)
    ev.osc_weight = osc_weight
    if sat_weight is not None:
        ev.cost_weights["sat_weight"] = float(sat_weight)
    if chatter_weight is not None:
        ev.cost_weights["chatter_weight"] = float(chatter_weight)
    try:
        ev.open()
        # 1. coarse
        res, all_pts, feasible = _coarse(ev, base, constraint, max(1, int(budget * coarse_share)), seed, space, T,
                                         meet, say)
        seen = {_key(p) for p in all_pts}
        used = len(all_pts)
        # 2. refine: pattern search around the best distinct points
        res, used = _refine(ev, base, res, all_pts, feasible, seen, used, budget, top, space, T, meet, say)
        costs_all = np.asarray(res["cost"], dtype=float)
        allowed = np.where(np.asarray(feasible, dtype=bool), costs_all, np.inf)
        met = bool(np.isfinite(allowed).any())
        ib = int(np.argmin(allowed)) if met else res.best("cost")
        unrounded = res.params[ib]
        unrounded_metrics = _row(res, ib)
        base_metrics = _row(res, 0)
        # 3. round to what the list and the NC take, and run the rounded set again: its metrics are reported
        best = unrounded
        try:
            best = to_params(unrounded, drop_inert_d_tv([round_point(_point_of(unrounded))])[0][0], T)
        except SpaceError:            # pragma: no cover - rounding left the valid range: keep the values
            pass
        if constraint is not None and met and not constraint.ok(best):
            best = constraint.fit_kp(best) or best        # rounding KP up left the constraint: lower it again
        vr = ev.evaluate([best], [_point_of(best)], description="verify rounded")
        best_metrics = _row(vr, 0)
        if not math.isfinite(float(best_metrics["cost"])) and math.isfinite(float(unrounded_metrics["cost"])):
            best, best_metrics = unrounded, unrounded_metrics      # pragma: no cover - rounding broke the set
        say(f"rounded set re-run: cost {float(best_metrics['cost']):.5g} mm "
            f"(before rounding {float(unrounded_metrics['cost']):.5g} mm)")
        kernel_res, kernel_feasible = res, feasible
        if fallback_note:
            res, feasible, best, best_metrics, base_metrics = _on_the_simulation(
                ev, scenario, inputs, res, feasible, base, best, constraint, T, say)
            costs_all = np.asarray(res["cost"], dtype=float)
            ib = int(np.argmin(np.where(np.asarray(feasible, dtype=bool), costs_all, np.inf)))
        # the best evaluated set without the constraint (the cost of the constraint, when it is worse)
        iu = res.best("cost")
        if feasible[iu] or not np.isfinite(costs_all[iu]) or costs_all[iu] >= float(best_metrics["cost"]):
            unconstrained, unconstrained_metrics = best, best_metrics     # the constraint cost nothing
        else:
            unconstrained, unconstrained_metrics = res.params[iu], _row(res, iu)
        # a set that changes the filter cannot be written over the CNC objects: the best one that keeps it
        objects = objects_metrics = None
        objects_note = ""
        if _filter_of(best) != _filter_of(base):
            objects, objects_metrics, objects_note = _objects_set(ev, kernel_res, base, best, kernel_feasible,
                                                                 constraint, T, say)
            if objects is not None and fallback_note:
                objects_metrics = _row(sim_evaluate(ev, scenario, inputs, [objects], [_point_of(objects)]), 0)
        if fallback_note:
            res = kernel_res             # sweep.csv: the search's table (the kernel's figures)
        # 4. robustness
        if robustness:
            nominal = (base_metrics, best_metrics)
            if fallback_note:          # the perturbed runs are the kernel's: against its own nominal figures
                kr = ev.evaluate([base, best], [_point_of(base), _point_of(best)],
                                 description="kernel nominal")
                nominal = (_row(kr, 0), _row(kr, 1))
            rob = _robustness(ev, kernel_scenario, inputs, cycles, base, best, *nominal)
        else:
            rob = []
        stats = dict(ev.stats)
    finally:
        if own:
            ev.close()

    weights = {"osc_weight": osc_weight, "sat_weight": SAT_WEIGHT, "chatter_weight": CHATTER_WEIGHT,
               **getattr(ev, "cost_weights", {})}
    if constraint is not None:
        mc = _constraint_report(constraint, best, base, met, counts)
    return TuneResult(inputs.axis, base, best, base_metrics, best_metrics, res, rob, used,
                      time.perf_counter() - t0, stats, unrounded=unrounded, unrounded_metrics=unrounded_metrics,
                      cost_weights=weights, stability=stability(scenario, best),
                      base_stability=stability(scenario, base), margin_constraint=mc, inputs=inputs,
                      cycles=cycles,
                      objects=objects, objects_metrics=objects_metrics or {}, objects_note=objects_note,
                      unconstrained=unconstrained, unconstrained_metrics=unconstrained_metrics,
                      fallback_note=fallback_note or "")


def _on_the_simulation(ev, scenario, inputs, res: SweepResult, feasible: list, base: AxisParameters,
                       best: AxisParameters, constraint, T: float, say):
    """The scenario's set, the tuned set and the search's :data:`FINALISTS` best other distinct feasible sets
    (rounded as the tuned one) run on the scalar simulation of ``scenario``; the best feasible of them by
    the simulation's cost is the tuned set. Returns (the simulation's table, feasible per row, tuned set,
    its metrics, the scenario's set's metrics)."""
    cands, keys = [best], {_key(_point_of(best))}
    costs = np.asarray(res["cost"], dtype=float)
    for i in res.order("cost"):
        if len(cands) > FINALISTS or not np.isfinite(costs[i]):
            break
        if not feasible[i]:
            continue
        q = _rounded(res.params[i], T, constraint)
        if q is None or q == base or _key(_point_of(q)) in keys:
            continue
        keys.add(_key(_point_of(q)))
        cands.append(q)
    sets = [base] + cands
    say(f"running the scenario's set and {len(cands)} tuned sets on the scalar simulation (the sensor's "
        "footprint), about as long as distctrl run each")
    sim = sim_evaluate(ev, scenario, inputs, sets, [_point_of(q) for q in sets])
    ok = [constraint is None or constraint.ok(base)] + [True] * len(cands)
    c = np.where(np.asarray(ok), np.asarray(sim["cost"], dtype=float), np.inf)
    j = int(np.argmin(c[1:])) + 1 if np.isfinite(c[1:]).any() else 1
    return sim, ok, sets[j], _row(sim, j), _row(sim, 0)


def _rounded(q: AxisParameters, T: float, constraint, pid_only: bool = False) -> AxisParameters | None:
    """``q`` rounded as the tuned set (``pid_only``: kp, i_tn, d_tv only), its KP lowered again if rounding
    left the margin constraint; None if not even the floor meets it."""
    try:
        pt = drop_inert_d_tv([round_point(_point_of(q))])[0][0]
        q = to_params(q, {k: v for k, v in pt.items() if k in _TUNED} if pid_only else pt, T)
    except SpaceError:            # pragma: no cover - rounding left the valid range: keep the values
        pass
    if constraint is not None and not constraint.ok(q):
        return constraint.fit_kp(q)
    return q


#: how many of the best sets' PID parts are tried with the scenario's filter when the search evaluated none
OBJECTS_TRIES = 6


def _objects_set(ev, res: SweepResult, base: AxisParameters, best: AxisParameters, feasible: list, constraint,
                 T: float, say) -> tuple[AxisParameters | None, dict | None, str]:
    """The best evaluated set that keeps the scenario's filter and meets the margin constraint (only the
    PID part differs from the scenario's set: what ``machine write`` can write), rounded as the tuned set
    and run again; the scenario's own set does not count (writing it changes nothing). When the search
    evaluated none, the PID parts of the best :data:`OBJECTS_TRIES` sets are run with the scenario's filter
    (KP lowered to meet the constraint). Returns (set, metrics, note); (None, None, why) if there is none."""
    keep = _filter_of(base)
    costs = np.asarray(res["cost"], dtype=float)
    order = [i for i in res.order("cost") if np.isfinite(costs[i])]
    cands = [res.params[i] for i in order if feasible[i] and _filter_of(res.params[i]) == keep
             and res.params[i] != base]
    note = ""
    if not cands:
        tries, seen = [], set()
        for i in [None] + order:
            src = best if i is None else res.params[i]
            q = base.replace(kp=src.kp, i_tn=src.i_tn, d_tv=src.d_tv)
            if constraint is not None and not constraint.ok(q):
                q = constraint.fit_kp(q)
            if q is None or q == base or _key(_point_of(q)) in seen:
                continue
            seen.add(_key(_point_of(q)))
            tries.append(q)
            if len(tries) >= OBJECTS_TRIES:
                break
        if not tries:
            return None, None, "no set with the scenario's filter meets the margin constraint"
        note = (f"the search evaluated no other set with the scenario's filter: {len(tries)} sets made of the "
                "best sets' PID parts and the scenario's filter were run")
        say(f"objects set: {note}")
        cands = tries
    else:
        cands = cands[:1]
    q = cands[0] if len(cands) == 1 else None
    if q is None:
        r = ev.evaluate(cands, [_point_of(c) for c in cands], description="objects")
        q = cands[int(r.best("cost"))]
    q = _rounded(q, T, constraint, pid_only=True) or q     # the filter stays the scenario's
    vr = ev.evaluate([q], [_point_of(q)], description="verify objects set")
    return q, _row(vr, 0), note


# ----------------------------------------------------------------------------- plot

def plot_before_after(scenario_or_inputs, base: AxisParameters, best: AxisParameters, path=None,
                      cycles: int | None = None, title: str | None = None):
    """Distance error over time for the scenario's and the tuned parameters (a Figure on an Agg
    canvas, no pyplot); saved to ``path`` (PNG/SVG) when given. Returns the Figure."""
    # matplotlib is imported here only: it stays off the import path of the batch kernel and the CLI
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    # numba (the [batch] extra) loads only when a batch runs
    from ..batch.closed_loop import LoopInputs, prepare, run_batch

    inputs = scenario_or_inputs if isinstance(scenario_or_inputs, LoopInputs) else prepare(scenario_or_inputs, cycles)
    offset, distance = run_batch(inputs, [base, best], cycles=cycles)
    n = distance.shape[1]
    t = np.arange(n) * inputs.cycle_time
    e = distance - wanted_distance(inputs, n)[None, :]
    k0 = inputs.k_on
    fig = Figure(figsize=(10, 6), constrained_layout=True)
    FigureCanvasAgg(fig)
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    for row, label, color in ((0, "scenario parameters", "tab:gray"), (1, "tuned", "tab:blue")):
        rms = float(np.sqrt(np.nanmean(e[row, k0:] ** 2)))
        ax1.plot(t[k0:], e[row, k0:], color=color, lw=0.8, label=f"{label} (RMS {rms:.4g} mm)")
        ax2.plot(t, offset[row], color=color, lw=0.8, label=label)
    ax1.axhline(0.0, color="k", lw=0.5)
    ax1.set_ylabel("distance error (mm)")
    ax1.legend(loc="upper right", fontsize=8)
    ax1.set_title(title or f"before / after tuning: {getattr(inputs.scenario, 'name', '')}")
    ax2.set_ylabel(f"{inputs.axis} offset (mm)")
    ax2.set_xlabel("t (s)")
    if path is not None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
    return fig
