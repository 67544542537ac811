"""Filter designs for many configurations at once (issue 27): design_rows gives design_coefficients' rows."""
from __future__ import annotations

import numpy as np
import pytest

from distctrl.base.kinds import FilterType
from distctrl.batch.design import design_rows
from distctrl.control import law
from distctrl.control.filters import FilterConfig, design_coefficients


def _random_configs(rng, k, cycle_time):
    ft = rng.choice([int(t) for t in FilterType], k)
    n = rng.integers(-1, 101, k)
    alpha = np.where(rng.random(k) < 0.1, rng.choice([1.0, 0.0, 1e-9, 1.5], k), np.round(rng.uniform(0, 1, k), 3))
    sigma = np.where(rng.random(k) < 0.05, rng.choice([0.5, 1.0, 10000.0, 2e4], k),
                     np.round(np.exp(rng.uniform(0, np.log(10000), k)), 1))
    order = rng.integers(-1, 8, k)
    nyq = 0.5 / cycle_time
    fg = np.where(rng.random(k) < 0.05, rng.choice([0.0, nyq, 1.5 * nyq, -1.0], k), rng.uniform(1e-3, 0.499, k) * 2 * nyq)
    return ft, n, alpha, sigma, order, fg


@pytest.mark.parametrize("seed", range(4))
def test_design_rows_are_design_coefficients_bit_for_bit_and_refuse_what_it_refuses(seed):
    rng = np.random.default_rng(seed)
    for cycle_time in (0.001, 0.0005, float(rng.uniform(1e-4, 0.01))):
        cols = _random_configs(rng, 1500, cycle_time)
        fc, errors = design_rows(*cols, cycle_time)
        for i in range(len(cols[0])):
            t = int(cols[0][i])
            cfg = FilterConfig(FilterType(t), int(cols[1][i]), float(cols[2][i]), float(cols[3][i]), int(cols[4][i]),
                               float(cols[5][i]))
            try:
                want = np.asarray(design_coefficients(cfg, cycle_time), dtype=np.float64)
            except Exception as exc:                                # noqa: BLE001
                assert i in errors, (cfg, exc)
                assert type(errors[i]) is type(exc) and str(errors[i]) == str(exc)
                continue
            assert i not in errors, (cfg, errors.get(i))
            assert fc.shape[1] == law.FC_LEN
            assert np.array_equal(fc[i].view(np.int64), want.view(np.int64)), (cfg, np.nonzero(fc[i] != want))


def test_design_rows_of_the_tuners_grid():
    """Every LOWPASS of the tuner's 0.1 Hz grid and the Kalman sigmas it draws."""
    T = 0.001
    fg = np.round(np.arange(5.0, 200.0, 0.1), 1)
    k = len(fg)
    for ft in (FilterType.LOWPASS, FilterType.KALMAN_MA, FilterType.KALMAN_EXPO, FilterType.EXPO_MEAN):
        cols = (np.full(k, int(ft)), 1 + np.arange(k) % 32, np.round(0.05 + (np.arange(k) % 951) * 0.001, 3),
                fg * 5, 1 + np.arange(k) % 6, fg)
        fc, errors = design_rows(*cols, T)
        assert not errors
        for i in range(0, k, 7):
            cfg = FilterConfig(ft, int(cols[1][i]), float(cols[2][i]), float(cols[3][i]), int(cols[4][i]), float(fg[i]))
            want = np.asarray(design_coefficients(cfg, T), dtype=np.float64)
            assert np.array_equal(fc[i].view(np.int64), want.view(np.int64)), cfg


def test_unique_rows_is_np_unique_of_the_rows():
    from distctrl.batch.design import unique_rows

    rng = np.random.default_rng(2)
    for k in (0, 1, 7, 5000):
        mat = np.stack([rng.integers(0, 4, k).astype(float), np.round(rng.uniform(0, 1, k), 1),
                        rng.choice([0.5, 1.5, 2.5], k)], axis=1)
        u, inv = unique_rows(mat)
        u2, inv2 = np.unique(mat, axis=0, return_inverse=True)
        assert np.array_equal(u, u2.reshape(-1, 3)) and np.array_equal(inv, inv2.reshape(-1))
        assert np.array_equal(u[inv], mat)


def test_a_type_without_vectorised_rows_is_designed_one_by_one(monkeypatch):
    # a new filter type needs no edit in design_rows (docs/architecture.md "A filter type"): a type it has
    # no rows for goes through design_coefficients; here EXPO_MEAN and LOWPASS play the unknown types
    import distctrl.batch.design as design
    monkeypatch.setattr(design, "_ROW_TYPES", design._ROW_TYPES - {int(FilterType.EXPO_MEAN), int(FilterType.LOWPASS)})
    calls = []
    monkeypatch.setattr(design, "design_coefficients", lambda cfg, T: calls.append(cfg) or design_coefficients(cfg, T))
    rng = np.random.default_rng(7)
    cycle_time = 0.001
    cols = _random_configs(rng, 400, cycle_time)
    fc, errors = design.design_rows(*cols, cycle_time)
    seen = 0
    for i in range(len(cols[0])):
        if i in errors or int(cols[0][i]) not in (int(FilterType.EXPO_MEAN), int(FilterType.LOWPASS)):
            continue
        cfg = FilterConfig(FilterType(int(cols[0][i])), int(cols[1][i]), float(cols[2][i]), float(cols[3][i]),
                           int(cols[4][i]), float(cols[5][i]))
        want = np.asarray(design_coefficients(cfg, cycle_time), dtype=np.float64)
        assert fc[i].tobytes() == want.tobytes(), cfg
        seen += 1
    assert seen > 50 and len(calls) == seen       # each of them, and only they, one by one


@pytest.mark.parametrize("kind", [law.KALMAN_MA, law.KALMAN_EXPO])
def test_kalman_predictions_of_many_smoothing_factors_are_kalman_design_of_each_bit_for_bit(kind):
    """design_rows designs the Kalman filters of one (kind, n) for all their smoothing factors at once
    (kalman_predictions: np.matmul of the stacked rows for kalman_design's np.dot): the same bits, for every
    n the law takes, factors from 1e-9 to 1 (no slope at 1), and one group of thousands of factors."""
    from distctrl.batch.design import kalman_predictions
    from distctrl.control.filters import kalman_design

    rng = np.random.default_rng(kind)
    for n in list(range(2, law.MAX_N)) + [13] * 3:
        alphas = np.unique(np.r_[np.round(rng.uniform(0, 1, 40), 3), 1.0, 1e-9, 0.5, rng.uniform(0, 1, 5)])
        if n == 13:
            alphas = np.unique(rng.uniform(1e-6, 1.0, 3000))
        v, c = kalman_predictions(kind, n, alphas)
        for i, a in enumerate(alphas.tolist()):
            d = kalman_design(kind, n, a, 1.0)
            assert d.prediction_variance == v[i] and np.array_equal(d.coefficients, c[i]), (kind, n, a)
