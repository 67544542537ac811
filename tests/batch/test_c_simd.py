"""The SIMD anchor of the batch kernel (bench/batch_c/closed_loop_simd.c) gives the kernel's numbers.

bench/bench_batch.py and bench/bench_sweep.py time the numba kernel beside this C loop, the law run
across sets on a structure-of-arrays layout and vectorised by gcc (-O3 -march=native); the figure
means something only while it computes the same thing. Built here with the benchmark's flags (no
fast math, no contraction into FMA), it must reproduce the kernel's offsets, distances and errors
bit for bit, as the scalar C reference does (tests/batch/test_c_reference.py): every mode, the plant's
options, blocks with a padded last lane, sets that run into errors in the middle of a block, and a
block the SIMD loop does not take (a modulo encoder, run one set after the other).
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest

pytest.importorskip("numba")
if shutil.which("gcc") is None:
    pytest.skip("gcc not found: the SIMD anchor of the batch kernel cannot be built", allow_module_level=True)

from distctrl.batch import closed_loop as CL  # noqa: E402
from distctrl.control import law  # noqa: E402
from tests.batch.test_c_reference import (MODES, PATH, _load_bench, assert_same, make_params,  # noqa: E402
                                          make_scenario, sets_for)


@pytest.fixture(scope="module")
def csimd(tmp_path_factory):
    bench = _load_bench()
    lib = bench.build_c(tmp_path_factory.mktemp("batch_c_simd"), flags=bench.CFLAGS_SIMD,
                        name="libclosed_loop_simd.so", source=bench.C_SIMD_SOURCE)
    return bench.CReference(lib, entry="closed_loop_simd_batch")


@pytest.mark.parametrize("mode", list(MODES))
def test_simd_reproduces_the_kernel(tmp_path, csimd, mode):
    block, extra = MODES[mode]
    sets = sets_for(extra)
    sc = make_scenario(tmp_path, sets[0], block + PATH)
    inputs = CL.prepare(sc)
    # 7 sets x 3, shuffled: blocks of 8, 8 and 5 lanes, errors in the middle of blocks
    order = np.random.default_rng(1).permutation(3 * len(sets))
    packed = CL.pack_sets(inputs, [sets[i % len(sets)] for i in order])
    off, err = assert_same(csimd, inputs, packed)
    assert np.ptp(off[0]) > 0.05 and (err[:, 1] != 0).sum() >= 6


@pytest.mark.parametrize("variant", ["drive_ff_bus0_resolution", "no_noise_no_delay", "set_before_select",
                                     "resonance_40hz"])
def test_simd_reproduces_the_plant_options(tmp_path, csimd, variant):
    program = MODES["SET_POS"][0] + PATH
    z, sensor = {}, {}
    if variant == "drive_ff_bus0_resolution":
        z = {"feedforward": 0.6, "bus_delay_cycles": 0, "resolution": 1e-3}
    elif variant == "no_noise_no_delay":
        sensor = {"noise_std": 0.0, "delay_cycles": 0}
    elif variant == "resonance_40hz":
        z = {"resonance_hz": 40.0, "damping": 0.05}
    else:
        program = "N5 Z[DIST_CTRL SET_POS=29.6]\nN10 G1 X5 F600\nN15 Z[DIST_CTRL ON]" + PATH
    sets = sets_for({})
    sc = make_scenario(tmp_path, sets[0], program, z=z, sensor=sensor)
    inputs = CL.prepare(sc)
    assert_same(csimd, inputs, CL.pack_sets(inputs, sets * 2), threads=2)


def test_simd_swept_columns_and_a_block_it_does_not_take(tmp_path, csimd):
    """Edited plain columns (as the benchmarks sweep them) agree; a block with a modulo encoder set runs
    one set after the other (closed_loop_one) and agrees too."""
    sc = make_scenario(tmp_path, make_params(), MODES["CONST_DIST_BOTH"][0] + PATH)
    inputs = CL.prepare(sc, cycles=800)
    packed = CL.pack_sets(inputs, [make_params(n_cycles=n, use_both_encoders=True) for n in (2, 7, 16, 30)] * 6)
    packed[:, law.FC_LEN + CL.Q_KP] = np.linspace(0.2, 1.5, len(packed))
    packed[:, law.FC_LEN + CL.Q_D_GAIN] = np.linspace(0.0, 0.45, len(packed))
    assert_same(csimd, inputs, packed, threads=2)
    modulo = CL.pack_sets(inputs, [make_params(kp=0.3, n_cycles=2, sensor_mode_act_pos=2, min_pos=-20.0,
                                               max_pos=20.0, use_both_encoders=True)])
    mixed = np.concatenate([packed[:5], modulo, packed[5:12]])
    assert mixed[5, law.FC_LEN + CL.Q_MODULO] == 1.0
    assert_same(csimd, inputs, mixed)


def test_bench_param_sets(csimd):
    """The benchmark's own sets (bench_batch.param_sets) on its scenario, shortened."""
    bench = _load_bench()
    inputs = CL.prepare(bench.SCENARIO, cycles=1500)
    assert_same(csimd, inputs, bench.param_sets(inputs, 45, seed=4))
