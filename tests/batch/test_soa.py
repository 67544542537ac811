"""The vectorised block kernel (distctrl.batch.soa) equals closed_loop bit for bit.

``run_batch(..., vectorised=False)`` runs every set through ``closed_loop`` (one set after the
other); the default runs MOVING_AVERAGE sets in blocks through ``soa.block_loop``. The two must
give identical offsets, distances and errors (NaN where a set stopped), for every option the
kernel has, for blocks that mix window lengths, for partial blocks and for batches that mix
block and one-by-one sets.
"""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from distctrl.batch import closed_loop as CL  # noqa: E402
from distctrl.batch import soa  # noqa: E402
from distctrl.control import FilterType, law  # noqa: E402
from distctrl.errors import ErrorId  # noqa: E402

from .test_closed_loop import (CHARACTERISTIC, FILTERS, MODES, PATH, VARIABLE, assert_replays, make_params,  # noqa: E402
                               make_scenario)

MA = dict(filter_type=FilterType.MOVING_AVERAGE)


def assert_same(inputs, sets):
    a = CL.run_batch(inputs, sets, return_errors=True, vectorised=False)
    b = CL.run_batch(inputs, sets, return_errors=True)
    for x, y, name in zip(a, b, ("offset", "distance", "errors")):
        assert np.array_equal(x, y, equal_nan=True), name
    return b


def option_sets(n_sets, seed=0):
    """MOVING_AVERAGE sets with random window lengths, gains and every law option mixed."""
    rng = np.random.default_rng(seed)
    sets = []
    for i in range(n_sets):
        kw = dict(MA, n_cycles=int(rng.integers(1, 40)), kp=float(rng.uniform(0.2, 1.9)),
                  d_tv=float(rng.choice([0.0, 0.001, 0.004])), i_tn=float(rng.choice([0.0, 0.05, 0.5])))
        if rng.random() < 0.3:
            kw.update(use_adaptive_acceleration=True, a_min=300.0, dist_error_a_min=0.05, dist_error_a_max=0.3)
        if rng.random() < 0.3:
            kw.update(v_weight_down=float(rng.uniform(0.3, 1.0)), a_weight_down=float(rng.uniform(0.3, 1.0)))
        if rng.random() < 0.3:
            kw.update(optimized_scheduling=False)
        if rng.random() < 0.2:
            kw.update(check_sw_limit_switch=True, sw_limit_min=-100.0, sw_limit_max=float(rng.uniform(30.2, 31.0)))
        if rng.random() < 0.1:
            kw.update(max_deviation=float(rng.uniform(0.1, 0.4)))       # 70331 at some point
        if rng.random() < 0.1:
            kw.update(max_act_value_change=100.0)                       # 70329 at the surface step
        if rng.random() < 0.2:
            kw.update(a_max=float(rng.uniform(200.0, 2000.0)), v_max=float(rng.uniform(5.0, 50.0)))
        sets.append(make_params(**kw))
    return sets


@pytest.mark.parametrize("resonant", [False, True])
@pytest.mark.parametrize("mode", list(MODES))
def test_mixed_blocks_equal_closed_loop(tmp_path, mode, resonant):
    block, extra = MODES[mode]
    sets = [p.replace(**extra) for p in option_sets(75, seed=len(mode))]
    z = {"resonance_hz": 40.0, "damping": 0.05} if resonant else None
    sc = make_scenario(tmp_path, sets[0], block + PATH, z=z)
    inputs = CL.prepare(sc)
    off, dist, err = assert_same(inputs, sets)
    packed = CL.pack_sets(inputs, sets)
    lanes, counts, rest = soa.plan_blocks(packed)
    # n_cycles 1 is no filter (PASS): those go one by one; the rest in blocks, the last one partial
    assert len(rest) == int(np.sum(packed[:, law.FC_KIND] != law.MOVING_AVERAGE)) < 10
    assert counts.sum() + len(rest) == 75 and counts.min() < soa.BLOCK
    # the options were exercised: errors of every kind drawn, and controlled offsets
    ids = set(err[err[:, 0] >= 0, 1].tolist())
    assert {int(ErrorId.MAX_DEVIATION), int(ErrorId.SENSOR_JUMP)} <= ids
    assert np.nanmax(np.abs(off)) > 0.05


@pytest.mark.parametrize("variant", ["no_optimized_scheduling", "drive_ff_bus0", "no_noise_no_delay_resolution",
                                     "set_before_select", "sw_limit_error", "lowering_weights",
                                     "resonance_40hz", "resonance_250hz_ff_bus0"])
def test_batch_of_one_replays_the_runner(tmp_path, variant):
    """The plant and law variants of test_closed_loop, with MOVING_AVERAGE: through the block kernel."""
    params = make_params(**MA, n_cycles=6)
    program = MODES["SET_POS"][0] + PATH
    z, sensor, error = {}, {}, None
    if variant == "no_optimized_scheduling":
        params = params.replace(optimized_scheduling=False, kp=1.2, d_tv=0.0)
    elif variant == "drive_ff_bus0":
        z = {"feedforward": 0.6, "bus_delay_cycles": 0, "resolution": 1e-3}
    elif variant == "no_noise_no_delay_resolution":
        params = params.replace(encoder_resolution_num=3, encoder_resolution_denom=7, sensor_sign_reversal=True,
                                ref_offset=0.25)
        sensor = {"noise_std": 0.0, "delay_cycles": 0}
    elif variant == "set_before_select":
        program = "N5 Z[DIST_CTRL SET_POS=29.6]\nN10 G1 X5 F600\nN15 Z[DIST_CTRL ON]" + PATH
    elif variant == "sw_limit_error":
        params = params.replace(check_sw_limit_switch=True, sw_limit_min=-100.0, sw_limit_max=30.3)
        error = ErrorId.SW_LIMIT
    elif variant == "resonance_40hz":              # the drive's mechanical resonance (issue 15)
        z = {"resonance_hz": 40.0, "damping": 0.05}
    elif variant == "resonance_250hz_ff_bus0":
        z = {"resonance_hz": 250.0, "damping": 0.2, "feedforward": 0.5, "bus_delay_cycles": 0, "resolution": 1e-3}
    else:
        params = params.replace(v_weight_down=0.4, a_weight_down=0.5, use_adaptive_acceleration=True,
                                a_min=300.0, dist_error_a_min=0.05, dist_error_a_max=0.3)
    sc = make_scenario(tmp_path, params, program, z=z, sensor=sensor)
    inputs = CL.prepare(sc)
    assert soa.soa_eligible(CL.pack_sets(inputs, [params])).all()
    assert_replays(sc, inputs, error)
    assert_same(inputs, [params, params.replace(kp=0.3), params.replace(n_cycles=1)])


def test_batch_mixing_block_and_one_by_one_sets(tmp_path):
    """Non-MOVING_AVERAGE filters and a modulo encoder go through closed_loop, in the same call."""
    sets = option_sets(40, seed=7)
    sets += [make_params(**FILTERS[f]) for f in ("LOWPASS", "KALMAN_MA", "EXPO_MEAN", "DEFAULT")]
    sc = make_scenario(tmp_path, sets[0], MODES["CONST_DIST_BOTH"][0] + PATH)
    inputs = CL.prepare(sc)
    packed = CL.pack_sets(inputs, sets)
    modulo_row = packed[:1].copy()
    modulo_row[0, law.FC_LEN + CL.Q_MODULO] = 1.0
    modulo_row[0, law.FC_LEN + CL.Q_MIN_POS] = -1000.0      # a span wide enough not to wrap here
    modulo_row[0, law.FC_LEN + CL.Q_MAX_POS] = 1000.0
    packed = np.vstack([packed, modulo_row])
    lanes, counts, rest = soa.plan_blocks(packed)
    assert {40, 41, 42, 44} <= set(rest.tolist())     # LOWPASS, KALMAN_MA, EXPO_MEAN, the modulo row
    assert counts.sum() + len(rest) == 45               # (DEFAULT is the moving average: a block)
    off, dist, err = assert_same(inputs, packed)
    # the modulo copy of row 0, far from wrapping: the same run up to the rounding of the modulo
    assert np.array_equal(err[-1], err[0])
    assert np.nanmax(np.abs(off[-1] - off[0])) < 1e-9


def test_uniform_and_mixed_window_lengths_give_the_same_numbers(tmp_path):
    """A set's result does not depend on the other lanes of its block (shared ring, wraps, errors)."""
    base = option_sets(1, seed=3)[0]
    sets = [base.replace(n_cycles=n, kp=kp) for n in (2, 3, 5, 13, 37, 99) for kp in (0.4, 1.1)]
    sc = make_scenario(tmp_path, sets[0], MODES["SET_POS"][0] + PATH)
    inputs = CL.prepare(sc)
    together = CL.run_batch(inputs, sets, return_errors=True)
    for i, p in enumerate(sets):
        alone = CL.run_batch(inputs, [p], return_errors=True)
        for x, y in zip(together, alone):
            assert np.array_equal(x[i], y[0], equal_nan=True)


@pytest.mark.parametrize("cycles", [1, 5, 7, 8, 9, 13, 64, 203, None])
def test_streamed_trace_lines_of_any_length_and_place(tmp_path, cycles):
    """The block kernel streams its traces a 64-byte line (8 cycles) at a time: rows of any length
    (no whole line, a partial first and last line) and rows that begin anywhere in a line (an odd
    row length places row i at 8 * i * cycles bytes) give closed_loop's numbers, NaN tails of
    errors included."""
    sets = option_sets(70, seed=11)
    sc = make_scenario(tmp_path, sets[0], MODES["CONST_DIST"][0] + PATH)
    inputs = CL.prepare(sc)
    a = CL.run_batch(inputs, sets, cycles=cycles, return_errors=True, vectorised=False)
    b = CL.run_batch(inputs, sets, cycles=cycles, return_errors=True)
    for x, y, name in zip(a, b, ("offset", "distance", "errors")):
        assert np.array_equal(x, y, equal_nan=True), name
    if cycles is None:
        assert (b[2][:, 0] >= 0).any()                # some sets stopped with an error: NaN tails


def test_outputs_that_are_not_contiguous_rows_take_ordinary_stores(tmp_path):
    """Outputs whose rows are strided views (no whole lines to stream) get the same numbers."""
    sets = option_sets(40, seed=5)
    sc = make_scenario(tmp_path, sets[0], MODES["SET_POS"][0] + PATH)
    inputs = CL.prepare(sc)
    ref = CL.run_batch(inputs, sets, return_errors=True, vectorised=False)
    packed = CL.pack_sets(inputs, sets)
    lanes, counts, rest = soa.plan_blocks(packed)
    n = inputs.n_cycles
    wide_o = np.full((len(sets), 2 * n), -7.0)
    wide_d = np.full((len(sets), 2 * n), -7.0)
    out_o, out_d = wide_o[:, ::2], wide_d[:, ::2]
    out_e = np.empty((len(sets), 2), dtype=np.int64)
    CL.run_blocks(packed, lanes, counts, rest, inputs.plant, inputs.prog, inputs.surface, inputs.noise,
                  out_o, out_d, out_e)
    for x, y in zip(ref, (out_o, out_d, out_e)):
        assert np.array_equal(x, y, equal_nan=True)
    assert np.all(wide_o[:, 1::2] == -7.0) and np.all(wide_d[:, 1::2] == -7.0)    # nothing else written


def test_run_batch_writes_into_given_outputs(tmp_path):
    """``out=``: the same numbers, in the caller's arrays (reused between calls); wrong arrays are
    refused with their shape and dtype named."""
    sets = option_sets(20, seed=8)
    sc = make_scenario(tmp_path, sets[0], MODES["SET_POS"][0] + PATH)
    inputs = CL.prepare(sc)
    ref = CL.run_batch(inputs, sets, cycles=301)
    out = (np.full((20, 301), 5.0), np.full((20, 301), 5.0))
    for vectorised in (True, False):
        got = CL.run_batch(inputs, sets, cycles=301, out=out, vectorised=vectorised)
        assert got[0] is out[0] and got[1] is out[1]
        assert np.array_equal(got[0], ref[0], equal_nan=True) and np.array_equal(got[1], ref[1], equal_nan=True)
    with pytest.raises(CL.ClosedLoopError, match=r"shape \(20, 301\).*float32"):
        CL.run_batch(inputs, sets, cycles=301, out=(np.zeros((20, 301), np.float32), out[1]))
    with pytest.raises(CL.ClosedLoopError, match="float64 array of shape"):
        CL.run_batch(inputs, sets, cycles=301, out=(np.zeros((20, 300)), out[1]))
    with pytest.raises(CL.ClosedLoopError, match="overlap"):
        CL.run_batch(inputs, sets, cycles=301, out=(out[0], out[0]))


def test_a_modulo_encoder_that_wraps_gives_the_continuous_run(tmp_path):
    """P-AXIS-00424 modulo in the compiled law (AxisDistanceController._unwrap): a 1 mm window that
    starts just below the first reading, which the reading leaves again and again, gives the same run
    as the linear encoder (no jump of a span, no error). The window must be wider than twice the
    largest real step of the reading (this run has steps of 0.29 mm): a modulo reading cannot tell a
    larger step from a wrap."""
    sets = option_sets(1, seed=7)
    sc = make_scenario(tmp_path, sets[0], MODES["CONST_DIST_BOTH"][0] + PATH)
    inputs = CL.prepare(sc)
    packed = CL.pack_sets(inputs, sets)
    off0, dist0, err0 = assert_same(inputs, packed)
    lo = -float(dist0[0, 0]) - 0.05
    wrapping = packed[:1].copy()
    wrapping[0, law.FC_LEN + CL.Q_MODULO] = 1.0
    wrapping[0, law.FC_LEN + CL.Q_MIN_POS] = lo
    wrapping[0, law.FC_LEN + CL.Q_MAX_POS] = lo + 1.0
    off, dist, err = assert_same(inputs, wrapping)
    valid = ~np.isnan(dist0[0])
    assert np.count_nonzero(-dist0[0][valid] < lo - 0.1) > 100          # the reading really wraps
    assert np.array_equal(err[0], err0[0])
    assert np.nanmax(np.abs(off[0] - off0[0])) < 1e-9
    assert np.array_equal(np.isnan(off[0]), np.isnan(off0[0]))


@pytest.mark.parametrize("mode", list(MODES))
def test_distance_sensor_mixed_blocks_equal_closed_loop(tmp_path, mode):
    """The point distance sensor (SENSOR_SOURCE=VARIABLE) with a characteristic, a quantised reading,
    noise and dead time, on the drive with a 40 Hz resonance: blocks of every option equal closed_loop."""
    block, extra = MODES[mode]
    block = block[:-1] + " " + VARIABLE + "]"
    sets = [p.replace(**extra) for p in option_sets(75, seed=7 + len(mode))]
    sc = make_scenario(tmp_path, sets[0], block + PATH, z={"resonance_hz": 40.0, "damping": 0.05},
                       sensor={"characteristic": CHARACTERISTIC, "resolution": 0.0005}, distance=True)
    inputs = CL.prepare(sc)
    assert inputs.plant[CL.PL_SENSOR] == CL.SENSOR_DISTANCE and inputs.plant[CL.PL_RESONANT] == 1.0
    off, dist, err = assert_same(inputs, sets)
    lanes, counts, rest = soa.plan_blocks(CL.pack_sets(inputs, sets))
    assert counts.sum() > 60
    ids = set(err[err[:, 0] >= 0, 1].tolist())
    assert int(ErrorId.SENSOR_JUMP) in ids
    assert np.nanmax(np.abs(off)) > 0.05


def test_kernel_order_puts_the_lane_rows_first_by_window_and_any_order_gives_each_row_its_numbers():
    """kernel_order (a sweep's blocks go through the kernel in it): the rows block_loop runs first, by window
    length, then the others, each group in its order; the same row gives the same numbers bit for bit in any
    order and any block (every set runs on its own), so the sweep's table does not depend on it."""
    from pathlib import Path

    from distctrl.tuning.columns import check_columns, drop_inert_columns, random_columns

    inputs = CL.prepare(Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "tune_sheet.toml", 400)
    pc, _ = drop_inert_columns(random_columns(300, 5, cycle_time=inputs.cycle_time))
    kept, fc, _ = check_columns(inputs.params, pc, inputs.cycle_time)
    packed = CL.pack_columns(inputs, inputs.params, kept.cols, kept.present, fc)
    order = soa.kernel_order(packed)
    assert sorted(order.tolist()) == list(range(len(packed)))
    lane = soa.soa_eligible(packed)[order]
    k = int(lane.sum())
    assert 0 < k < len(packed) and lane[:k].all() and not lane[k:].any()
    n = packed[order[:k], law.FC_N]
    assert (np.diff(n) >= 0).all()
    assert all((np.diff(order[:k][n == v]) > 0).all() for v in np.unique(n))     # in their order per length
    assert (np.diff(order[k:]) > 0).all()
    want = CL.run_batch(inputs, packed, return_errors=True)
    for block in (37, 256):
        got = [CL.run_batch(inputs, packed[order[a:a + block]], return_errors=True)
               for a in range(0, len(packed), block)]
        for i, name in enumerate(("offset", "distance", "errors")):
            assert np.array_equal(np.concatenate([g[i] for g in got]), want[i][order], equal_nan=True), name
