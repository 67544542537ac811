"""Tuning on the fitted plant (issue 15): a Z drive with a 40 Hz, zeta 0.05 resonance.

examples/scenarios/resonant_z.toml is tune_sheet.toml with that resonance. The demonstration of
docs/tuning.md "Tuning on a resonant drive":

(a) settings tuned on the idealised (rigid) plant, tune_sheet, oscillate on the resonant plant in
    the scalar simulation (warning 900032 near the resonance) and `distctrl margins` predicts it
    (unstable: gain margin < 1);
(b) settings tuned on the resonant plant itself (`distctrl tune resonant_z.toml`) run there without
    an oscillation, and the predicted gain margin is > 1 (stable).
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

pytest.importorskip("numba")

from distctrl.sim.runner import run  # noqa: E402
from distctrl.sim.scenario import load_scenario  # noqa: E402
from distctrl.tuning.tune import tune  # noqa: E402
from distctrl.workbench.margins import analyse, loop_model  # noqa: E402

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
RIGID = SCN / "tune_sheet.toml"
RESONANT = SCN / "resonant_z.toml"
OSCILLATION = 900032
BUDGET, SEED = 400, 0          # docs/tuning.md's example budget


def _on_plant(scenario, params):
    """``scenario`` with ``params`` as the Z axis's list."""
    ax = dataclasses.replace(scenario.axes["Z"], params=params)
    return dataclasses.replace(scenario, axes={**scenario.axes, "Z": ax})


@pytest.fixture(scope="module")
def tuned():
    return {name: tune(path, budget=BUDGET, seed=SEED, mode="local", robustness=False, progress=False).best
            for name, path in (("rigid", RIGID), ("resonant", RESONANT))}


def test_the_example_is_tune_sheet_with_a_resonance():
    rigid, res = load_scenario(RIGID), load_scenario(RESONANT)
    assert (res.axes["Z"].resonance_hz, res.axes["Z"].damping) == (40.0, 0.05)
    assert rigid.axes["Z"].resonance_hz == 0.0
    assert dataclasses.replace(res.axes["Z"], resonance_hz=0.0, damping=0.05) == rigid.axes["Z"]
    assert repr(res.surface) == repr(rigid.surface) and res.sensor == rigid.sensor and res.program_file == rigid.program_file


def test_settings_tuned_on_the_rigid_plant_oscillate_on_the_resonant_one(tuned):
    params = tuned["rigid"]
    # on the plant it was tuned for, it is fine
    home = run(_on_plant(load_scenario(RIGID), params))
    assert home.completed and not [w for w in home.warnings if w["id"] == OSCILLATION]
    assert analyse(loop_model(_on_plant(load_scenario(RIGID), params))).stable
    # on the resonant plant: an oscillation near the resonance for the whole run, predicted unstable
    sc = _on_plant(load_scenario(RESONANT), params)
    r = run(sc)
    osc = [w for w in r.warnings if w["id"] == OSCILLATION]
    assert osc, r.warnings
    assert 25.0 <= r.metrics["oscillation_frequency_hz"] <= 45.0          # still oscillating at the end
    assert r.metrics["oscillation_amplitude_mm"] > 0.2
    assert r.metrics["distance_error_rms"] > 3 * home.metrics["distance_error_rms"]
    m = analyse(loop_model(sc))
    assert not m.stable and m.gain_margin < 1.0
    assert 25.0 <= m.phase_crossover_hz <= 45.0


def test_settings_tuned_on_the_resonant_plant_are_stable_there(tuned):
    params = tuned["resonant"]
    sc = _on_plant(load_scenario(RESONANT), params)
    r = run(sc)
    assert r.completed and not [w for w in r.warnings if w["id"] == OSCILLATION], r.warnings
    assert r.metrics["oscillation_frequency_hz"] is None and r.metrics["oscillations"] == 0
    m = analyse(loop_model(sc))
    assert m.stable and m.gain_margin > 1.0 and m.gain_margin_db > 0.0
    assert m.phase_margin_deg is None or m.phase_margin_deg > 0.0
    # and it is the better choice there by far
    other = run(_on_plant(load_scenario(RESONANT), tuned["rigid"]))
    assert r.metrics["distance_error_rms"] < 0.5 * other.metrics["distance_error_rms"]


def test_sweep_and_margins_cli_accept_the_resonant_plant(tmp_path):
    from distctrl.cli import main

    out = tmp_path / "s.csv"
    res = CliRunner().invoke(main, ["sweep", str(RESONANT), "--grid", "kp=0.1,0.5,n_cycles=4", "--local",
                                    "--out", str(out)])
    assert res.exit_code == 0, res.output
    import csv

    rows = {float(r["kp"]): r for r in csv.DictReader(out.open())}
    # KP 0.5 is above the resonant plant's stability limit: its fast oscillation shows in hf_rms
    assert float(rows[0.5]["hf_rms"]) > 5 * float(rows[0.1]["hf_rms"])
    res = CliRunner().invoke(main, ["margins", str(RESONANT), "--json"])
    assert res.exit_code == 0, res.output
    d = json.loads(res.output)
    assert d["model"]["drive_resonance_hz"] == 40.0 and d["model"]["drive_damping"] == 0.05
    assert d["stable"] is False and 0.0 < d["kp_limit"] < 0.5
    assert np.isfinite(d["gain_margin"])
