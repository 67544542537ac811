"""Known values: the documents' sequences (%DIST_1..5, chapter 10, Fig. 31, §7) through the core."""
from __future__ import annotations

import math

import pytest

from distctrl.control import (Action, AxisDistanceController, Command, CommandSource, CycleInput, CycleOutput,
                              FilterType, HliState, InternalState, ObjectWrite, Result, SensorSource)
from distctrl.control import law
from distctrl.errors import ParameterError
from distctrl.params import AxisParameters

from .rig import Rig

FAST = dict(enabled=True, v_max=100.0, a_max=20000.0, max_act_value_change=1e6, optimized_scheduling=True,
            max_pos=50.0, min_pos=-50.0)


def params(**kw) -> AxisParameters:
    return AxisParameters(**{**FAST, **kw})


ON = Action.ON


# ----------------------------------------------------------------------------- %DIST examples

def test_dist_1_set_position_then_select_then_deselect():
    rig = Rig(params(), p=40.0, surface=30.0)
    out = rig.cycle(Command(set_pos=30.0, line=10))
    assert out.hli_state == HliState.INACTIVE and out.set_pos == 30.0 and out.offset == 0.0
    out = rig.cycle(Command(ON, line=20))
    assert out.hli_state == HliState.ACTIVE and out.state == InternalState.ACTIVE
    rig.surface = 30.5                                   # real surface 0.5 mm higher than programmed
    out = rig.cycle(n=300)
    assert out.offset == pytest.approx(0.5, abs=1e-9)
    assert out.target_deviation == pytest.approx(0.5, abs=1e-9)   # sf - SET_POS
    assert out.surface_position == pytest.approx(30.5)
    out = rig.cycle(Command(Action.OFF, line=30))
    assert out.hli_state == HliState.TURNING_OFF and out.state == InternalState.OFF
    out = rig.run_until(lambda o: o.hli_state == HliState.INACTIVE)
    assert out.offset == 0.0 and out.command_position == 40.0 and rig.event_ids() == []


def test_dist_2_freeze_holds_the_offset():
    rig = Rig(params(), p=35.0, surface=30.0)
    rig.cycle(Command(ON, set_pos=30.0, line=10))
    rig.surface = 29.0
    out = rig.cycle(n=300)
    assert out.offset == pytest.approx(-1.0, abs=1e-9)
    out = rig.cycle(Command(Action.FREEZE))
    assert out.hli_state == HliState.FREEZE and out.state == InternalState.FREEZE
    rig.surface = 31.0
    frozen = [rig.cycle().offset for _ in range(200)]
    assert all(o == frozen[0] for o in frozen) and frozen[0] == pytest.approx(-1.0, abs=1e-9)
    out = rig.cycle(Command(Action.OFF))
    out = rig.run_until(lambda o: o.hli_state == HliState.INACTIVE)
    assert out.offset == 0.0


def test_dist_3_off_no_move_absorbs_the_offset_without_moving_the_axis():
    rig = Rig(params(), p=55.0, surface=50.0)
    rig.cycle(Command(ON, set_pos=50.0, line=10))
    rig.surface = 48.75
    out = rig.cycle(n=300)
    assert out.offset == pytest.approx(-1.25, abs=1e-9)
    before = out.command_position
    out = rig.cycle(Command(Action.OFF, no_move=True, line=20))
    assert out.hli_state == HliState.INACTIVE and out.state == InternalState.OFF_NO_MOVE
    assert out.offset == 0.0 and out.absorbed_offset == pytest.approx(-1.25, abs=1e-9)
    assert out.command_position == pytest.approx(before, abs=1e-12)         # the axis does not move
    out = rig.cycle()
    assert out.state == InternalState.IDLE and rig.p == pytest.approx(55.0 - 1.25)
    assert out.command_position == pytest.approx(before, abs=1e-12)
    rig.p = 100.0                                        # N.. G0 Z100: the next move removes it
    assert rig.cycle().command_position == 100.0


def test_dist_4_surface_then_constant_distance():
    rig = Rig(params(), p=40.0, surface=30.0)
    rig.cycle(Command(set_pos=30.0, line=10))
    rig.cycle(Command(ON, line=20))
    rig.cycle(Command(Action.OFF), n=1)
    rig.run_until(lambda o: o.hli_state == HliState.INACTIVE)
    rig.cycle(Command(set_dist=10.0))
    out = rig.cycle(Command(ON, const_dist=True))
    assert out.hli_state == HliState.ACTIVE_CONST_DIST and out.set_distance == 10.0
    out = rig.cycle(n=500)
    assert out.measured_distance == pytest.approx(10.0, abs=1e-6)          # 40 - 30 = 10 already
    rig.surface = 31.0                                                     # profiled surface
    out = rig.cycle(n=800)
    assert rig.actual - rig.surface == pytest.approx(10.0, abs=1e-6)
    assert out.offset == pytest.approx(1.0, abs=1e-6)
    rig.cycle(Command(Action.OFF))
    assert rig.run_until(lambda o: o.hli_state == HliState.INACTIVE).offset == 0.0


def test_dist_5_filter_dryrun_pid_const_dist_filter_change():
    rig = Rig(params(), p=41.0, surface=40.0)
    rig.cycle(Command(filter_type=FilterType.KALMAN_MA, line=10))
    out = rig.cycle(Command(n_cycles=30, kalman_sigma=1000.0, line=20))
    assert (out.filter_type, out.n_cycles, out.kalman_sigma) == ("KALMAN_MA", 30, 1000.0)
    # N30 DRYRUN without SET_POS: SPEC §12 makes it an error (70335); give the value
    out = rig.cycle(Command(Action.DRYRUN, line=30))
    assert rig.result == Result.ERROR and out.hli_state == HliState.ERROR
    assert out.events[0].id == 70335 and out.events[0].line == 30
    assert out.state == InternalState.ERROR_NO_SET_VALUE
    rig.cycle(Command(Action.OFF))
    rig.run_until(lambda o: o.hli_state == HliState.INACTIVE)
    out = rig.cycle(Command(Action.DRYRUN, set_pos=40.0, line=31))
    assert out.hli_state == HliState.DRYRUN_SETPOS and out.state == InternalState.DRYRUN
    rig.surface = 40.3
    outs = [rig.cycle() for _ in range(1500)]
    assert all(o.offset == 0.0 for o in outs)                       # DRYRUN: the axis is not tracked
    assert outs[-1].target_deviation > 0.2                          # ... but the data is evaluated
    rig.cycle(Command(Action.FREEZE))
    out = rig.cycle(Command(kp=0.3, i_tn=0.0, d_tv=0.01, line=40))
    assert (out.kp, out.i_tn, out.d_tv) == (0.3, 0.0, 0.01)         # programmed: effective at once
    rig.cycle(Command(Action.OFF))
    rig.run_until(lambda o: o.hli_state == HliState.INACTIVE)
    out = rig.cycle(Command(ON, const_dist=True, set_dist=1.0, line=50))
    assert out.hli_state == HliState.ACTIVE_CONST_DIST
    # KP 0.3 with the 30-value Kalman filter in the plain CONST_DIST loop: the filter's feedback
    # makes the axis oscillate, as FCT-M3 §4 warns ('an enabled distance controller automatically
    # causes a feedback on the filter ... even result in oscillations on the axis')
    distance = [rig.cycle() and rig.actual - rig.surface for _ in range(3000)]
    assert max(distance[-500:]) - min(distance[-500:]) > 0.1
    before = rig.out.filtered_feedback
    out = rig.cycle(Command(filter_type=FilterType.KALMAN_EXPO, smooth_fact=0.3, line=60))
    assert out.filter_type == "KALMAN_EXPO" and out.smoothing_fact == 0.3
    # bumpless: the new filter starts from the last filtered value (its history is filled with it), so
    # its first output lies between that value and the new measurement
    lo, hi = sorted((before, out.feedback_value))
    assert lo - 1e-12 <= out.filtered_feedback <= hi + 1e-12
    # the exponential model (alpha 0.3) has little delay: the same loop settles at SET_DIST
    rig.cycle(n=3000)
    assert rig.actual - rig.surface == pytest.approx(1.0, abs=1e-3)
    out = rig.cycle(Command(Action.OFF, line=70))
    rig.run_until(lambda o: o.hli_state == HliState.INACTIVE)
    out = rig.cycle(Command(Action.PROGRAM_END, line=999))
    assert rig.result == Result.OK


# ----------------------------------------------------------------------------- chapter 10

def test_chapter_10_reference_set_position_freeze_reactivate_off():
    p = params(max_pos=1000000 * 1e-4, min_pos=-1000000 * 1e-4)
    rig = Rig(p, p=40.0, surface=10.0)            # probe delivers some absolute value (-299999 incr.)
    rig.sensor_extra = -299999 * 1e-4 - rig.reading()
    # 1. referencing the sensor, "sensor zero": REF with the surface where the tool is (REF_POS = the
    #    axis position, 40 mm; HLI position = reference position of the workpiece surface, SPEC §2)
    out = rig.cycle(Command.from_hli(3, 40.0))
    assert out.sensor_value == pytest.approx(0.0, abs=1e-12) and out.hli_state == HliState.INACTIVE
    out = rig.cycle(Command.from_hli(1, 400000 * 1e-4))   # 2.-5. position 400000, transition 1 ON
    assert out.hli_state == HliState.ACTIVE and out.command_source == CommandSource.PLC
    assert out.sensor_value == pytest.approx(0.0, abs=1e-12) and out.offset == 0.0
    rig.sensor_extra += 1.0                       # surface offset: the sensor changes by +1 mm
    out = rig.cycle(n=300)
    assert out.sensor_value == pytest.approx(0.0, abs=1e-9)  # re-adjusted until the sensor reads 0 again
    assert out.offset == pytest.approx(1.0, abs=1e-9)
    out = rig.cycle(Command.from_hli(2))          # FREEZE
    assert out.hli_state == HliState.FREEZE
    rig.sensor_extra -= 2.0                       # changed sensor value -20000 (x 0.1 µm)
    outs = [rig.cycle() for _ in range(200)]
    assert all(o.offset == pytest.approx(1.0, abs=1e-9) for o in outs)   # no influence while frozen
    assert outs[-1].sensor_value == pytest.approx(-2.0, abs=1e-9)
    out = rig.cycle(Command.from_hli(1, 400000 * 1e-4))   # re-activation restores the sensor value
    out = rig.cycle(n=300)
    assert out.sensor_value == pytest.approx(0.0, abs=1e-9) and out.offset == pytest.approx(-1.0, abs=1e-9)
    rig.cycle(Command.from_hli(0))                # OFF: the offset is cancelled
    out = rig.run_until(lambda o: o.hli_state == HliState.INACTIVE)
    assert out.offset == 0.0 and rig.actual == pytest.approx(40.0)


# ----------------------------------------------------------------------------- Fig. 31, §7.4, KP

def test_fig_31_adaptive_acceleration_rule_with_the_example_values():
    # FCT-M3 §7.2 example: a_min 1000, a_max 10000, dist_error_a_min 250, dist_error_a_max 500 (0.1 µm)
    f = law.adaptive_acceleration
    assert f(0.0, 1000, 10000, 0.025, 0.05) == 1000
    assert f(0.025, 1000, 10000, 0.025, 0.05) == 1000
    assert f(0.0375, 1000, 10000, 0.025, 0.05) == pytest.approx(5500)
    assert f(0.05, 1000, 10000, 0.025, 0.05) == 10000
    assert f(3.0, 1000, 10000, 0.025, 0.05) == 10000
    for dev, expect in [(0.01, 1000.0), (0.0375, 5500.0), (0.2, 10000.0)]:
        rig = Rig(params(use_adaptive_acceleration=True, a_min=1000, a_max=10000, dist_error_a_min=0.025,
                         dist_error_a_max=0.05), p=40.0, surface=40.0 + dev)
        out = rig.cycle(Command(ON, set_pos=40.0))
        assert out.a_max_int == pytest.approx(expect)
        assert abs(out.offset_velocity) <= expect * 0.001 + 1e-9


def test_lowering_weighting_halves_velocity_and_weights_acceleration():
    # FCT-M3 §7.4 example: v_weight_down 500, a_weight_down 300 (0.1 %) -> 0.5, 0.3 internally
    p = params(v_max=20.0, a_max=1000.0, v_weight_down=0.5, a_weight_down=0.3)
    rig = Rig(p, p=40.0, surface=40.0)
    rig.cycle(Command(ON, set_pos=40.0))
    rig.surface = 35.0                                    # lowering by 5 mm
    rig.run_until(lambda o: abs(o.offset + 5.0) < 1e-9)
    down = rig.history
    v_min = min(o.offset_velocity for o in down)
    assert v_min == pytest.approx(-10.0)                  # 50 % of v_max
    dv = max(abs(a.offset_velocity - b.offset_velocity) for a, b in zip(down, down[1:]))
    assert dv <= 300.0 * 0.001 + 1e-9                     # 30 % of a_max
    rig.history.clear()
    rig.surface = 40.0                                    # lifting: full dynamics
    rig.run_until(lambda o: abs(o.offset) < 1e-9)
    assert max(o.offset_velocity for o in rig.history) == pytest.approx(20.0)


@pytest.mark.parametrize("kp", [0.2, 1.0, 1.5, 1.9])
def test_kp_below_2_converges_in_set_pos(kp):
    p = params(kp=kp, filter_type=FilterType.MOVING_AVERAGE, n_cycles=1, v_max=1e6, a_max=1e9)
    rig = Rig(p, p=40.0, surface=40.0)
    rig.cycle(Command(ON, set_pos=40.0))
    rig.surface = 41.0
    out = rig.cycle(n=400)
    assert out.offset == pytest.approx(1.0, abs=1e-6)


def test_kp_2_does_not_converge_and_above_2_is_rejected():
    p = params(kp=2.0, filter_type=FilterType.MOVING_AVERAGE, n_cycles=1, v_max=1e6, a_max=1e9)
    rig = Rig(p, p=40.0, surface=40.0)
    rig.cycle(Command(ON, set_pos=40.0))
    rig.surface = 41.0
    outs = [rig.cycle().offset for _ in range(200)]
    assert max(outs[-20:]) - min(outs[-20:]) > 1.0            # pole at -1: sustained oscillation
    with pytest.raises(ParameterError, match="P-AXIS-00759"):
        AxisParameters(kp=2.01)
    out = rig.cycle(Command(kp=2.5, line=77))
    assert out.events[0].id == 900005 and out.events[0].line == 77 and "KP" in out.events[0].message


def test_pid_i_part_removes_a_permanent_deviation_in_const_dist_with_drive_lag():
    p = params(kp=0.2, i_tn=0.05, n_cycles=1, v_max=50.0, a_max=5000.0, optimized_scheduling=False)
    rig = Rig(p, p=41.0, surface=40.0, drive_lag=0.01)
    rig.cycle(Command(ON, const_dist=True, set_dist=1.0))
    for k in range(3000):
        rig.surface = 40.0 + 0.002 * k * 0.001 * 1000 / 1000   # slow ramp: P alone lags behind
        rig.cycle()
    assert abs(rig.actual - rig.surface - 1.0) < 2e-3


def test_feed_override_zero_freezes_the_offset_without_changing_state():
    rig = Rig(params(v_max=20.0, a_max=1000.0), p=40.0, surface=40.0)
    rig.cycle(Command(ON, set_pos=40.0))
    rig.surface = 45.0
    rig.cycle(n=40)
    v0 = rig.out.offset_velocity
    assert v0 > 10
    outs = [rig.cycle(override=0.0) for _ in range(100)]
    assert all(o.hli_state == HliState.ACTIVE for o in outs)
    for a, b in zip([rig.history[-101]] + outs, outs):
        assert abs(b.offset_velocity - a.offset_velocity) <= 1000.0 * 0.001 + 1e-9
    assert outs[-1].offset_velocity == 0.0 and outs[-1].offset == outs[-2].offset
    outs = [rig.cycle(override=0.5) for _ in range(400)]
    assert max(o.offset_velocity for o in outs) == pytest.approx(10.0)
    outs = [rig.cycle(override=1.0, feed_hold=True) for _ in range(100)]
    assert outs[-1].offset_velocity == 0.0


# ----------------------------------------------------------------------------- errors (SPEC §7)

def enter_active(rig, **kw):
    out = rig.cycle(Command(ON, set_pos=rig.surface, **kw))
    assert out.hli_state == HliState.ACTIVE
    return out


def assert_error(rig, out, error_id, code):
    assert rig.result == Result.ERROR
    assert out.hli_state == HliState.ERROR and out.state == code
    assert error_id in [e.id for e in out.events]


def test_70329_sensor_jump():
    rig = Rig(params(max_act_value_change=5.0), surface=40.0)     # 5 mm/s = 5 µm per 1 ms cycle
    enter_active(rig)
    rig.sensor_extra = 0.004
    assert rig.cycle().hli_state == HliState.ACTIVE
    rig.sensor_extra = 0.0101
    assert_error(rig, rig.cycle(), 70329, InternalState.ERROR_SENSOR_JUMP)


def test_70330_and_70576_sensor_run_out_and_check_pos():
    p = params(max_pos=2.0, min_pos=-2.0, tolerance=0.5)
    rig = Rig(p, surface=40.0)
    enter_active(rig)
    rig.sensor_extra = 1.6                                        # s > max_pos - tolerance
    out = rig.cycle()
    assert_error(rig, out, 70330, InternalState.ERROR_SENSOR_MAX)
    rig = Rig(p, surface=40.0)
    enter_active(rig)
    rig.sensor_extra = -1.6
    assert_error(rig, rig.cycle(), 70576, InternalState.ERROR_SENSOR_MIN)
    rig = Rig(p, surface=40.0)
    assert rig.cycle(Command(Action.CHECK_POS)).events == []      # inside the window: nothing
    rig.sensor_extra = 1.7
    out = rig.cycle(Command(Action.CHECK_POS, line=12))
    assert_error(rig, out, 70330, InternalState.ERROR_SENSOR_MAX)
    assert out.events[0].line == 12


def test_70331_offset_limited_at_max_deviation():
    rig = Rig(params(max_deviation=2.0, v_max=50.0, a_max=2000.0), surface=40.0)
    enter_active(rig)
    rig.surface = 43.0                                            # would need +3 mm
    outs = []
    while rig.out.hli_state != HliState.ERROR and len(outs) < 5000:
        outs.append(rig.cycle())
    assert_error(rig, outs[-1], 70331, InternalState.ERROR_MAX_DEVIATION)
    assert max(o.offset for o in rig.history) <= 2.0
    assert outs[-1].offset == pytest.approx(2.0, abs=1e-9)
    for a, b in zip(rig.history, rig.history[1:]):
        assert abs(b.offset_velocity - a.offset_velocity) <= 2000.0 * 0.001 * (1 + 1e-9)
    held = [rig.cycle().offset for _ in range(100)]
    assert all(h == held[0] for h in held)


def test_70332_program_end_while_active_is_a_warning_and_forgets_set_values():
    rig = Rig(params(), surface=40.0)
    enter_active(rig)
    out = rig.cycle(Command(Action.PROGRAM_END, line=999))
    assert rig.result == Result.WARNING and out.hli_state == HliState.ACTIVE
    assert out.events[0].id == 70332 and out.events[0].severity == "warning"
    rig.cycle(Command(Action.FREEZE))
    out = rig.cycle(Command(ON, line=5))                           # next select without SET_POS
    assert_error(rig, out, 70335, InternalState.ERROR_NO_SET_VALUE)


def test_70333_axis_release_while_active():
    rig = Rig(params(), surface=40.0)
    assert rig.cycle(Command(Action.AXIS_RELEASE)).events == []
    enter_active(rig)
    assert_error(rig, rig.cycle(Command(Action.AXIS_RELEASE)), 70333, InternalState.ERROR_COMMAND)


def test_70334_select_while_turning_off():
    rig = Rig(params(v_max=5.0), surface=40.0)
    enter_active(rig)
    rig.surface = 41.0
    rig.cycle(n=500)
    assert rig.cycle(Command(Action.OFF)).hli_state == HliState.TURNING_OFF
    assert_error(rig, rig.cycle(Command(ON, set_pos=41.0)), 70334, InternalState.ERROR_COMMAND)


def test_70335_select_without_set_value():
    rig = Rig(params(), surface=40.0)
    assert_error(rig, rig.cycle(Command(ON, const_dist=True, set_pos=40.0)), 70335,
                 InternalState.ERROR_NO_SET_VALUE)


def test_70336_not_enabled_keeps_inactive():
    rig = Rig(params(enabled=False), surface=40.0)
    out = rig.cycle(Command(ON, set_pos=40.0))
    assert [e.id for e in out.events] == [70336] and out.hli_state == HliState.INACTIVE


def test_invalid_transition_and_error_left_only_by_off():
    rig = Rig(params(), surface=40.0)
    rig.cycle(Command(set_dist=1.0))
    enter_active(rig)
    out = rig.cycle(Command(ON, const_dist=True))                  # ACTIVE -> ACTIVE_CONST_DIST directly
    assert_error(rig, out, 900003, InternalState.ERROR_COMMAND)
    for cmd in (Command(ON, set_pos=40.0), Command(Action.FREEZE), Command(Action.REF),
                Command(Action.DRYRUN, set_pos=40.0)):
        assert rig.cycle(cmd).hli_state == HliState.ERROR
    assert rig.cycle(Command(Action.OFF)).hli_state in (HliState.TURNING_OFF, HliState.INACTIVE)
    assert rig.run_until(lambda o: o.hli_state == HliState.INACTIVE).offset == 0.0


def test_software_limit_check_keeps_the_command_position_inside():
    p = params(check_sw_limit_switch=True, sw_limit_max=41.0, sw_limit_min=-100.0, v_max=50.0, a_max=2000.0)
    rig = Rig(p, p=40.0, surface=40.0)
    enter_active(rig)
    rig.surface = 43.0
    for _ in range(3000):
        out = rig.cycle()
        assert out.command_position <= 41.0 + 1e-12
        if out.hli_state == HliState.ERROR:
            break
    assert_error(rig, out, 900002, InternalState.ERROR_OTHER)
    p = p.replace(check_sw_limit_switch=False)
    rig = Rig(p, p=40.0, surface=40.0)                             # default: offset not considered
    enter_active(rig)
    rig.surface = 43.0
    assert rig.cycle(n=1000).command_position == pytest.approx(43.0)


def test_non_finite_sensor_in_active_is_an_error_and_never_reaches_the_outputs():
    rig = Rig(params(), surface=40.0)
    rig.sensor_extra = math.nan
    out = rig.cycle()
    assert out.events == [] and out.sensor_valid is False            # INACTIVE: nothing to monitor
    rig.sensor_extra = 0.0
    enter_active(rig)
    for bad in (math.nan, math.inf, -math.inf):
        rig.sensor_extra = bad
        out = rig.cycle()
        assert all(math.isfinite(getattr(out, f)) for f in ("offset", "command_position", "sensor_value",
                                                             "feedback_value", "filtered_feedback",
                                                             "target_deviation", "delta_deviation_pre_limiter"))
    assert 900001 in rig.event_ids() and out.hli_state == HliState.ERROR
    out = rig.cycle(programmed_position=math.nan, actual_position=math.inf, override=math.nan)
    assert math.isfinite(out.command_position)


# ----------------------------------------------------------------------------- states, adoption, pipeline

def test_reset_and_axis_error_deselect_at_once_absorbing_the_offset():
    for action in (Action.RESET, Action.AXIS_ERROR):
        rig = Rig(params(), p=40.0, surface=40.0)
        enter_active(rig)
        rig.surface = 40.7
        before = rig.cycle(n=300)
        out = rig.cycle(Command(action))
        assert out.hli_state == HliState.INACTIVE and out.offset == 0.0
        assert out.absorbed_offset == pytest.approx(0.7, abs=1e-9)
        assert out.command_position == pytest.approx(before.command_position, abs=1e-12)
        assert_error(rig, rig.cycle(Command(ON)), 70335, InternalState.ERROR_NO_SET_VALUE)


def test_object_writes_are_adopted_only_on_activation_or_freeze_to_active():
    rig = Rig(params(kp=1.0), surface=40.0)
    enter_active(rig)
    out = rig.cycle(ObjectWrite("kp", 0.4), ObjectWrite("v_max", 7.0), ObjectWrite("a_max", 900.0))
    assert out.kp == 1.0 and out.v_max_param == 100.0
    out = rig.cycle(Command(ON, set_pos=40.0))                     # re-select: no adoption
    assert out.kp == 1.0
    rig.cycle(Command(Action.FREEZE))
    out = rig.cycle(Command(ON, set_pos=40.0))                     # FREEZE -> ACTIVE: adopted
    assert (out.kp, out.v_max_param, out.a_max_param) == (0.4, 7.0, 900.0)
    out = rig.cycle(ObjectWrite("kp", 3.0), ObjectWrite("state", 1.0))
    assert [e.id for e in out.events] == [900005, 900006] and out.hli_state == HliState.ACTIVE


def test_pending_write_adopted_on_inactive_to_active():
    rig = Rig(params(d_tv=0.0), surface=40.0)
    out = rig.cycle(ObjectWrite("d_tv", 0.02))
    assert out.d_tv == 0.0
    assert enter_active(rig).d_tv == 0.02


def test_sensor_pipeline_resolution_sign_offset_and_modulo():
    p = params(encoder_resolution_num=4, encoder_resolution_denom=1, sensor_sign_reversal=True,
               ref_offset=0.05, max_pos=1.0, min_pos=-1.0)
    ctrl = AxisDistanceController(p)
    inp, out = CycleInput(sensor_increments=-4000.0), CycleOutput()
    ctrl.update(inp, out)            # 4 incr. per 0.1 µm: -4000 incr. = -0.1 mm, reversed +0.1, + 0.05
    assert out.sensor_value == pytest.approx(0.15)
    assert out.measured_distance == pytest.approx(-0.15)
    pm = p.replace(sensor_mode_act_pos=2, sensor_sign_reversal=False, ref_offset=0.0)
    ctrl = AxisDistanceController(pm)
    inp.sensor_increments = 4 * 25000                            # 2.5 mm -> wraps into [-1, 1)
    ctrl.update(inp, out)
    assert out.sensor_value == pytest.approx(0.5)
    assert law.encoder_reading(-30000, 1e-4, False, 0.0, True, -1.0, 1.0) == pytest.approx(-1.0)


def test_variable_source_distance_in_mm():
    p = params()
    rig = Rig(p, p=41.0, surface=40.0)
    out = rig.cycle(Command(sensor_source=SensorSource.VARIABLE, sensor_var="V.E.DIST"))
    out = rig.cycle()
    assert out.sensor_value == pytest.approx(1.0) and out.measured_distance == pytest.approx(1.0)
    rig.cycle(Command(ON, const_dist=True, set_dist=0.5))
    rig.cycle(n=1000)
    assert rig.actual - rig.surface == pytest.approx(0.5, abs=1e-6)
    out = rig.cycle(Command(sensor_source=SensorSource.SECOND_ENCODER))
    assert_error(rig, out, 900004, InternalState.ERROR_COMMAND)


def test_optimized_scheduling_removes_one_cycle_of_dead_time():
    for opt, lag in ((True, 0), (False, 1)):
        rig = Rig(params(optimized_scheduling=opt, filter_type=FilterType.MOVING_AVERAGE, n_cycles=1), p=40.0,
                  surface=40.0)
        rig.cycle(Command(Action.DRYRUN, set_pos=40.0))
        rig.cycle(n=3)
        rig.surface = 41.0
        outs = [rig.cycle() for _ in range(3)]
        assert [o.feedback_value for o in outs][lag] == pytest.approx(41.0)
        if lag:
            assert outs[0].feedback_value == pytest.approx(40.0)


def test_both_encoders_const_dist_steady_state_and_target_deviation():
    p = params(use_both_encoders=True, kp=0.5)
    rig = Rig(p, p=41.0, surface=40.0, drive_lag=0.005)
    rig.cycle(Command(ON, const_dist=True, set_dist=0.8))
    rig.surface = 40.4
    out = rig.cycle(n=2000)
    assert rig.actual - rig.surface == pytest.approx(0.8, abs=1e-6)
    # the filter input d + c - a (SPEC §3): the distance once the drive has reached its command
    assert out.feedback_value == pytest.approx(out.measured_distance + out.command_position - rig.actual, abs=1e-9)
    assert out.feedback_value == pytest.approx(0.8, abs=1e-6)
    assert out.surface_position == pytest.approx(40.4, abs=1e-6)
    assert out.target_deviation == pytest.approx(out.filtered_feedback - 0.8, abs=1e-12)


def test_plc_cyclic_distance_is_read_every_cycle_only_when_plc_commanded():
    rig = Rig(params(), p=41.0, surface=40.0)
    rig.cycle(Command.from_hli(4, 1.0))
    assert rig.out.hli_state == HliState.ACTIVE_CONST_DIST and rig.out.command_source == 1
    out = rig.cycle(n=600, cyclic_set_dist=1.5)
    assert out.set_distance == 1.5 and rig.actual - rig.surface == pytest.approx(1.5, abs=1e-9)
    rig2 = Rig(params(), p=41.0, surface=40.0)
    rig2.cycle(Command(ON, const_dist=True, set_dist=1.0))
    assert rig2.cycle(cyclic_set_dist=1.5).set_distance == 1.0


def test_target_reached_flag_for_wait():
    rig = Rig(params(v_max=10.0, tolerance=0.0), surface=40.0)
    assert rig.cycle().target_reached                               # INACTIVE
    rig.surface = 41.0
    out = rig.cycle(Command(ON, set_pos=40.0))
    assert not out.target_reached
    out = rig.run_until(lambda o: o.target_reached)
    assert abs(out.offset - 1.0) <= 1e-3


def test_outputs_name_every_axis_cnc_object_of_7_5():
    names = ["set_pos", "set_distance", "target_deviation", "delta_deviation_pre_limiter", "m_actual_offset",
             "sloped_delta_deviation", "offset", "delta_offset", "sensor_value", "feedback_value",
             "filtered_feedback", "state", "kp", "i_tn", "d_tv", "smoothing_fact", "kalman_sigma", "n_cycles",
             "filter_type", "v_max_int", "a_max_int"]
    out = CycleOutput()
    for n in names:
        assert hasattr(out, n)


def test_cycle_time_is_validated():
    with pytest.raises(ParameterError, match="cycle_time"):
        AxisDistanceController(params(), cycle_time=0.0)
    with pytest.raises(ParameterError, match="P-AXIS-00508"):
        AxisDistanceController(params(filter_type=FilterType.LOWPASS, low_pass_filter_fg_f0=600.0), 0.001)


def test_dist_5_path_dryrun_directly_to_on_const_dist_does_not_adopt_pending_writes():
    """FCT-M3 §7.6 / §9.4: object writes are adopted only on INACTIVE -> ACTIVE and FREEZE -> ACTIVE
    (SPEC §8: exactly these, not on entering or leaving a DRYRUN state)."""
    rig = Rig(params(), p=41.0, surface=40.0)
    rig.cycle(Command(set_pos=40.0))
    rig.cycle(ObjectWrite("kp", 0.5))
    assert rig.cycle(Command(Action.DRYRUN)).hli_state == HliState.DRYRUN_SETPOS
    assert rig.out.kp == 1.0                                          # INACTIVE -> DRYRUN: not adopted
    out = rig.cycle(ObjectWrite("kp", 0.6))
    assert out.kp == 1.0
    out = rig.cycle(Command(ON, const_dist=True, set_dist=1.0))
    assert out.hli_state == HliState.ACTIVE_CONST_DIST and out.events == []
    assert out.kp == 1.0                                              # DRYRUN -> ACTIVE: not adopted
    out = rig.cycle(Command(Action.DRYRUN, const_dist=True))          # active -> dry run: tracking stops
    assert out.hli_state == HliState.DRYRUN_CONST_DIST and out.kp == 1.0
    rig.cycle(n=50)
    rig.cycle(Command(Action.FREEZE))
    out = rig.cycle(Command(ON, const_dist=True, set_dist=1.0))       # FREEZE -> ACTIVE_CONST_DIST: adopted
    assert out.hli_state == HliState.ACTIVE_CONST_DIST and out.kp == 0.6


def test_integrator_does_not_wind_up_while_the_limiter_clips():
    p = params(kp=0.5, i_tn=0.05, v_max=5.0, a_max=1000.0, filter_type=FilterType.MOVING_AVERAGE, n_cycles=1)
    rig = Rig(p, p=40.0, surface=40.0)
    rig.cycle(Command(ON, set_pos=40.0))
    rig.surface = 42.0                                   # 2 mm at 5 mm/s: 0.4 s in the velocity limit
    outs = [rig.cycle() for _ in range(2000)]
    assert sum(1 for o in outs if abs(o.offset_velocity) >= 5.0 - 1e-9) > 300      # it really clipped
    assert max(o.offset for o in outs) <= 2.0 + 0.01                                # no wind-up overshoot
    assert outs[-1].offset == pytest.approx(2.0, abs=1e-6)
    # the same law without the anti-windup rule would have integrated the clipped error:
    wound = sum(0.5 * (0.001 / 0.05) * (2.0 - o.offset) for o in outs if abs(o.offset_velocity) >= 5.0 - 1e-9)
    assert wound > 0.5


def test_derivative_acts_on_the_measurement_not_on_a_set_value_change():
    p = params(kp=0.5, d_tv=0.5, filter_type=FilterType.MOVING_AVERAGE, n_cycles=1)
    rig = Rig(p, p=40.0, surface=40.0)
    rig.cycle(Command(ON, set_pos=40.0))
    rig.cycle(n=50)
    out = rig.cycle(Command(ON, set_pos=39.0))           # re-select with a new set value: no kick
    e = out.target_deviation - rig.history[-2].offset
    assert out.delta_deviation_pre_limiter == pytest.approx(0.5 * e, abs=1e-12)
    rig.cycle(Command(ON, set_pos=40.0))
    rig.cycle(n=300)
    o_before = rig.history[-1].offset
    rig.surface = 40.01                                  # a measured change of 10 µm: D acts
    out = rig.cycle()
    e = out.target_deviation - o_before
    x = 0.5 * 0.5 / 0.001                                 # kp d_tv / T
    g = x / (1 + x / (0.3 * (1 - 0.5)))                     # the D part's per-cycle gain (SPEC §5, docs)
    assert out.delta_deviation_pre_limiter == pytest.approx(0.5 * e + g * 0.01, rel=1e-9)


def test_a_max_zero_uses_the_axis_acceleration_p_axis_00008():
    rig = Rig(params(a_max=0.0, axis_a_max=777.0), surface=40.0)
    rig.cycle(Command(ON, set_pos=40.0))
    rig.surface = 41.0
    out = rig.cycle()
    assert out.a_max_int == 777.0 and out.a_max_param == 0.0
    assert abs(out.offset_velocity) <= 777.0 * 0.001 + 1e-12


def test_nc_and_plc_both_command_and_the_last_command_sets_the_source():
    """SPEC §8: NC and PLC may both command; state_r shows the source of the last accepted command
    (the documents only show the source: no command is refused for coming from the other one)."""
    from distctrl.control import CommandSource
    rig = Rig(params(), surface=40.0)
    out = rig.cycle(Command.from_hli(1, 40.0))                      # the PLC selects
    assert out.hli_state == HliState.ACTIVE and out.command_source == 1
    out = rig.cycle(Command(Action.FREEZE, line=12))                # an NC FREEZE acts
    assert out.hli_state == HliState.FREEZE and out.command_source == 0 and out.events == []
    out = rig.cycle(Command.from_hli(1, 40.0))                      # the PLC re-activates
    assert out.hli_state == HliState.ACTIVE and out.command_source == 1
    out = rig.cycle(Command(Action.OFF, line=13))                   # an NC OFF switches it off
    assert out.hli_state in (HliState.TURNING_OFF, HliState.INACTIVE) and out.command_source == 0
    assert out.events == []
    rig.run_until(lambda o: o.hli_state == HliState.INACTIVE)
    out = rig.cycle(Command(ON, set_pos=40.0))
    out = rig.cycle(Command(Action.RESET, source=CommandSource.PLC))  # reset always acts
    assert out.hli_state == HliState.INACTIVE


def test_off_no_move_in_error_runs_the_offset_out_through_turning_off():
    """FCT-M3 §8.1 ERROR: 'Only a transition to TURNING OFF is possible to exit this state' (SPEC §8):
    OFF NO_MOVE in ERROR acts as OFF and says so (warning 900009)."""
    rig = Rig(params(max_deviation=0.5), p=40.0, surface=40.0)
    rig.cycle(Command(ON, set_pos=40.0))
    rig.surface = 41.0                                               # the offset runs into max_deviation
    out = rig.run_until(lambda o: o.hli_state == HliState.ERROR)
    rig.cycle(n=100)
    assert abs(rig.out.offset) > 0.4
    out = rig.cycle(Command(Action.OFF, no_move=True, line=30))
    assert out.hli_state == HliState.TURNING_OFF and out.absorbed_offset == 0.0
    assert [(e.id, e.severity, e.line) for e in out.events] == [(900009, "warning", 30)]
    out = rig.run_until(lambda o: o.hli_state == HliState.INACTIVE)
    assert out.offset == 0.0


def test_review_select_in_the_very_first_cycle_reads_no_phantom_previous_value():
    """Found in review: with optimized_scheduling = 0 the first cycle used an initial 0 as 'last reading'."""
    p = params(optimized_scheduling=False, max_act_value_change=5.0)
    ctrl = AxisDistanceController(p)
    inp, out = CycleInput(programmed_position=50.0, actual_position=50.0, sensor_increments=-10.0 / 1e-4), CycleOutput()
    inp.commands.append(Command(ON, set_pos=40.0))
    ctrl.update(inp, out)
    assert out.filtered_feedback == pytest.approx(40.0) and out.events == []
    ctrl.update(inp, out)
    assert out.events == [] and out.hli_state == HliState.ACTIVE


def test_review_dryrun_from_tracking_keeps_the_offset_constant():
    """SPEC §6 DRYRUN => o constant: while the offset still brakes the state is FREEZE."""
    rig = Rig(params(v_max=5.0, a_max=200.0), p=40.0, surface=40.0)
    rig.cycle(Command(ON, set_pos=40.0))
    rig.surface = 41.0
    rig.cycle(n=100)                                                   # moving at up to 5 mm/s
    assert rig.history[-1].offset_velocity > 1.0
    outs = [rig.cycle(Command(Action.DRYRUN, set_pos=40.0))] + [rig.cycle() for _ in range(200)]
    states = [o.hli_state for o in outs]
    assert states[0] == HliState.FREEZE and states[-1] == HliState.DRYRUN_SETPOS
    dry = [o.offset for o in outs if o.hli_state == HliState.DRYRUN_SETPOS]
    assert len(dry) > 100 and max(dry) == min(dry)
    for a, b in zip(outs, outs[1:]):
        assert abs(b.offset_velocity - a.offset_velocity) <= 200.0 * 0.001 + 1e-9


def test_review_no_derivative_kick_when_tracking_resumes_after_freeze():
    p = params(kp=0.5, d_tv=0.01, filter_type=FilterType.MOVING_AVERAGE, n_cycles=1)
    rig = Rig(p, p=41.0, surface=40.0)
    rig.cycle(Command(ON, const_dist=True, set_dist=1.0))
    rig.cycle(n=200)
    rig.cycle(Command(Action.FREEZE))
    rig.p = 43.0                                                       # lift Z by 2 mm while frozen
    rig.cycle(n=200)
    out = rig.cycle(Command(ON, const_dist=True, set_dist=3.0))
    e = 3.0 - out.filtered_feedback
    assert out.delta_deviation_pre_limiter == pytest.approx(0.5 * e, abs=1e-9)   # kp·e, no D kick


@pytest.mark.parametrize("cmd, list_fg", [
    (Command(filter_type=FilterType.LOWPASS, fg_f0=0.0, line=12), 25.0),       # FG_F0=0 with LOWPASS
    (Command(fg_f0=0.0, filter_type=FilterType.LOWPASS, order=2, line=12), 25.0),
    (Command(filter_type=FilterType.LOWPASS, line=12), 600.0),                 # the list's fg above Nyquist
    (Command(fg_f0=500.0, line=12), 25.0),                                      # at Nyquist (LOWPASS listed)
])
def test_a_lowpass_that_cannot_run_is_refused_at_the_block_never_raised(cmd, list_fg):
    """FCT-M3 §6 FG_F0 (P-AXIS-00508, '0 <= fg_f0'): a block leaving a low-pass that cannot run at this
    cycle time (cut-off 0, or at/above Nyquist 1/(2T)) is refused with 900005 naming the value and the
    NC line; the filter stays as it was; update() never raises on cycle data."""
    filter_type = FilterType.LOWPASS if cmd.filter_type is None else FilterType.MOVING_AVERAGE
    p = params(low_pass_filter_fg_f0=list_fg if list_fg < 500.0 else 25.0, filter_type=filter_type, n_cycles=3)
    ctrl = AxisDistanceController(p, 0.001)
    if list_fg >= 500.0:
        # a list cut-off above Nyquist is allowed while the list's filter is not LOWPASS
        p = params(low_pass_filter_fg_f0=list_fg, filter_type=FilterType.MOVING_AVERAGE, n_cycles=3)
        ctrl = AxisDistanceController(p, 0.001)
    inp, out = CycleInput(programmed_position=40.0, actual_position=40.0), CycleOutput()
    before = ctrl.tuning.filter
    inp.commands.append(cmd)
    result = ctrl.update(inp, out)
    assert result == Result.ERROR
    assert [(e.id, e.line) for e in out.events] == [(900005, 12)]
    assert "P-AXIS-00508" in out.events[0].message and "Nyquist" in out.events[0].message
    assert ctrl.tuning.filter == before


def test_sensor_source_default_is_the_second_encoder_on_an_axis():
    """FCT-M3 §6 SENSOR_SOURCE: 'IF "DEFAULT" is selected as the sensor source, the CNC automatically
    sets to the "SECOND_ENCODER" sensor source internally' (the axis variant)."""
    rig = Rig(params(), p=41.0, surface=40.0)
    rig.cycle(Command(sensor_source=SensorSource.VARIABLE, sensor_var="V.E.D"))
    assert rig.ctrl.state.sensor_source == SensorSource.VARIABLE
    out = rig.cycle(Command(sensor_source=SensorSource.DEFAULT))
    assert rig.ctrl.state.sensor_source == SensorSource.SECOND_ENCODER and out.events == []
    out = rig.cycle(Command(ON, const_dist=True, set_dist=1.0), n=3)
    assert out.sensor_value == pytest.approx(-1.0) and out.measured_distance == pytest.approx(1.0)
