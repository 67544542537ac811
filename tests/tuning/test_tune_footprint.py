"""tune accepts a capacitive sensor with a footprint (issue 39): the kernel does not model the edge effect,
so the search runs on it with a point sensor and the sets tune chooses between run on the scalar
simulation; the figures it reports are those of ``distctrl run`` for the same set (its trace, measured
with the tuner's metrics)."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

pytest.importorskip("numba")

from distctrl.cli import main  # noqa: E402
from distctrl.tuning.metrics import compute_metrics, cost  # noqa: E402

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
SCN = EXAMPLES / "capacitive_edge.toml"          # footprint_radius 3 mm, bursts


def _scenario_with(tmp_path: Path, lis: Path) -> Path:
    text = SCN.read_text()
    text = text.replace('params = "z_laser.lis"', f'params = "{lis}"')
    text = text.replace('program = "capacitive_edge.nc"', f'program = "{EXAMPLES / "capacitive_edge.nc"}"')
    p = tmp_path / f"with_{lis.stem}.toml"
    p.write_text(text)
    return p


def _run_figures(tmp_path: Path, scenario: Path, n: int, k_on: int, wanted: float, weights: dict) -> dict:
    trace = tmp_path / f"{scenario.stem}.csv"
    r = CliRunner().invoke(main, ["run", str(scenario), "--trace", str(trace)])
    assert r.exit_code == 0, r.output
    with open(trace, newline="") as fh:
        rows = list(csv.DictReader(fh))
    off = np.array([float(row["Z.dc.offset"]) for row in rows[:n]])[None, :]
    dist = np.array([float(row["true.distance"]) for row in rows[:n]])[None, :]
    m = compute_metrics(off, dist, wanted, 0.001, k_on)
    m["cost_no_sat"] = cost(m, weights["osc_weight"], sat_weight=0.0,
                            chatter_weight=weights["chatter_weight"])
    return {k: float(np.asarray(v)[0]) for k, v in m.items()}


def test_tune_accepts_a_footprint_and_reports_distctrl_runs_figures(tmp_path):
    out = tmp_path / "tuned"
    res = CliRunner().invoke(main, ["tune", str(SCN), "--budget", "8", "--local", "--no-robustness",
                                    "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    d = json.loads(res.stdout)
    assert d["evaluated_by"] == "simulation" and "footprint" in d["fallback_note"]
    assert "footprint" in res.stderr                           # said while it runs too
    from distctrl.batch.closed_loop import prepare
    from distctrl.tuning.simfallback import kernel_proxy
    from distctrl.sim.scenario import load_scenario

    inputs = prepare(kernel_proxy(load_scenario(SCN))[0])
    n, k_on, wanted = inputs.n_cycles, inputs.k_on, float(inputs.set_value)
    w = d["cost_weights"]
    for key, lis in (("tuned", out / "tuned.lis"), ("scenario_params", EXAMPLES / "z_laser.lis")):
        fig = _run_figures(tmp_path, _scenario_with(tmp_path, lis), n, k_on, wanted, w)
        mine = d[key]["metrics"]
        for name in ("rms_error", "max_error", "hf_rms", "offset_hf_rms", "overshoot"):
            assert mine[name] == pytest.approx(fig[name], rel=1e-9, abs=1e-12), (key, name)
        # the cost adds sat_share, which needs the limiter's data of the set: the rest of it is run's
        sat = mine["sat_share"] or 0.0
        assert mine["cost"] == pytest.approx(fig["cost_no_sat"] + w["sat_weight"] * sat, rel=1e-9)
