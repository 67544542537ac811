"""Shared hypothesis strategies, a closed-loop plant and the per-cycle invariant checker (SPEC §3-§8).

Import from the test modules with ``from .conftest import ...`` (tests/control is a package).

The plant is deliberately simple: the axis follows its command exactly one cycle late
(``actual = command_position of the last cycle``) and the probe reads
``increments = (surface - actual) / mm_per_increment`` (SPEC §1/§2: s = surface - a, d = -s),
corrected for sign reversal and the reference offset so that the controller sees ``s = surface - a``.
"""
from __future__ import annotations

import dataclasses
import math
import random

from hypothesis import strategies as st

from distctrl.control import (Action, AxisDistanceController, Command, CycleInput, CycleOutput, FilterType,
                              HliState, ObjectWrite, SensorSource)
from distctrl.base.states import MONITORED_STATES
from distctrl.params import AxisParameters

S = HliState
RUNNING = frozenset(MONITORED_STATES)                    # ACTIVE, ACTIVE_CD, DRYRUN_SETPOS, DRYRUN_CD
HLI_VALUES = frozenset(int(s) for s in HliState)
INTERNAL_VALUES = frozenset({0, 2, 3, 4, 5, *range(6, 13), 15})
#: internal DIST_CTRL::state codes allowed for each HLI state (SPEC §8)
INTERNAL_FOR_HLI = {
    S.INACTIVE: {0, 5},                  # 5 = OFF_NO_MOVE in the cycle it happens
    S.ACTIVE: {2}, S.ACTIVE_CONST_DIST: {2},
    S.FREEZE: {3},
    S.TURNING_OFF: {4},
    S.ERROR: set(range(6, 13)),
    S.DRYRUN_SETPOS: {15}, S.DRYRUN_CONST_DIST: {15},
}
SELECTS = (Action.ON, Action.DRYRUN)
ABSORBING = (Action.RESET, Action.AXIS_ERROR)
#: states from which a select to ACTIVE / ACTIVE_CONST_DIST adopts pending CNC-object writes (SPEC §8,
#: FCT-M3 §7.6: exactly INACTIVE -> ACTIVE and FREEZE -> ACTIVE; not on entering or leaving a DRYRUN)
#: docs/states.md: a DRYRUN state is left like FREEZE)
ADOPTING = frozenset({HliState.INACTIVE, HliState.FREEZE})
TRACKING = frozenset({HliState.ACTIVE, HliState.ACTIVE_CONST_DIST})
HELD = frozenset({HliState.FREEZE, HliState.ERROR, HliState.DRYRUN_SETPOS, HliState.DRYRUN_CONST_DIST})

REL, ABS = 1e-9, 1e-12                                  # float slack of the invariant checks


def le(a: float, b: float) -> bool:
    """a <= b with the float slack used throughout."""
    return a <= b + REL * max(abs(a), abs(b)) + ABS


def close(a: float, b: float, rel: float = REL, abs_: float = ABS) -> bool:
    return abs(a - b) <= rel * max(abs(a), abs(b)) + abs_


# ============================================================================ strategies

#: cycle times the strategies use (Nyquist of the low-pass is 0.5/T)
CYCLE_TIMES = (0.0005, 0.001, 0.002, 0.004)
#: smoothing factors (tiny ones included: they used to crash the EXPO filters, see
#: test_expo_filters_with_tiny_smoothing_factor)
ALPHAS = st.one_of(st.just(1.0), st.floats(1e-3, 1.0), st.floats(0.0, 1e-3, exclude_min=True))


def rare(draw, n: int) -> bool:
    """True with probability about 1/n; shrinks to False (the common case)."""
    return draw(st.integers(0, n - 1)) == n - 1


def either(draw, common, uncommon, n: int = 4):
    """A value of ``common`` mostly, of ``uncommon`` about once in n draws."""
    return draw(uncommon if rare(draw, n) else common)


def nonneg(hi: float):
    """0, or a value in [1e-3, hi] (no subnormals)."""
    return st.one_of(st.just(0.0), st.floats(1e-3, hi))


@st.composite
def axis_parameters(draw, enabled: bool = True):
    """A random valid AxisParameters (internal units) and a cycle time T: (params, T, p0).

    ``p0`` is a programmed position inside the software limits (the plant keeps it constant).
    Degenerate but legal values (v_max = 0, max_deviation = 0, a software limit at p0, a tiny
    jump limit, a narrow sensor window) are drawn, but rarely, so most examples track for long.
    """
    T = draw(st.sampled_from(CYCLE_TIMES))
    ft = draw(st.sampled_from([FilterType.DEFAULT, FilterType.MOVING_AVERAGE, FilterType.EXPO_MEAN,
                               FilterType.LOWPASS, FilterType.KALMAN_MA, FilterType.KALMAN_EXPO]))
    nyq = 0.5 / T
    v_max = either(draw, st.floats(0.5, 500.0), st.sampled_from([0.0, 0.01]), 10)
    a_max = either(draw, st.floats(1.0, 20000.0), st.just(0.0), 4)
    axis_a_max = draw(st.floats(1.0, 20000.0))
    adaptive = draw(st.booleans())
    d_a_min = draw(st.floats(0.0, 2.0))
    d_a_max = draw(st.floats(0.0, 5.0))
    wd = st.floats(0.001, 1.999)
    p0 = draw(st.floats(-100.0, 100.0))
    check_sw = draw(st.booleans())
    sw_lo = p0 - either(draw, st.floats(0.5, 20.0), st.sampled_from([0.0, 0.01]), 8)
    sw_hi = p0 + either(draw, st.floats(0.5, 20.0), st.sampled_from([0.0, 0.01]), 8)
    if sw_hi <= sw_lo:
        sw_hi = sw_lo + 1e-3
    # "wild" examples (about one in three) also exercise the monitoring errors early: small jump
    # limit, narrow sensor window, little room for the offset, large D part
    wild = rare(draw, 3)
    if not wild:
        min_pos, max_pos, tol = -50.0, 50.0, draw(st.sampled_from([0.0, 0.01]))
        max_dev = draw(st.floats(10.0, 50.0))
        max_change = draw(st.floats(2e3, 1e6))
        d_tv = either(draw, st.just(0.0), st.floats(0.0, 0.01), 3)
    else:
        min_pos = draw(st.floats(-20.0, -0.5))
        max_pos = draw(st.floats(0.0, 20.0))
        tol = draw(st.floats(0.0, 0.2))
        if min_pos + tol >= max_pos - tol:
            tol = 0.0
        max_dev = either(draw, st.floats(0.001, 50.0), st.just(0.0), 6)
        max_change = draw(st.one_of(st.floats(0.0, 20.0), st.floats(1e3, 1e6)))
        d_tv = draw(st.one_of(st.just(0.0), st.floats(0.0, 0.05), st.floats(0.0, 2.0)))
    params = AxisParameters(
        enabled=enabled,
        n_cycles=draw(st.integers(0, 99)),
        max_deviation=max_dev,
        v_max=v_max,
        a_max=a_max,
        axis_a_max=axis_a_max,
        max_act_value_change=max_change,
        ref_offset=either(draw, st.just(0.0), st.floats(-5.0, 5.0), 3),
        max_pos=max_pos, min_pos=min_pos, tolerance=tol,
        check_sw_limit_switch=check_sw, sw_limit_min=sw_lo, sw_limit_max=sw_hi,
        use_both_encoders=draw(st.booleans()),
        use_adaptive_acceleration=adaptive,
        a_min=draw(st.floats(1.0, 20000.0)),
        dist_error_a_min=d_a_min, dist_error_a_max=d_a_max,
        low_pass_filter_order=draw(st.integers(0, 6)),
        low_pass_filter_fg_f0=draw(st.floats(0.5, 0.45 * nyq)),
        optimized_scheduling=draw(st.booleans()),
        v_weight_down=either(draw, st.just(0.0), wd, 2), a_weight_down=either(draw, st.just(0.0), wd, 2),
        encoder_resolution_num=draw(st.integers(1, 50)),
        encoder_resolution_denom=draw(st.integers(1, 50)),
        sensor_sign_reversal=draw(st.booleans()),
        sensor_mode_act_pos=draw(st.sampled_from([0, 1])),
        kp=draw(st.floats(0.0, 2.0, exclude_min=True)),
        i_tn=either(draw, st.just(0.0), st.floats(0.001, 50.0), 2),
        d_tv=d_tv,
        filter_type=ft,
        kalman_sigma=draw(st.floats(1.0, 10000.0)),
        smoothing_factor=draw(ALPHAS),
    )
    return params, T, p0


def _filter_fields(draw, T):
    kind = draw(st.sampled_from(["type", "n", "alpha", "sigma", "order", "fg"]))
    if kind == "type":
        return {"filter_type": draw(st.sampled_from([FilterType.DEFAULT, FilterType.MOVING_AVERAGE,
                                                     FilterType.EXPO_MEAN, FilterType.LOWPASS,
                                                     FilterType.KALMAN_MA, FilterType.KALMAN_EXPO]))}
    if kind == "n":
        return {"n_cycles": draw(st.integers(0, 99))}
    if kind == "alpha":
        return {"smooth_fact": draw(ALPHAS)}
    if kind == "sigma":
        return {"kalman_sigma": draw(st.floats(1.0, 10000.0))}
    if kind == "order":
        return {"order": draw(st.integers(0, 6))}
    return {"fg_f0": draw(st.floats(0.5, 0.45 * 0.5 / T))}


@st.composite
def commands(draw, T: float, set_pos_center: float = 0.0):
    """One random command: every Action, with or without set values, tuning, invalid values,
    and CNC-object writes (valid, out-of-range, read-only)."""
    kind = draw(st.sampled_from(["select"] * 6 + ["freeze"] * 2 + ["off"] * 2 + ["object"] * 2 + [
        "reset", "axis_error", "program_end", "ref", "check_pos", "none", "release", "source"]))
    if kind == "object":
        name = draw(st.sampled_from(["kp", "i_tn", "d_tv", "v_max", "a_max", "kp", "v_max", "a_max",
                                     "max_deviation"]))
        # (a subnormal a_max is covered by test_subnormal_a_max_with_adaptive_acceleration)
        good = {"kp": st.floats(0.0, 2.0, exclude_min=True), "i_tn": st.floats(0.0, 50.0),
                "d_tv": st.floats(0.0, 2.0), "v_max": st.floats(0.0, 500.0), "a_max": nonneg(20000.0),
                "max_deviation": st.floats(0.0, 10.0)}[name]
        value = draw(st.one_of(good, good, good, st.sampled_from([-1.0, 3.0, math.nan, math.inf])))
        return ObjectWrite(name, value)
    fields: dict = {}
    if draw(st.integers(0, 3)) == 0:          # NC tuning with the block
        which = draw(st.sampled_from(["kp", "i_tn", "d_tv", "filter", "bad"]))
        if which == "kp":
            fields["kp"] = draw(st.floats(1e-3, 2.0))
        elif which == "i_tn":
            fields["i_tn"] = draw(st.one_of(st.just(0.0), st.floats(0.001, 50.0)))
        elif which == "d_tv":
            fields["d_tv"] = draw(st.floats(0.0, 0.05))
        elif which == "filter":
            fields.update(_filter_fields(draw, T))
        else:
            fields.update(draw(st.sampled_from([{"kp": 5.0}, {"kp": 0.0}, {"n_cycles": 100},
                                                {"set_pos": math.nan}, {"fg_f0": 0.5 / T}])))
    if kind == "select":
        const = draw(st.booleans())
        given = draw(st.integers(0, 4)) > 0
        if given and "set_pos" not in fields:
            if const:
                fields["set_dist"] = draw(st.floats(0.0, 5.0))
            else:
                fields["set_pos"] = set_pos_center + draw(st.floats(-3.0, 3.0))
        return Command(draw(st.sampled_from(SELECTS)), const_dist=const, **fields)
    if kind == "freeze":
        return Command(Action.FREEZE, **fields)
    if kind == "off":
        return Command(Action.OFF, no_move=draw(st.booleans()), **fields)
    if kind == "reset":
        return Command(Action.RESET)
    if kind == "axis_error":
        return Command(Action.AXIS_ERROR)
    if kind == "program_end":
        return Command(Action.PROGRAM_END)
    if kind == "release":
        return Command(Action.AXIS_RELEASE)
    if kind == "ref":
        return Command(Action.REF, ref_position=draw(st.floats(-2.0, 2.0)), **fields)
    if kind == "check_pos":
        return Command(Action.CHECK_POS, **fields)
    if kind == "source":
        return Command(Action.NONE, sensor_source=draw(st.sampled_from(list(SensorSource))))
    # NONE: values only
    if draw(st.booleans()):
        fields.setdefault("set_pos", set_pos_center + draw(st.floats(-3.0, 3.0)))
    else:
        fields.setdefault("set_dist", draw(st.floats(0.0, 5.0)))
    return Command(Action.NONE, **fields)


BAD_FLOATS = (math.nan, math.inf, -math.inf)


@st.composite
def scenarios(draw, T: float, set_pos_center: float = 0.0, min_cycles: int = 150, max_cycles: int = 400):
    """Commands at random cycles, override/feed-hold changes, sensor jumps and non-finite inputs."""
    n = draw(st.integers(min_cycles, max_cycles))
    cyc = st.integers(1, n - 1)
    cmds = {}
    if not rare(draw, 6):                       # usually start with a valid select
        const = draw(st.booleans())
        first = Command(Action.DRYRUN if rare(draw, 4) else Action.ON, const_dist=const,
                        set_pos=None if const else set_pos_center + draw(st.floats(-2.0, 2.0)),
                        set_dist=draw(st.floats(0.2, 3.0)) if const else None)
        cmds[draw(st.integers(0, 10))] = first
    n_cmds = either(draw, st.integers(0, 4), st.integers(5, 14), 3)
    for c, cmd in draw(st.lists(st.tuples(cyc, commands(T, set_pos_center)), min_size=n_cmds, max_size=n_cmds)):
        cmds.setdefault(c, cmd)
    override = draw(st.lists(st.tuples(cyc, st.one_of(st.sampled_from([0.0, 1.0, 0.5, 2.0, -1.0, math.nan,
                                                                       math.inf]),
                                                      st.floats(0.0, 1.0))), max_size=5))
    hold = draw(st.lists(st.tuples(cyc, st.booleans()), max_size=3))
    jumps = draw(st.lists(st.tuples(cyc, st.floats(-5.0, 5.0)), max_size=4))
    bad = []
    if rare(draw, 3):
        bad = draw(st.lists(st.tuples(st.integers(2, n - 1),
                                      st.sampled_from(["incr", "var", "prog", "act", "cyclic"]),
                                      st.sampled_from(BAD_FLOATS + (1e13,))), min_size=1, max_size=4))
    surface = dict(base=draw(st.floats(-3.0, 0.0)), amp=draw(st.floats(0.0, 1.0)),
                   freq=draw(st.floats(0.0, 20.0)), noise=either(draw, st.floats(0.0, 0.01), st.floats(0.0, 0.05), 3),
                   seed=draw(st.integers(0, 2**32 - 1)))
    return dict(n=n, commands=cmds, override=dict(override), hold=dict(hold), jumps=dict(jumps),
                bad={(c, k): v for c, k, v in bad}, surface=surface)


# ============================================================================ plant + checker


@dataclasses.dataclass
class Step:
    """What one cycle was given (the context the checker needs)."""

    commands: list
    pre_state: HliState
    prog: float                      # the programmed position the controller used (last finite)
    override: float
    feed_hold: bool


class InvariantError(AssertionError):
    pass


class InvariantChecker:
    """Checks SPEC §6-§8 invariants on every cycle from the previous and the current output.

    One exemption is made for a known bug pinned by a strict-xfail test
    (test_law_properties.py::test_bug_slope_limit_lowering_limits_for_positive_velocity): slope_limit
    reports (and uses) the lowering limits for a positive (lifting) velocity when the first, unweighted
    pass would have gone negative; ``v_max_int`` may then be the weighted value.
    """

    def __init__(self, params: AxisParameters, T: float):
        self.p = params
        self.T = T
        self.prev: CycleOutput | None = None

    # -- helpers
    def _fail(self, out: CycleOutput, msg: str):
        raise InvariantError(f"cycle {out.cycle} state {HliState(out.hli_state).name}: {msg}")

    def check(self, step: Step, out: CycleOutput) -> None:
        p, T = self.p, self.T
        prev = self.prev
        prev_o = prev.offset if prev else 0.0
        prev_v = prev.offset_velocity if prev else 0.0
        prev_c = prev.command_position if prev else None
        cmds = [c for c in step.commands if isinstance(c, Command)]
        actions = {c.action for c in cmds}
        state = out.hli_state
        pre = step.pre_state

        # -- no NaN / inf anywhere
        for f in dataclasses.fields(out):
            v = getattr(out, f.name)
            if isinstance(v, float) and not math.isfinite(v):
                self._fail(out, f"{f.name} = {v!r} not finite")
        for v in out.vals:
            if not math.isfinite(v):
                self._fail(out, f"vals has {v!r}")
        # -- state codes
        if state not in HLI_VALUES:
            self._fail(out, f"hli_state {state} unknown")
        if out.state not in INTERNAL_VALUES or out.state not in INTERNAL_FOR_HLI[HliState(state)]:
            self._fail(out, f"internal state {out.state} not allowed for HLI {state}")
        # -- bounds
        if not le(abs(out.offset), p.max_deviation):
            self._fail(out, f"|o| = {abs(out.offset)} > max_deviation {p.max_deviation}")
        if p.check_sw_limit_switch:
            c = step.prog + out.offset
            if not (le(p.sw_limit_min, c) and le(c, p.sw_limit_max)):
                self._fail(out, f"p + o = {c} outside [{p.sw_limit_min}, {p.sw_limit_max}]")
        if state == S.INACTIVE and out.offset != 0.0:
            self._fail(out, f"INACTIVE with offset {out.offset}")
        # -- absorption (RESET / AXIS_ERROR / OFF NO_MOVE): INACTIVE at once, the channel takes the offset
        no_move = any(c.action == Action.OFF and c.no_move for c in cmds)
        absorbing = bool(actions & set(ABSORBING)) or out.state == 5
        if actions & set(ABSORBING) and state != S.INACTIVE:
            self._fail(out, "RESET/AXIS_ERROR did not deselect at once")
        if absorbing:
            if out.absorbed_offset != prev_o or out.offset != 0.0 or out.offset_velocity != 0.0:
                self._fail(out, f"absorbed {out.absorbed_offset} (offset {out.offset}) != previous offset {prev_o}")
            if prev_c is not None and step.prog == self._prev_prog and not close(out.command_position, prev_c,
                                                                                  abs_=1e-9):
                self._fail(out, f"command position jumps {prev_c} -> {out.command_position} on absorption")
        elif out.absorbed_offset != 0.0:
            self._fail(out, "absorbed offset without RESET/AXIS_ERROR/OFF NO_MOVE")
        if out.state == 5 and not no_move:
            self._fail(out, "OFF_NO_MOVE reported without OFF NO_MOVE")

        # -- velocity / acceleration
        v = out.offset_velocity
        a_int, v_int = out.a_max_int, out.v_max_int
        if not absorbing:
            # on the cycle the offset runs out (TURNING_OFF -> INACTIVE) an offset |o| <= 1e-9 mm is set to
            # exactly 0 (controller _LAND): delta_offset may differ from v*T by that much
            landing = pre != S.INACTIVE and state == S.INACTIVE
            if not close(v * T, out.delta_offset, abs_=1e-9 if landing else 1e-12):
                self._fail(out, f"offset_velocity*T {v * T} != delta_offset {out.delta_offset}")
            # the velocity is (o_new - o) / T: its rounding is about eps*|o|/T
            ulp_v = 4e-16 * (abs(out.offset) + abs(prev_o) + 1.0) / T
            if not le(abs(v - prev_v), a_int * T + ulp_v):
                self._fail(out, f"|dv| = {abs(v - prev_v)} > a_max_int*T = {a_int * T} ({prev_v} -> {v})")
            if not le(abs(v), max(v_int, abs(prev_v) - a_int * T) + ulp_v):
                self._fail(out, f"|v| = {abs(v)} > max(v_max_int {v_int}, |v_prev| - aT {abs(prev_v) - a_int * T})")
        # -- the applied limits
        ovr = step.override
        ovr = 0.0 if (not (ovr > 0.0) or step.feed_hold) else min(ovr, 1.0)
        base_v = out.v_max_param * ovr
        w_v = p.v_weight_down if p.v_weight_down > 0 else 1.0
        w_a = p.a_weight_down if p.a_weight_down > 0 else 1.0
        v_sign = out.delta_offset if not absorbing else 0.0
        allowed_v = set()
        if v_sign < 0:
            allowed_v.add(base_v * w_v)
        elif v_sign > 0:
            allowed_v.add(base_v)
        else:
            allowed_v.update({base_v, base_v * w_v})
        if not any(close(v_int, x) for x in allowed_v):
            self._fail(out, f"v_max_int {v_int} not in {allowed_v} (v_max {out.v_max_param}, override {ovr})")
        a_base = out.a_max_param if out.a_max_param > 0 else p.axis_a_max
        cands = [a_base] + ([p.a_min] if p.use_adaptive_acceleration else [])
        a_lo, a_hi = min(cands) * min(1.0, w_a), max(cands) * max(1.0, w_a)
        # a lowered a_max adopted while the offset still moves: the bounds keep braking with the old
        # acceleration until the offset is at rest (reported in a_max_int), so the old range carries over
        a_hi_carry = a_hi if prev_v == 0.0 else max(a_hi, self._a_hi_carry)
        self._a_hi_carry = a_hi_carry
        if not (le(a_lo, a_int) and le(a_int, a_hi_carry)):
            self._fail(out, f"a_max_int {a_int} outside [{a_lo}, {a_hi_carry}]")

        # -- held offsets: FREEZE / ERROR / DRYRUN decelerate without a step, then stay constant.
        # Errors found at the bound (70331 / 900002) are raised after this cycle's motion was computed,
        # so the hold starts with the next cycle.
        bound_error = any(e.id in (70331, 900002) for e in out.events)
        if state in HELD and not absorbing and prev is not None and not bound_error:
            if prev_v == 0.0 and out.offset != prev_o:
                self._fail(out, f"held offset moved {prev_o} -> {out.offset} after braking")
            if prev_v == 0.0 and v != 0.0:
                self._fail(out, f"held state started moving again (v = {v})")
            if not le(abs(v), abs(prev_v)):
                self._fail(out, f"held state accelerates {prev_v} -> {v}")
            if prev_v != 0.0 and v != 0.0 and (v > 0) != (prev_v > 0):
                self._fail(out, f"held state reverses {prev_v} -> {v}")

        # -- transitions (one command per cycle)
        if pre == S.ERROR and state != S.ERROR:
            if not (actions & {Action.OFF, Action.RESET, Action.AXIS_ERROR}):
                self._fail(out, f"ERROR left to {state} without OFF/RESET/AXIS_ERROR")
        # SPEC §8 / docs/states.md: ACTIVE <-> ACTIVE_CONST_DIST only through FREEZE or INACTIVE
        # (a DRYRUN state may be left directly, as the documents' %DIST_5 does)
        if {pre, state} == {S.ACTIVE, S.ACTIVE_CONST_DIST}:
            self._fail(out, f"direct switch {HliState(pre).name} -> {HliState(state).name}")
        if pre == S.INACTIVE and state in RUNNING and not (actions & set(SELECTS)):
            self._fail(out, "INACTIVE -> running without a select")
        if pre == S.TURNING_OFF and state == S.INACTIVE and not absorbing and out.offset != 0.0:
            self._fail(out, "TURNING_OFF -> INACTIVE before the offset ran out")
        if Action.PROGRAM_END in actions:
            ids = [e.id for e in out.events]
            # automatic changes that may fall into the program-end cycle: a monitoring error, the run-out
            # landing, and FREEZE -> a pending DRYRUN once the offset stands
            automatic = (pre in RUNNING and state == S.ERROR) or (pre == S.TURNING_OFF and state == S.INACTIVE) \
                or (pre == S.FREEZE and state in (S.DRYRUN_SETPOS, S.DRYRUN_CONST_DIST) and out.delta_offset == 0.0)
            if state != pre and not automatic:
                self._fail(out, f"PROGRAM_END changed the state {pre} -> {state}")
            if (pre not in (S.INACTIVE, S.TURNING_OFF)) != (70332 in ids):      # warning only while active
                self._fail(out, f"PROGRAM_END in {pre}: events {ids}")
        # -- tuning adoption (CNC-object writes only on INACTIVE/FREEZE -> ACTIVE / ACTIVE_CONST_DIST)
        if prev is not None:
            select_from_rest = bool(actions & set(SELECTS)) and pre in ADOPTING and state in TRACKING
            # a select that was taken (adopting the writes) and hit a monitoring error in the same cycle
            monitoring = {70329, 70330, 70576, 70331, 900001, 900002}
            select_from_rest = select_from_rest or (bool(actions & set(SELECTS)) and pre in ADOPTING
                                                    and state == S.ERROR
                                                    and any(e.id in monitoring for e in out.events))
            for name in ("v_max_param", "a_max_param", "kp", "i_tn", "d_tv"):
                if getattr(out, name) != getattr(prev, name) and not select_from_rest:
                    nc = name in ("kp", "i_tn", "d_tv") and any(getattr(c, name) is not None for c in cmds)
                    if not nc:
                        self._fail(out, f"{name} changed {getattr(prev, name)} -> {getattr(out, name)} "
                                        f"outside an INACTIVE/FREEZE -> running transition")
        self._prev_prog = step.prog
        self.prev = out

    _prev_prog = None
    _a_hi_carry = 0.0


class Plant:
    """Closed loop: actual = last command position; probe increments from (surface - actual)."""

    def __init__(self, params: AxisParameters, T: float, p0: float = 0.0):
        self.params = params
        self.T = T
        self.ctrl = AxisDistanceController(params, T)
        self.check = InvariantChecker(params, T)
        self.p = p0                     # channel programmed position (absorption moves it)
        self.actual = p0
        self.last_prog = 0.0            # what the controller falls back to for a non-finite p
        self.outputs: list[CycleOutput] = []

    def increments_for(self, surface: float, actual: float) -> float:
        p = self.params
        s = surface - actual - p.ref_offset
        if p.sensor_sign_reversal:
            s = -s
        return s / p.sensor_mm_per_increment

    def step(self, surface: float, commands=(), override: float = 1.0, feed_hold: bool = False,
             bad: dict | None = None, cyclic=None) -> CycleOutput:
        bad = bad or {}
        prog = bad.get("prog", self.p)
        act = bad.get("act", self.actual)
        incr = bad.get("incr", self.increments_for(surface, self.actual))
        var = bad.get("var", self.actual - surface)
        inp = CycleInput(programmed_position=prog, actual_position=act, sensor_increments=incr,
                         sensor_variable=var, override=override, feed_hold=feed_hold,
                         cyclic_set_pos=bad.get("cyclic", cyclic), commands=list(commands))
        pre = self.ctrl.hli_state
        if math.isfinite(prog) and abs(prog) < 1e12:
            self.last_prog = prog
        out = CycleOutput()
        self.ctrl.update(inp, out)
        self.check.check(Step(list(commands), pre, self.last_prog, override, feed_hold), out)
        # the channel takes over an absorbed offset; the axis follows its command one cycle late
        self.p += out.absorbed_offset
        self.actual = out.command_position
        self.outputs.append(out)
        return out


def surface_fn(spec: dict, T: float, jumps: dict):
    """surface(k): base + sine + noise + accumulated jumps (deterministic from spec['seed'])."""
    rng = random.Random(spec["seed"])
    level = 0.0

    def f(k: int) -> float:
        nonlocal level
        level += jumps.get(k, 0.0)
        return (spec["base"] + spec["amp"] * math.sin(2 * math.pi * spec["freq"] * k * T)
                + spec["noise"] * rng.gauss(0.0, 1.0) + level)
    return f


def run_scenario(params: AxisParameters, T: float, p0: float, sc: dict) -> Plant:
    """Drive the plant through a scenario from :func:`scenarios`; the checker runs every cycle."""
    plant = Plant(params, T, p0)
    surf = surface_fn(sc["surface"], T, sc["jumps"])
    override, hold = 1.0, False
    for k in range(sc["n"]):
        override = sc["override"].get(k, override)
        hold = sc["hold"].get(k, hold)
        cmd = sc["commands"].get(k)
        bad = {key: v for (c, key), v in sc["bad"].items() if c == k}
        plant.step(surf(k) + p0, [cmd] if cmd is not None else [], override, hold, bad)
    return plant
