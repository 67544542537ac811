"""Lift between cuts (issue 16): the CNC's lift motion, the PLC's FREEZE interlock, the scenario table,
and the example plate end to end through `distctrl run`."""
import csv
import json
import math
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from distctrl.control import CycleOutput, HliState
from distctrl.plc.process import LIFT_DEFAULTS, Lift, ProcessProgram
from distctrl.plc.process.channel import MOTION_LINEAR, MOTION_NONE, MOTION_RAPID, ChannelPathStatus
from distctrl.sim import run
from distctrl.sim.interpolator import AxisLimits, Interpolator
from distctrl.sim.lift import LiftMotion, attach_lift
from distctrl.sim.scenario import ScenarioError, load_scenario, scenario_from_text

EX = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
T = 0.001
V_Z, A_Z = 200.0, 5000.0


def _attached(f):
    """A lift function with its CNC part, as the machine that hosts it attaches it."""
    attach_lift(f)
    return f


def _machine(state=HliState.INACTIVE):
    interp = Interpolator(T, {"X": AxisLimits(500.0, 3000.0), "Y": AxisLimits(500.0, 3000.0),
                              "Z": AxisLimits(V_Z, A_Z)})
    out = CycleOutput()
    out.hli_state = int(state)
    return SimpleNamespace(interp=interp, outputs={"Z": out}, cycle=0, nc=None, channel_override=1.0)


def _run_block(m, motion, target, max_cycles=20000):
    """Start a G0 to ``target`` and step interpolator and lift until both are at rest; the lift offsets."""
    m.interp.start_linear(target, None)
    offsets, path_end = [], None
    for k in range(max_cycles):
        m.interp.step()
        motion.step(m)
        m.cycle += 1
        offsets.append(motion.offset)
        if path_end is None and m.interp.done:
            path_end = k
        if m.interp.done and not motion.busy:
            break
    return np.array(offsets), path_end


def _within_limits(z, v_max, a_max):
    v = np.diff(np.concatenate(([0.0], z, [0.0]))) / T
    a = np.diff(v) / T
    return np.abs(v).max() <= v_max * (1 + 1e-9) and np.abs(a).max() <= a_max * (1 + 1e-9)


# ---------------------------------------------------------------------------- the CNC part
def test_a_long_rapid_lifts_to_the_height_and_lands_when_the_path_stops():
    m = _machine()
    lm = LiftMotion("Z", T, 5.0, V_Z, A_Z)
    z, path_end = _run_block(m, lm, {"X": 200.0})
    assert z.max() == pytest.approx(5.0)                   # the full height
    assert _within_limits(z, V_Z, A_Z)                     # the Z axis's v_max, a_max
    assert z[path_end] == 0.0 and len(z) - 1 <= path_end   # landed no later than the path stopped
    assert lm.peaks == [pytest.approx(5.0)] and not lm.lift_active
    # it rose at once: 10 cycles into the block the head is already up while X moves
    assert z[10] > 0.0


def test_a_short_rapid_gets_a_lower_lift_and_costs_no_time():
    m = _machine()
    lm = LiftMotion("Z", T, 5.0, V_Z, A_Z)
    z, path_end = _run_block(m, lm, {"X": 8.0})
    assert 0.0 < z.max() < 5.0                             # what fits into the rapid
    assert z[path_end] == 0.0 and len(z) - 1 == path_end   # landed when the path stopped
    assert _within_limits(z, V_Z, A_Z)


def test_settle_time_lands_earlier():
    m = _machine()
    lm = LiftMotion("Z", T, 5.0, V_Z, A_Z, settle_time=0.05)
    z, path_end = _run_block(m, lm, {"X": 200.0})
    landed = [c for c, e in lm.log if e == "landed"][0]
    assert path_end - landed >= 0.05 / T - 3              # about 50 ms before the path stops
    assert np.all(z[landed:] == 0.0)


def test_lift_waits_for_distance_control_to_stop_tracking():
    m = _machine(HliState.ACTIVE_CONST_DIST)
    lm = LiftMotion("Z", T, 5.0, V_Z, A_Z)
    m.interp.start_linear({"X": 200.0}, None)
    for _ in range(5):
        m.interp.step()
        lm.step(m)
    assert lm.phase == "WAITING" and lm.lift_active and lm.offset == 0.0   # the PLC must FREEZE first
    m.outputs["Z"].hli_state = int(HliState.FREEZE)
    m.interp.step()
    lm.step(m)
    assert lm.phase == "UP" and lm.offset > 0.0


def test_lift_waits_for_the_offset_to_stand():
    m = _machine(HliState.TURNING_OFF)                  # an OFF still runs its offset out
    m.outputs["Z"].offset_velocity = -10.0
    lm = LiftMotion("Z", T, 5.0, V_Z, A_Z)
    m.interp.start_linear({"X": 200.0}, None)
    for _ in range(20):
        m.interp.step()
        lm.step(m)
        m.cycle += 1
    assert lm.phase == "WAITING" and lm.offset == 0.0   # the sum would exceed the axis's limits
    m.outputs["Z"].hli_state = int(HliState.INACTIVE)
    m.outputs["Z"].offset_velocity = 0.0
    while not m.interp.done or lm.busy:
        m.interp.step()
        lm.step(m)
        m.cycle += 1
    assert [e for _, e in lm.log] == ["start", "down", "landed"]
    assert lm.log[0][0] == 20 and lm.peaks == [pytest.approx(5.0)]


@pytest.mark.parametrize("target, kwargs", [({"X": 50.0, "Z": 3.0}, {}),          # the G0 moves the lift axis
                                            ({"X": 5.0}, {"min_distance": 10.0}),  # shorter than min_distance
                                            ({"X": 0.5}, {"settle_time": 0.05})])   # 26 ms: no time to lift
def test_suppressed_lifts(target, kwargs):
    m = _machine()
    lm = LiftMotion("Z", T, 5.0, V_Z, A_Z, **kwargs)
    z, _ = _run_block(m, lm, target)
    assert np.all(z == 0.0) and lm.lift_suppressed and lm.log[0][1] == "suppressed"


def test_no_lift_on_g1_or_while_switched_off():
    m = _machine()
    lm = LiftMotion("Z", T, 5.0, V_Z, A_Z)
    m.interp.start_linear({"X": 50.0}, 3000.0)
    for _ in range(2000):
        m.interp.step()
        lm.step(m)
    assert lm.offset == 0.0 and not lm.log
    off = _attached(Lift("Z", T, V_Z, A_Z, enabled=False))
    z, _ = _run_block(_machine(), off.motion, {"X": 100.0})
    assert np.all(z == 0.0) and not off.motion.log


def test_switched_off_during_a_lift_it_keeps_the_freeze_until_the_head_has_landed():
    f = _attached(Lift("Z", T, V_Z, A_Z))
    prog = ProcessProgram([f])
    hold = prog.holds["Z"]
    m = _machine()
    m.hli = {"Z": _Unit(state_r=SimpleNamespace(actual_state=0))}
    m.interp.start_linear({"X": 200.0}, None)
    for _ in range(50):
        m.interp.step()
        f.motion.step(m)
    assert f.motion.offset > 0.0
    f.enabled = False                    # as ProcessProgram.set_enabled does: switch, reset, withdraw
    f.reset()
    hold.withdraw(f.name)
    assert f.enabled and not f.switched_on          # still running: the head is up
    requested = []
    while not m.interp.done or f.motion.busy:
        if f.enabled:
            f.step(m, m.cycle)
        requested.append((f.motion.lift_active, "lift" in hold._requested_now))
        hold._requested_now.clear()
        m.interp.step()
        f.motion.step(m)
    assert all(r for active, r in requested if active)   # the hold requested while the head was up
    assert f.motion.offset == 0.0 and not f.enabled      # landed, then off
    m.interp.start_linear({"X": 0.0}, None)               # the next rapid is not lifted
    for _ in range(300):
        m.interp.step()
        f.motion.step(m)
    assert f.motion.offset == 0.0


def test_set_enabled_off_then_on_during_a_lift_switches_it_back_on():
    # enabled reads true while the head is up: the program must compare with the switch itself
    f = _attached(Lift("Z", T, V_Z, A_Z))
    prog = ProcessProgram([f])
    m = _machine()
    m.hli = {"Z": _Unit(state_r=SimpleNamespace(actual_state=0))}
    m.interp.start_linear({"X": 200.0}, None)
    for _ in range(50):
        m.interp.step()
        f.motion.step(m)
    assert f.motion.lift_active
    prog.set_enabled("lift", "Z", False)
    assert not f.switched_on
    prog.set_enabled("lift", "Z", True)               # on again before the head has landed
    assert f.switched_on and f.enabled


def test_a_feed_hold_keeps_the_head_up_and_the_landing_follows_the_resumed_path():
    m = _machine()
    lm = LiftMotion("Z", T, 5.0, V_Z, A_Z)
    m.interp.start_linear({"X": 300.0}, None)
    for k in range(3000):
        m.interp.feed_override = 0.0 if 100 <= k < 1100 else 1.0
        m.interp.step()
        lm.step(m)
        if 700 <= k < 1100:
            assert lm.offset == pytest.approx(5.0)        # held up while the path stands
        if m.interp.done:
            break
    assert lm.offset == 0.0 and m.interp.done


# ---------------------------------------------------------------------------- the PLC part
class _Unit(SimpleNamespace):
    pass


def test_the_plc_part_requests_the_hold_while_the_cnc_lift_is_active():
    f = _attached(Lift("Z", T, V_Z, A_Z))
    prog = ProcessProgram([f])
    hold = prog.holds["Z"]
    m = SimpleNamespace(hli={"Z": _Unit(state_r=SimpleNamespace(actual_state=0))})
    f.motion.lift_active = True
    f.step(m, 0)
    assert f.requesting and hold._requested_now == {"lift"}
    f.motion.lift_active = False
    hold._requested_now.clear()
    f.step(m, 1)
    assert not f.requesting and not hold._requested_now
    f.requesting = True
    f.reset()
    assert not f.requesting


@pytest.mark.parametrize("kwargs, key", [({"height": 0.0}, "lift.height"), ({"v_max": -1.0}, "lift.v_max"),
                                         ({"min_distance": -1.0}, "lift.min_distance"),
                                         ({"settle_time": 2.0}, "lift.settle_time")])
def test_invalid_arguments_name_the_key(kwargs, key):
    args = {"v_max": V_Z, "a_max": A_Z, **kwargs}
    with pytest.raises(Exception) as exc:
        Lift("Z", T, **args)
    assert exc.value.key == key


# ---------------------------------------------------------------------------- channel status and interpolator
def test_channel_status_motion_type_and_covered_distance():
    m = _machine()
    m.nc = None
    ch = ChannelPathStatus(m)
    assert ch.motion_type == MOTION_NONE and ch.D_CoveredDistance == 0
    m.interp.start_linear({"X": 100.0}, None)
    assert ch.motion_type == MOTION_RAPID
    while m.interp.path_position < 50.0:
        m.interp.step()
    assert 500 <= ch.D_CoveredDistance <= 520                 # 0.1 %
    while not m.interp.done:
        m.interp.step()
    m.interp.start_linear({"X": 0.0}, 3000.0)
    assert ch.motion_type == MOTION_LINEAR


@pytest.mark.parametrize("length, override", [(3.0, 1.0), (100.0, 1.0), (400.0, 0.5)])
def test_remaining_time_predicts_the_end_of_the_block(length, override):
    ip = Interpolator(T, {"X": AxisLimits(500.0, 3000.0)})
    ip.feed_override = override
    ip.start_linear({"X": length}, None)
    predictions = []
    k = 0
    while not ip.done:
        predictions.append((k, ip.remaining_time()))
        ip.step()
        k += 1
    for k0, tau in predictions:
        assert abs((k - k0) * T - tau) <= 2.5 * T            # within about two cycles
    ip.start_linear({"X": 0.0}, None)
    ip.feed_override = 0.0
    assert math.isinf(ip.remaining_time())


# ---------------------------------------------------------------------------- the scenario table
BASE = """
program_text = "N10 G90 G0 X0 Z31\\nN20 M30\\n"
[axes.X]
[axes.Z]
params = "{lis}"
start = 31.0
v_max = 150.0
a_max = 4000.0
[sensor]
axis = "Z"
kind = "arc_voltage"
variable = "SENSOR"
voltage_variable = "ARC_VOLTAGE"
"""


def _scenario(body):
    return scenario_from_text(BASE.format(lis=(EX / "z_plasma.lis").as_posix()) + "[[process]]\n" + body, base_dir=EX)


def test_defaults_are_the_documented_ones_and_the_axis_limits():
    pc = _scenario('function = "lift"\naxis = "Z"\n').processes[0]
    assert pc.params == {**LIFT_DEFAULTS, "v_max": 150.0, "a_max": 4000.0}
    f = pc.make(T)
    assert isinstance(f, Lift) and attach_lift(f).height == 5.0 and f.motion.a_max == 4000.0


@pytest.mark.parametrize("body, key, words", [
    ('height = 0', "process[0].height", "out of range"),
    ('a_max = 5000', "process[0].a_max", "out of range"),          # above the axis's 4000 mm/s²
    ('v_max = 151', "process[0].v_max", "out of range"),
    ('min_distance = -1', "process[0].min_distance", "out of range"),
    ('settle_time = 1.5', "process[0].settle_time", "out of range"),
    ('safe_height = 5', "process[0].safe_height", "unknown key"),
])
def test_invalid_lift_tables_name_key_value_and_range(body, key, words):
    with pytest.raises(ScenarioError) as exc:
        _scenario('function = "lift"\naxis = "Z"\n' + body + "\n")
    assert exc.value.key == key and words in str(exc.value)


# ---------------------------------------------------------------------------- end to end: `distctrl run`
def _read(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    data = np.array(rows[1:], dtype=float)
    return {name: data[:, i] for i, name in enumerate(rows[0])}


def _distctrl_run(toml, trace):
    proc = subprocess.run([sys.executable, "-m", "distctrl", "run", str(toml), "--json", "--trace", str(trace)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout), _read(trace)


def test_example_plate_end_to_end(tmp_path):
    text = (EX / "process_lift.toml").read_text()
    assert '[[process]]\nfunction = "lift"' in text
    without = text[:text.index("# lift 5 mm")]                       # the same plate, no [[process]] table
    without = without.replace('program = "process_lift.nc"', f'program = "{(EX / "process_lift.nc").as_posix()}"')
    without = without.replace('params = "z_plasma.lis"', f'params = "{(EX / "z_plasma.lis").as_posix()}"')
    (tmp_path / "without.toml").write_text(without)
    res_w, w = _distctrl_run(EX / "process_lift.toml", tmp_path / "with.csv")
    res_wo, wo = _distctrl_run(tmp_path / "without.toml", tmp_path / "without.csv")
    nc = (EX / "process_lift.nc").read_text().splitlines()
    cut_lines = [i + 1 for i, line in enumerate(nc) if " G1 " in line]       # the first block of every cut
    off_line = next(i + 1 for i, line in enumerate(nc) if "DIST_CTRL OFF" in line)
    assert len(cut_lines) == 16

    # the torch was lifted over every rapid (15 between the holes): 5 mm above the cut height
    lifted = w["Z.prog"] > 31.5 + 1e-9
    assert np.count_nonzero(np.diff(lifted.astype(int)) == 1) >= 15
    assert w["Z.prog"].max() == pytest.approx(31.5 + 5.0)
    # overlapped: while the torch is up, X/Y move (at the top they run at rapid speed)
    top = w["Z.prog"] > 36.4
    vxy = np.hypot(np.gradient(w["X.prog"]), np.gradient(w["Y.prog"])) / T
    assert vxy[top].min() > 100.0

    # Z within its axis limits (v_max 200 mm/s, a_max 5000 mm/s²) on the setpoint the drive gets
    v = np.diff(w["Z.cmd"]) / T
    a = np.diff(w["Z.cmd"], 2) / T ** 2
    assert np.abs(v).max() <= V_Z * (1 + 1e-6) and np.abs(a).max() <= A_Z * (1 + 1e-6)

    # the head is at the cut height when each cut starts: the lift has landed, the true distance is 1.5 mm
    starts = [int(np.argmax(w["line"] == ln)) for ln in cut_lines]
    assert np.all(w["Z.prog"][starts] == 31.5)
    assert np.all(np.abs(w["true.distance"][starts] - 1.5) < 0.1)
    assert np.all(w["Z.dc.state"][starts[1:]] == int(HliState.ACTIVE_CONST_DIST))   # re-activated after the lift

    # the path time: with the lift at most 5 % longer than without (measured: the same to the cycle)
    t_with = w["t"][int(np.argmax(w["line"] == off_line))]
    t_without = wo["t"][int(np.argmax(wo["line"] == off_line))]
    assert t_without > 10.0 and t_with <= 1.05 * t_without
    assert res_w["metrics"]["collisions"] == 0 and res_w["metrics"]["min_distance_mm"] > 1.0


def test_served_machine_lifts_and_the_plc_freezes_and_re_activates():
    from distctrl.ads.devices import serve_over_ads

    served = serve_over_ads(load_scenario(EX / "process_lift.toml"), port=0, discovery_port=None)
    m = served.machine
    lm = m.lift_motions[0]
    top = 0.0
    for _ in range(1100):                     # the first rapid between two holes: 0.85 .. 1.03 s
        served.step()
        top = max(top, m.inputs["Z"].programmed_position)
    assert top == pytest.approx(36.5)
    assert [e for _, e in lm.log][-3:] == ["start", "down", "landed"]
    hold = m.process_program.holds["Z"]
    assert [t for _, t in hold.log] == [2, 4]             # FREEZE for the lift, ON_CONST_DIST after it
    assert hold.log[0][0] < [c for c, e in lm.log if e == "start"][-1]   # frozen before Z rose
    assert m.hli["Z"].state_r.actual_state == 4 and m.hli["Z"].state_r.command_source == 1


def _switch_off_at(cycle, keep_freeze):
    sc = load_scenario(EX / "process_lift.toml")

    def plc(m, k):
        if k == cycle:                       # mid-lift over the first rapid between two holes (0.85 .. 1.03 s)
            f = m.process_program.function("lift")
            assert f.motion.offset > 1.0
            if keep_freeze:                  # as ProcessProgram.set_enabled does: switch, reset, withdraw
                f.enabled = False
                f.reset()
                f.hold.withdraw(f.name)
            else:                            # a PLC part that just stops: the hold releases at once
                f.step = lambda *a: None
    r = run(sc, plc_program=plc)
    t = r.trace.data[:, 0]
    d = r.trace.data[:, r.trace.columns.index("true.distance")]
    return r, d[(t > 0.85) & (t < 1.3)].min()


def test_switched_off_mid_lift_in_a_run_the_head_lands_without_diving():
    r, dmin = _switch_off_at(900, keep_freeze=True)
    assert r.completed and r.metrics["collisions"] == 0 and dmin > 1.2
    # why: distance control re-activated while the head is up pulls it down (100 mm/s) and cannot
    # follow the landing (156 mm/s): the torch hits the plate
    r, dmin = _switch_off_at(900, keep_freeze=False)
    assert dmin < 0.0 and r.metrics["collisions"] >= 1
