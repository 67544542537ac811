"""3D distance control on the shared core: MODE geometry, inclination, the 3D rules."""
from __future__ import annotations

import math

import pytest

from distctrl.control import Action
from distctrl.control.commands3d import Command3D, CompensationMode
from distctrl.control.controller3d import ChannelDistanceController, Cycle3DInput, Cycle3DOutput
from distctrl.params.channel import ChannelParameters

M = CompensationMode


def params(**kw) -> ChannelParameters:
    base = dict(fct_3d_dist_ctrl=True, kp=0.5, v_max=100.0, a_max=20000.0, max_act_value_change=1e6, max_pos=50.0,
                min_pos=-50.0, max_deviation=20.0)
    base.update(kw)
    return ChannelParameters(**base)


class Loop:
    """Clamping point above a horizontal surface; the compensation moves it by δ·e (ideal axes)."""

    def __init__(self, p, *, z=41.0, surface=40.0, theta_deg=0.0, kin98=True, cs_tilt_deg=0.0):
        self.ctrl = ChannelDistanceController(p, 0.001)
        self.ctrl.set_kinematics(kin98)
        self.z_prog, self.surface = z, surface
        t = math.radians(theta_deg)
        self.u = (0.0, -math.sin(t), math.cos(t))          # CA head, C = 0: u = (0, -sin A, cos A)
        c = math.radians(cs_tilt_deg)
        self.cs_z = (0.0, -math.sin(c), math.cos(c))
        self.comp = (0.0, 0.0, 0.0)
        self.out = Cycle3DOutput()

    def cycle(self, *commands, n=1):
        for k in range(n):
            z = self.z_prog + self.comp[2]
            inp = Cycle3DInput(programmed_z=self.z_prog, actual_z=z, sensor_distance=z - self.surface,
                               tool_direction=self.u, cs_z_axis=self.cs_z, kin98_active=True,
                               commands=list(commands) if k == 0 else [])
            self.result = self.ctrl.update(inp, self.out)
            self.comp = self.out.compensation
        return self.out


def test_acs_z_behaves_like_the_axis_variant():
    lp = Loop(params(), z=41.0, surface=40.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.ACS, direction="Z"))
    out = lp.cycle(n=600)
    assert out.delta == pytest.approx(0.5, abs=1e-6) and out.compensation == pytest.approx((0, 0, 0.5), abs=1e-6)
    assert out.core.hli_state == 4


@pytest.mark.parametrize("mode", [M.ECS, M.MCS, M.PCS])
def test_orthogonal_set_distance_shrinks_with_inclination_in_every_mode(mode):
    lp = Loop(params(), z=41.0, surface=40.0, theta_deg=30.0, cs_tilt_deg=30.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=2.0, mode=mode))
    out = lp.cycle(n=1500)
    z = lp.z_prog + lp.comp[2]
    assert z - lp.surface == pytest.approx(2.0 * math.cos(math.radians(30)), abs=1e-6)   # SET_DIST·cos θ
    assert out.orthogonal_set_distance == pytest.approx(2.0 * math.cos(math.radians(30)))
    assert out.inclination == pytest.approx(math.radians(30))
    o = out.core.offset
    if mode == M.MCS:
        assert out.compensation[:2] == (0.0, 0.0) and out.delta == pytest.approx(o)       # XY projection kept
    else:
        assert out.delta == pytest.approx(o / math.cos(math.radians(30)))               # δ·cos θ = o
        direction = lp.u if mode == M.ECS else lp.cs_z
        assert out.compensation == pytest.approx(tuple(out.delta * c for c in direction))


def test_kinematic_98_extension_scales_the_set_distance():
    lp = Loop(params(), z=41.0, surface=40.0, theta_deg=40.0)
    inp_ext = 1.2
    lp.ctrl.update(Cycle3DInput(programmed_z=41.0, actual_z=41.0, sensor_distance=1.0, tool_direction=lp.u,
                                extension=inp_ext, commands=[Command3D(Action.ON, const_dist=True, set_dist=1.0,
                                                                       mode=M.ECS)]), lp.out)
    assert lp.out.orthogonal_set_distance == pytest.approx(math.cos(math.radians(40)) * 1.2)


def test_mode_off_computes_but_does_not_superimpose():
    lp = Loop(params(), z=41.0, surface=40.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5))         # MODE default OFF
    out = lp.cycle(n=800)
    assert out.compensation == (0.0, 0.0, 0.0) and out.core.offset == pytest.approx(0.5, abs=1e-6)


def test_mode_change_while_active_is_51064_and_a_max_zero_is_315001():
    lp = Loop(params())
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.0, mode=M.MCS))
    out = lp.cycle(Command3D(mode=M.ECS, line=40))
    assert [(e.id, e.line) for e in out.events] == [(51064, 40)] and lp.ctrl.mode == M.MCS
    lp2 = Loop(params(a_max=0.0))
    out = lp2.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.0, mode=M.MCS, line=7))
    assert [e.id for e in out.events] == [315001] and out.core.hli_state == 0


def test_ecs_needs_kinematic_98():
    lp = Loop(params(), kin98=False)
    out = lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.0, mode=M.ECS, line=3))
    assert out.events and out.events[0].line == 3 and out.core.hli_state == 0


def test_core_errors_carry_their_3d_ids():
    lp = Loop(params(max_deviation=0.2))
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=2.0, mode=M.MCS))      # wants +1 mm
    ids = {e.id for _ in range(2000) for e in lp.cycle().events}
    assert 310017 in ids                                                          # 70331 in 3D


def test_filter_time_blends_activation_with_sin2():
    lp = Loop(params(), z=41.0, surface=40.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS, filter_time=100))
    weights = [lp.cycle().blend for _ in range(120)]
    assert weights[0] == pytest.approx(math.sin(math.pi / 2 * 2 / 100) ** 2)
    assert weights[48] == pytest.approx(0.5, abs=0.03) and weights[-1] == 1.0
    assert all(b >= a for a, b in zip(weights, weights[1:]))


def test_reset_and_program_end_keep_the_offset_static_and_ignore_the_sensor():
    for action in (Action.RESET, Action.PROGRAM_END):
        lp = Loop(params(), z=41.0, surface=40.0)
        lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS))
        before = lp.cycle(n=500).delta
        out = lp.cycle(Command3D(action))
        lp.surface = 39.0                                   # sensor changes no longer act
        after = [lp.cycle().delta for _ in range(200)]
        assert out.static and all(d == pytest.approx(before, abs=1e-9) for d in after)


def test_select_with_mode_off_warns_900023():
    lp = Loop(params())
    out = lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.0, line=30))
    assert [(e.id, e.severity, e.line) for e in out.events] == [(900023, "warning", 30)]
    out = Loop(params()).cycle(Command3D(Action.ON, const_dist=True, set_dist=1.0, mode=M.MCS))
    assert out.events == []


def test_without_fct_3d_dist_ctrl_every_command_is_51061():
    lp = Loop(params(fct_3d_dist_ctrl=False))
    out = lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.0, mode=M.MCS, line=5))
    assert [(e.id, e.line) for e in out.events] == [(51061, 5)] and out.core.hli_state == 0


def test_sensor_variable_change_while_active_is_310028():
    lp = Loop(params())
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.0, mode=M.MCS, sensor_var="V.E.SENSOR"))
    out = lp.cycle(Command3D(sensor_var="V.E.OTHER", line=9))
    assert [(e.id, e.line) for e in out.events] == [(310028, 9)]


def test_3d_object_writes_are_adopted_only_on_inactive_or_freeze_to_active():
    """FCT-M3 §12.6, DIST_CTRL[0]::kp / i_tn / d_tv and DIST_CTRL_PARAM[0]::v_max / a_max: 'The new values
    only become effective with the following transitions: from INACTIVE to ACTIVE, from FREEZE to ACTIVE'."""
    from distctrl.control.commands import ObjectWrite
    lp = Loop(params(kp=0.5), z=41.0, surface=40.0)
    lp.cycle(ObjectWrite("kp", 0.8))
    assert lp.ctrl.core.tuning.kp == 0.5                       # INACTIVE: pending
    out = lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.0, mode=M.ACS, direction="Z"))
    assert lp.ctrl.core.tuning.kp == 0.8 and out.core.kp == 0.8   # INACTIVE -> ACTIVE_CONST_DIST
    lp.cycle(ObjectWrite("kp", 0.3), n=50)
    assert lp.ctrl.core.tuning.kp == 0.8                       # ACTIVE: pending
    lp.cycle(Command3D(Action.FREEZE), n=5)
    assert lp.ctrl.core.tuning.kp == 0.8                       # FREEZE: still pending
    lp.cycle(Command3D(Action.ON, const_dist=True), n=2)
    assert lp.ctrl.core.tuning.kp == 0.3                       # FREEZE -> ACTIVE_CONST_DIST


@pytest.mark.parametrize("set_dist, tool_length, warned", [(80.0, 80.0, False), (1.0, 80.0, True),
                                                           (1.0, None, False)])
def test_const_dist_with_a_set_distance_other_than_the_tool_length_warns_900024(set_dist, tool_length, warned):
    """FCT-M3 §12.1.2 (Notice): 'The distance control set distance must be identical to the tool length
    for kinematic transformation' (else the transformation cannot plan within the dynamic limits). A
    CONST_DIST select with a kinematic transformation on (``tool_length`` given) and another SET_DIST
    warns 900024 at its line; the select goes on. Without a transformation there is nothing to match."""
    lp = Loop(params(), z=41.0, surface=40.0)
    lp.ctrl.set_kinematics(True, tool_length)
    out = lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=set_dist, mode=M.ECS, line=40))
    got = [(e.id, e.severity, e.line) for e in out.events]
    assert got == ([(900024, "warning", 40)] if warned else [])
    assert out.core.hli_state == 4
    if warned:
        assert "SET_DIST 1 mm" in out.events[0].message and "tool length 80 mm" in out.events[0].message


def test_filter_time_blends_deactivation_with_sin2_too():
    """PROG #DIST CTRL, FILTER_TIME: 'distance control activation and deactivation are smoothed by a
    sin² filter'. After OFF the superimposed compensation is the core's run-out times a weight falling
    as cos²(π/2·k/N) from 1 to 0 over N cycles: no jump at OFF, nothing left after N cycles."""
    lp = Loop(params(v_max=1.0, a_max=100.0), z=41.0, surface=40.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS, filter_time=100))
    before = lp.cycle(n=2000).delta
    assert before == pytest.approx(0.5, abs=1e-6)
    out = lp.cycle(Command3D(Action.OFF))
    weights, deltas = [out.blend], [out.delta]
    for _ in range(150):
        out = lp.cycle()
        weights.append(out.blend)
        deltas.append(out.delta)
    assert weights[0] == pytest.approx(math.cos(math.pi / 2 / 100) ** 2)
    assert weights[49] == pytest.approx(0.5, abs=0.02)
    assert all(b <= a for a, b in zip(weights[:100], weights[1:100]))
    assert abs(deltas[0] - before) < 0.01                       # continuous at OFF
    assert deltas[99] == 0.0 and deltas[-1] == 0.0
    assert max(abs(b - a) for a, b in zip(deltas, deltas[1:])) < 0.02
    # the core runs its offset out within v_max 1 mm/s: it still turns off while the blend is done
    assert out.core.hli_state in (3, 0)


def test_off_no_move_is_not_blended():
    lp = Loop(params(), z=41.0, surface=40.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS, filter_time=100))
    lp.cycle(n=600)
    out = lp.cycle(Command3D(Action.OFF, no_move=True))
    assert out.blend == 1.0


@pytest.mark.parametrize("axis", ["X", "Y"])
def test_direction_x_or_y_is_in_preparation_310015(axis):
    """FCT-M3 §12.2 DIRECTION: 'At present, DIRECTION = Z is supported (DIRECTION=X/Y are in
    preparation.)': 310015 'Function is not available' at the block, nothing selected."""
    lp = Loop(params(), z=41.0, surface=40.0)
    out = lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.0, mode=M.MCS, direction=axis, line=7))
    assert [(e.id, e.line) for e in out.events] == [(310015, 7)] and out.core.hli_state == 0


def test_dryrun_freeze_check_pos_and_ref_through_the_channel():
    """FCT-M3 §12.2: DRYRUN evaluates without tracking, FREEZE keeps the compensation, CHECK_POS checks
    the window, REF references the sensor; the shared core does each, the channel superimposes it."""
    lp = Loop(params(), z=41.0, surface=40.0)
    out = lp.cycle(Command3D(Action.REF))
    assert out.events == [] and lp.ctrl.core.state.referenced
    out = lp.cycle(Command3D(Action.DRYRUN, const_dist=True, set_dist=1.5, mode=M.MCS), n=200)
    assert out.core.hli_state == 6 and out.delta == 0.0 and out.core.target_deviation != 0.0
    lp.cycle(Command3D(Action.OFF), n=5)
    out = lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5), n=600)
    assert out.delta == pytest.approx(0.5, abs=1e-6)
    out = lp.cycle(Command3D(Action.FREEZE), n=5)
    lp.surface = 40.3                                    # the sheet rises: FREEZE does not follow
    out = lp.cycle(n=300)
    assert out.core.hli_state == 2 and out.delta == pytest.approx(0.5, abs=1e-6)
    out = lp.cycle(Command3D(Action.CHECK_POS))
    assert out.events == []                              # the reading is inside the sensor window


def _reported_is_applied(out) -> bool:
    """What the 3D control reports (the core's offset, DIST_CTRL[0]::m_actual_offset) is what it
    superimposes: δ = o / e_z along e (MCS / ACS: e = machine Z, e_z = 1), no FILTER_TIME blend."""
    return out.delta == out.core.offset and out.compensation[2] == out.delta


def test_program_end_during_the_run_out_of_off_lets_it_finish():
    """FCT-M3 §12.4.4: OFF (default) resets the offset to zero "on the fly". A program end that comes
    while the deselected control still runs its offset out must not freeze it (audit W1): the run-out
    completes to zero, the state reaches INACTIVE, and the offset reported is the one applied."""
    lp = Loop(params(v_max=10.0, a_max=100.0), z=41.0, surface=40.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS))
    assert lp.cycle(n=2000).delta == pytest.approx(0.5, abs=1e-6)
    lp.cycle(Command3D(Action.OFF), n=20)
    out = lp.cycle(Command3D(Action.PROGRAM_END, line=99))
    assert out.core.hli_state == 3 and out.events == []          # deselected: no 310021
    assert not out.static and _reported_is_applied(out)
    for _ in range(2000):
        out = lp.cycle()
        assert _reported_is_applied(out)
    assert out.core.hli_state == 0 and out.delta == 0.0 and out.compensation == (0.0, 0.0, 0.0)


def _within_limits(deltas, v_max, a_max, T=0.001, slack=1e-9):
    """Every step of the superimposed compensation keeps v_max (P-CHAN-00802) and a_max (P-CHAN-00803)."""
    v = [(b - a) / T for a, b in zip(deltas, deltas[1:])]
    assert max(abs(x) for x in v) <= v_max * (1 + 1e-9) + slack
    assert max(abs(b - a) for a, b in zip(v, v[1:])) <= a_max * T * (1 + 1e-9) + slack


def test_reselect_after_program_end_tracks_again():
    """Audit W2 (PROG #DIST CTRL SET_DIST: "In the event of reset or program end, the distance is reset,
    i.e. a new distance must be specified before distance control is reactivated"): after program end
    a select with a new SET_DIST is accepted and the control tracks the surface again (it was frozen
    until an OFF). A select without one is refused (310026)."""
    lp = Loop(params(), z=41.0, surface=40.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS))
    lp.cycle(n=500)
    out = lp.cycle(Command3D(Action.PROGRAM_END, line=50))
    assert [e.id for e in out.events] == [310021] and out.static
    lp.cycle(n=10)
    out = lp.cycle(Command3D(Action.ON, const_dist=True, line=60))                  # SET_DIST forgotten
    assert [(e.id, e.line) for e in out.events] == [(310026, 60)] and out.static

    lp = Loop(params(), z=41.0, surface=40.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS))
    lp.cycle(n=500)
    lp.cycle(Command3D(Action.PROGRAM_END))
    lp.surface = 40.3                        # ignored while the program has ended ...
    out = lp.cycle(n=100)
    assert out.delta == pytest.approx(0.5, abs=1e-6)
    out = lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS))
    assert out.events == []
    deltas = [out.delta] + [lp.cycle().delta for _ in range(1500)]
    out = lp.out
    assert not out.static and out.core.hli_state == 4
    assert deltas[-1] == pytest.approx(0.8, abs=1e-6)                 # ... and followed after the select
    _within_limits(deltas, 100.0, 20000.0)
    assert _reported_is_applied(out)


def test_reselect_after_reset_takes_the_retained_offset_over_bumplessly():
    """Audit W2 (FCT-M3 §12.4.4 reset: "The previous offset due to distance control is retained";
    P-CHAN-00802/00803): the next select starts from the retained compensation instead of dropping it
    in one cycle; the compensation then moves within v_max and a_max. Reported = applied throughout."""
    lp = Loop(params(), z=41.0, surface=40.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS))
    lp.cycle(n=500)
    out = lp.cycle(Command3D(Action.RESET))
    assert out.core.hli_state == 0 and out.static and out.events == []
    assert out.delta == pytest.approx(0.5, abs=1e-6) and _reported_is_applied(out)
    lp.surface = 40.3                                                 # ignored after the reset
    deltas = [out.delta] + [lp.cycle().delta for _ in range(50)]
    out = lp.cycle(Command3D(Action.ON, const_dist=True, mode=M.MCS, line=70))   # no SET_DIST: forgotten
    assert [(e.id, e.line) for e in out.events] == [(310026, 70)]
    lp.cycle(Command3D(Action.OFF), n=2000)                           # OFF runs the retained offset out
    assert lp.out.core.hli_state == 0 and lp.out.delta == 0.0 and not lp.out.static

    lp = Loop(params(), z=41.0, surface=40.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS))
    lp.cycle(n=500)
    lp.cycle(Command3D(Action.RESET))
    lp.surface = 40.3
    deltas = [lp.cycle().delta for _ in range(50)]
    assert deltas[-1] == pytest.approx(0.5, abs=1e-6)
    out = lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS))
    deltas.append(out.delta)
    assert out.delta == pytest.approx(0.5, abs=1e-6)                  # taken over: no drop to 0
    for _ in range(1500):
        out = lp.cycle()
        deltas.append(out.delta)
        assert _reported_is_applied(out)
    assert out.core.hli_state == 4 and deltas[-1] == pytest.approx(0.8, abs=1e-6)
    _within_limits(deltas, 100.0, 20000.0)


@pytest.mark.parametrize("no_move", [False, True])
def test_off_after_reset_runs_the_retained_offset_out_or_hands_it_to_the_channel(no_move):
    """After a reset the retained offset is the control's: OFF resets it to zero within the limits,
    OFF NO_MOVE hands it to the channel (absorbed_offset), as for a selected control (FCT-M3 §12.4.4)."""
    lp = Loop(params(v_max=10.0, a_max=100.0), z=41.0, surface=40.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS))
    lp.cycle(n=2000)
    lp.cycle(Command3D(Action.RESET), n=10)
    out = lp.cycle(Command3D(Action.OFF, no_move=no_move))
    if no_move:
        assert out.core.absorbed_offset == pytest.approx(0.5, abs=1e-6) and out.delta == 0.0
        assert out.core.hli_state == 0 and not out.static
        return
    deltas = [out.delta] + [lp.cycle().delta for _ in range(1000)]
    assert lp.out.core.hli_state == 0 and deltas[-1] == 0.0 and deltas[0] > 0.49
    _within_limits(deltas, 10.0, 100.0)


def test_reset_while_the_offset_moves_stops_it_within_the_limits():
    """FCT-M3 §12.4.4: "When the controller is reset, the program stops within the dynamic limits. The
    previous offset ... is retained": a moving offset brakes with a_max and stands; state INACTIVE."""
    lp = Loop(params(v_max=10.0, a_max=100.0), z=41.0, surface=40.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=3.0, mode=M.MCS))   # wants +2 mm
    deltas = [lp.cycle().delta for _ in range(150)]
    assert 9.9 < (deltas[-1] - deltas[-2]) / 0.001 <= 10.0 + 1e-9      # moving at v_max
    out = lp.cycle(Command3D(Action.RESET))
    assert out.core.hli_state == 0
    deltas.append(out.delta)
    for _ in range(300):
        out = lp.cycle()
        deltas.append(out.delta)
        assert _reported_is_applied(out)
    _within_limits(deltas, 10.0, 100.0)
    assert deltas[-1] == deltas[-2] and out.core.offset_velocity == 0.0 and out.core.hli_state == 0


def test_mode_cannot_change_while_a_reset_keeps_the_offset_51064():
    """The kept offset is orthogonal and superimposed along the MODE's direction: another MODE would
    move it sideways at once. While a reset keeps it, a MODE change is 51064 as while active."""
    lp = Loop(params(), z=41.0, surface=40.0, theta_deg=30.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS))
    lp.cycle(n=600)
    lp.cycle(Command3D(Action.RESET), n=5)
    out = lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.ECS, line=12))
    assert [(e.id, e.line) for e in out.events] == [(51064, 12)] and lp.ctrl.mode == M.MCS
    lp.cycle(Command3D(Action.OFF), n=1000)
    out = lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.ECS, line=13))
    assert out.events == [] and lp.ctrl.mode == M.ECS                 # after OFF it may change


@pytest.mark.parametrize("action", [Action.RESET, Action.PROGRAM_END])
@pytest.mark.parametrize("const_dist", [True, False])
def test_reset_and_program_end_forget_set_pos_and_set_dist(action, const_dist):
    """PROG #DIST CTRL SET_POS / SET_DIST: "In the event of reset or program end, the set position is
    reset, i.e. a new set position must be specified before distance control is reactivated" (310026)."""
    lp = Loop(params(), z=41.0, surface=40.0)
    value = {"set_dist": 1.5} if const_dist else {"set_pos": 40.0}
    lp.cycle(Command3D(Action.ON, const_dist=const_dist, mode=M.MCS, **value), n=300)
    lp.cycle(Command3D(action), n=5)
    out = lp.cycle(Command3D(Action.ON, const_dist=const_dist, line=8))
    assert [(e.id, e.line) for e in out.events] == [(310026, 8)]


def test_a_reset_with_nothing_to_keep_leaves_no_kept_offset_behind():
    """A reset while selected with the offset 0 and at rest keeps nothing: not static, and the next
    program may choose another MODE."""
    lp = Loop(params(), z=41.5, surface=40.0)                       # distance = SET_DIST: offset stays 0
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS), n=100)
    assert lp.out.core.offset == 0.0 and lp.out.core.offset_velocity == 0.0
    out = lp.cycle(Command3D(Action.RESET))
    assert out.core.hli_state == 0 and not out.static
    out = lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.ECS, line=4))
    assert out.events == [] and lp.ctrl.mode == M.ECS


@pytest.mark.parametrize("action", [Action.PROGRAM_END, Action.RESET], ids=["program_end", "reset"])
def test_a_filter_time_blend_at_program_end_or_reset_is_folded_into_the_kept_offset(action):
    """A FILTER_TIME blend-in that runs at program end / reset ends there: the compensation applied
    at that moment is kept (no jump), and from then on the reported offset is the applied one."""
    lp = Loop(params(), z=41.0, surface=40.0)
    lp.cycle(Command3D(Action.ON, const_dist=True, set_dist=1.5, mode=M.MCS, filter_time=400))
    before = lp.cycle(n=100)
    assert 0.0 < before.blend < 0.5 and before.delta != before.core.offset
    applied = before.delta
    out = lp.cycle(Command3D(action))
    assert abs(out.delta - applied) <= 100.0 * 0.001 + 1e-12 and out.blend == 1.0
    deltas = [applied, out.delta]
    for _ in range(300):
        out = lp.cycle()
        deltas.append(out.delta)
        assert _reported_is_applied(out) and out.blend == 1.0
    _within_limits(deltas, 100.0, 20000.0)
    assert deltas[-1] == deltas[-2]                                   # held
