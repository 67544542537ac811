"""The numba kernel runs the very same law as the CPython cycle core.

Reference: :class:`AxisDistanceController` in a closed loop with an ideal plant (the axis is where
it was commanded last cycle, the probe reads s = surface - actual), ON with SET_POS at cycle 0.
The encoder is configured to 1 mm per increment, so the controller reads exactly the s the
kernel computes.
"""
from __future__ import annotations

import json
import subprocess
import sys
import types

import numpy as np
import pytest

numba = pytest.importorskip("numba")

from distctrl.batch import kernel as K  # noqa: E402
from distctrl.batch import numba_available  # noqa: E402
from distctrl.control import (Action, AxisDistanceController, Command, CycleInput, CycleOutput,  # noqa: E402
                              FilterType, Result, law)
from distctrl.params import AxisParameters  # noqa: E402

T = 0.001
PROG = 40.0          # programmed position of Z, mm (constant)
SET_POS = 40.0       # workpiece surface programmed at 40 mm
N = 3000

FILTERS = {
    "MOVING_AVERAGE": dict(filter_type=FilterType.MOVING_AVERAGE, n_cycles=8),
    "EXPO_MEAN": dict(filter_type=FilterType.EXPO_MEAN, n_cycles=12, smoothing_factor=0.3),
    "LOWPASS": dict(filter_type=FilterType.LOWPASS, low_pass_filter_order=4, low_pass_filter_fg_f0=40.0),
    "KALMAN_MA": dict(filter_type=FilterType.KALMAN_MA, n_cycles=20, kalman_sigma=1000.0),
    "KALMAN_EXPO": dict(filter_type=FilterType.KALMAN_EXPO, n_cycles=10, smoothing_factor=0.4, kalman_sigma=50.0),
}


def make_params(**changes) -> AxisParameters:
    base = dict(enabled=True, kp=0.5, i_tn=0.05, d_tv=0.002, v_max=5.0, a_max=800.0,
                max_act_value_change=100000.0,          # the kernel does not monitor: stay clear of 70329
                optimized_scheduling=True,
                encoder_resolution_num=1, encoder_resolution_denom=10000)   # 1 mm per increment
    base.update(changes)
    return AxisParameters(**base)


def surface_signal(n: int = N, seed: int = 7) -> np.ndarray:
    """Surface near SET_POS: a step (the limiter clips), a slope, a sine and noise."""
    k = np.arange(n)
    rng = np.random.default_rng(seed)
    surface = (SET_POS + 0.4 * (k >= 300) - 0.3 * (k >= 1500) + 0.2 * np.sin(2 * np.pi * 3.0 * k * T)
               + 1e-4 * np.clip(k - 2000, 0, None) + rng.normal(0.0, 0.003, n))
    return surface.astype(np.float64)


def run_controller(params: AxisParameters, surface: np.ndarray, s_before: float | None = None,
                   stop_at_error: bool = False):
    """Offsets and velocities of the CPython cycle core in the ideal closed loop (up to and
    including the cycle of the first error if ``stop_at_error``)."""
    ctrl = AxisDistanceController(params, T)
    inp, out = CycleInput(programmed_position=PROG), CycleOutput()
    act = PROG
    if s_before is not None:                 # one INACTIVE cycle before: the delayed reading
        inp.actual_position = act
        inp.sensor_increments = s_before
        assert ctrl.update(inp, out) == Result.OK
    inp.commands.append(Command(Action.ON, set_pos=SET_POS))
    offsets, velocities = [], []
    for x in surface:
        inp.actual_position = act
        inp.sensor_increments = float(x) - act
        result = ctrl.update(inp, out)
        offsets.append(out.offset)
        velocities.append(out.offset_velocity)
        if stop_at_error and result == Result.ERROR:
            break
        assert result == Result.OK, out.events
        act = out.command_position
    return np.array(offsets), np.array(velocities)


@pytest.mark.parametrize("name", list(FILTERS))
def test_kernel_reproduces_cycle_core(name):
    params = make_params(**FILTERS[name])
    surface = surface_signal()
    o_ref, v_ref = run_controller(params, surface)
    fc, prm = K.pack_params(params, T, SET_POS, PROG)
    o, v = K.run_setpos_loop(fc, prm, surface, len(surface))
    assert o.shape == (N,) and v.shape == (N,)
    np.testing.assert_allclose(o, o_ref, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(v, v_ref, rtol=0.0, atol=1e-6)
    # the scenario exercises the limiter: velocity or acceleration limit reached
    at_v_max = np.max(np.abs(v_ref)) >= params.v_max * (1 - 1e-9)
    at_a_max = np.max(np.abs(np.diff(v_ref))) >= params.a_max * T * (1 - 1e-9)
    assert at_v_max or at_a_max


def test_kernel_lowering_weights_and_adaptive_acceleration():
    params = make_params(**FILTERS["KALMAN_MA"], v_weight_down=0.5, a_weight_down=0.25,
                         use_adaptive_acceleration=True, a_min=200.0, dist_error_a_min=0.01,
                         dist_error_a_max=0.2)
    surface = surface_signal(seed=3)
    o_ref, _ = run_controller(params, surface)
    fc, prm = K.pack_params(params, T, SET_POS, PROG)
    o, _ = K.run_setpos_loop(fc, prm, surface, len(surface))
    np.testing.assert_allclose(o, o_ref, rtol=0.0, atol=1e-9)


def test_kernel_offset_bound():
    """max_deviation: both brake onto the bound; the cycle core then raises 70331 (the kernel does
    not monitor and stays at the bound), so the comparison ends with that cycle."""
    params = make_params(**FILTERS["MOVING_AVERAGE"], max_deviation=0.35)
    surface = surface_signal(seed=5)          # the 0.4 mm step wants more than 0.35 mm
    o_ref, _ = run_controller(params, surface, stop_at_error=True)
    assert len(o_ref) < N and o_ref[-1] == pytest.approx(0.35, abs=1e-9)
    fc, prm = K.pack_params(params, T, SET_POS, PROG)
    o, _ = K.run_setpos_loop(fc, prm, surface, len(surface))
    np.testing.assert_allclose(o[:len(o_ref)], o_ref, rtol=0.0, atol=1e-9)
    assert np.all(np.abs(o) <= 0.35)


def test_kernel_without_optimized_scheduling():
    """optimized_scheduling = 0: the law sees the previous cycle's reading in both."""
    params = make_params(**FILTERS["EXPO_MEAN"], optimized_scheduling=False)
    surface = surface_signal(seed=11)
    s_before = float(surface[0]) - PROG
    o_ref, _ = run_controller(params, surface, s_before=s_before)
    fc, prm = K.pack_params(params, T, SET_POS, PROG, s_before=s_before)
    o, _ = K.run_setpos_loop(fc, prm, surface, len(surface))
    np.testing.assert_allclose(o, o_ref, rtol=0.0, atol=1e-9)


def test_batch_equals_single_runs():
    sets = [make_params(**f) for f in FILTERS.values()]
    packed = [K.pack_params(p, T, SET_POS, PROG) for p in sets]
    fc2 = np.stack([fc for fc, _ in packed])
    prm2 = np.stack([prm for _, prm in packed])
    surface = surface_signal(seed=1)
    o2, v2 = K.run_setpos_batch(fc2, prm2, surface, len(surface))
    assert o2.shape == (len(sets), N)
    for i, (fc, prm) in enumerate(packed):
        o, v = K.run_setpos_loop(fc, prm, surface, len(surface))
        np.testing.assert_array_equal(o2[i], o)
        np.testing.assert_array_equal(v2[i], v)


def test_n_cycles_shorter_than_surface_and_into():
    fc, prm = K.pack_params(make_params(), T, SET_POS, PROG)
    surface = surface_signal()
    o, v = K.run_setpos_loop(fc, prm, surface, 100)
    o_full, v_full = K.run_setpos_loop(fc, prm, surface, len(surface))
    assert o.shape == (100,)
    np.testing.assert_array_equal(o, o_full[:100])
    out_o, out_v = np.full(N + 5, np.nan), np.full(N + 5, np.nan)
    assert K.run_setpos_loop_into(fc, prm, surface, out_o, out_v) == N
    np.testing.assert_array_equal(out_o[:N], o_full)
    np.testing.assert_array_equal(out_v[:N], v_full)
    assert np.isnan(out_o[N:]).all()


_COMPILE_SCRIPT = r"""
import warnings
warnings.simplefilter("error")          # numba's pedantic IR warnings included
from distctrl.batch import kernel
kernel.compile_kernels()
print("ok")
"""


def test_kernels_compile_without_warnings():
    proc = subprocess.run([sys.executable, "-c", _COMPILE_SCRIPT], capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr[-3000:]


# ----------------------------------------------------------------------------- CPython unaffected

_REFERENCE_SCRIPT = r"""
import json, sys
from distctrl.control import law
from distctrl.control.filters import FilterConfig, design_coefficients
from distctrl.base.kinds import FilterType
import distctrl.control.controller  # the whole cycle core
out = {}
for ft in (FilterType.MOVING_AVERAGE, FilterType.EXPO_MEAN, FilterType.LOWPASS, FilterType.KALMAN_MA,
           FilterType.KALMAN_EXPO):
    fc = design_coefficients(FilterConfig(ft, 7, 0.3, 20.0, 3, 30.0), 0.001)
    fs, buf = [0.0] * law.FS_LEN, [0.0] * law.MAX_N
    law.filter_seed(fc, fs, buf, 1.0)
    out[ft.name] = [law.filter_step(fc, fs, buf, 1.0 + 0.01 * k + (0.5 if k > 20 else 0.0)) for k in range(60)]
out["numba_imported"] = "numba" in sys.modules
print(json.dumps(out))
"""


def test_law_from_cpython_unchanged_after_kernel_import():
    """Registering with numba leaves the law functions plain Python functions, same numbers."""
    proc = subprocess.run([sys.executable, "-c", _REFERENCE_SCRIPT], capture_output=True, text=True, check=True)
    reference = json.loads(proc.stdout)
    assert reference.pop("numba_imported") is False      # distctrl.control never imports numba
    from distctrl.control.filters import FilterConfig, design_coefficients

    for fn in law.LAW_FUNCTIONS:
        assert type(fn) is types.FunctionType
        assert getattr(law, fn.__name__) is fn
    K.register_law()                                      # idempotent
    for name, values in reference.items():
        fc = design_coefficients(FilterConfig(FilterType[name], 7, 0.3, 20.0, 3, 30.0), 0.001)
        fs, buf = [0.0] * law.FS_LEN, [0.0] * law.MAX_N
        law.filter_seed(fc, fs, buf, 1.0)
        got = [law.filter_step(fc, fs, buf, 1.0 + 0.01 * k + (0.5 if k > 20 else 0.0)) for k in range(60)]
        assert got == values, name


def test_numba_available():
    assert numba_available() is True
    assert K.numba_available() is True
