"""The tools do not offer a knob that does nothing (new-user audit M6): the D part has no room and no
effect at kp >= 1 (docs/control-law.md, "The D part"), so sweep and tune neither vary d_tv there nor
report a value for it as if it mattered."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from distctrl.control.law import derivative_gain
from distctrl.params import AxisParameters
from distctrl.tuning.runner import SweepResult
from distctrl.tuning.space import (D_NO_EFFECT_KP, DEFAULT_SPACE, D_TV_NOTE, drop_inert_d_tv, grid_points,
                                   parse_grid, random_sample)

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "tune_sheet.toml"


def test_the_threshold_is_where_the_law_drops_the_d_part():
    assert derivative_gain(D_NO_EFFECT_KP, 0.01, 0.001) == 0.0
    assert derivative_gain(np.nextafter(D_NO_EFFECT_KP, 0), 0.01, 0.001) > 0.0


def test_random_points_at_kp_1_or_above_do_not_vary_d_tv():
    pts = random_sample(2000, seed=3)
    high = [p for p in pts if p["kp"] >= 1.0]
    low = [p for p in pts if p["kp"] < 1.0]
    assert len(high) > 200 and len(low) > 200
    assert all(p["d_tv"] == 0.0 for p in high)
    assert sum(p["d_tv"] > 0 for p in low) > 100            # below kp 1 the D part is still searched


def test_grid_points_at_kp_1_or_above_collapse_to_d_tv_0():
    pts = grid_points(parse_grid("kp=0.5,1.0,1.3,d_tv=0,0.002,0.01,n_cycles=2,4"))
    kept, merged = drop_inert_d_tv(pts)
    assert len(pts) == 18 and len(kept) == 3 * 2 + 2 * 2 and merged == 8
    assert {(p["kp"], p["d_tv"]) for p in kept if p["kp"] >= 1} == {(1.0, 0.0), (1.3, 0.0)}
    assert sum(p["kp"] == 0.5 for p in kept) == 6


def test_tune_neighbours_spend_no_budget_on_d_tv_at_kp_1_or_above():
    from distctrl.control import FilterType
    from distctrl.tuning.tune import _neighbours, _refine_dims

    dims = _refine_dims(FilterType.MOVING_AVERAGE, DEFAULT_SPACE, 0.001)
    p = {"kp": 1.3, "i_tn": 0.0, "d_tv": 0.0, "filter_type": FilterType.MOVING_AVERAGE, "n_cycles": 8}
    nb = _neighbours(p, dims, 1.0)
    assert nb and not [q for q in nb if q["kp"] == p["kp"] and q["d_tv"] != p["d_tv"]]
    assert all(q["d_tv"] == 0.0 for q in nb if q["kp"] >= 1.0)
    # from below: the kp step up that crosses 1 drops the D part
    q0 = dict(p, kp=0.9, d_tv=0.01)
    up = [q for q in _neighbours(q0, dims, 1.0) if q["kp"] > 1.0]
    assert up and all(q["d_tv"] == 0.0 for q in up)


def test_sweep_table_and_json_say_d_tv_does_not_apply(tmp_path):
    pytest.importorskip("numba")
    from distctrl.cli import main

    args = ["sweep", str(SCN), "--grid", "kp=0.5,1.3,d_tv=0,0.01", "--local", "--cycles", "300",
            "--out", str(tmp_path / "s.csv")]
    r = CliRunner().invoke(main, args + ["--json"])
    assert r.exit_code == 0, r.output
    obj = json.loads(r.stdout)
    assert obj["sets"] == 3                                       # kp 1.3 runs once, with d_tv 0
    rows = {(row["kp"], row["d_tv"]) for row in obj["best"]}
    assert rows == {(0.5, 0.0), (0.5, 0.01), (1.3, None)}, rows
    assert D_TV_NOTE in obj["notes"]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    line = [ln for ln in r.stdout.splitlines() if ln.startswith("1.3 ")]
    assert line and line[0].split()[1] == "-", r.stdout
    assert D_TV_NOTE in r.stdout


def test_a_tuned_set_at_kp_1_or_above_carries_d_tv_0_and_says_why():
    from distctrl.tuning.tune import TuneResult

    base = AxisParameters().replace(kp=0.4, d_tv=0.01)
    best = AxisParameters().replace(kp=1.2, d_tv=0.0)
    res = TuneResult("Z", base, best, {}, {}, SweepResult({}))
    d = res.to_dict()
    assert d["tuned"]["values"]["d_tv"] is None and D_TV_NOTE in d["notes"]
    assert "D_TV=0" in res.nc_block
    assert D_TV_NOTE in res.report()
