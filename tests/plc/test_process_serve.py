"""`distctrl serve` runs a scenario's [[process]] functions: the served machine is built from the
scenario, so they run in every cycle it steps (no server started here: the cycles are stepped by hand)."""
from pathlib import Path

from distctrl.ads.machine import ServedMachine
from distctrl.sim.scenario import load_scenario

EX = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def test_served_machine_runs_the_corner_lock():
    served = ServedMachine(load_scenario(EX / "process_corner.toml"), port=0, discovery_port=None)
    m = served.machine
    assert m.process_program is not None and m.publish_hli
    for _ in range(2300):                     # past the corner (2.01 .. 2.19 s)
        served.step()
    hold = m.process_program.holds["Z"]
    assert [t for _, t in hold.log] == [2, 4]             # FREEZE at the corner, ON after it
    assert m.hli["Z"].state_r.actual_state == 4           # ACTIVE_CONST_DIST again
    assert m.hli["Z"].state_r.command_source == 1         # re-activated by the PLC
    assert m.true_distance > 1.2


# ------------------------------------------------------------------ touch-off and collision retract (h16-touch)
def test_served_machine_runs_the_touch_off():
    served = ServedMachine(load_scenario(EX / "process_touch.toml"), port=0, discovery_port=None)
    m = served.machine
    f = m.process_program.function("touch_off", "Z")
    for _ in range(1000):                     # the touch-off hands back at 0.873 s
        served.step()
    (res,) = f.log
    assert abs(res["surface"] - 33.2) < 0.05 and res["attempts"] == 1
    assert m.variables["V.E.TOUCH_OFF"] == 0.0 and m.nc.running and m.events == []


def test_served_machine_runs_the_collision_retract():
    served = ServedMachine(load_scenario(EX / "process_collision.toml"), port=0, discovery_port=None)
    m = served.machine
    f = m.process_program.function("collision_retract", "Z")
    for _ in range(1000):                     # contact at 0.889 s, the retract takes 32 ms
        served.step()
    (c,) = f.log
    assert abs(c["retract"] - 5.0) < 0.15 and c["line"] == 7
    assert [ev.id for _, ev in m.events] == [900053] and m.nc.aborted
    assert m.hli["Z"].state_r.actual_state == 0
