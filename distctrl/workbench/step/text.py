"""The step responses as text: the metrics table (:func:`format_table`), the hints along the documents'
method (:func:`hints`, :func:`suggested_kp`) and the report ``distctrl step --json`` prints
(:func:`results_json`).

Part of :mod:`distctrl.workbench.step` (docs/workbench-step.md); the package face re-exports every name.
"""
from __future__ import annotations

import math
from typing import Sequence

from ..tables import render_table
from .metrics import StepMetrics, _classify
from .model import AUTO_MARGIN, LARGE_PCT, LIMITED_SHARE, RECOGNISABLE_PCT, StepSetting, _round_down
from .result import StepResult, _errors_of

TABLE_COLUMNS = ("setting", "rise 10-90 % [ms]", "overshoot [%]", "overshoot [mm]", "settling [ms]",
                 "band ± [mm]", "steady-state error [mm]", "oscillation", "at limiter [%]")
#: the limiter's parameters, as the hints name them
LIMITER_IDS = "P-AXIS-00415/00416"


def _ms(v: float | None, missing: str = "-") -> str:
    return missing if v is None or not math.isfinite(v) else f"{v * 1e3:.1f}"


def _row(r: StepResult) -> tuple[str, ...]:
    m = r.metrics
    errors = _errors_of(r)
    label = r.setting.label + (" (error " + ", ".join(str(e["id"]) for e in errors) + ")" if errors else "")
    share = "-" if m.limited_share is None else f"{m.limited_share * 100:.0f}" + (" !" if m.limiter_bound else "")
    return (label, _ms(m.rise_time_s), f"{m.overshoot_pct:.1f}", f"{m.overshoot_mm:.4f}",
            _ms(m.settling_time_s, "not settled"), f"{m.band:.4f}", _signed(m.steady_state_error_mm),
            str(m.oscillation), share)


def _signed(v: float) -> str:
    """``+0.0250``; values that round to zero print as ``+0.0000`` (no ``-0.0000``)."""
    return f"{0.0 if abs(v) < 5e-5 else v:+.4f}"


def format_table(results: Sequence[StepResult], title: str | None = None, plain: bool = False) -> str:
    """The metrics of every setting as a text table (rich, no colour; ``plain=True``: fixed-width ASCII).
    ``at limiter [%]``: :attr:`StepMetrics.limited_share`, marked ``!`` when the response is limiter-bound."""
    rows = [_row(r) for r in results]
    return render_table(TABLE_COLUMNS, rows, title, plain)


def _decay_text(m: StepMetrics) -> str:
    if m.oscillation == 0:
        return "decaying without a further swing"
    return f"decaying in {m.periods} period{'s' if m.periods != 1 else ''}"



def _overshoot_text(m: StepMetrics) -> str:
    if m.overshoot_pct < RECOGNISABLE_PCT:
        return f"no recognisable overshoot ({m.overshoot_pct:.1f} %), rise time {_ms(m.rise_time_s)} ms"
    return f"overshoot {m.overshoot_pct:.0f} % {_decay_text(m)}"


def _linear_step(r: StepResult) -> float | None:
    v = r.trace.meta.get("step", {}).get("linear_step_mm") if hasattr(r.trace, "meta") else None
    return float(v) if v is not None and math.isfinite(float(v)) else None


def _step_advice(results: Sequence[StepResult]) -> str:
    """``--step 0.013`` (half the smallest linear step of the given results) or a generic advice."""
    lin = [x for x in (_linear_step(r) for r in results) if x is not None]
    if not lin:
        return "a smaller --step"
    return f"a smaller --step (at most about {_round_down(AUTO_MARGIN * min(lin)):g} mm)"


def suggested_kp(results: Sequence[StepResult]) -> StepResult | None:
    """The setting the summary suggests: the largest P-only KP whose response is "recognisable but
    rapidly decaying", settled, ran without an error and was not limiter-bound; None if there is none."""
    good = [r for r in results if r.setting.kind == "P" and not _errors_of(r) and not r.metrics.limiter_bound
            and r.metrics.settled and _classify(r.metrics) == "good"]
    return max(good, key=lambda r: r.setting.kp) if good else None


#: from this KP on the D part has no room and no effect (docs/control-law.md, "The D part":
#: kp + g < 1 with g_max = 0.3·(1 − kp); :func:`distctrl.control.law.derivative_gain` is 0 there)
D_NO_EFFECT_KP = 1.0
_NO_D = "D_TV has no effect at KP >= 1 (KP already takes the whole error in one cycle)"


def _remedy(s: StepSetting) -> str:
    """What to change for too much overshoot / oscillation: KP, and the D part only where it acts."""
    if s.kp >= D_NO_EFFECT_KP:
        return "lower KP" + (f"; {_NO_D}" if s.d_tv > 0 else "")
    return "lower KP or D_TV" if s.d_tv > 0 else "lower KP or add D (method step 4)"


def _setting_hint(r: StepResult) -> str:
    """The hint for one setting (method steps 1, 2 and 4 by its class; the limiter's share if it decided)."""
    s, m = r.setting, r.metrics
    errors = _errors_of(r)
    head = f"{s.label}: "
    if errors:
        ids = ", ".join(str(e["id"]) for e in errors)
        return head + f"the run stopped with error {ids} — the loop is unstable or a limit was hit: lower KP"
    kind = _classify(m)
    limited = ""
    if m.limiter_bound:
        limited = (f"response limited by {LIMITER_IDS} (the limiter changed the PID's step in "
                   f"{m.limited_share * 100:.0f} % of the cycles")
        limited += " until it settled)" if m.settled else " after the step)"
    if m.limiter_bound and kind in ("good", "damped", "large", "slow"):
        # the shape is the limiter's: KP cannot be judged from it
        lin = _linear_step(r)
        if lin is not None and abs(m.step_mm) <= lin:
            # the step's first cycle was inside the limiter: something else drove the offset there
            return head + (f"{_overshoot_text(m)} — {limited}, although the step's first cycle was inside "
                           f"it: the ramp, the I part or the loop's own swing drove the offset to the limit; "
                           f"not a setting to judge by this response")
        return head + f"{_overshoot_text(m)} — {limited} — use {_step_advice([r])} to see KP's own response"
    if kind == "oscillating":
        remedy = _remedy(s)
        state = (f"not settled within ±{m.band:.4g} mm by the end of the run" if not m.settled
                 else f"settled after {_ms(m.settling_time_s)} ms")
        text = (f"overshoot {m.overshoot_pct:.0f} %, {m.oscillation} zero crossings after the first "
                f"peak, {state} — more oscillation than 'rapidly decaying': {remedy}")
        if m.limiter_bound:
            text += f"; {limited}: its amplitude is the limiter's"
    elif kind == "deviation":
        text = (f"{_overshoot_text(m)}; steady-state error {m.steady_state_error_mm:+.4f} mm — a "
                f"permanent control deviation: " + ("add I (T_n from 5 s, then reduce it; method step 2)"
                                                    if s.i_tn == 0 else "reduce I_TN"))
        if m.limiter_bound:
            text += f"; {limited}"
    elif kind == "slow":
        text = (f"{_overshoot_text(m)}; not settled within ±{m.band:.4g} mm by the end of the run "
                f"without oscillating: a slow approach (a longer run shows more)")
    elif kind == "large":
        remedy = _remedy(s)
        text = f"{_overshoot_text(m)} — a large overshoot (above {LARGE_PCT:.0f} %): {remedy}"
    elif kind == "damped":
        text = (f"{_overshoot_text(m)} — well damped"
                + (": KP may be raised (method step 1)" if s.kind == "P" else ""))
    else:
        text = (f"{_overshoot_text(m)} — recognisable but rapidly decaying"
                + (": a good P setting" if s.kind == "P" else ""))
    return head + text


def _d_hints(results: Sequence[StepResult]) -> list[str]:
    """Method step 4: the same KP and I_TN with and without D_TV."""
    out: list[str] = []
    by_pi: dict[tuple[float, float], list[StepResult]] = {}
    for r in results:
        by_pi.setdefault((r.setting.kp, r.setting.i_tn), []).append(r)
    for (kp, tn), group in by_pi.items():
        without = [r for r in group if r.setting.d_tv == 0]
        if not without:
            continue
        m0 = without[0].metrics
        for r in group:
            if r.setting.d_tv == 0:
                continue
            if kp >= D_NO_EFFECT_KP:
                out.append(f"KP={kp:g} I_TN={tn:g}: D_TV={r.setting.d_tv:g}: {_NO_D}; the response is that "
                           f"of D_TV=0")
                continue
            if m0.overshoot_pct < RECOGNISABLE_PCT:
                continue
            m1 = r.metrics
            if m0.limiter_bound and m1.limiter_bound:
                out.append(f"KP={kp:g} I_TN={tn:g}: D_TV={r.setting.d_tv:g} cannot be judged: the limiter "
                           f"({LIMITER_IDS}) decided both responses")
                continue
            verb = "reduces" if m1.overshoot_pct < m0.overshoot_pct else "does not reduce"
            settle = "" if m1.settled or not m0.settled else "; and it no longer settles: lower D_TV"
            out.append(f"KP={kp:g} I_TN={tn:g}: D_TV={r.setting.d_tv:g} {verb} the overshoot "
                       f"({m0.overshoot_pct:.0f} % -> {m1.overshoot_pct:.0f} %, oscillation "
                       f"{m0.oscillation} -> {m1.oscillation} zero crossings){settle}")
    return out


def _summary_hints(results: Sequence[StepResult]) -> list[str]:
    """The summary for the P part: the largest KP with a recognisable but rapidly decaying overshoot,
    never one the limiter decided or one that did not settle."""
    out: list[str] = []
    p_only = [r for r in results if r.setting.kind == "P" and not _errors_of(r)]
    # limiter-bound and not oscillating: the limiter shaped the response, KP cannot be judged from it (an
    # oscillating one is judged: it oscillates, whatever bounds its swing)
    undecided = [r for r in p_only if r.metrics.limiter_bound and _classify(r.metrics) != "oscillating"]
    free = [r for r in p_only if r not in undecided]
    best = suggested_kp(results)
    if best is not None:
        out.append(f"suggested P setting: KP={best.setting.kp:g} (the largest tested KP whose overshoot is "
                   f"recognisable but rapidly decaying, not decided by the limiter)")
    elif p_only and not free:
        out.append(f"the limiter ({LIMITER_IDS}) decided every P response: no KP can be judged from this step; "
                   f"use {_step_advice(undecided)}")
    elif free and not undecided and all(_classify(r.metrics) == "damped" for r in free):
        top = max(r.setting.kp for r in free)
        out.append(f"no tested KP overshoots recognisably: try KP above {top:g}")
    elif free and not undecided and all(_classify(r.metrics) == "oscillating" for r in free):
        out.append(f"every tested KP oscillates too much: try KP below {min(r.setting.kp for r in free):g}")
    if undecided and free:
        names = ", ".join(f"KP={r.setting.kp:g}" for r in undecided)
        out.append(f"not judged (the limiter, {LIMITER_IDS}, decided the response): {names}; use "
                   f"{_step_advice(undecided)} for them")
    return out


def hints(results: Sequence[StepResult]) -> list[str]:
    """Short factual hints along the documents' method (FCT-M3 ch. 3), one per setting plus a summary.

    Step 1 (P only): a setting without a recognisable overshoot (< 2 %) is slow but safe (raise KP);
    one with a recognisable overshoot (2 ... 40 %) that decays within 2 periods is what the method
    looks for; a larger overshoot, more swings or no settling: lower KP or add D. Step 2 (I): only
    for a permanent control deviation. Step 4 (D): the overshoot with and without D_TV at the same
    KP / I_TN is compared (below KP 1 only: from KP 1 on the D part has no effect, and no hint offers
    D_TV there). A response the slope limiter decided (:attr:`StepMetrics.limiter_bound`)
    says so and is never called good nor suggested: it shows the limiter, not KP.
    """
    return [_setting_hint(r) for r in results] + _d_hints(results) + _summary_hints(results)


def results_json(results: Sequence[StepResult]) -> dict:
    """The results as one JSON-able object (``distctrl step --json``): the step, per setting its
    words, metrics (s, mm, %), class, limiter share and errors, the hints and the suggested KP."""
    info0 = results[0].trace.meta.get("step", {}) if results else {}
    best = suggested_kp(results)
    rows = [r.to_dict() for r in results]
    return {"step_mm": info0.get("step_mm"), "step_auto": info0.get("auto"), "mode": info0.get("mode"),
            "t_step_s": info0.get("t_step"), "ramp_mm_s": info0.get("ramp_mm_s"),
            "limited_share_threshold": LIMITED_SHARE, "results": rows, "hints": hints(results),
            "suggested_kp": best.setting.kp if best is not None else None}
