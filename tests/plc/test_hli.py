"""The HLI DistanceControl control unit (HLI DistanceControl, FCT-M3 §8 and ch. 10, SPEC §9) driving a real
AxisDistanceController."""
from __future__ import annotations

import pytest

from distctrl.control import (Action, AxisDistanceController, Command, CommandSource, CycleInput, CycleOutput,
                              HliState)
from distctrl.base.states import HliTransition
from distctrl.params import AxisParameters
from distctrl.plc import (ChannelDistanceStatus, DistanceControlUnit, HliCyclicCommand, HliDistanceControlCommand,
                          HliDistanceControlState, SemaphoreBusyError, transition_number)

INT32_MAX, INT32_MIN = 2**31 - 1, -2**31


class Axis:
    """One axis in the GEO cycle: PLC unit consumed before the controller update, published after.
    The drive follows the command one cycle late; the probe reads s = surface - actual (mm)."""

    def __init__(self, p: float = 41.0, surface: float = 40.0, **param_changes):
        kw = dict(enabled=True, v_max=20.0, a_max=2000.0, max_act_value_change=1e5, max_pos=50.0, min_pos=-50.0,
                  optimized_scheduling=True)
        kw.update(param_changes)
        self.params = AxisParameters(**kw)
        self.ctrl = AxisDistanceController(self.params, 0.001)
        self.unit = DistanceControlUnit(1)
        self.p, self.surface, self.actual = p, surface, p
        self.sensor_zero = 0.0            # unknown zero of a non-absolute sensor (mm), removed by REF
        self.inp, self.out = CycleInput(), CycleOutput()
        self.events = []
        self.semaphore_after_prepare = []

    def cycle(self, *nc_commands, n: int = 1) -> CycleOutput:
        for k in range(n):
            inp = self.inp
            inp.programmed_position, inp.actual_position = self.p, self.actual
            inp.sensor_increments = (self.surface - self.actual + self.sensor_zero) / self.params.sensor_mm_per_increment
            if k == 0:
                inp.commands.extend(nc_commands)
            self.unit.prepare(inp)
            self.semaphore_after_prepare.append(self.unit.command_semaphore_rw)
            self.ctrl.update(inp, self.out)
            self.unit.publish(self.out)
            self.events += self.out.events
            self.actual = self.out.command_position
        return self.out

    def until(self, predicate, limit: int = 20000) -> CycleOutput:
        for _ in range(limit):
            out = self.cycle()
            if predicate(out):
                return out
        raise AssertionError("condition not reached")

    def plc(self, transition, position_mm: float = 0.0) -> CycleOutput:
        """The PLC commands and the CNC takes it in the next cycle."""
        assert self.unit.plc_command(transition, position_mm)
        out = self.cycle()
        assert self.unit.command_semaphore_rw is False
        return out

    @property
    def state_r(self) -> HliDistanceControlState:
        return self.unit.state_r


# ----------------------------------------------------------------------------- handshake

def test_defaults_and_types():
    unit = DistanceControlUnit()
    assert unit.command_w == HliDistanceControlCommand(0, 0)
    assert unit.enable_w is False and unit.command_semaphore_rw is False
    assert unit.state_r == HliDistanceControlState(0, 0, 0, 0, 0)
    assert unit.cyclic == HliCyclicCommand(0, 0, False, False)
    assert unit.consume() is None and unit.cyclic_inputs() == (None, None)
    assert ChannelDistanceStatus() == ChannelDistanceStatus(virt_tool_length_r=0, inclination_r=0)


def test_semaphore_handshake():
    unit = DistanceControlUnit()
    assert unit.plc_command("ON", 40.0) is True
    assert unit.command_w == HliDistanceControlCommand(1, 400000)      # 0.1 µm
    assert unit.enable_w and unit.command_semaphore_rw
    # while the semaphore is TRUE the PLC cannot update the commanded values
    assert unit.plc_command("FREEZE") is False
    assert unit.plc_command(HliTransition.OFF, 12.0) is False
    with pytest.raises(SemaphoreBusyError):
        unit.write_command(transition=2)
    assert unit.command_w == HliDistanceControlCommand(1, 400000)
    cmd = unit.consume()
    assert cmd == Command(Action.ON, set_pos=40.0, source=CommandSource.PLC)
    assert unit.command_semaphore_rw is False                            # cleared by the CNC
    assert unit.consume() is None                                        # consumed once only
    # now the PLC may write again
    assert unit.plc_command("FREEZE") is True
    assert unit.consume() == Command(Action.FREEZE, source=CommandSource.PLC)


def test_consumed_only_when_enable_and_semaphore_are_true():
    unit = DistanceControlUnit()
    unit.write_command(transition=1, position=123)
    assert unit.consume() is None                                        # neither set
    unit.enable_w = True
    assert unit.consume() is None                                        # semaphore FALSE
    unit.enable_w, unit.command_semaphore_rw = False, True
    assert unit.consume() is None and unit.command_semaphore_rw is True  # not taken: stays TRUE
    unit.enable_w = True
    assert unit.consume() == Command(Action.ON, set_pos=123e-4, source=CommandSource.PLC)
    assert unit.command_semaphore_rw is False and unit.consumed == 1


def test_semaphore_is_cleared_in_the_cycle_the_command_is_taken():
    ax = Axis(p=40.0, surface=40.0)
    ax.cycle(n=3)
    assert ax.unit.plc_command("ON", 40.0)
    out = ax.cycle()
    assert ax.semaphore_after_prepare[-1] is False                      # cleared before the update
    assert out.hli_state == HliState.ACTIVE and ax.state_r.actual_state == 1


def test_values_written_while_the_semaphore_is_true_are_not_taken():
    ax = Axis(p=40.0, surface=40.0)
    ax.unit.enable_w = True
    assert ax.unit.plc_command("ON", 40.0)
    assert not ax.unit.plc_command("ON", 45.0)                          # refused, not written
    out = ax.cycle()
    assert out.set_pos == 40.0


def test_invalid_transition_is_consumed_and_recorded():
    ax = Axis()
    assert ax.unit.plc_command(7, 1.0)
    out = ax.cycle()
    assert ax.unit.command_semaphore_rw is False
    assert [(r.transition, r.position) for r in ax.unit.rejected] == [(7, 10000)]
    assert out.hli_state == HliState.INACTIVE and out.events == []
    with pytest.raises(ValueError):
        ax.unit.plc_command("JUMP")
    with pytest.raises(ValueError):
        ax.unit.plc_command(-1)
    with pytest.raises(ValueError):
        ax.unit.plc_command("ON", float("nan"))


def test_transition_names():
    assert [transition_number(n) for n in ("OFF", "on", "HLI_DIST_CTRL_FREEZE", "REF", "ON_CONST_DIST", "DRYRUN",
                                           "CONST_DIST")] == list(range(7))
    assert transition_number(6) == 6


def test_command_position_saturates_to_dint():
    unit = DistanceControlUnit()
    unit.plc_command("ON", 1e6)                                         # 1 km in 0.1 µm > DINT_MAX
    assert unit.command_w.position == INT32_MAX
    unit.consume()
    unit.plc_command("REF", -0.00005)                                   # half a unit: away from zero
    assert unit.command_w.position == -1


def test_state_r_units_and_saturation():
    unit = DistanceControlUnit()
    out = CycleOutput(hli_state=4, surface_position=40.12345, offset=-0.00016, command_source=1,
                      measured_distance=1.5)
    unit.publish(out)
    assert unit.state_r == HliDistanceControlState(actual_state=4, actual_position=401235, actual_offset=-2,
                                                   command_source=1, actual_distance=15000)
    unit.publish(CycleOutput(surface_position=1e9, offset=-1e9))
    assert unit.state_r.actual_position == INT32_MAX and unit.state_r.actual_offset == INT32_MIN


# ----------------------------------------------------------------------------- the seven transitions

def test_all_seven_transitions_through_the_unit():
    """FCT-M3 ch. 10: reference the sensor, ON with position 400000, surface change, FREEZE,
    then the remaining transitions, OFF -> TURNING_OFF -> INACTIVE."""
    ax = Axis(p=41.0, surface=40.0)                   # tool 1 mm above the surface: s = -1 mm
    ax.sensor_zero = 0.3                              # ... but the sensor is not referenced yet
    ax.cycle(n=5)
    assert ax.state_r.actual_distance == 7000
    # REF (3): the position is the reference position of the workpiece surface (REF_POS, HLI
    # DistanceControl, SPEC §2): the surface is at 40 mm, so the reading becomes -1 mm (d = 1 mm)
    out = ax.plc(3, 40.0)
    assert out.hli_state == HliState.INACTIVE and ax.state_r.actual_state == 0
    ax.cycle()
    assert ax.state_r.actual_distance == 10000 and ax.state_r.actual_position == 400000
    # ON (1) with position 400000 = 40 mm
    out = ax.plc(1, 40.0)
    assert ax.state_r.actual_state == 1 and ax.state_r.command_source == 1
    assert out.set_pos == 40.0
    ax.surface = 40.2                                 # "surface offset": the axis follows
    ax.cycle(n=500)
    assert ax.state_r.actual_offset == 2000 and ax.state_r.actual_position == 402000
    assert ax.state_r.actual_distance == 10000
    # FREEZE (2): a sensor change has no influence
    out = ax.plc(2)
    assert ax.state_r.actual_state == 2
    ax.surface = 40.5
    ax.cycle(n=300)
    assert ax.state_r.actual_offset == 2000 and ax.state_r.actual_distance == 7000
    # ON_CONST_DIST (4) with position = distance 1.5 mm
    out = ax.plc(4, 1.5)
    assert ax.state_r.actual_state == 4 and out.set_distance == 1.5
    ax.cycle(n=600)
    assert ax.state_r.actual_distance == 15000 and ax.state_r.actual_offset == 10000
    # DRYRUN (5) with a surface position: evaluation only, the offset stays
    out = ax.plc(5, 40.5)
    assert ax.state_r.actual_state == 7 and out.set_pos == 40.5
    ax.surface = 40.4
    ax.cycle(n=100)
    assert ax.state_r.actual_offset == 10000
    # CONST_DIST (6): dry run with distance
    out = ax.plc(6, 2.0)
    assert ax.state_r.actual_state == 6 and out.set_distance == 2.0
    ax.cycle(n=100)
    assert ax.state_r.actual_offset == 10000
    # OFF (0): TURNING_OFF, the offset runs out, INACTIVE
    ax.plc(0)
    assert ax.state_r.actual_state == 3
    seen = set()
    ax.until(lambda o: seen.add(ax.state_r.actual_state) or o.hli_state == HliState.INACTIVE)
    assert seen <= {3, 0}
    assert ax.state_r.actual_state == 0 and ax.state_r.actual_offset == 0
    assert [e.id for e in ax.events] == [] and ax.unit.rejected == []
    assert ax.unit.consumed == 7


def test_cyclic_distance_is_re_read_every_cycle_while_plc_commanded():
    ax = Axis(p=41.0, surface=40.0)
    ax.plc("ON_CONST_DIST", 1.0)
    assert ax.state_r.actual_state == 4
    for k in range(200):
        d = 1.0 + 0.001 * k
        ax.unit.plc_cyclic(distance_mm=d)
        assert ax.unit.cyclic.D_Distance == round(d * 1e4) and ax.unit.cyclic.valid_distance
        out = ax.cycle()
        assert out.set_distance == pytest.approx(round(d * 1e4) * 1e-4, abs=1e-15)
    ax.unit.plc_cyclic_stop()
    last = out.set_distance
    out = ax.cycle(n=600)
    assert out.set_distance == last                                   # the last value stays
    assert ax.state_r.actual_distance == round(last * 1e4)


def test_cyclic_position_is_re_read_every_cycle_in_set_pos_mode():
    ax = Axis(p=41.0, surface=40.0)
    ax.plc("ON", 40.0)
    for k in range(50):
        ax.unit.plc_cyclic(position_mm=40.0 - 0.002 * k)
        out = ax.cycle()
        assert out.set_pos == pytest.approx(40.0 - 0.002 * k, abs=1e-12)
    assert ax.unit.cyclic_inputs()[1] is None                          # D_Distance never written


def test_cyclic_values_are_ignored_while_the_nc_owns_distance_control():
    ax = Axis(p=41.0, surface=40.0)
    out = ax.cycle(Command(Action.ON, const_dist=True, set_dist=1.0))
    ax.unit.plc_cyclic(distance_mm=2.0)
    out = ax.cycle(n=10)
    assert out.set_distance == 1.0 and ax.state_r.command_source == 0


# ----------------------------------------------------------------------------- NC / PLC

def test_nc_and_plc_both_command_and_state_r_shows_the_last_source():
    """HLI DistanceControl / FCT-M3 §8.1: state_r shows the active command source (0 = NC, 1 = PLC);
    NC and PLC may both command, the last accepted command sets it (SPEC §8)."""
    ax = Axis(p=40.0, surface=40.0)
    out = ax.cycle(Command(Action.ON, set_pos=40.0))                   # NC selects
    assert ax.state_r.actual_state == 1 and ax.state_r.command_source == 0
    out = ax.plc("FREEZE")                                             # the PLC freezes
    assert out.events == [] and out.hli_state == HliState.FREEZE
    ax.cycle()
    assert ax.state_r.actual_state == 2 and ax.state_r.command_source == 1
    ax.cycle(Command(Action.ON, set_pos=40.0, line=20))                # the NC re-activates
    ax.cycle()
    assert ax.state_r.actual_state == 1 and ax.state_r.command_source == 0
    ax.plc("OFF")                                                      # and the PLC switches off
    ax.until(lambda o: o.hli_state == HliState.INACTIVE)
    assert ax.state_r.actual_state == 0 and ax.state_r.command_source == 1


def test_ref_position_is_the_reference_position_of_the_workpiece_surface():
    """HLI DistanceControl: HLI_DIST_CTRL_REF, position = 'Reference position of the workpiece surface
    (REF_POS)': afterwards state_r.actual_position (the measured surface) is REF_POS."""
    ax = Axis(p=41.0, surface=40.0)
    ax.sensor_zero = 0.3                              # the sensor is not referenced: it reads 0.3 mm off
    ax.cycle(n=3)
    assert ax.state_r.actual_position == 403000
    ax.plc(3, 40.0)                                   # REF: the surface is at 40 mm
    ax.cycle()
    assert ax.state_r.actual_position == 400000 and ax.state_r.actual_distance == 10000
    ax.plc(3, 38.5)                                   # referencing to 38.5 mm says: 2.5 mm above it
    ax.cycle()
    assert ax.state_r.actual_position == 385000 and ax.state_r.actual_distance == 25000


def test_cyclic_d_position_is_the_ref_pos_when_ref_is_commanded_through_the_hli():
    """FCT-M3 §8.2 / TF5200 §9.2, CyclicCommand.D_Position: 'HLI_DIST_CTRL_REF: Reference position of
    the workpiece surface (REF_POS)'. With the cyclic position valid, the REF the PLC commands takes
    D_Position as REF_POS (not command_w.position); without it, command_w.position (test above)."""
    ax = Axis(p=41.0, surface=40.0)
    ax.sensor_zero = 0.3                              # not referenced: the measured surface is 40.3 mm
    ax.cycle(n=3)
    assert ax.state_r.actual_position == 403000
    ax.unit.plc_cyclic(position_mm=39.25)             # the PLC specifies the surface cyclically ...
    ax.plc("REF", 12.0)                               # ... and commands REF (command_w.position 12 mm)
    ax.cycle()
    assert ax.state_r.actual_position == 392500 and ax.state_r.actual_distance == 17500
    assert ax.state_r.actual_state == 0 and ax.events == []
    # the reference holds: the cyclic value is REF_POS only of the REF it was valid with
    ax.unit.plc_cyclic(position_mm=30.0)
    ax.cycle(n=5)
    assert ax.state_r.actual_position == 392500
    # the PLC stops the cyclic specification: the next REF takes command_w.position again
    ax.unit.plc_cyclic_stop()
    ax.plc("REF", 40.0)
    ax.cycle()
    assert ax.state_r.actual_position == 400000


def test_an_nc_ref_ignores_the_cyclic_position():
    """NC REF has no value and references 'sensor zero' (SPEC §2); the PLC's cyclic values do not
    apply to commands of the NC."""
    ax = Axis(p=41.0, surface=40.0)
    ax.sensor_zero = 0.3
    ax.unit.plc_cyclic(position_mm=39.25)
    ax.cycle(Command(Action.REF), n=2)
    assert ax.state_r.actual_position == 410000 and ax.state_r.actual_distance == 0   # s = 0: surface = a


def test_reset_acts_whoever_owns():
    ax = Axis(p=40.0, surface=40.0)
    ax.plc("ON", 40.0)
    out = ax.cycle(Command(Action.RESET))
    assert out.hli_state == HliState.INACTIVE and ax.state_r.actual_state == 0


def test_positions_are_entered_only_when_distance_control_is_on_in_the_axis_parameters():
    """HLI DistanceControl, state_r.actual_position / .actual_offset, "Characteristics": the data item
    is entered only if distance control is activated in the axis parameters (P-AXIS-00328)."""
    off = Axis(enabled=False)
    off.unit.distance_control_on = False
    off.cycle(n=5)
    assert (off.unit.state_r.actual_position, off.unit.state_r.actual_offset) == (0, 0)
    assert off.unit.state_r.actual_distance == 0
    assert off.unit.state_r.actual_state == 0
    on = Axis()
    on.cycle(n=5)
    assert on.unit.state_r.actual_position == 400000


def test_the_virtual_machine_tells_each_unit_whether_distance_control_is_on():
    from pathlib import Path

    from distctrl.sim.machine import Machine
    from distctrl.sim.scenario import scenario_from_dict
    scn = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
    sc = scenario_from_dict({"name": "t", "program_text": "N10 M30", "duration": 0.01,
                             "axes": {"X": {}, "Z": {"params": "z_probe.lis", "start": 40.0}},
                             "surface": {"base": 40.0}, "sensor": {"axis": "Z", "kind": "encoder"}}, base_dir=scn)
    vm = Machine(sc)
    assert vm.hli["Z"].distance_control_on is True
    assert vm.hli["X"].distance_control_on is False


@pytest.mark.parametrize("transition, position_mm", [(1, 40.0), (4, 1.0), (5, 40.0), (6, 1.0)])
def test_a_sensor_that_is_not_absolute_must_be_referenced_before_each_select(transition, position_mm):
    """HLI DistanceControl, transitions 1, 4, 5, 6: 'If no absolute encoder is used, distance control must
    first be referenced' (SPEC §2). Refused with 900008 like any invalid transition (ERROR, left through
    OFF), accepted after REF (3)."""
    ax = Axis(p=41.0, surface=40.0, sensor_absolute=False)
    ax.plc(transition, position_mm)
    assert ax.state_r.actual_state == 5 and ax.state_r.actual_offset == 0
    assert [e.id for e in ax.events] == [900008]
    ax.plc(0)
    ax.until(lambda o: o.hli_state == HliState.INACTIVE)
    ax.plc(3, 40.0)
    ax.plc(transition, position_mm)
    assert ax.state_r.actual_state == {1: 1, 4: 4, 5: 7, 6: 6}[transition]
    assert [e.id for e in ax.events] == [900008]


@pytest.mark.parametrize("surface", [40.2, 39.7])
def test_in_the_stationary_state_the_offset_is_the_distance_between_surface_and_set_pos(surface):
    """HLI DistanceControl, state_r.actual_offset: in the stationary state (constant surface, offset run
    out) |actual_offset| = |SET_POS - actual_position|. distctrl's sign follows the physics (SPEC §3): the
    axis moved up (+) when the real surface is above SET_POS, so actual_offset = actual_position - SET_POS."""
    ax = Axis(p=41.0, surface=40.0)
    ax.plc(1, 40.0)
    ax.surface = surface
    ax.cycle(n=800)
    s = ax.state_r
    assert s.actual_position == round(surface * 1e4)
    assert s.actual_offset == s.actual_position - 400000
    # the offset 'by which the axis was moved' (HLI DistanceControl's first sentence, FCT-M3 §2):
    # command position - programmed position, with the same sign
    assert s.actual_offset == round((ax.out.command_position - ax.p) * 1e4)
    assert s.actual_offset == -(400000 - s.actual_position)       # the printed formula, negated
