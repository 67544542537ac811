"""Property tests: the SPEC §6-§8 invariants hold on every cycle of a closed loop, whatever the
parameters, commands, override and sensor signal (incl. NaN/inf) are.

The invariant checker and the strategies live in conftest.py; every ``Plant.step`` runs the checker.
"""
from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from distctrl.control import Action, Command, CycleInput, CycleOutput, HliState, ObjectWrite
from distctrl.params import AxisParameters

from .conftest import Plant, axis_parameters, run_scenario, scenarios

S = HliState
SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@st.composite
def closed_loop_cases(draw):
    params, T, p0 = draw(axis_parameters())
    sc = draw(scenarios(T, set_pos_center=p0 - 1.5))
    return params, T, p0, sc


@settings(max_examples=250, **SETTINGS)
@given(closed_loop_cases())
def test_invariants_hold_every_cycle(case):
    params, T, p0, sc = case
    plant = run_scenario(params, T, p0, sc)
    assert len(plant.outputs) == sc["n"]
    for state in sorted({o.hli_state for o in plant.outputs}):
        event(f"visited {HliState(state).name}")
    for eid in sorted({e.id for o in plant.outputs for e in o.events}):
        event(f"event {eid}")
    if any(o.offset_velocity != 0.0 for o in plant.outputs):
        event("offset moved")


# ---------------------------------------------------------------------------- focused properties

def _tracking_params(**kw) -> AxisParameters:
    base = dict(enabled=True, v_max=50.0, a_max=2000.0, max_act_value_change=1e5, max_deviation=20.0,
                optimized_scheduling=True, filter_type="MOVING_AVERAGE", n_cycles=1, min_pos=-100.0,
                max_pos=100.0)
    base.update(kw)
    return AxisParameters(**base)


@settings(max_examples=60, **SETTINGS)
@given(surface=st.floats(-5.0, 5.0), set_pos=st.floats(-5.0, 5.0), kp=st.floats(0.05, 2.0),
       freeze_at=st.integers(5, 150), hold_cycles=st.integers(1, 100),
       override=st.sampled_from([0.0, 0.3, 1.0, math.nan]), feed_hold=st.booleans())
def test_freeze_holds_offset_after_braking(surface, set_pos, kp, freeze_at, hold_cycles, override, feed_hold):
    """FREEZE: the offset decelerates within the limits, then stays constant while frozen, even
    when the surface moves (lifting Z while frozen is the documented use)."""
    params = _tracking_params(kp=kp)
    plant = Plant(params, 0.001, 0.0)
    plant.step(surface, [Command(Action.ON, set_pos=set_pos)])
    for _ in range(freeze_at):
        plant.step(surface)
    plant.step(surface, [Command(Action.FREEZE)], override, feed_hold)
    offsets = []
    for k in range(hold_cycles + 200):
        out = plant.step(surface + 3.0 * math.sin(k / 7.0), override=override, feed_hold=feed_hold)
        assert out.hli_state == S.FREEZE
        if out.offset_velocity == 0.0:
            offsets.append(out.offset)
    assert offsets and all(o == offsets[0] for o in offsets)


@settings(max_examples=60, **SETTINGS)
@given(const=st.booleans(), value=st.floats(0.1, 5.0), jump=st.floats(-3.0, 3.0), n=st.integers(10, 200))
def test_dryrun_from_inactive_keeps_offset_zero(const, value, jump, n):
    params = _tracking_params()
    plant = Plant(params, 0.001, 0.0)
    cmd = Command(Action.DRYRUN, const_dist=True, set_dist=value) if const else \
        Command(Action.DRYRUN, set_pos=-value)
    out = plant.step(-1.0, [cmd])
    assert out.hli_state == (S.DRYRUN_CONST_DIST if const else S.DRYRUN_SETPOS)
    for k in range(n):
        out = plant.step(-1.0 + (jump if k > n // 2 else 0.0) * min(1.0, k / n))
        assert out.offset == 0.0 and out.offset_velocity == 0.0
        # the evaluation runs (target deviation from the filtered feedback), only the tracking is off
        assert out.target_deviation == pytest.approx(out.filtered_feedback - (value if const else -value), abs=1e-12)


@settings(max_examples=60, **SETTINGS)
@given(set_pos=st.floats(-4.0, 2.0), run=st.integers(5, 150), wait=st.integers(0, 60),
       how=st.sampled_from(["off", "off_no_move", "reset", "axis_error"]))
def test_error_holds_then_leaves_only_by_off_or_reset(set_pos, run, wait, how):
    params = _tracking_params(a_max=500.0)
    plant = Plant(params, 0.001, 0.0)
    plant.step(-1.0, [Command(Action.ON, set_pos=set_pos)])
    for _ in range(run):
        plant.step(-1.0)
    # a direct switch ACTIVE -> ACTIVE_CONST_DIST is an invalid transition: ERROR (900003)
    out = plant.step(-1.0, [Command(Action.ON, const_dist=True, set_dist=1.0)])
    assert out.hli_state == S.ERROR and [e.id for e in out.events] == [900003]
    for cmd in (Command(Action.ON, set_pos=0.0), Command(Action.FREEZE), Command(Action.DRYRUN, set_pos=0.0),
                Command(Action.REF, ref_position=0.0), Command(Action.PROGRAM_END)):
        out = plant.step(-1.0, [cmd])
        assert out.hli_state == S.ERROR
    for _ in range(wait):
        out = plant.step(-1.0)
        assert out.hli_state == S.ERROR
    held = out.offset
    if how in ("off", "off_no_move"):
        # ERROR is left only through TURNING_OFF (FCT-M3 §8.1): OFF NO_MOVE acts as OFF (warning 900009)
        out = plant.step(-1.0, [Command(Action.OFF, no_move=how == "off_no_move")])
        assert out.hli_state in (S.TURNING_OFF, S.INACTIVE) and out.absorbed_offset == 0.0
        assert [e.id for e in out.events] == ([900009] if how == "off_no_move" else [])
        for _ in range(5000):
            if out.hli_state == S.INACTIVE:
                break
            out = plant.step(-1.0)
        assert out.hli_state == S.INACTIVE and out.offset == 0.0
    else:
        action = {"reset": Action.RESET, "axis_error": Action.AXIS_ERROR}[how]
        prev_c = out.command_position
        out = plant.step(-1.0, [Command(action)])
        assert out.hli_state == S.INACTIVE and out.offset == 0.0
        assert out.absorbed_offset == held
        assert out.command_position == pytest.approx(prev_c, abs=1e-12)


@settings(max_examples=80, **SETTINGS)
@given(params=axis_parameters(),
       values=st.lists(st.sampled_from([math.nan, math.inf, -math.inf, 1e300, -1e300, 1e13, 0.0]),
                       min_size=6, max_size=6),
       cycles=st.integers(1, 30))
def test_no_nan_leaves_the_core(params, values, cycles):
    """Whatever the inputs, every float of CycleOutput is finite (checked by the plant's checker)."""
    params, T, p0 = params
    plant = Plant(params, T, p0)
    plant.step(p0 - 1.0, [Command(Action.ON, set_pos=p0 - 1.0)])
    plant.step(p0 - 1.0)
    inc, var, prog, act, ovr, cyc = values
    for k in range(cycles):
        ctrl, out = plant.ctrl, CycleOutput()
        inp = CycleInput(programmed_position=prog if k % 2 else p0, actual_position=act, sensor_increments=inc,
                         sensor_variable=var, override=ovr, cyclic_set_pos=cyc, cyclic_set_dist=cyc)
        ctrl.update(inp, out)
        for name in out.__dataclass_fields__:
            v = getattr(out, name)
            if isinstance(v, float):
                assert math.isfinite(v), name
        assert all(math.isfinite(x) for x in out.vals)
        if not abs(inc) < 1e12:          # non-finite (|x| >= 1e12 counts as such) while running: 900001
            assert out.hli_state == S.ERROR


@settings(max_examples=60, **SETTINGS)
@given(v_new=st.floats(0.0, 200.0), a_new=st.floats(0.0, 5000.0), kp_new=st.floats(0.01, 2.0),
       via_freeze=st.booleans())
def test_object_writes_adopted_only_on_inactive_or_freeze_to_active(v_new, a_new, kp_new, via_freeze):
    params = _tracking_params(kp=0.5, v_max=30.0, a_max=1000.0)
    plant = Plant(params, 0.001, 0.0)
    if via_freeze:
        plant.step(-1.0, [Command(Action.ON, set_pos=-1.2)])
    for w in (ObjectWrite("v_max", v_new), ObjectWrite("a_max", a_new), ObjectWrite("kp", kp_new)):
        out = plant.step(-1.0, [w])
    for _ in range(20):
        out = plant.step(-1.0)
        assert (out.v_max_param, out.a_max_param, out.kp) == (30.0, 1000.0, 0.5)
    if via_freeze:
        out = plant.step(-1.0, [Command(Action.ON, set_pos=-1.3)])          # re-select: no adoption
        assert (out.v_max_param, out.a_max_param, out.kp) == (30.0, 1000.0, 0.5)
        out = plant.step(-1.0, [Command(Action.FREEZE)])
        assert (out.v_max_param, out.a_max_param, out.kp) == (30.0, 1000.0, 0.5)
        for _ in range(100):
            plant.step(-1.0)
    out = plant.step(-1.0, [Command(Action.ON, set_pos=-1.0)])
    assert out.hli_state == S.ACTIVE
    assert (out.v_max_param, out.a_max_param, out.kp) == (v_new, a_new, kp_new)


# ---------------------------------------------------------------------------- regressions
# Each of these was a bug these property tests found (reported as strict-xfail "BUG:" tests, since fixed):
# they pin the fixed behaviour.

def _run_off_to_landing(params, T=0.001):
    """ACTIVE with an offset of 0.5 mm, then OFF until INACTIVE; returns (cycle function, outputs)."""
    from distctrl.control import AxisDistanceController
    ctrl = AxisDistanceController(params, T)
    p, surface, act = 0.0, 0.5, 0.0
    outs = []

    def cyc(cmds=()):
        nonlocal act
        inp = CycleInput(programmed_position=p, actual_position=act,
                         sensor_increments=(surface - act) / params.sensor_mm_per_increment, commands=list(cmds))
        out = CycleOutput()
        ctrl.update(inp, out)
        act = out.command_position
        outs.append(out)
        return out
    cyc([Command(Action.ON, set_pos=0.0)])
    for _ in range(300):
        cyc()
    cyc([Command(Action.OFF)])
    for _ in range(500):
        if cyc().hli_state == S.INACTIVE:
            break
    return cyc, outs


_LAND_PARAMS = dict(enabled=True, a_max=100.0, v_max=50.0, optimized_scheduling=True, max_act_value_change=1000.0)


def test_landing_cycle_reports_the_velocity_it_moved_with():
    """Was BUG: on TURNING_OFF -> INACTIVE the controller reported offset_velocity = 0 although the offset
    moved that cycle (a reported velocity step up to ~2*a_max*T)."""
    params = AxisParameters(**_LAND_PARAMS)
    _, outs = _run_off_to_landing(params)
    land, prev = outs[-1], outs[-2]
    assert land.hli_state == S.INACTIVE and prev.hli_state == S.TURNING_OFF and land.offset == 0.0
    assert land.delta_offset != 0.0
    assert land.offset_velocity * 0.001 == pytest.approx(land.delta_offset, abs=1e-15)
    assert abs(land.offset_velocity - prev.offset_velocity) <= land.a_max_int * 0.001 * (1 + 1e-9)


@pytest.mark.parametrize("set_pos", [-1.0, 1.0])
def test_reselect_right_after_landing_keeps_the_acceleration_bound(set_pos):
    """Was BUG: a select in the cycle after the landing started from a remembered velocity 0 while the
    offset had still moved in the landing cycle: a physical velocity step > a_max*T."""
    params = AxisParameters(**_LAND_PARAMS)
    cyc, outs = _run_off_to_landing(params)
    land = outs[-1]
    nxt = cyc([Command(Action.ON, set_pos=set_pos)])
    assert nxt.hli_state == S.ACTIVE
    v_land, v_next = land.delta_offset / 0.001, nxt.delta_offset / 0.001
    assert abs(v_next - v_land) <= nxt.a_max_int * 0.001 * (1 + 1e-9) + 1e-12


def test_lower_a_max_adopted_while_moving_brakes_without_a_step():
    """Was BUG: a lower a_max adopted at FREEZE -> ACTIVE while the offset still moved made the bound
    brake with the new acceleration floor: 19 mm/s -> 1.24 mm/s in one cycle."""
    from distctrl.control import AxisDistanceController
    params = AxisParameters(enabled=True, a_max=1000.0, v_max=200.0, optimized_scheduling=True,
                            max_act_value_change=1e6, max_deviation=1.0)
    ctrl = AxisDistanceController(params, 0.001)
    act, surface = 0.0, 3.0
    outs = []
    script = {0: [Command(Action.ON, set_pos=0.0)], 19: [ObjectWrite("a_max", 1.0)],
              20: [Command(Action.FREEZE)], 21: [Command(Action.ON, set_pos=0.0)]}
    for k in range(400):
        inp = CycleInput(programmed_position=0.0, actual_position=act,
                         sensor_increments=(surface - act) / params.sensor_mm_per_increment,
                         commands=list(script.get(k, [])))
        out = CycleOutput()
        ctrl.update(inp, out)
        act = out.command_position
        outs.append(out)
    assert outs[21].a_max_param == 1.0 and abs(outs[20].offset_velocity) > 10.0     # adopted while moving
    for prev, out in zip(outs, outs[1:]):
        assert abs(out.offset_velocity - prev.offset_velocity) <= out.a_max_int * 0.001 * (1 + 1e-9) + 1e-12, \
            (out.cycle, prev.offset_velocity, out.offset_velocity, out.a_max_int)
        assert abs(out.offset) <= 1.0
    assert outs[-1].offset_velocity == 0.0 or abs(outs[-1].offset_velocity) < abs(outs[21].offset_velocity)


@pytest.mark.parametrize("filter_type", ["EXPO_MEAN", "KALMAN_EXPO"])
@pytest.mark.parametrize("alpha", [1e-17, 5e-324])
def test_expo_filters_with_tiny_smoothing_factor(filter_type, alpha):
    """Was BUG: smoothing_factor < ~1.1e-16 (legal: 0 < alpha <= 1) made 1 - (1 - alpha)^n round to 0
    and update() raised ZeroDivisionError."""
    params = AxisParameters(enabled=True, filter_type=filter_type, smoothing_factor=alpha, n_cycles=4,
                            max_act_value_change=1e5, optimized_scheduling=True)
    plant = Plant(params, 0.001, 0.0)
    plant.step(-1.0, [Command(Action.ON, set_pos=-1.0)])
    for _ in range(5):
        out = plant.step(-1.0)
    assert out.hli_state == S.ACTIVE and out.filtered_feedback == pytest.approx(-1.0)


@pytest.mark.parametrize("kw", [dict(i_tn=5e-324), dict(i_tn=1e-310), dict(a_max=1e-306), dict(a_max=1e-300)])
def test_tiny_tuning_values_keep_the_core_finite(kw):
    """Was BUG: i_tn = 5e-324 leaked -inf into delta_deviation_pre_limiter; a_max = 1e-306 made
    brake_velocity() raise OverflowError out of update(). Both are inside the documented ranges."""
    params = AxisParameters(enabled=True, optimized_scheduling=True, max_act_value_change=1e5, **kw)
    plant = Plant(params, 0.001, 0.0)          # the plant's checker asserts every float output is finite
    plant.step(-1.0, [Command(Action.ON, set_pos=0.0)])
    for _ in range(20):
        plant.step(-1.0)
    # the same values through CNC-object writes, adopted at FREEZE -> ACTIVE
    name, value = next(iter(kw.items()))
    plant.step(-1.0, [ObjectWrite(name, value)])
    plant.step(-1.0, [Command(Action.FREEZE)])
    plant.step(-1.0, [Command(Action.ON, set_pos=-3.0)])
    for _ in range(20):
        plant.step(-1.0)


# Was BUG: a subnormal but positive acceleration with adaptive acceleration made brake_velocity() divide
# by a*T*T == 0.0 inside update() ("never raises on cycle data"). Fixed in law.brake_velocity.
def test_subnormal_a_max_with_adaptive_acceleration():
    params = AxisParameters(enabled=True, optimized_scheduling=True, max_act_value_change=1e5, a_max=5e-324,
                            use_adaptive_acceleration=True, a_min=500.0, dist_error_a_min=10.0,
                            dist_error_a_max=20.0)
    plant = Plant(params, 0.001, 0.0)
    plant.step(-1.0, [Command(Action.ON, set_pos=0.0)])
    for _ in range(5):
        plant.step(-1.0)
