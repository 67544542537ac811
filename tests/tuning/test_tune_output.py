"""Tuning advice that cannot mislead (issue 13): the cost penalises chatter (time at the limiter,
high-frequency offset motion), the tuned values are rounded to what the list and the NC take and the
rounded set is what is reported, the two settle times have two names, and --json."""
from __future__ import annotations

import json
import math
from pathlib import Path

import click
import numpy as np
import pytest
from click.testing import CliRunner

pytest.importorskip("numba")

from distctrl.batch.closed_loop import prepare, run_batch  # noqa: E402
from distctrl.params import parse_list_text  # noqa: E402
from distctrl.cli.tune import sweep, tune_cmd  # noqa: E402
from distctrl.tuning.metrics import METRIC_NAMES, compute_metrics, cost, limits_from_packed, wanted_distance  # noqa: E402
from distctrl.tuning.space import REAL_RESOLUTION, random_sample, resolution  # noqa: E402
from distctrl.tuning.tune import tune  # noqa: E402

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "tune_sheet.toml"


def test_the_cost_penalises_time_at_the_limiter_and_offset_chatter():
    calm = {"rms_error": np.array([0.07]), "hf_rms": np.array([0.03]), "overshoot": np.array([0.0]),
            "sat_share": np.array([0.01]), "offset_hf_rms": np.array([0.02]), "failed": np.array([False])}
    at_limit = dict(calm, rms_error=np.array([0.069]), sat_share=np.array([0.37]))
    chatter = dict(calm, rms_error=np.array([0.069]), offset_hf_rms=np.array([0.1]))
    assert cost(at_limit)[0] > cost(calm)[0]           # 1 µm less error does not buy 37 % at the limiter
    assert cost(chatter)[0] > cost(calm)[0]
    assert cost(at_limit, sat_weight=0.0, chatter_weight=0.0)[0] < cost(calm, sat_weight=0.0, chatter_weight=0.0)[0]


def test_offset_hf_rms_is_the_offsets_fast_motion():
    t = np.arange(3000) * 0.001
    offset = np.vstack([0.1 * np.sin(2 * np.pi * 50 * t), 0.1 * np.sin(2 * np.pi * 2 * t)])
    m = compute_metrics(offset, np.ones((2, 3000)), 1.0, 0.001, k_on=0, f_osc=20.0)
    assert m["offset_hf_rms"][0] == pytest.approx(0.1 / math.sqrt(2), rel=1e-3)
    assert m["offset_hf_rms"][1] < 1e-3


def test_the_two_settle_times_have_two_names():
    """run's settle_time (last entry into ±0.01 mm) and the tuner's first 0.1 s inside ±0.05 mm differed
    by 10x under the same name."""
    assert "settle_time_50um" in METRIC_NAMES and "settling_time" not in METRIC_NAMES
    assert "settle_time" not in METRIC_NAMES


@pytest.mark.parametrize("seed", [4, 6])
def test_a_tuned_set_does_not_sit_at_the_limiter(seed):
    """With the error-only cost, tune_sheet with budget 200 picked sets at the limiter 20 % and 14 % of the
    time (seeds 4 and 6; 37 % in the audit on an older law, 48 % with seed 8 once the values are rounded);
    with the chatter terms 0.6 ... 1.1 % over seeds 0 ... 9."""
    res = tune(SCN, budget=200, seed=seed, mode="local", progress=False, robustness=False)
    assert res.best_metrics["sat_share"] < 0.05, res.best_metrics
    assert res.best_metrics["rms_error"] < res.base_metrics["rms_error"]


@pytest.fixture(scope="module")
def tuned():
    return tune(SCN, budget=60, seed=1, cycles=2000, mode="local", progress=False, robustness=False)


def test_tuned_values_are_rounded_to_the_resolution_and_the_rounded_set_is_what_is_reported(tuned):
    values = tuned.tuned_values()
    for name, v in values.items():
        step = resolution(name)
        if isinstance(v, float) and step:
            assert abs(v / step - round(v / step)) < 1e-6, (name, v)
    # the list and the NC block carry those values, not 12 digits
    for line in tuned.param_list.splitlines():
        key, value = line.split()[:2]
        if key in ("kenngr.distc.kp", "kenngr.distc.i_tn", "kenngr.distc.d_tv"):
            assert len(value.split(".")[-1]) <= 4, line
    assert parse_list_text(tuned.param_list).params.kp == values["kp"]
    assert f"KP={values['kp']:g} " in tuned.nc_block
    # the printed metrics are a run of the rounded set
    inputs = prepare(SCN, 2000)
    from distctrl.batch.closed_loop import pack_sets

    packed = pack_sets(inputs, [tuned.best])
    offset, distance = run_batch(inputs, packed)
    m = compute_metrics(offset, distance, wanted_distance(inputs, distance.shape[1]), inputs.cycle_time,
                        inputs.k_on, limits_from_packed(packed))
    for name in ("rms_error", "sat_share", "offset_hf_rms"):
        assert tuned.best_metrics[name] == pytest.approx(float(m[name][0]), rel=1e-12, abs=1e-15), name
    assert "rounded" in tuned.report() and tuned.unrounded is not None


def test_random_points_are_rounded_too():
    for p in random_sample(20, 5, cycle_time=0.001):
        for name in REAL_RESOLUTION:
            if name in p:
                assert abs(p[name] / REAL_RESOLUTION[name] - round(p[name] / REAL_RESOLUTION[name])) < 1e-6


@click.group()
def _cli():
    pass


_cli.add_command(sweep)
_cli.add_command(tune_cmd)


def test_sweep_json_is_one_object_with_units(tmp_path):
    r = CliRunner().invoke(_cli, ["sweep", str(SCN), "--grid", "kp=0.2,0.8,n_cycles=2,8", "--local", "--cycles",
                                  "1500", "--out", str(tmp_path / "s.csv"), "--json", "--top", "3"])
    assert r.exit_code == 0, r.output
    obj = json.loads(r.stdout)
    assert obj["command"] == "sweep" and obj["sets"] == 4 and obj["cycles"] == 1500 and len(obj["best"]) == 3
    assert obj["units"]["rms_error"] == "mm" and obj["units"]["sat_share"] == "0..1"
    assert {"kp", "n_cycles", "cost", "sat_share", "offset_hf_rms", "settle_time_50um"} <= set(obj["best"][0])
    assert "kalman_sigma" not in obj["best"][0]          # MOVING_AVERAGE does not use it


def test_tune_json_is_one_object(tmp_path):
    r = CliRunner().invoke(_cli, ["tune", str(SCN), "--budget", "20", "--local", "--cycles", "1500",
                                  "--no-robustness", "--out", str(tmp_path / "t"), "--json"])
    assert r.exit_code == 0, r.output
    obj = json.loads(r.stdout)
    assert obj["command"] == "tune" and obj["nc_block"].startswith("Z[DIST_CTRL KP=")
    assert obj["tuned"]["metrics"]["sat_share"] is not None and obj["metric_units"]["cost"] == "mm"
    assert obj["cost_weights"]["sat_weight"] > 0 and obj["cost_weights"]["chatter_weight"] > 0
    # tuned-objects.lis beside them when the tuned set changes the filter (issue 39)
    assert len(obj["files"]) == 5 + (obj["objects_set"] is not None)
    assert all(Path(f).exists() for f in obj["files"])
