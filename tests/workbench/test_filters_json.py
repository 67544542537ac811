"""distctrl filters --json (issue 13): one JSON object on stdout, NaN as null, nothing else on stdout."""
from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner

from distctrl.cli.filters import filters


def test_filters_json_is_one_object_with_the_metrics():
    res = CliRunner().invoke(filters, ["MOVING_AVERAGE:n_cycles=10,20", "KALMAN_MA:n_cycles=30,kalman_sigma=100",
                                       "--json"])
    assert res.exit_code == 0, res.output
    obj = json.loads(res.stdout)
    assert obj["command"] == "filters" and obj["edges_s"] == [0.5, 1.0] and obj["cycle_time_s"] == 0.001
    labels = [r["label"] for r in obj["results"]]
    assert labels == ["MOVING_AVERAGE(n_cycles=10)", "MOVING_AVERAGE(n_cycles=20)",
                      "KALMAN_MA(n_cycles=30, kalman_sigma=100)"]
    ma10 = obj["results"][0]
    assert ma10["params"] == {"n_cycles": 10} and 0 < ma10["noise_rms_mm"] < obj["raw_noise_rms_mm"]
    assert 0 < ma10["delay_s"] < obj["results"][1]["delay_s"]


def test_filters_json_has_null_where_nothing_can_be_measured(tmp_path):
    t = np.arange(2000) * 0.001
    rec = tmp_path / "flat.csv"
    rec.write_text("t,d\n" + "".join(f"{a:.3f},{b:.6f}\n" for a, b in
                                      zip(t, 1.0 + 0.001 * np.random.default_rng(0).normal(size=t.size))))
    res = CliRunner().invoke(filters, ["MOVING_AVERAGE:n_cycles=4", "--recording", str(rec), "--json"])
    assert res.exit_code == 0, res.output
    obj = json.loads(res.stdout)
    assert obj["edges_s"] == [] and obj["results"][0]["delay_s"] is None and obj["results"][0]["noise_rms_mm"] > 0
