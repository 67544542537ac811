"""Sensor filters: scipy oracle, a procedural twin per filter, and the documents' filter claims."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from distctrl.control.filters import FilterConfig, SensorFilter
from distctrl.control.kinds import FilterType
from distctrl.errors import ParameterError

T = 0.001


def obstacle_signal(noise=0.05, seed=7, n_flat=600, n_high=600, height=2.8):
    """The documents' test (seeds/000 §4): a ~2.8 mm obstacle crossed by the sensor, with noise."""
    rng = np.random.default_rng(seed)
    x = np.r_[np.zeros(n_flat), np.full(n_high, height)]
    return x + rng.normal(0.0, noise, x.size), n_flat


def noise_rms(y, n_flat, warm=150):
    flat = y[warm:n_flat]
    return float(np.sqrt(np.mean((flat - flat.mean()) ** 2)))


def delay_cycles(y, n_flat, height=2.8):
    """Cycles from the obstacle edge until the output first reaches half the obstacle height."""
    after = np.nonzero(y[n_flat:] >= height / 2)[0]
    return int(after[0]) if after.size else 10**9


def run(cfg, x):
    return SensorFilter(cfg, T).apply(x)


# ----------------------------------------------------------------------------- oracle / twins

@pytest.mark.parametrize("order", [1, 2, 3, 4, 5, 6])
@pytest.mark.parametrize("fg", [5.0, 30.0, 250.0, 499.0])
def test_lowpass_equals_scipy_sosfilt(order, fg):
    x, _ = obstacle_signal(noise=0.2)
    y = run(FilterConfig(FilterType.LOWPASS, order=order, fg_f0=fg), x)
    sos = signal.butter(order, fg, btype="low", fs=1 / T, output="sos")
    ref, _ = signal.sosfilt(sos, x, zi=signal.sosfilt_zi(sos) * x[0])
    assert np.max(np.abs(y - ref)) <= 1e-9


def test_lowpass_order_zero_is_pass_through():
    x, _ = obstacle_signal()
    assert np.array_equal(run(FilterConfig(FilterType.LOWPASS, order=0, fg_f0=0.0), x), x)


@pytest.mark.parametrize("fg", [500.0, 800.0, 0.0])
def test_lowpass_cutoff_at_or_above_nyquist_or_zero_is_a_parameter_error(fg):
    with pytest.raises(ParameterError, match="P-AXIS-00508"):
        SensorFilter(FilterConfig(FilterType.LOWPASS, order=2, fg_f0=fg), T)


def twin_moving_average(x, n):
    padded = np.r_[np.full(n - 1, x[0]), x]
    return np.convolve(padded, np.ones(n) / n, mode="valid")


def twin_expo_mean(x, n, alpha):
    w = alpha * (1 - alpha) ** np.arange(n)             # k = 0 newest
    padded = np.r_[np.full(n - 1, x[0]), x]
    return np.array([np.dot(w, padded[i + n - 1::-1][:n]) for i in range(x.size)]) / w.sum()


def twin_kalman(x, n, sigma, alpha=None):
    """Straightforward Kalman with a mean-of-last-n-estimates prediction (SPEC §4)."""
    est = [x[0]] * n
    p = (-1 + np.sqrt(1 + 4 * sigma)) / 2                # stationary variance, as the filter starts
    w = np.ones(n) if alpha is None else alpha * (1 - alpha) ** np.arange(n)
    out = []
    for z in x:
        last = np.array(est[-n:][::-1])                  # newest first
        pred = float(np.dot(w, last) / w.sum())
        pm = p + 1
        k = pm / (pm + sigma)
        xe = pred + k * (z - pred)
        p = (1 - k) * pm
        est.append(xe)
        out.append(xe)
    return np.array(out)


@pytest.mark.parametrize("n", [2, 4, 17, 99])
def test_moving_average_equals_twin(n):
    x, _ = obstacle_signal(noise=0.3)
    np.testing.assert_allclose(run(FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=n), x),
                               twin_moving_average(x, n), atol=1e-10)


def test_default_is_moving_average_of_four_whatever_n_cycles():
    x, _ = obstacle_signal(noise=0.3)
    np.testing.assert_allclose(run(FilterConfig(FilterType.DEFAULT, n_cycles=30), x),
                               twin_moving_average(x, 4), atol=1e-10)


@pytest.mark.parametrize("n, alpha", [(2, 0.5), (30, 0.3), (30, 0.05), (99, 0.01)])
def test_expo_mean_equals_twin(n, alpha):
    x, _ = obstacle_signal(noise=0.3)
    np.testing.assert_allclose(run(FilterConfig(FilterType.EXPO_MEAN, n_cycles=n, smoothing_factor=alpha), x),
                               twin_expo_mean(x, n, alpha), atol=1e-9)


@pytest.mark.parametrize("kind", [FilterType.KALMAN_MA, FilterType.KALMAN_EXPO])
@pytest.mark.parametrize("n, sigma", [(2, 1.0), (20, 1000.0), (30, 100.0)])
def test_kalman_equals_twin(kind, n, sigma):
    x, _ = obstacle_signal(noise=0.3)
    alpha = 0.3 if kind == FilterType.KALMAN_EXPO else None
    cfg = FilterConfig(kind, n_cycles=n, kalman_sigma=sigma, smoothing_factor=alpha or 0.7)
    np.testing.assert_allclose(run(cfg, x), twin_kalman(x, n, sigma, alpha), atol=1e-9)


@pytest.mark.parametrize("cfg", [FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=1),
                                 FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=0),
                                 FilterConfig(FilterType.KALMAN_MA, n_cycles=1),
                                 FilterConfig(FilterType.EXPO_MEAN, n_cycles=10, smoothing_factor=1.0)])
def test_pass_through_cases(cfg):
    x, _ = obstacle_signal()
    assert np.array_equal(run(cfg, x), x)


@pytest.mark.parametrize("ft", [FilterType.MOVING_AVERAGE, FilterType.EXPO_MEAN, FilterType.LOWPASS,
                                FilterType.KALMAN_MA, FilterType.KALMAN_EXPO])
def test_starting_from_the_first_sample_causes_no_jump(ft):
    y = run(FilterConfig(ft, n_cycles=20, fg_f0=30, order=4, kalman_sigma=100), np.full(50, 31.7))
    assert np.max(np.abs(y - 31.7)) <= 1e-12


def test_running_sum_does_not_drift_over_a_long_signal():
    rng = np.random.default_rng(3)
    x = 1e4 + rng.normal(0, 1, 200_000)
    x[1000] = 1e9                                     # a glitch passes through the window
    y = run(FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=7), x)
    np.testing.assert_allclose(y[-5000:], twin_moving_average(x, 7)[-5000:], rtol=0, atol=1e-9)


# ----------------------------------------------------------------------------- the documents' claims

def test_moving_average_more_n_less_noise_more_delay():
    x, edge = obstacle_signal()
    ys = [run(FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=n), x) for n in (5, 10, 20, 40)]
    noise = [noise_rms(y, edge) for y in ys]
    delay = [delay_cycles(y, edge) for y in ys]
    assert noise == sorted(noise, reverse=True) and len(set(noise)) == 4
    assert delay == sorted(delay) and len(set(delay)) == 4


def test_expo_mean_more_n_less_noise_more_delay_and_larger_alpha_less_smoothing():
    x, edge = obstacle_signal()
    ys = [run(FilterConfig(FilterType.EXPO_MEAN, n_cycles=n, smoothing_factor=0.05), x) for n in (5, 10, 20, 40)]
    noise = [noise_rms(y, edge) for y in ys]
    delay = [delay_cycles(y, edge) for y in ys]
    assert noise == sorted(noise, reverse=True) and delay == sorted(delay) and delay[0] < delay[-1]
    ys = [run(FilterConfig(FilterType.EXPO_MEAN, n_cycles=30, smoothing_factor=a), x) for a in (0.05, 0.1, 0.3, 0.7)]
    noise = [noise_rms(y, edge) for y in ys]
    delay = [delay_cycles(y, edge) for y in ys]
    assert noise == sorted(noise) and len(set(noise)) == 4          # larger alpha: less smoothing
    assert delay == sorted(delay, reverse=True) and delay[0] > delay[-1]


def test_expo_mean_influence_of_n_shrinks_with_larger_alpha():
    x, edge = obstacle_signal()

    def spread(alpha):
        ns = [noise_rms(run(FilterConfig(FilterType.EXPO_MEAN, n_cycles=n, smoothing_factor=alpha), x), edge)
              for n in (10, 40)]
        return abs(ns[0] - ns[1])
    assert spread(0.7) < spread(0.1) < spread(0.02)


@pytest.mark.parametrize("kind", [FilterType.KALMAN_MA, FilterType.KALMAN_EXPO])
def test_kalman_larger_sigma_less_noise(kind):
    x, edge = obstacle_signal()
    noise = [noise_rms(run(FilterConfig(kind, n_cycles=20, kalman_sigma=s, smoothing_factor=0.3), x), edge)
             for s in (1, 10, 100, 1000, 10000)]
    assert noise == sorted(noise, reverse=True) and len(set(noise)) == 5


@pytest.mark.parametrize("kind", [FilterType.KALMAN_MA, FilterType.KALMAN_EXPO])
def test_kalman_more_n_less_noise_more_delay(kind):
    x, edge = obstacle_signal()
    ys = [run(FilterConfig(kind, n_cycles=n, kalman_sigma=100, smoothing_factor=0.1), x) for n in (3, 10, 30, 90)]
    noise = [noise_rms(y, edge) for y in ys]
    delay = [delay_cycles(y, edge) for y in ys]
    assert noise == sorted(noise, reverse=True)
    assert delay == sorted(delay) and delay[0] < delay[-1]


def dead_time_cycles(y, n_flat, height=2.8, fraction=0.1):
    """Cycles from the edge until the output has made 10 % of the step: the filter's dead time."""
    after = np.nonzero(y[n_flat:] >= fraction * height)[0]
    return int(after[0]) if after.size else 10**9


@pytest.mark.parametrize("n", [20, 40, 90])
@pytest.mark.parametrize("sigma", [1.0, 10.0, 30.0])
@pytest.mark.parametrize("kind, plain", [(FilterType.KALMAN_MA, FilterType.MOVING_AVERAGE),
                                         (FilterType.KALMAN_EXPO, FilterType.EXPO_MEAN)])
def test_kalman_dead_time_is_shorter_than_the_plain_filter(n, sigma, kind, plain):
    """seeds/000 §4.4.1: 'The prediction characteristic of the Kalman filter reduces the dead time
    compared to a conventional moving averaging filter' (same n). With SPEC §4's law this holds for
    sigma up to about 30; see docs/control-law.md for the trade-off at larger sigma."""
    x, edge = obstacle_signal(noise=0.0)
    kal = dead_time_cycles(run(FilterConfig(kind, n_cycles=n, kalman_sigma=sigma, smoothing_factor=0.05), x), edge)
    base = dead_time_cycles(run(FilterConfig(plain, n_cycles=n, smoothing_factor=0.05), x), edge)
    assert kal < base


@pytest.mark.parametrize("n", [5, 10, 20, 40, 90])
def test_kalman_with_small_sigma_also_reaches_half_the_step_sooner(n):
    x, edge = obstacle_signal(noise=0.0)
    kal = delay_cycles(run(FilterConfig(FilterType.KALMAN_MA, n_cycles=n, kalman_sigma=1.0), x), edge)
    ma = delay_cycles(run(FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=n), x), edge)
    assert kal < ma


def test_lowpass_lower_cutoff_less_noise_more_delay():
    x, edge = obstacle_signal()
    ys = [run(FilterConfig(FilterType.LOWPASS, order=2, fg_f0=fg), x) for fg in (100.0, 30.0, 10.0)]
    noise = [noise_rms(y, edge) for y in ys]
    delay = [delay_cycles(y, edge) for y in ys]
    assert noise == sorted(noise, reverse=True) and delay == sorted(delay)


def test_filter_object_state_is_public_and_apply_starts_fresh():
    f = SensorFilter(FilterConfig(FilterType.MOVING_AVERAGE, n_cycles=3), T)
    assert [f.step(v) for v in (3.0, 3.0, 6.0)] == [3.0, 3.0, 4.0]
    assert f.last == 4.0 and f.buf[:3] == [3.0, 3.0, 6.0] or sorted(f.buf[:3]) == [3.0, 3.0, 6.0]
    np.testing.assert_allclose(f.apply([1.0, 1.0, 4.0]), [1.0, 1.0, 2.0])
    assert f.last == 4.0                                # apply() did not touch this filter's state
