"""The LOWPASS design without scipy (distctrl.control.butter) is scipy.signal.butter's, bit for bit.

The controller and the batch kernels both use it, so scalar core and kernel stay equal by
construction; these tests pin it to scipy over all orders, the tuner's cut-off grid (0.1 Hz up to
0.45/T) at several cycle times, and random unrounded cut-offs."""
import subprocess
import sys

import numpy as np
import pytest

from distctrl.control.butter import butter_lowpass

signal = pytest.importorskip("scipy.signal")


def _bits(x):
    return np.ascontiguousarray(x, dtype=np.float64).view(np.int64)


def _check(order, fgs, fs):
    sos, zi = butter_lowpass(order, fgs, fs)
    for i, fg in enumerate(fgs):
        ref = signal.butter(order, float(fg), btype="low", fs=fs, output="sos")
        assert np.array_equal(_bits(sos[i]), _bits(ref)), (order, fg, fs)
        assert np.array_equal(_bits(zi[i]), _bits(signal.sosfilt_zi(ref))), (order, fg, fs)
    one, one_zi = butter_lowpass(order, fgs[:1], fs)           # one design = the same as in a batch
    assert np.array_equal(_bits(one), _bits(sos[:1])) and np.array_equal(_bits(one_zi), _bits(zi[:1]))


@pytest.mark.parametrize("cycle_time", [1e-3, 5e-4, 2e-3, 1.25e-4])
@pytest.mark.parametrize("order", range(1, 7))
def test_grid_equals_scipy(order, cycle_time):
    grid = np.round(np.arange(5.0, 0.45 / cycle_time, 0.1), 1)
    _check(order, grid[order % 5::5], 1.0 / cycle_time)


@pytest.mark.parametrize("order", range(1, 7))
def test_random_cutoffs_equal_scipy(order):
    rng = np.random.default_rng(order)
    for cycle_time in (1e-3, 3.3e-4, 7e-3):
        fs = 1.0 / cycle_time
        _check(order, rng.uniform(1e-3, 0.4999, 60) * fs, fs)


def test_refuses_what_scipy_refuses():
    with pytest.raises(ValueError):
        butter_lowpass(2, [600.0], 1000.0)
    with pytest.raises(ValueError):
        butter_lowpass(7, [10.0], 1000.0)


def test_lowpass_design_does_not_import_scipy_signal():
    """Importing scipy.signal took seconds (most of a small sweep's fixed cost)."""
    code = ("import sys; from distctrl.control.filters import FilterConfig, design_coefficients; "
            "from distctrl.base.kinds import FilterType; "
            "fc = design_coefficients(FilterConfig(FilterType.LOWPASS, 4, 0.5, 1.0, 4, 120.0), 1e-3); "
            "print('scipy.signal' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "False"


@pytest.mark.parametrize("seed", range(6))
def test_the_vectorised_pairing_gives_the_per_design_numbers_bit_for_bit(seed):
    """butter_lowpass_many (issue 27: no Python per design) against butter_lowpass over thousands of random
    (order, fg, fs), and the tuner's whole 0.1 Hz grid."""
    from distctrl.control.butter import butter_lowpass_many

    rng = np.random.default_rng(seed)
    for order in range(1, 7):
        fs = float(rng.choice([1000.0, 2000.0, 500.0, 4000.0, rng.uniform(100.0, 20000.0)]))
        fgs = np.concatenate([rng.uniform(1e-4, 0.4999, 400) * fs, np.exp(rng.uniform(-6, 0, 100)) * 0.499 * fs,
                              np.round(np.arange(5.0, min(200.0, 0.45 * fs), 0.1), 1) if seed == 0 else []])
        sos, zi = butter_lowpass(order, fgs, fs)
        sos2, zi2 = butter_lowpass_many(order, fgs, fs)
        assert sos2.shape == sos.shape
        assert np.array_equal(sos.view(np.int64), sos2.view(np.int64)), order
        assert np.array_equal(zi.view(np.int64), zi2.view(np.int64)), order
