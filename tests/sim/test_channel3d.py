"""The kinematic / 3D part of the channel (distctrl/sim/channel3d.py) is a part the Machine owns; the
machine's channel protocol (what the NC interpreter calls) and its trace values are unchanged."""
from __future__ import annotations

from pathlib import Path

from distctrl.sim.channel3d import KinematicChannel
from distctrl.sim.machine import Machine
from distctrl.sim.runner import load_program
from distctrl.sim.scenario import load_scenario

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def machine(name: str) -> Machine:
    sc = load_scenario(SCN / f"{name}.toml")
    return Machine(sc, load_program(sc))


def test_a_3d_channel_runs_the_cycle_of_its_kinematic_part():
    m = machine("app_90")
    assert isinstance(m.channel3d, KinematicChannel) and m.kinematic_path
    assert m.step == m.channel3d.step
    assert (m.ch3d, m.in3d, m.out3d) == (m.channel3d.ch3d, m.channel3d.in3d, m.channel3d.out3d)
    for _ in range(200):
        m.step()
    assert m.cycle == 200 and m.channel3d_values() is not None
    assert m.true_clamp != (0.0, 0.0, 0.0) and m.prog_values == [m.interp.position[n] for n in m.axis_names]


def test_the_axis_variant_keeps_its_own_cycle_and_the_channel_protocol_is_the_machines():
    m = machine("const_dist_sheet")
    assert not m.kinematic_path and m.step == m._step_axes and m.ch3d is None
    assert m.channel3d_values() is None
    for name in ("start_linear", "start_dwell", "motion_done", "dist_ctrl", "dist_ctrl_done", "dist_ctrl_3d",
                 "dist_ctrl_3d_done", "kinematics", "variables_assigned", "positions", "variables"):
        assert hasattr(m, name), name
