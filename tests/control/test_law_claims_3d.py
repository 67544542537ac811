"""The documents' dynamic claims hold for the 3D (channel) variant too (FCT-M3 ch. 12, SPEC §11).

The channel controller runs the axis core on orthogonal quantities ("one law, not a copy"). So the
claims checked on the axis core (test_law_claims.py, test_filters.py) carry over exactly when, with
the tool upright and MODE=ACS DIRECTION=Z, the channel controller gives the axis core's offsets
cycle by cycle for every claim's configuration: the filters at the channel example list's values
(FCT-M3 §12.8.3), the D part (P-CHAN-00823), both encoders (P-CHAN-00810) and adaptive acceleration
(P-CHAN-00811 to 00814). The D part's claim is also measured on the 3D loop itself, inclined.
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np
import pytest

from distctrl.control import (Action, AxisDistanceController, Command, CycleInput, CycleOutput, FilterType,
                              SensorSource)
from distctrl.control.commands3d import Command3D, CompensationMode
from distctrl.control.controller3d import ChannelDistanceController, Cycle3DInput, Cycle3DOutput
from distctrl.params.channel import ChannelParameters

T = 0.001

# FCT-M3 §12.8.3, the channel parameterisation example (internal units: mm, mm/s, mm/s²)
EXAMPLE = dict(fct_3d_dist_ctrl=True, max_deviation=1000.0, v_max=10.0, a_max=100.0, max_act_value_change=1e4,
               max_pos=150.0, min_pos=-150.0, kp=0.3, i_tn=0.0, d_tv=0.01, n_cycles=20,
               filter_type=FilterType.MOVING_AVERAGE, smoothing_factor=0.05, kalman_sigma=2000.0,
               low_pass_filter_order=3, low_pass_filter_fg_f0=50.0, a_min=1.0, dist_error_a_min=0.04,
               dist_error_a_max=0.25)

CONFIGS = {
    "example list (MOVING_AVERAGE n 20, kp 0.3, D_TV 0.01)": {},
    "DEFAULT": dict(filter_type=FilterType.DEFAULT),
    "LOWPASS order 3 50 Hz": dict(filter_type=FilterType.LOWPASS),
    "KALMAN_MA sigma 2000": dict(filter_type=FilterType.KALMAN_MA),
    "EXPO_MEAN 0.05": dict(filter_type=FilterType.EXPO_MEAN),
    "KALMAN_EXPO": dict(filter_type=FilterType.KALMAN_EXPO),
    "D_TV 0 (no D part)": dict(d_tv=0.0),
    "I_TN 0.5": dict(i_tn=0.5, kp=0.5),
    "both encoders": dict(use_both_encoders=True, kp=0.6),
    "adaptive acceleration": dict(use_adaptive_acceleration=True, a_max=2000.0, v_max=50.0, kp=1.0),
    "lowering weighted": dict(v_weight_down=0.5, a_weight_down=0.5, a_max=2000.0, v_max=50.0),
}


class Plant:
    """A Z axis that follows its setpoint one cycle late with a first-order lag of 2 ms, over a surface
    with a 0.5 mm step and a little deterministic noise on the distance the PLC supplies."""

    def __init__(self, z: float = 41.0):
        self.actual = z
        self.setpoints = deque([z, z], maxlen=2)
        self.k = 0
        self.rng = np.random.default_rng(3)

    def surface(self) -> float:
        return 40.0 + (0.5 if self.k >= 400 else 0.0) + 0.2 * math.sin(2 * math.pi * 3.0 * self.k * T)

    def distance(self) -> float:
        return self.actual - self.surface() + 0.002 * self.rng.standard_normal()

    def follow(self, command: float) -> None:
        self.setpoints.append(command)
        self.actual += (self.setpoints[0] - self.actual) * T / 0.002
        self.k += 1


def axis_offsets(p: ChannelParameters, cycles: int) -> np.ndarray:
    ctrl = AxisDistanceController(p.to_axis_parameters(), T)
    plant = Plant()
    inp, out = CycleInput(), CycleOutput()
    inp.commands += [Command(sensor_source=SensorSource.VARIABLE), Command(Action.ON, const_dist=True, set_dist=1.0)]
    ys = []
    for _ in range(cycles):
        inp.programmed_position, inp.actual_position = 41.0, plant.actual
        inp.sensor_variable = plant.distance()
        ctrl.update(inp, out)
        assert not [e for e in out.events if e.severity == "error"], out.events
        plant.follow(out.command_position)
        ys.append(out.offset)
    return np.array(ys)


def channel_offsets(p: ChannelParameters, cycles: int) -> np.ndarray:
    ctrl = ChannelDistanceController(p, T)
    ctrl.set_kinematics(False)
    plant = Plant()
    out = Cycle3DOutput()
    cmds = [Command3D(Action.ON, const_dist=True, set_dist=1.0, mode=CompensationMode.ACS, direction="Z")]
    ys = []
    for _ in range(cycles):
        inp = Cycle3DInput(programmed_z=41.0, actual_z=plant.actual, sensor_distance=plant.distance(), commands=cmds)
        cmds = []
        ctrl.update(inp, out)
        assert not [e for e in out.events if e.severity == "error"], out.events
        plant.follow(41.0 + out.compensation[2])
        ys.append(out.compensation[2])
    return np.array(ys)


@pytest.mark.parametrize("name", list(CONFIGS))
def test_the_channel_controller_gives_the_axis_cores_offsets_cycle_by_cycle(name):
    p = ChannelParameters(**{**EXAMPLE, **CONFIGS[name]})
    a, c = axis_offsets(p, 1500), channel_offsets(p, 1500)
    assert np.ptp(a) > 0.1                    # it really tracked the step
    np.testing.assert_array_equal(c, a)


def inclined_step(kp: float, d_tv: float, lag: float) -> np.ndarray:
    """ECS with the tool inclined by 30° over a horizontal sheet (kinematic 98 active): CONST_DIST 1 mm,
    then the surface rises by 0.3 mm. The drive follows the compensation one cycle late with a lag
    ``lag`` s. Returns the distance error (mm) over the 2 s after the step."""
    p = ChannelParameters(**{**EXAMPLE, "filter_type": FilterType.DEFAULT, "kp": kp, "d_tv": d_tv,
                             "a_max": 5000.0, "v_max": 100.0})
    ctrl = ChannelDistanceController(p, T)
    ctrl.set_kinematics(True)
    u = (0.0, -math.sin(math.radians(30.0)), math.cos(math.radians(30.0)))
    z, surface, comp = 41.0, 40.0, 0.0
    setpoints = deque([0.0, 0.0], maxlen=2)
    out = Cycle3DOutput()
    cmds = [Command3D(Action.ON, const_dist=True, set_dist=1.0, mode=CompensationMode.ECS)]
    ys = []
    for k in range(3000):
        if k == 1000:
            surface = 40.3
        actual_z = z + comp
        ctrl.update(Cycle3DInput(programmed_z=z, actual_z=actual_z, sensor_distance=actual_z - surface,
                                 tool_direction=u, kin98_active=True, commands=cmds), out)
        cmds = []
        setpoints.append(out.compensation[2])
        comp += (setpoints[0] - comp) * T / lag
        ys.append(actual_z - surface)
    return np.array(ys[1000:]) - 1.0 * math.cos(math.radians(30.0))     # target: SET_DIST·cos θ


@pytest.mark.parametrize("kp, lag", [(0.2, 0.002), (0.2, 0.006), (0.3, 0.001), (0.3, 0.002)])
def test_the_d_part_damps_the_inclined_3d_loop_and_never_destabilises_it(kp, lag):
    """P-CHAN-00823: the D part 'stabilises controller behaviour and reduces oscillations'; the
    start value D_TV = 0.01 s, measured on the 3D loop itself: on loops that settle without it, the
    loop with D_TV 0.01 settles too and lifts past the target by no more (0.2/2 ms: 155 -> 111 µm)."""
    without, with_d = inclined_step(kp, 0.0, lag), inclined_step(kp, 0.01, lag)
    assert abs(without[-500:]).max() < 1e-3
    assert abs(with_d[-500:]).max() < 1e-3
    assert with_d.max() <= without.max() + 1e-6


def test_the_d_part_stabilises_an_inclined_3d_loop_that_oscillates_without_it():
    """kp 0.3 on a drive with a 4 ms lag oscillates in a ±0.2 mm limit cycle without the D part; with
    the documents' start value D_TV = 0.01 s it settles (FCT-M3 ch. 3, P-CHAN-00823)."""
    without, with_d = inclined_step(0.3, 0.0, 0.004), inclined_step(0.3, 0.01, 0.004)
    assert np.ptp(without[-500:]) > 0.2
    assert abs(with_d[-500:]).max() < 1e-3
