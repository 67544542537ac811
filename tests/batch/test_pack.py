"""pack_sets packs parameter sets straight into the kernel's rows (issue 27): no AxisDistanceController per
set, each distinct filter designed once, and the rows bit for bit those the controller's constants give."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("numba")

from distctrl.batch import closed_loop as CL  # noqa: E402
from distctrl.batch import kernel as K  # noqa: E402
from distctrl.control import FilterType, filters  # noqa: E402
from distctrl.control import controller as ctl  # noqa: E402
from distctrl.control import law  # noqa: E402
from distctrl.tuning.space import build_sets, random_sample  # noqa: E402

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


@pytest.fixture(scope="module")
def inputs():
    return CL.prepare(SCN / "tune_sheet.toml", cycles=50)


def reference_rows(inputs, param_sets) -> np.ndarray:
    """The rows as pack_sets wrote them up to issue 27: from one AxisDistanceController per set."""
    T = inputs.cycle_time
    rows = np.zeros((len(param_sets), CL.PACKED_LEN))
    for i, p in enumerate(param_sets):
        ctrl = ctl.AxisDistanceController(p, T)
        c = ctrl.law_constants()
        probe = inputs.scenario.sensor.make_sensor(T, p)
        q = np.zeros(CL.Q_LEN)
        K.put_law_constants(q, c)
        q[CL.Q_ADAPTIVE] = 1.0 if p.use_adaptive_acceleration else 0.0
        q[CL.Q_A_MIN] = p.a_min
        q[CL.Q_DEV_A_MIN] = p.dist_error_a_min
        q[CL.Q_DEV_A_MAX] = p.dist_error_a_max
        q[CL.Q_OPTIMIZED] = 1.0 if p.optimized_scheduling else 0.0
        q[CL.Q_BOTH] = 1.0 if p.use_both_encoders else 0.0
        q[CL.Q_MAX_DEV] = p.max_deviation
        q[CL.Q_CHECK_SW] = 1.0 if p.check_sw_limit_switch else 0.0
        q[CL.Q_SW_MIN] = p.sw_limit_min
        q[CL.Q_SW_MAX] = p.sw_limit_max
        q[CL.Q_JUMP] = ctrl._jump_limit
        q[CL.Q_S_HI] = ctrl._s_hi
        q[CL.Q_S_LO] = ctrl._s_lo
        q[CL.Q_MM_PER_INCR] = ctrl._mm_per_incr
        q[CL.Q_SIGN_REV] = 1.0 if p.sensor_sign_reversal else 0.0
        q[CL.Q_REF_OFF] = p.ref_offset + ctrl.state.ref_shift
        q[CL.Q_MODULO] = 1.0 if ctrl._modulo else 0.0
        q[CL.Q_MIN_POS] = p.min_pos
        q[CL.Q_MAX_POS] = p.max_pos
        q[CL.Q_PROBE_IPM] = probe.increments_per_mm
        q[CL.Q_PROBE_REF] = probe.ref_offset
        rows[i, :law.FC_LEN] = c["fc"]
        rows[i, law.FC_LEN:] = q
    return rows


def varied_sets(inputs, n=400):
    """Random tuning points, plus sets that change the limiter, encoder and monitoring parameters."""
    base = inputs.params
    sets, _, rejected = build_sets(base, random_sample(n, seed=11, cycle_time=inputs.cycle_time),
                                   inputs.cycle_time)
    assert not rejected
    extra = [dict(a_max=0.0), dict(use_adaptive_acceleration=True, a_min=50.0), dict(v_weight_down=0.5),
             dict(a_weight_down=0.25, use_adaptive_acceleration=True, a_min=10.0), dict(i_tn=1e-12),
             dict(optimized_scheduling=False), dict(use_both_encoders=True), dict(check_sw_limit_switch=True),
             dict(sensor_sign_reversal=True), dict(encoder_resolution_num=3, encoder_resolution_denom=7),
             dict(ref_offset=-0.0), dict(ref_offset=1.25), dict(sensor_mode_act_pos=2), dict(kp=0.99, d_tv=0.3),
             dict(filter_type=FilterType.DEFAULT), dict(filter_type=FilterType.LOWPASS, low_pass_filter_order=0),
             dict(filter_type=FilterType.EXPO_MEAN, n_cycles=1, smoothing_factor=1.0)]
    return sets + [base.replace(**e) for e in extra]


def test_pack_sets_gives_the_controllers_rows_bit_for_bit(inputs):
    sets = varied_sets(inputs)
    got = CL.pack_sets(inputs, sets)
    want = reference_rows(inputs, sets)
    assert got.shape == want.shape
    same = (got.view(np.int64) == want.view(np.int64))
    bad = np.argwhere(~same)
    assert same.all(), f"{len(bad)} values differ, first at row {bad[0][0]} column {bad[0][1]}"


def test_pack_sets_builds_no_controller_and_designs_each_filter_once(inputs, monkeypatch):
    sets = varied_sets(inputs)
    built, designed = [], []
    init, design = ctl.AxisDistanceController.__init__, filters.design_coefficients

    def counting_init(self, *a, **k):
        built.append(1)
        init(self, *a, **k)

    def counting_design(config, cycle_time):
        designed.append(config)
        return design(config, cycle_time)

    from distctrl.batch import design as D
    D.clear_cache()
    monkeypatch.setattr(ctl.AxisDistanceController, "__init__", counting_init)
    monkeypatch.setattr(filters, "design_coefficients", counting_design)
    monkeypatch.setattr(D, "design_coefficients", counting_design)
    CL.pack_sets(inputs, sets + sets)
    distinct = {D.filter_config(p) for p in sets}
    assert not built
    assert len(designed) == len(distinct) < len(sets)


def test_pack_sets_refuses_what_it_refused(inputs):
    with pytest.raises(CL.ClosedLoopError, match=r"param_sets\[1\]: an AxisParameters, not dict"):
        CL.pack_sets(inputs, [inputs.params, {"kp": 1}])
    with pytest.raises(CL.ClosedLoopError, match=r"param_sets\[0\]: distance control not enabled"):
        CL.pack_sets(inputs, [inputs.params.replace(enabled=False)])


def test_derivative_gains_is_law_derivative_gain_bit_for_bit():
    rng = np.random.default_rng(4)
    kp = np.concatenate([rng.uniform(0, 2.5, 20000), [0.0, 1.0, 0.999, 1.5, -0.1]])
    d_tv = np.concatenate([np.where(rng.random(20000) < 0.2, 0.0, np.exp(rng.uniform(-12, 1, 20000))),
                           [0.01, 0.01, 0.05, 0.01, 0.01]])
    for T in (0.001, 0.0005, 0.0037):
        got = CL.derivative_gains(kp, d_tv, T)
        want = np.array([law.derivative_gain(a, b, T) for a, b in zip(kp.tolist(), d_tv.tolist())])
        assert np.array_equal(got.view(np.int64), want.view(np.int64))
