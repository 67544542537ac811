"""The C reference of the closed-loop kernel (bench/batch_c/closed_loop.c) gives the kernel's numbers.

bench/bench_batch.py times the numba kernel beside this C loop; the comparison is only worth
something while the C code computes the same thing. Built here with the benchmark's flags
(``gcc -O2 -fno-fast-math -ffp-contract=off``) into a temporary directory, it must reproduce the
kernel's offsets, distances and errors for MOVING_AVERAGE sets in SET_POS and both CONST_DIST
variants bit for bit: both are compiled without fast math and without contraction into FMA, the C
code repeats the kernel's operations in its order, so there is nothing to round differently. An
exact comparison also catches harmless-looking rewrites (``u * (1 / T)`` for ``u / T`` differs by
~1e-15 mm) that a tolerance would let through.
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest

pytest.importorskip("numba")
if shutil.which("gcc") is None:
    pytest.skip("gcc not found: the C reference of the batch kernel cannot be built", allow_module_level=True)

from distctrl.batch import closed_loop as CL  # noqa: E402
from distctrl.control import FilterType, law  # noqa: E402
from distctrl.errors import ErrorId  # noqa: E402
from distctrl.params import AxisParameters  # noqa: E402
from distctrl.params.listfile import format_list  # noqa: E402
from distctrl.sim.scenario import scenario_from_dict  # noqa: E402
from tests.scripts import load_script  # noqa: E402

MODES = {
    "SET_POS": ("N10 Z[DIST_CTRL ON SET_POS=29.7]", {}),
    "CONST_DIST": ("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5]", dict(use_both_encoders=False)),
    "CONST_DIST_BOTH": ("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5]", dict(use_both_encoders=True)),
}
PATH = "\nN20 G1 X100 Y50 F3000\nN30 G1 X0 Y0\nN999 M30\n"


def _load_bench():
    return load_script("bench/bench_batch.py")


@pytest.fixture(scope="module")
def cref(tmp_path_factory):
    bench = _load_bench()
    lib = bench.build_c(tmp_path_factory.mktemp("batch_c"))
    return bench.CReference(lib)


def make_params(**changes) -> AxisParameters:
    base = dict(enabled=True, filter_type=FilterType.MOVING_AVERAGE, n_cycles=8, kp=0.6, i_tn=0.05,
                d_tv=0.001, v_max=100.0, a_max=5000.0, max_deviation=25.0, max_act_value_change=10000.0,
                max_pos=20.0, min_pos=-20.0)
    base.update(changes)
    return AxisParameters(**base)


def make_scenario(tmp_path, params, program, *, z=None, sensor=None):
    (tmp_path / "z.lis").write_text(format_list(params))
    zcfg = {"params": "z.lis", "start": 30.0, "kv": 50.0, "v_max": 300.0, "a_max": 10000.0}
    zcfg.update(z or {})
    scfg = {"axis": "Z", "kind": "encoder", "range_min": -20.0, "range_max": 20.0, "noise_std": 0.002,
            "delay_cycles": 2, "seed": 3}
    scfg.update(sensor or {})
    return scenario_from_dict({
        "name": "c-reference", "program_text": program, "duration": 1.5,
        "axes": {"X": {"v_max": 300.0, "a_max": 3000.0}, "Y": {"v_max": 300.0, "a_max": 3000.0}, "Z": zcfg},
        "surface": {"base": 29.7, "features": [
            {"type": "sine", "axis": "X", "amplitude": 0.2, "wavelength": 40.0},
            {"type": "step", "axis": "X", "at": 30.0, "height": 0.3}]},
        "sensor": scfg}, base_dir=tmp_path)


def sets_for(extra):
    """A few MOVING_AVERAGE sets exercising the law's branches; the last two run into errors."""
    return [make_params(kp=0.3, n_cycles=2, **extra),
            make_params(kp=1.4, n_cycles=29, d_tv=0.004, **extra),
            make_params(kp=0.9, n_cycles=5, optimized_scheduling=False, d_tv=0.0, **extra),
            make_params(kp=0.8, n_cycles=12, use_adaptive_acceleration=True, a_min=300.0,
                        dist_error_a_min=0.05, dist_error_a_max=0.3, v_weight_down=0.5, a_weight_down=0.7,
                        check_sw_limit_switch=True, sw_limit_min=-100.0, sw_limit_max=31.0, **extra),
            make_params(kp=0.6, n_cycles=3, encoder_resolution_num=3, encoder_resolution_denom=7,
                        sensor_sign_reversal=True, ref_offset=0.25, **extra),
            make_params(max_deviation=0.25, **extra),                                  # 70331
            make_params(max_act_value_change=100.0, **extra)]                          # 70329 at the step


def assert_same(cref, inputs, packed, threads=1):
    off, dist, err = CL.run_batch(inputs, packed, threads=1, return_errors=True)
    c_off, c_dist, c_err = cref.run(inputs, packed, threads=threads)
    assert np.array_equal(err, c_err)
    assert np.array_equal(np.isnan(off), np.isnan(c_off))
    assert np.array_equal(np.isnan(dist), np.isnan(c_dist))
    assert np.array_equal(off, c_off, equal_nan=True), \
        f"max |offset diff| {np.nanmax(np.abs(off - c_off)):.3g} mm"
    assert np.array_equal(dist, c_dist, equal_nan=True), \
        f"max |distance diff| {np.nanmax(np.abs(dist - c_dist)):.3g} mm"
    return off, err


@pytest.mark.parametrize("mode", list(MODES))
def test_c_reproduces_the_kernel(tmp_path, cref, mode):
    block, extra = MODES[mode]
    sets = sets_for(extra)
    sc = make_scenario(tmp_path, sets[0], block + PATH)
    inputs = CL.prepare(sc)
    off, err = assert_same(cref, inputs, CL.pack_sets(inputs, sets))
    assert inputs.n_cycles >= 1000
    assert np.ptp(off[0]) > 0.05                           # it really controlled something
    ids = {int(e) for e in err[:, 1] if e}
    assert int(ErrorId.SENSOR_JUMP) in ids or int(ErrorId.MAX_DEVIATION) in ids


@pytest.mark.parametrize("variant", ["drive_ff_bus0_resolution", "no_noise_no_delay", "set_before_select",
                                     "resonance_40hz"])
def test_c_reproduces_the_plant_options(tmp_path, cref, variant):
    program = MODES["SET_POS"][0] + PATH
    z, sensor = {}, {}
    if variant == "drive_ff_bus0_resolution":
        z = {"feedforward": 0.6, "bus_delay_cycles": 0, "resolution": 1e-3}
    elif variant == "no_noise_no_delay":
        sensor = {"noise_std": 0.0, "delay_cycles": 0}
    elif variant == "resonance_40hz":              # the drive's mechanical resonance (issue 15)
        z = {"resonance_hz": 40.0, "damping": 0.05}
    else:
        program = "N5 Z[DIST_CTRL SET_POS=29.6]\nN10 G1 X5 F600\nN15 Z[DIST_CTRL ON]" + PATH
    sets = sets_for({})
    sc = make_scenario(tmp_path, sets[0], program, z=z, sensor=sensor)
    inputs = CL.prepare(sc)
    assert_same(cref, inputs, CL.pack_sets(inputs, sets), threads=2)


def test_swept_columns_and_other_filters(tmp_path, cref):
    """Edited plain columns (as the benchmark sweeps them) agree too; a set with a filter the C
    reference does not have is marked (-2, kind) and left NaN, never silently computed."""
    sc = make_scenario(tmp_path, make_params(), MODES["CONST_DIST_BOTH"][0] + PATH)
    inputs = CL.prepare(sc, cycles=800)
    packed = CL.pack_sets(inputs, [make_params(n_cycles=n, use_both_encoders=True) for n in (2, 7, 16)] * 4)
    packed[:, law.FC_LEN + CL.Q_KP] = np.linspace(0.2, 1.5, len(packed))
    packed[:, law.FC_LEN + CL.Q_D_GAIN] = np.linspace(0.0, 0.45, len(packed))   # per-cycle D gain
    assert_same(cref, inputs, packed, threads=2)
    other = CL.pack_sets(inputs, [make_params(filter_type=FilterType.EXPO_MEAN, n_cycles=12,
                                               smoothing_factor=0.3)])
    off, _, err = cref.run(inputs, other)
    assert err[0].tolist() == [-2, law.EXPO_MEAN] and np.isnan(off).all()


def test_c_reproduces_a_wrapping_modulo_encoder(tmp_path, cref):
    """P-AXIS-00424 = 2 (modulo) with a 1 mm window starting just below the first reading (-0.3 mm),
    which the reading (down to -0.33 mm while tracking) leaves again and again: the C reference unwraps
    like the kernel (AxisDistanceController._unwrap)."""
    sets = [make_params(kp=0.3, n_cycles=2, sensor_mode_act_pos=2, min_pos=-0.31, max_pos=0.69),
            make_params(kp=0.9, n_cycles=5, optimized_scheduling=False, sensor_mode_act_pos=2, min_pos=-0.305,
                        max_pos=0.695)]
    sc = make_scenario(tmp_path, sets[0], MODES["SET_POS"][0] + PATH)
    inputs = CL.prepare(sc)
    packed = CL.pack_sets(inputs, sets)
    assert (packed[:, law.FC_LEN + CL.Q_MODULO] == 1.0).all()
    off, err = assert_same(cref, inputs, packed)
    assert (err[:, 1] == 0).all() and np.ptp(off[0]) > 0.05
    _, dist, _ = CL.run_batch(inputs, packed, return_errors=True)
    assert np.count_nonzero(-dist[0] < -0.315) > 10                 # below min_pos: the reading wraps


def test_c_reference_refuses_the_distance_sensor(tmp_path, cref):
    """The C reference models the probe only: a plant with the distance sensor (issue 15) is marked
    (-3, SENSOR_DISTANCE) and left NaN, never computed as if it were the probe."""
    from tests.batch.test_closed_loop import make_scenario as make_distance_scenario

    params = make_params(use_both_encoders=False)
    sc = make_distance_scenario(tmp_path, params, "N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=0.5 SENSOR_SOURCE=VARIABLE "
                                "SENSOR_VAR=V.E.SENSOR]" + PATH, distance=True)
    inputs = CL.prepare(sc, cycles=500)
    assert inputs.plant[CL.PL_SENSOR] == CL.SENSOR_DISTANCE
    off, dist, err = cref.run(inputs, CL.pack_sets(inputs, [params]))
    assert err[0].tolist() == [-3, CL.SENSOR_DISTANCE] and np.isnan(off).all() and np.isnan(dist).all()
