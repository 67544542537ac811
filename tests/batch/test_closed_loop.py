"""The closed-loop batch kernel replays distctrl.sim.runner.run bit for bit.

Each scenario: X/Y move the tool along a surface with a sine and a step, the Z probe has noise and
dead time, distance control is selected in the first block. A batch of one must reproduce the
runner's ``Z.dc.offset`` and ``true.distance`` traces (asserted to 1e-9 mm; in fact they are equal).
"""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from distctrl.batch import closed_loop as CL  # noqa: E402
from distctrl.control import FilterType  # noqa: E402
from distctrl.errors import ErrorId  # noqa: E402
from distctrl.params import AxisParameters  # noqa: E402
from distctrl.params.listfile import format_list  # noqa: E402
from distctrl.sim.runner import run  # noqa: E402
from distctrl.sim.scenario import scenario_from_dict  # noqa: E402

TOL = 1e-9
FILTERS = {
    "MOVING_AVERAGE": dict(filter_type=FilterType.MOVING_AVERAGE, n_cycles=8),
    "EXPO_MEAN": dict(filter_type=FilterType.EXPO_MEAN, n_cycles=12, smoothing_factor=0.3),
    "LOWPASS": dict(filter_type=FilterType.LOWPASS, low_pass_filter_order=4, low_pass_filter_fg_f0=40.0),
    "KALMAN_MA": dict(filter_type=FilterType.KALMAN_MA, n_cycles=20, kalman_sigma=1000.0),
    "KALMAN_EXPO": dict(filter_type=FilterType.KALMAN_EXPO, n_cycles=10, smoothing_factor=0.4,
                        kalman_sigma=50.0),
    "DEFAULT": dict(filter_type=FilterType.DEFAULT),
}
#: SENSOR_SOURCE=VARIABLE: the control reads the distance sensor's variable (FCT-M3 §6, PROG DIST_CTRL)
VARIABLE = "SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR"
#: a capacitive sensor's characteristic (reported vs true distance, mm), as distctrl identify writes it
CHARACTERISTIC = [[0.0, -0.01], [0.3, 0.296], [0.625, 0.628], [1.0, 1.03], [2.0, 2.09], [4.0, 4.2], [7.6, 7.97],
                  [10.0, 10.55]]
MODES = {
    "SET_POS": ("N10 Z[DIST_CTRL ON SET_POS=29.7]", {}),
    "CONST_DIST": ("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5]", dict(use_both_encoders=False)),
    "CONST_DIST_BOTH": ("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5]", dict(use_both_encoders=True)),
}
PATH = "\nN20 G1 X100 Y50 F3000\nN30 G1 X0 Y0\nN999 M30\n"


def make_params(**changes) -> AxisParameters:
    base = dict(enabled=True, kp=0.6, i_tn=0.05, d_tv=0.001, v_max=100.0, a_max=5000.0, max_deviation=25.0,
                max_act_value_change=10000.0, max_pos=20.0, min_pos=-20.0)
    base.update(changes)
    return AxisParameters(**base)


def make_scenario(tmp_path, params: AxisParameters, program: str, *, duration=2.5, z=None, sensor=None,
                  name="z", distance=False):
    """``distance``: the point distance sensor (kind "distance", V.E.SENSOR) instead of the probe."""
    (tmp_path / f"{name}.lis").write_text(format_list(params))
    zcfg = {"params": f"{name}.lis", "start": 30.0, "kv": 50.0, "v_max": 300.0, "a_max": 10000.0}
    zcfg.update(z or {})
    scfg = {"axis": "Z", "kind": "encoder", "range_min": -20.0, "range_max": 20.0, "noise_std": 0.002,
            "delay_cycles": 2, "seed": 3}
    if distance:
        scfg = {"axis": "Z", "kind": "distance", "variable": "SENSOR", "range_max": 10.0, "noise_std": 0.002,
                "delay_cycles": 2, "seed": 3}
    scfg.update(sensor or {})
    return scenario_from_dict({
        "name": "closed-loop", "program_text": program, "duration": duration,
        "axes": {"X": {"v_max": 300.0, "a_max": 3000.0}, "Y": {"v_max": 300.0, "a_max": 3000.0}, "Z": zcfg},
        "surface": {"base": 29.7, "features": [
            {"type": "sine", "axis": "X", "amplitude": 0.2, "wavelength": 40.0},
            {"type": "step", "axis": "X", "at": 30.0, "height": 0.3}]},
        "sensor": scfg}, base_dir=tmp_path)


def assert_replays(sc, inputs=None, error=None):
    """A batch of one equals the runner; with ``error`` both stop at that error at the same cycle."""
    inputs = inputs or CL.prepare(sc)
    off, dist, err = CL.run_batch(inputs, [sc.axes["Z"].params], return_errors=True)
    r = run(sc)
    tr = r.trace
    n = inputs.n_cycles
    assert n >= 2000
    if error is None:
        assert err[0, 0] == -1 and r.errors == []
    else:
        n = int(err[0, 0])
        assert err[0, 1] == int(error) and r.errors[0]["id"] == int(error)
        assert r.errors[0]["t"] == pytest.approx(n * inputs.cycle_time)
        assert np.isnan(off[0, n:]).all() and np.isnan(dist[0, n:]).all()
    ref_off = np.asarray(tr["Z.dc.offset"][:n], dtype=float)
    ref_dist = np.asarray(tr["true.distance"][:n], dtype=float)
    assert np.max(np.abs(off[0, :n] - ref_off)) <= TOL
    assert np.max(np.abs(dist[0, :n] - ref_dist)) <= TOL
    assert np.ptp(ref_off) > 0.05                      # it really controlled something


@pytest.mark.parametrize("mode", list(MODES))
@pytest.mark.parametrize("filt", list(FILTERS))
def test_batch_of_one_replays_the_runner(tmp_path, filt, mode):
    block, extra = MODES[mode]
    sc = make_scenario(tmp_path, make_params(**FILTERS[filt], **extra), block + PATH)
    assert_replays(sc)


@pytest.mark.parametrize("variant", ["no_optimized_scheduling", "adaptive_lowering_sw", "sw_limit_error",
                                     "sensor_jump_error", "drive_ff_bus0",
                                     "no_noise_no_delay_resolution", "set_before_select",
                                     "resonance_40hz", "resonance_250hz_ff_bus0"])
def test_plant_and_law_options_replay(tmp_path, variant):
    params = make_params(**FILTERS["EXPO_MEAN"])
    program = MODES["SET_POS"][0] + PATH
    z, sensor, error = {}, {}, None
    if variant == "no_optimized_scheduling":
        params = params.replace(optimized_scheduling=False, kp=1.2, d_tv=0.0)
    elif variant == "adaptive_lowering_sw":
        params = params.replace(use_adaptive_acceleration=True, a_min=300.0, dist_error_a_min=0.05,
                                dist_error_a_max=0.3, v_weight_down=0.5, a_weight_down=0.7,
                                check_sw_limit_switch=True, sw_limit_min=-100.0, sw_limit_max=31.0)
    elif variant == "sw_limit_error":
        params = params.replace(check_sw_limit_switch=True, sw_limit_min=-100.0, sw_limit_max=30.3)
        error = ErrorId.SW_LIMIT
    elif variant == "sensor_jump_error":
        params = params.replace(max_act_value_change=100.0)     # the 0.3 mm surface step: 300 mm/s
        error = ErrorId.SENSOR_JUMP
    elif variant == "drive_ff_bus0":
        z = {"feedforward": 0.6, "bus_delay_cycles": 0, "resolution": 1e-3}
    elif variant == "no_noise_no_delay_resolution":
        params = params.replace(encoder_resolution_num=3, encoder_resolution_denom=7,
                                sensor_sign_reversal=True,
                                ref_offset=0.25)
        sensor = {"noise_std": 0.0, "delay_cycles": 0}
    elif variant == "resonance_40hz":              # the drive's mechanical resonance (issue 15)
        z = {"resonance_hz": 40.0, "damping": 0.05}
    elif variant == "resonance_250hz_ff_bus0":     # f0 = 1/(4T), with feed-forward and no bus delay
        z = {"resonance_hz": 250.0, "damping": 0.2, "feedforward": 0.5, "bus_delay_cycles": 0}
    else:
        program = "N5 Z[DIST_CTRL SET_POS=29.6]\nN10 G1 X5 F600\nN15 Z[DIST_CTRL ON]" + PATH
    sc = make_scenario(tmp_path, params, program, z=z, sensor=sensor)
    inputs = CL.prepare(sc)
    if variant == "set_before_select":
        assert inputs.k_on > 100
    if variant.startswith("resonance"):
        assert inputs.plant[CL.PL_RESONANT] == 1.0
        # the nozzle really leaves the motor: the rigid plant gives another distance trace
        rigid = make_scenario(tmp_path, params, program, z={k: v for k, v in z.items() if "reson" not in k
                                                            and k != "damping"}, sensor=sensor, name="rigid")
        a = CL.run_batch(inputs, [params])[1]
        b = CL.run_batch(CL.prepare(rigid), [params])[1]
        assert np.max(np.abs(a - b)) > 1e-3
    assert_replays(sc, inputs, error)


def test_several_sets_equal_one_by_one(tmp_path):
    sets = [make_params(**FILTERS[f], kp=kp) for f, kp in
            (("MOVING_AVERAGE", 0.3), ("LOWPASS", 0.9), ("KALMAN_EXPO", 1.4), ("DEFAULT", 0.6),
             ("EXPO_MEAN", 0.8))]
    sets.append(make_params(max_deviation=0.25))           # runs into 70331
    sc = make_scenario(tmp_path, sets[0], MODES["SET_POS"][0] + PATH)
    inputs = CL.prepare(sc)
    off, dist, err = CL.run_batch(inputs, sets, threads=2, return_errors=True)
    assert off.shape == dist.shape == (len(sets), inputs.n_cycles)
    for i, p in enumerate(sets):
        o1, d1, e1 = CL.run_batch(inputs, [p], threads=1, return_errors=True)
        assert np.array_equal(off[i], o1[0], equal_nan=True)
        assert np.array_equal(dist[i], d1[0], equal_nan=True)
        assert np.array_equal(err[i], e1[0])
    # packed rows: editing the plain columns equals packing the changed parameter set (the D part's
    # per-cycle gain depends on kp: law.derivative_gain)
    packed = CL.pack_sets(inputs, sets[:1])
    packed[0, CL.law.FC_LEN + CL.Q_KP] = 0.45
    packed[0, CL.law.FC_LEN + CL.Q_D_GAIN] = CL.law.derivative_gain(0.45, sets[0].d_tv, inputs.cycle_time)
    o2, _ = CL.run_batch(inputs, packed)
    o3, _ = CL.run_batch(inputs, [sets[0].replace(kp=0.45)])
    assert np.array_equal(o2, o3)
    # the error set: the runner reports 70331 at the same time; the kernel's outputs stop there
    assert err[-1, 1] == int(ErrorId.MAX_DEVIATION)
    k = err[-1, 0]
    assert np.isnan(off[-1, k:]).all() and not np.isnan(off[-1, :k]).any()
    r = run(make_scenario(tmp_path, sets[-1], MODES["SET_POS"][0] + PATH, name="e"))
    assert r.errors[0]["id"] == int(ErrorId.MAX_DEVIATION)
    assert r.errors[0]["t"] == pytest.approx(k * inputs.cycle_time)
    assert np.max(np.abs(off[-1, :k] - np.asarray(r.trace["Z.dc.offset"][:k]))) <= TOL


def test_replay_stops_before_the_next_command(tmp_path):
    program = MODES["SET_POS"][0] + "\nN20 G1 X60 F3000\nN30 Z[DIST_CTRL OFF]\nN40 G1 X0\nN999 M30\n"
    sc = make_scenario(tmp_path, make_params(), program)
    inputs = CL.prepare(sc)
    tr = run(sc).trace
    assert tr["Z.dc.state"][inputs.n_cycles - 1] == 1 and tr["Z.dc.state"][inputs.n_cycles] != 1
    with pytest.raises(CL.ClosedLoopError, match="at most"):
        CL.prepare(sc, cycles=inputs.n_cycles + 1)
    assert CL.prepare(sc, cycles=500).n_cycles == 500


@pytest.mark.parametrize("program, extra, match", [
    ("N10 Z[DIST_CTRL ON SET_POS=29.7 WAIT]" + PATH, {}, "WAIT"),
    ("N10 Z[DIST_CTRL ON SET_POS=29.7 KP=0.3]" + PATH, {}, "KP"),
    (MODES["SET_POS"][0] + PATH, {"events": [{"t": 0.5, "override": {"value": 0.5}}]}, "events"),
    (MODES["SET_POS"][0] + PATH, {"sensor_faults": True}, "faults"),
    ("N10 G1 X10 F3000\nN999 M30\n", {}, "PROGRAM_END before the select"),
    ("N10 Z[DIST_CTRL ON SET_POS=29.7]\nN20 X[DIST_CTRL ON SET_POS=0]" + PATH, {}, "only the sensor axis"),
])
def test_unsupported_scenarios_are_refused(tmp_path, program, extra, match):
    extra = dict(extra)
    sensor = None
    if extra.pop("sensor_faults", False):
        sensor = {"faults": [{"kind": "jump", "value": 1.0, "start_time": 0.5}]}
    sc = make_scenario(tmp_path, make_params(), program, sensor=sensor)
    if extra:
        from dataclasses import replace

        from distctrl.sim.scenario import Event
        sc = replace(sc, events=[Event(e["t"], "override", e["override"]) for e in extra["events"]])
    with pytest.raises(CL.ClosedLoopError, match=match):
        CL.prepare(sc)


# ----------------------------------------------------------------------------- the distance sensor

DISTANCE_VARIANTS = {
    # name: (program, parameter changes, scenario Z axis, sensor keys, expected error)
    "const_dist_ma": ("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5 " + VARIABLE + "]",
                      dict(FILTERS["MOVING_AVERAGE"], use_both_encoders=False), {}, {}, None),
    "const_dist_both_expo": ("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5 " + VARIABLE + "]",
                             dict(FILTERS["EXPO_MEAN"], use_both_encoders=True), {}, {}, None),
    "set_pos_kalman": ("N10 Z[DIST_CTRL ON SET_POS=29.7 " + VARIABLE + "]", FILTERS["KALMAN_EXPO"], {}, {}, None),
    # the characteristic, a quantised reading and the drive's 40 Hz resonance (the fitted plant of issue 15)
    "characteristic_resolution_resonance": (
        "N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5 " + VARIABLE + "]",
        dict(FILTERS["MOVING_AVERAGE"], use_both_encoders=True, kp=0.3),
        {"resonance_hz": 40.0, "damping": 0.05}, {"characteristic": CHARACTERISTIC, "resolution": 0.0005}, None),
    "characteristic_lowpass_resonance_250hz": (
        "N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5 " + VARIABLE + "]",
        dict(FILTERS["LOWPASS"], use_both_encoders=False, kp=0.4),
        {"resonance_hz": 250.0, "damping": 0.2, "feedforward": 0.5, "bus_delay_cycles": 0},
        {"characteristic": CHARACTERISTIC}, None),
    # the reading saturates at range_max before the control brings the head down
    "saturated_start": ("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5 " + VARIABLE + "]",
                        dict(FILTERS["MOVING_AVERAGE"], use_both_encoders=False), {"start": 31.5},
                        {"range_max": 1.0, "noise_std": 0.0}, None),
    # the source switched blocks before the select (its history restarts there), no optimized scheduling
    "source_before_select": ("N3 G1 X3 F600\nN5 Z[DIST_CTRL " + VARIABLE + "]\nN7 Z[DIST_CTRL SET_POS=29.6]\nN10 G1 X5 F600\n"
                             "N15 Z[DIST_CTRL ON]", dict(FILTERS["MOVING_AVERAGE"], optimized_scheduling=False,
                                                         kp=1.2, d_tv=0.0), {}, {"delay_cycles": 0}, None),
    "source_in_select_no_optimized": ("N10 Z[DIST_CTRL ON SET_POS=29.7 " + VARIABLE + "]",
                                      dict(FILTERS["EXPO_MEAN"], optimized_scheduling=False), {},
                                      {"delay_cycles": 3}, None),
    "sensor_jump_error": ("N10 Z[DIST_CTRL ON SET_POS=29.7 " + VARIABLE + "]",
                          dict(FILTERS["MOVING_AVERAGE"], max_act_value_change=100.0), {}, {},
                          ErrorId.SENSOR_JUMP),
}


@pytest.mark.parametrize("variant", list(DISTANCE_VARIANTS))
def test_distance_sensor_replays_the_runner(tmp_path, variant):
    """The point distance sensor (kind "distance", SENSOR_SOURCE=VARIABLE): noise, range saturation,
    characteristic, quantisation and dead time as DistanceSensor computes them, bit for bit, in both
    kernels (closed_loop one by one, soa.block_loop for MOVING_AVERAGE)."""
    program, changes, z, sensor, error = DISTANCE_VARIANTS[variant]
    params = make_params(**changes)
    sc = make_scenario(tmp_path, params, program + PATH, z=z, sensor=sensor, distance=True)
    assert sc.sensor.kind == "distance"
    inputs = CL.prepare(sc)
    assert inputs.plant[CL.PL_SENSOR] == CL.SENSOR_DISTANCE
    if variant == "source_before_select":
        assert 0 < inputs.plant[CL.PL_K_FIRST] < inputs.k_on - 100
    else:
        assert inputs.plant[CL.PL_K_FIRST] == inputs.k_on
    if "characteristic" in sensor:
        assert inputs.plant[CL.PL_NCHAR] == len(CHARACTERISTIC)
    assert_replays(sc, inputs, error)
    # several sets: both kernels, one by one and in blocks, agree
    sets = [params, params.replace(kp=params.kp * 0.5), params.replace(n_cycles=3)]
    a = CL.run_batch(inputs, sets, return_errors=True, vectorised=False)
    b = CL.run_batch(inputs, sets, return_errors=True)
    for x, y in zip(a, b):
        assert np.array_equal(x, y, equal_nan=True)
    if variant == "saturated_start":           # the reading really saturated (true distance above the range)
        assert np.count_nonzero(np.asarray(run(sc).trace["true.distance"]) > 1.0) > 10


def test_distance_sensor_characteristic_changes_the_loop(tmp_path):
    """The characteristic is really applied: without it the tracked true distance differs (by the
    table's error at the set distance)."""
    params = make_params(**FILTERS["MOVING_AVERAGE"], use_both_encoders=False, kp=0.1, i_tn=0.0, d_tv=0.0)
    program = "N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=2 " + VARIABLE + "]\nN20 G1 X5 F60\nN999 M30\n"
    with_char = CL.prepare(make_scenario(tmp_path, params, program, sensor={"characteristic": CHARACTERISTIC},
                                         distance=True))
    plain = CL.prepare(make_scenario(tmp_path, params, program, distance=True, name="plain"))
    d1 = CL.run_batch(with_char, [params])[1][0, -500:].mean()
    d0 = CL.run_batch(plain, [params])[1][0, -500:].mean()
    # reported 2 mm at true 1 + (2 - 1.03) / 1.06 = 1.915 mm: the loop holds 0.085 mm lower
    assert d0 - d1 == pytest.approx(2.0 - (1.0 + 0.97 / 1.06), abs=0.01)


def test_distance_sensor_modulo_replays(tmp_path):
    """P-AXIS-00424 modulo with the variable source: the reading wraps into [min_pos, max_pos) and is
    unwrapped (closed_loop; the block kernel takes no modulo sets)."""
    params = make_params(kp=0.3, **FILTERS["EXPO_MEAN"], sensor_mode_act_pos=2, min_pos=-0.31, max_pos=0.69)
    sc = make_scenario(tmp_path, params, "N10 Z[DIST_CTRL ON SET_POS=29.7 " + VARIABLE + "]" + PATH, distance=True)
    inputs = CL.prepare(sc)
    assert CL.pack_sets(inputs, [params])[0, CL.law.FC_LEN + CL.Q_MODULO] == 1.0
    assert_replays(sc, inputs)
    dist = CL.run_batch(inputs, [params])[1]
    assert np.count_nonzero(-dist[0] < -0.315) > 10                 # below min_pos: the reading wraps


@pytest.mark.parametrize("program, sensor, match", [
    ("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5]", {}, "SENSOR_SOURCE=VARIABLE"),
    ("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5 SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.OTHER]", {},
     "SENSOR_VAR=V.E.OTHER"),
    ("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5 " + VARIABLE + "]", {"footprint_radius": 2.0},
     r"\[sensor\] footprint_radius"),
    ("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5 " + VARIABLE + "]",
     {"bursts": {"rate": 2.0, "duration": 0.01, "amplitude": 0.05}}, r"\[sensor\] bursts"),
    ("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5 " + VARIABLE + "]",
     {"kind": "arc_voltage", "voltage_variable": "ARC_V"}, "kind = 'arc_voltage'"),
    ("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5 " + VARIABLE + "]",
     {"faults": [{"kind": "jump", "value": 1.0, "start_time": 0.5}]}, r"\[sensor\] faults"),
])
def test_distance_sensor_refusals(tmp_path, program, sensor, match):
    """What the kernels do not model of the distance sensors is refused, naming the key."""
    sc = make_scenario(tmp_path, make_params(use_both_encoders=False), program + PATH, sensor=sensor, distance=True)
    with pytest.raises(CL.ClosedLoopError, match=match):
        CL.prepare(sc)
