"""Tuning stays safe on the fitted plant (issue 26): recordings of an unseen plant
(tests/workbench/unseen_plants.py: a 66 Hz mode with zeta 0.019 that the frequency-response-only fit
missed) -> ``distctrl identify --out`` -> ``distctrl tune`` on the fitted twin -> the tuned list on the
TRUE plant (the fitted scenario with the generator's kv, dead time, limits, mode, sensor delay, noise
and characteristic): ``distctrl margins`` stable with positive margins, ``distctrl run`` without an
oscillation warning."""
from __future__ import annotations

import json
import math
import re
import shutil
import tomllib

import numpy as np
import pytest
from click.testing import CliRunner

pytest.importorskip("numba")

from distctrl.cli import main  # noqa: E402
from tests.workbench.unseen_plants import T, random_plant, recordings, write_csv  # noqa: E402

OSCILLATION = 900032
SEED = 0


def cli(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def _set(text: str, section: str, key: str, value: str) -> str:
    """Replace ``key = ...`` inside ``[section]`` (up to the next table header)."""
    head = text.index(f"[{section}]")
    end = text.find("\n[", head + 1)
    end = len(text) if end < 0 else end
    body, n = re.subn(rf"(?m)^{re.escape(key)} = .*$", f"{key} = {value}", text[head:end], count=1)
    assert n == 1, (section, key)
    return text[:head] + body + text[end:]


def test_tuned_on_the_fitted_twin_is_stable_on_the_true_plant(tmp_path):
    plant = random_plant(SEED)
    files = []
    for name, rows in recordings(plant, SEED).items():
        p = tmp_path / f"{name}.csv"
        write_csv(p, *rows)
        files.append(p)
    fitted = tmp_path / "fitted"
    r = cli("identify", *files, "--command", "set_pos", "--actual", "act_pos", "--sensor", "sensor",
            "--surface", plant.surface, "--out", fitted)
    assert r.exit_code == 0, r.output
    scenario = fitted / "fitted.toml"
    doc = tomllib.loads(scenario.read_text())
    assert abs(doc["axes"]["Z"]["resonance_hz"] / plant.resonance_hz - 1) <= 0.1

    tuned = tmp_path / "tuned"
    r = cli("tune", scenario, "--budget", 40, "--local", "--no-robustness", "--out", tuned, "--json")
    assert r.exit_code == 0, r.output
    shutil.copy(tuned / "tuned.lis", fitted / doc["axes"]["Z"]["params"])

    # the true plant: the fitted scenario with the generator's figures
    text = scenario.read_text()
    z = {"kv": repr(-math.expm1(-plant.kv * T) / T), "bus_delay_cycles": str(plant.dead_cycles),
         "v_max": repr(plant.v_max), "a_max": repr(plant.a_max), "resonance_hz": repr(plant.resonance_hz),
         "damping": repr(plant.damping)}
    for k, v in z.items():
        text = _set(text, "axes.Z", k, v)
    d = np.round(np.arange(0.0, 10.0001, 0.1), 6)
    table = "[" + ", ".join(f"[{a:.6g}, {b:.6f}]" for a, b in zip(d, plant.characteristic(d))) + "]"
    for k, v in {"delay_cycles": str(int(round(plant.delay / T))), "noise_std": repr(plant.noise_std),
                 "characteristic": table}.items():
        text = _set(text, "sensor", k, v)
    true = fitted / "true.toml"
    true.write_text(text)

    r = cli("margins", true, "--json")
    assert r.exit_code == 0, r.output
    m = json.loads(r.stdout)
    assert m["model"]["drive_resonance_hz"] == pytest.approx(plant.resonance_hz)
    assert m["stable"] and m["gain_margin"] > 1.0 and m["phase_margin_deg"] > 0.0, m
    r = cli("run", true, "--json")
    assert r.exit_code == 0, r.output
    run = json.loads(r.stdout)
    assert run["completed"] and run["errors"] == []
    assert not [w for w in run["warnings"] if w["id"] == OSCILLATION], run["warnings"]
