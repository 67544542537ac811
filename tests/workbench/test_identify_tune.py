"""Tuning on the fitted plant (issue 15), end to end on the command line.

Recordings of a known plant (a Z drive with a 40 Hz, zeta 0.05 resonance, a capacitive sensor with
a characteristic, delay and noise: tests/workbench/identify_plants.py) -> ``distctrl identify --out``
writes the fitted scenario (the point distance sensor, kind "distance", read through
SENSOR_SOURCE=VARIABLE) -> ``distctrl tune`` on it (the batch kernel runs that sensor) -> the tuned
list in the scalar simulation of the fitted plant (``distctrl run``: no oscillation warning 900032)
and in ``distctrl margins`` (stable, positive margins).
"""
from __future__ import annotations

import json
import shutil
import tomllib

import pytest
from click.testing import CliRunner

pytest.importorskip("numba")

from distctrl.cli import main  # noqa: E402
from tests.workbench.identify_plants import (Plant, chirp_command, ramp_command, simulate,  # noqa: E402
                                             steps_command, write_csv)

OSCILLATION = 900032
ARGS = ["--command", "set_pos", "--actual", "act_pos", "--sensor", "sensor"]


def cli(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def test_tune_on_the_fitted_plant(tmp_path):
    plant = Plant()                                      # 40 Hz, zeta 0.05
    assert (plant.resonance_hz, plant.damping) == (40.0, 0.05)
    files = []
    for i, (name, cmd) in enumerate([("steps", steps_command(seconds=6.0)), ("chirp", chirp_command(seconds=12.0)),
                                     ("ramp", ramp_command(seconds=10.0, surface=plant.surface))]):
        p = tmp_path / f"{name}.csv"
        write_csv(p, *simulate(plant, cmd, seed=i))
        files.append(p)
    fitted = tmp_path / "fitted"
    r = cli("identify", *files, *ARGS, "--surface", plant.surface, "--out", fitted)
    assert r.exit_code == 0, r.output
    scenario = fitted / "fitted.toml"
    doc = tomllib.loads(scenario.read_text())
    assert doc["sensor"]["kind"] == "distance" and len(doc["sensor"]["characteristic"]) > 2
    assert abs(doc["axes"]["Z"]["resonance_hz"] / 40.0 - 1) <= 0.1

    # tune on the fitted plant: the batch kernel accepts the distance sensor
    tuned = tmp_path / "tuned"
    r = cli("tune", scenario, "--budget", 60, "--local", "--no-robustness", "--out", tuned, "--json")
    assert r.exit_code == 0, r.output
    res = json.loads(r.stdout)
    assert res["evaluations"] == 60 and not res["tuned"]["metrics"]["failed"]
    assert res["tuned"]["metrics"]["cost"] <= res["scenario_params"]["metrics"]["cost"]

    # the tuned list in place of the fitted scenario's list
    shutil.copy(tuned / "tuned.lis", fitted / doc["axes"]["Z"]["params"])
    r = cli("run", scenario, "--json")
    assert r.exit_code == 0, r.output
    run = json.loads(r.stdout)
    assert run["completed"] and run["errors"] == []
    assert not [w for w in run["warnings"] if w["id"] == OSCILLATION], run["warnings"]
    assert run["metrics"]["oscillations"] == 0
    r = cli("margins", scenario, "--json")
    assert r.exit_code == 0, r.output
    m = json.loads(r.stdout)
    assert m["model"]["kp"] == res["tuned"]["values"]["kp"]
    assert m["model"]["drive_resonance_hz"] == pytest.approx(doc["axes"]["Z"]["resonance_hz"])
    assert m["stable"] and m["gain_margin"] > 1.0 and m["phase_margin_deg"] > 0.0
