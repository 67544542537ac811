"""Grid parsing, random samples and the validation of points."""
from __future__ import annotations

import pytest

from distctrl.control import FilterType
from distctrl.params import AxisParameters
from distctrl.tuning.space import (SpaceError, build_sets, grid_points, parse_grid, random_sample,
                                   to_params)


def test_parse_grid_ranges_and_lists():
    g = parse_grid("kp=0.1:1.0:10,d_tv=0,0.01,0.02,filter_type=MOVING_AVERAGE,n_cycles=4,8,16")
    assert list(g) == ["kp", "d_tv", "filter_type", "n_cycles"]
    assert len(g["kp"]) == 10 and g["kp"][0] == pytest.approx(0.1) and g["kp"][-1] == pytest.approx(1.0)
    assert g["d_tv"] == [0.0, 0.01, 0.02]
    assert g["filter_type"] == [FilterType.MOVING_AVERAGE]
    assert g["n_cycles"] == [4, 8, 16]
    assert len(grid_points(g)) == 10 * 3 * 1 * 3


def test_parse_grid_aliases_and_log():
    g = parse_grid("order=1,2, fg_f0=10:100:3:log,smooth_fact=0.5")
    assert g["low_pass_filter_order"] == [1, 2]
    assert g["low_pass_filter_fg_f0"] == [10.0, 31.6, 100.0]          # rounded to 0.1 Hz (R15)
    assert g["smoothing_factor"] == [0.5]


@pytest.mark.parametrize("text, words", [
    ("kp=0:1:3", "P-AXIS-00759"),               # kp = 0 outside (0, 2]
    ("kp=3", "out of range"),
    ("n_cycles=2.5", "not an integer"),
    ("filter_type=PASS", "allowed"),
    ("foo=1", "unknown sweep parameter"),
    ("kp=1,kp=2", "given twice"),
    ("kp=0.1:1", "a:b:n"),
    ("0.1,kp=1", "name=values"),
    ("", "empty grid"),
])
def test_parse_grid_errors(text, words):
    with pytest.raises(SpaceError, match=words):
        parse_grid(text)


def test_random_sample_reproducible_and_valid():
    a = random_sample(50, seed=3, cycle_time=0.001)
    b = random_sample(50, seed=3, cycle_time=0.001)
    assert a == b
    base = AxisParameters(enabled=True)
    sets, kept, rejected = build_sets(base, a, 0.001)
    assert not rejected and len(sets) == 50
    for p in a:                                  # only the filter's own parameters are set
        if p["filter_type"] == FilterType.MOVING_AVERAGE:
            assert "kalman_sigma" not in p and "smoothing_factor" not in p


def test_invalid_combination_rejected_with_message():
    base = AxisParameters(enabled=True)
    with pytest.raises(SpaceError, match="Nyquist"):
        to_params(base, {"filter_type": FilterType.LOWPASS, "low_pass_filter_fg_f0": 600.0}, 0.001)
    sets, kept, rejected = build_sets(base, [{"kp": 0.5}, {"filter_type": FilterType.LOWPASS,
                                                            "low_pass_filter_fg_f0": 900.0}], 0.001)
    assert len(sets) == 1 and len(rejected) == 1 and "P-AXIS-00508" in rejected[0][1]


def test_grid_ranges_are_rounded_to_the_parameters_resolution():
    """new-user audit R15: ``kp=0.1:1.5:8`` gave 0.8999999999999999 and 1.0999999999999999."""
    g = parse_grid("kp=0.1:1.5:8,d_tv=0:0.01:7,fg_f0=10:100:3:log")
    assert g["kp"] == [0.1, 0.3, 0.5, 0.7, 0.9, 1.1, 1.3, 1.5]
    assert g["d_tv"] == [0.0, 0.0017, 0.0033, 0.005, 0.0067, 0.0083, 0.01]       # 0.1 ms steps
    assert g["low_pass_filter_fg_f0"] == [10.0, 31.6, 100.0]                     # 0.1 Hz steps


def test_a_grid_range_finer_than_the_resolution_keeps_its_values_without_artefacts():
    g = parse_grid("kp=0.1:0.1003:4")           # steps of 0.0001 < the 0.001 resolution of kp
    assert len(g["kp"]) == 4
    assert g["kp"] == [0.1, 0.1001, 0.1002, 0.1003]
    assert all(len(repr(v)) <= 12 for v in g["kp"]), g["kp"]


def test_grid_lists_keep_the_values_typed():
    assert parse_grid("d_tv=0.00015,0.0035")["d_tv"] == [0.00015, 0.0035]


def _mixed_points():
    pts = random_sample(300, seed=7, cycle_time=0.001)
    bad = [{"kp": 0.0}, {"kp": -1.0}, {"kp": float("nan")}, {"kp": True}, {"kp": "0.5"},
           {"n_cycles": 100}, {"n_cycles": 4.5}, {"i_tn": -0.1}, {"d_tv": 1e9},
           {"filter_type": FilterType.LOWPASS, "low_pass_filter_fg_f0": 600.0},
           {"filter_type": FilterType.LOWPASS, "low_pass_filter_order": 7},
           {"filter_type": "LOWPASS", "low_pass_filter_fg_f0": 40.0},
           {"filter_type": FilterType.PASS}, {"smoothing_factor": 0.0}, {"kalman_sigma": 0.5},
           {"v_max": 0.0}, {"optimized_scheduling": False}, {"a_max": 1e12}]
    out = []
    for i, p in enumerate(pts):
        out.append(p)
        if i % 17 == 0:
            out.append(bad[(i // 17) % len(bad)])
    return out + bad


def test_build_sets_builds_no_controller_per_set_and_gives_what_to_params_gives(monkeypatch):
    """issue 27: the sets are checked against the parameter table for all points at once; what
    to_params (one controller per set) accepts and the messages of what it rejects stay the same."""
    from distctrl.control import controller as ctl

    base = AxisParameters(enabled=True)
    pts = _mixed_points()
    want_sets, want_rejected = [], []
    for pt in pts:
        try:
            want_sets.append(to_params(base, pt, 0.001))
        except SpaceError as exc:
            want_rejected.append((pt, str(exc)))
    built = []
    init = ctl.AxisDistanceController.__init__

    def counting_init(self, *a, **k):
        built.append(1)
        init(self, *a, **k)

    monkeypatch.setattr(ctl.AxisDistanceController, "__init__", counting_init)
    sets, kept, rejected = build_sets(base, pts, 0.001)
    assert sets == want_sets
    assert rejected == want_rejected
    assert len(kept) == len(sets) and all(k in pts for k in kept)
    assert len(built) <= len(want_rejected)       # only the refused points take the per-set path
