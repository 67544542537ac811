"""format_rows: byte-identical to '%.17g' and exact round trips, over every float64 kind."""
from __future__ import annotations

import numpy as np
import pytest

from distctrl.trace import format_rows


def ref(a: np.ndarray) -> bytes:
    return "".join(",".join("%.17g" % v for v in row) + "\n" for row in a.tolist()).encode()


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    nan = np.isnan(a) & np.isnan(b)
    return bool(np.all(nan | (a.view(np.uint64) == b.view(np.uint64))))


SPECIAL = [0.0, -0.0, 1.0, -1.0, 3.0, 7.0, 1e16, 1e17, 9.999999999999999e16, 99999999999999999.0, 0.1, 0.3,
           0.1 + 0.2, 1e-4, 1e-5, 9.99999999999999e-5, 5e-324, -5e-324, 2.2250738585072014e-308,
           2.225073858507201e-308, 1.7976931348623157e308, -1.7976931348623157e308, 1e-250, 9.9e-251,
           1e270, 9.99e269, 1e22, 1e23, 123456789012345678.0, 1250000000000000.25, 3 * 2.0 ** -24,
           2.0 ** 53, 2.0 ** 53 + 2, 0.001, 0.003, 1e100, 1e-100, 1e99, 1e-99, float("nan"), float("inf"),
           float("-inf"), -float("nan")]


def test_special_values_match_percent_17g():
    a = np.array([SPECIAL])
    assert format_rows(a) == ref(a)
    a = np.array(SPECIAL).reshape(-1, 1)
    assert format_rows(a) == ref(a)


def test_nan_and_inf_words():
    out = format_rows(np.array([[np.nan, np.inf, -np.inf, -0.0, 0.0]]))
    assert out == b"nan,inf,-inf,-0,0\n"


def test_integers_are_written_as_integers():
    out = format_rows(np.array([[1.0, 12.0, 0.0, -7.0, 1234567.0, 2.0 ** 52]]))
    assert out == b"1,12,0,-7,1234567,4503599627370496\n"


def test_random_bit_patterns_match_and_round_trip():
    rng = np.random.default_rng(7)
    a = rng.integers(0, 2 ** 64, size=(60_000, 5), dtype=np.uint64).view(np.float64)
    out = format_rows(a)
    assert out == ref(a)
    back = np.array([[float(v) for v in line.split(b",")] for line in out.splitlines()])
    assert same_bits(back, a)


def test_random_magnitudes_match():
    rng = np.random.default_rng(8)
    a = rng.standard_normal((20_000, 8)) * 10.0 ** rng.integers(-12, 12, size=(20_000, 8))
    a[::5, 2] = np.round(a[::5, 2])
    a[::3, 3] = 0.0
    a[:, 0] = np.arange(20_000) * 0.001
    assert format_rows(a) == ref(a)


def test_neighbours_of_powers_of_ten():
    p = 10.0 ** np.arange(-307, 308)
    bits = p.view(np.int64)
    a = (bits[:, None] + np.arange(-20, 21)).view(np.float64)   # 20 ulps either side of each power
    assert format_rows(a) == ref(a)
    assert format_rows(-a.T) == ref(-a.T)


def test_values_rounding_into_the_next_decade():
    # 17 nines and beyond round up to 1e(n+1): 9.99999999999999999e n
    a = np.array([[float("9.999999999999999999e%d" % n) for n in range(-30, 30)]])
    assert format_rows(a) == ref(a)


@pytest.mark.parametrize("shape", [(0, 3), (1, 1), (3, 1), (1, 40), (5000, 7)])
def test_shapes_and_blocks(shape):
    rng = np.random.default_rng(1)
    a = rng.standard_normal(shape)
    assert format_rows(a) == ref(a)
    assert format_rows(a, block_values=3) == ref(a)


def test_rejects_1d():
    with pytest.raises(ValueError):
        format_rows(np.zeros(3))
