"""Points as columns (issue 27): the same points as the per-point functions, without Python per point."""
from __future__ import annotations

import math

import numpy as np
import pytest

from distctrl.base.kinds import FilterType
from distctrl.tuning.columns import columns_of, drop_inert_columns, random_columns, round_column
from distctrl.tuning.space import (DEFAULT_SPACE, NC_WORDS, REAL_RESOLUTION, d_tv_applies, drop_inert_d_tv,
                                   filter_fields, random_sample, round_point, round_value)


def _random_sample_per_point(n, seed=0, space=DEFAULT_SPACE, *, cycle_time=None):
    """random_sample as it was before the columns (one dict per point, rounded per value): the reference."""
    rng = np.random.default_rng(seed)
    dims = {d.field: d for d in space}
    draws = {f: d.sample(rng, n) for f, d in dims.items()}
    points = []
    for i in range(n):
        p: dict = {}
        ft = draws["filter_type"][i] if "filter_type" in dims else None
        for f, d in dims.items():
            if f in NC_WORDS and f not in ("kp", "i_tn", "d_tv", "filter_type") and ft is not None \
                    and f not in filter_fields(ft):
                continue
            v = draws[f][i]
            v = FilterType(v) if f == "filter_type" else (int(v) if d.kind == "int" else float(v))
            if f == "low_pass_filter_fg_f0" and cycle_time:
                v = min(v, 0.45 / cycle_time)
            p[f] = v
        if "kp" in p and "d_tv" in p and not d_tv_applies(round_value("kp", p["kp"])):
            p["d_tv"] = 0.0
        points.append(round_point(p))
    return points


def _same(a: list[dict], b: list[dict]) -> None:
    assert len(a) == len(b)
    for p, q in zip(a, b):
        assert list(p) == list(q)
        for k in p:
            assert type(p[k]) is type(q[k]), k
            assert p[k] == q[k] and (not isinstance(p[k], float) or math.copysign(1, p[k]) == math.copysign(1, q[k]))


@pytest.mark.parametrize("seed", range(0, 400, 7))
def test_random_columns_draw_the_points_the_per_point_sample_drew(seed):
    n = 50 + seed * 3
    for ct in (0.001, 0.0005, None):
        want = _random_sample_per_point(n, seed, cycle_time=ct)
        _same(random_columns(n, seed, cycle_time=ct).to_points(), want)
        _same(random_sample(n, seed, cycle_time=ct), want)


@pytest.mark.parametrize("field", sorted(REAL_RESOLUTION))
def test_round_column_is_round_value_bit_for_bit(field):
    rng = np.random.default_rng(1)
    x = np.concatenate([rng.uniform(0, 3, 20000), np.exp(rng.uniform(-9, 9.5, 20000)),
                        np.arange(0, 2000) * REAL_RESOLUTION[field] * 0.5, [0.0, 1e-300, 2e-4, 5e-4, 0.0005]])
    got = round_column(field, x)
    want = np.array([round_value(field, float(v)) for v in x])
    assert np.array_equal(got.view(np.int64), want.view(np.int64))


@pytest.mark.parametrize("seed", range(5))
def test_drop_inert_columns_is_drop_inert_d_tv(seed):
    rng = np.random.default_rng(seed)
    points = []
    for _ in range(400):                 # a grid-like list with many repeats
        p = {"kp": float(rng.choice([0.5, 1.0, 1.5])), "d_tv": float(rng.choice([0.0, 0.01, 0.02]))}
        if rng.random() < 0.5:
            p["filter_type"] = FilterType.LOWPASS
            p["low_pass_filter_order"] = int(rng.integers(1, 3))
        else:
            p["filter_type"] = FilterType.MOVING_AVERAGE
            p["n_cycles"] = int(rng.integers(2, 4))
        points.append(p)
    want, merged = drop_inert_d_tv(points)
    pc = columns_of(points, ["kp", "d_tv", "filter_type", "low_pass_filter_order", "n_cycles"])
    got, m2 = drop_inert_columns(pc)
    assert m2 == merged
    _same(got.to_points(), want)


def test_columns_of_refuses_points_it_cannot_hold():
    assert columns_of([{"kp": 0.5}, {"kp": 1}]) is None            # int and float in one field
    assert columns_of([{"kp": 0.5, "d_tv": 0.0}, {"d_tv": 0.0, "kp": 0.5}]) is None   # two key orders
    assert columns_of([{"kp": "0.5"}]) is None


def _grid_points():
    from distctrl.tuning.space import grid_points, parse_grid

    return grid_points(parse_grid("kp=0.3,0.8,1.2,filter_type=LOWPASS,order=1,2,4,fg_f0=100,490,800"))


@pytest.mark.parametrize("case", ["random0", "random1", "random7", "grid", "random_t05"])
def test_check_and_pack_columns_give_build_sets_and_pack_sets_rows_bit_for_bit(case):
    pytest.importorskip("numba")
    from pathlib import Path

    from distctrl.batch import closed_loop as CL
    from distctrl.tuning.columns import COLUMN_FIELDS, check_columns
    from distctrl.tuning.space import build_sets

    assert COLUMN_FIELDS == CL.PACKED_COLUMN_FIELDS
    inputs = CL.prepare(Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "tune_sheet.toml",
                        cycles=20)
    T = inputs.cycle_time if case != "random_t05" else 0.0005
    if case == "grid":
        pc = columns_of(_grid_points())
    else:
        pc = random_columns(3000, int(case[6:]) if case[6:].isdigit() else 5, cycle_time=T)
    pc, _ = drop_inert_columns(pc)
    points = pc.to_points()
    sets, kept, rejected = build_sets(inputs.params, points, T)
    kept_pc, fc, rej2 = check_columns(inputs.params, pc, T)
    assert rej2 == rejected
    _same(kept_pc.to_points(), kept)
    if T == inputs.cycle_time:
        want = CL.pack_sets(inputs, sets)
        got = CL.pack_columns(inputs, inputs.params, kept_pc.cols, kept_pc.present, fc)
        assert np.array_equal(got.view(np.int64), want.view(np.int64))


def test_check_columns_leaves_what_it_does_not_cover_to_build_sets():
    from distctrl.params import AxisParameters
    from distctrl.tuning.columns import check_columns

    base = AxisParameters(enabled=True)
    assert columns_of([{"kp": 0.5, "optimized_scheduling": True}]) is None     # a bool value
    pc = columns_of([{"kp": 0.5, "max_deviation": 3.0}])
    assert check_columns(base, pc, 0.001) is None                 # a field the columns do not pack
    pc = columns_of([{"kp": 0.5, "n_cycles": 4.0}])
    assert check_columns(base, pc, 0.001) is None                 # a float n_cycles: the per-set way


def test_first_of_equal_rows_finds_the_first_of_every_group_and_survives_a_hash_collision(monkeypatch):
    from distctrl.tuning import columns as C

    rng = np.random.default_rng(3)
    mat = np.stack([rng.choice([0.0, 0.5, 1.5, np.nan], 5000), rng.integers(0, 3, 5000).astype(float),
                    rng.choice([1e-3, 2e-3], 5000)], axis=1)
    rows = np.ascontiguousarray(mat).view(np.dtype((np.void, 24)))[:, 0]
    want = np.unique(rows, return_index=True)[1]
    assert np.array_equal(np.sort(C._first_of_equal_rows(mat)), np.sort(want))
    monkeypatch.setattr(C, "_H1", np.uint64(0))                   # every row the same hash: the fallback
    assert np.array_equal(np.sort(C._first_of_equal_rows(mat)), np.sort(want))
