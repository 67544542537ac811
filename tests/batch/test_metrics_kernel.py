"""The compiled metrics pass (distctrl.batch.metrics_kernel) equals the numpy definition bit for bit.

The sweep table is pinned bit for bit (tests/tuning/test_sweep_golden.py); these tests compare every
figure of many random chunks (NaN tails of failed sets, adaptive acceleration, lowering weights,
short windows, windows shorter than the hold time) with :func:`reference_metrics`, not a few.
"""
import numpy as np
import pytest

pytest.importorskip("numba")

from distctrl.batch import metrics_kernel as MK  # noqa: E402
from distctrl.tuning.metrics import METRIC_NAMES, compute_metrics, reference_metrics  # noqa: E402


def _bits(x):
    return np.asarray(x, dtype=np.float64).view(np.int64)


def test_pairwise_sum_is_numpys():
    rng = np.random.default_rng(7)
    lengths = list(range(0, 300)) + [int(v) for v in rng.integers(300, 20000, 300)]
    for n in lengths:
        x = rng.normal(size=n) * 10.0 ** rng.integers(-6, 6)
        if n and rng.random() < 0.3:
            x[rng.random(n) < 0.5] = 0.0
        assert _bits(MK.row_sum(x)) == _bits(x.sum()), n
        rows = np.ascontiguousarray(np.stack([x, -x[::-1]]))
        assert np.array_equal(_bits([MK.row_sum(r) for r in rows]), _bits(rows.sum(axis=1))), n


def _limits(rng, n_sets):
    return {"v_lim": rng.uniform(1.0, 60.0, n_sets), "a_lim": rng.uniform(50.0, 3000.0, n_sets),
            "w_v": rng.choice([1.0, 0.5, 0.8], n_sets), "w_a": rng.choice([1.0, 0.3], n_sets),
            "adaptive": rng.random(n_sets) < 0.4, "a_min": rng.uniform(10.0, 50.0, n_sets),
            "dev_a_min": rng.uniform(0.0, 0.1, n_sets), "dev_a_max": rng.uniform(0.05, 0.6, n_sets),
            "T": np.full(n_sets, 1e-3)}


def _chunk(rng, n_sets, n):
    t = np.arange(n) * 1e-3
    f = rng.uniform(1.0, 80.0, (n_sets, 1))
    amp = 10.0 ** rng.uniform(-3, 0.3, (n_sets, 1))
    distance = 1.0 + amp * np.exp(-t * rng.uniform(0, 20, (n_sets, 1))) * np.sin(2 * np.pi * f * t) \
        + rng.normal(0, 0.01, (n_sets, n)) * rng.random((n_sets, 1))
    offset = np.cumsum(rng.normal(0, 0.02, (n_sets, n)) * rng.random((n_sets, 1)), axis=1)
    offset[rng.random(n_sets) < 0.2] = np.round(offset[0], 1)     # flat stretches: v = 0, ties
    for i in np.nonzero(rng.random(n_sets) < 0.25)[0]:             # failed sets: NaN from the error cycle
        k = int(rng.integers(0, n))
        distance[i, k:] = np.nan
        offset[i, k:] = np.nan
    distance[rng.random(n_sets) < 0.05] = 1.0                      # exactly on the wanted distance
    return offset, distance


@pytest.mark.parametrize("seed", range(12))
def test_compiled_metrics_equal_numpy_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.choice([3, 5, 60, 101, 257, 1000, 2031, 2048]))
    n_sets = int(rng.integers(1, 70))
    offset, distance = _chunk(rng, n_sets, n)
    k_on = int(rng.integers(0, max(1, n // 3)))
    wanted = 1.0 if rng.random() < 0.5 else 1.0 + 0.01 * np.sin(np.arange(n) * 0.01)
    options = dict(skip=float(rng.choice([0.0, 0.0005, 0.02])), band=float(rng.choice([0.05, 0.01])),
                   hold=float(rng.choice([0.1, 0.002])), f_osc=float(rng.choice([20.0, 5.0])))
    for limits in (_limits(rng, n_sets), None):
        got = compute_metrics(offset, distance, wanted, 1e-3, k_on, limits, **options)
        ref = reference_metrics(offset, distance, wanted, 1e-3, k_on, limits, **options)
        assert np.array_equal(got["failed"], ref["failed"])
        for name in METRIC_NAMES:
            assert got[name].shape == ref[name].shape, name
            assert np.array_equal(_bits(got[name]), _bits(ref[name])), (name, seed)


def test_compiled_metrics_on_a_kernel_chunk():
    """The figures of real closed-loop traces (the sweep's scenario, all filter types)."""
    from pathlib import Path

    from distctrl.batch.closed_loop import pack_sets, prepare, run_batch
    from distctrl.tuning.metrics import limits_from_packed, wanted_distance
    from distctrl.tuning.space import build_sets, random_sample

    root = Path(__file__).resolve().parents[2]
    inputs = prepare(root / "examples/scenarios/tune_sheet.toml", cycles=600)
    base = inputs.params
    pts = random_sample(60, seed=3, cycle_time=inputs.cycle_time)
    sets, _, _ = build_sets(base, pts, inputs.cycle_time)
    packed = pack_sets(inputs, sets)
    offset, distance = run_batch(inputs, packed, cycles=600)
    args = (offset, distance, wanted_distance(inputs, 600), inputs.cycle_time, inputs.k_on,
            limits_from_packed(packed))
    got, ref = compute_metrics(*args), reference_metrics(*args)
    for name in METRIC_NAMES:
        assert np.array_equal(_bits(got[name]), _bits(ref[name])), name


def test_compiled_metrics_load_from_the_disk_cache():
    """A fresh process loads the pass from numba's disk cache and runs it (a recursive pairwise sum
    compiled, cached and loaded again crashed the second process with a segmentation fault)."""
    import subprocess
    import sys

    code = ("import numpy as np; from distctrl.tuning.metrics import compute_metrics, reference_metrics; "
            "r = np.random.default_rng(0); d = 1 + r.normal(0, .1, (4, 3000)); o = np.cumsum(d, axis=1); "
            "a = compute_metrics(o, d, 1.0, 1e-3, 10)['rms_error']; "
            "b = reference_metrics(o, d, 1.0, 1e-3, 10)['rms_error']; assert np.array_equal(a, b); print('ok')")
    for _ in range(2):                   # the first may compile and cache, the second loads
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
        assert done.returncode == 0 and done.stdout.strip() == "ok", (done.returncode, done.stderr[-2000:])


@pytest.mark.parametrize("threads", [1, 2])
def test_the_two_transforms_in_two_threads_give_the_same_bits(threads, monkeypatch):
    """With numba's thread count at 2 the offset's FFT runs in a second thread (tuning.metrics._fft_pool),
    at 1 in the calling thread: the figures are the numpy definition's either way."""
    from distctrl.batch.closed_loop import numba_threads
    from distctrl.tuning import metrics as M

    used = []
    real = M._fft_pool
    monkeypatch.setattr(M, "_fft_pool", lambda: used.append(1) or real())
    rng = np.random.default_rng(11)
    offset, distance = _chunk(rng, 64, 2031)
    limits = _limits(rng, 64)
    with numba_threads(threads):
        got = compute_metrics(offset, distance, 1.0, 1e-3, 5, limits)
    ref = reference_metrics(offset, distance, 1.0, 1e-3, 5, limits)
    assert bool(used) == (threads >= 2)
    for name in ("hf_rms", "offset_hf_rms", "rms_error", "sat_share"):
        assert np.array_equal(_bits(got[name]), _bits(ref[name])), name
