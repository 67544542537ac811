"""Tuning stays safe on the fitted plant (issue 26): recordings of unseen plants
(tests/workbench/unseen_plants.py; seed 0: a 66 Hz mode with zeta 0.019 that the frequency-response-only
fit missed; seed 5: 39 Hz, zeta 0.010, the lightest damping of the first seeds; seed 6: 67 Hz, zeta
0.028, with 4 cycles of dead time) -> ``distctrl identify --out`` -> ``distctrl tune`` on the fitted twin -> the tuned list on the
TRUE plant (the fitted scenario with the generator's kv, dead time, limits, mode, sensor delay, noise
and characteristic): ``distctrl margins`` stable with positive margins, ``distctrl run`` without an
oscillation warning.

Not among the seeds: 3 (17 Hz, zeta 0.035) and 11 (13.5 Hz, zeta 0.018). Their modes are low in the
loop's band: on the fitted twin and on the true plant, the scenario's own list (KP 0.05, the space's
lowest) already crosses 0 dB a second time at the resonance with a negative phase margin (-15 deg,
-19 deg; the closed loop is still stable, gain margin 1.3-1.5), and so does the tuned set; ``tune``
now reports it (``stability``), but no list in the space gives positive margins there."""
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
from tests.workbench.unseen_plants import T, random_plant, write_recordings  # noqa: E402

OSCILLATION = 900032
SEEDS = (0, 5, 6)


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


@pytest.mark.parametrize("seed", SEEDS)
def test_tuned_on_the_fitted_twin_is_stable_on_the_true_plant(tmp_path, seed):
    plant = random_plant(seed)
    files = write_recordings(plant, seed, tmp_path)
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
    st = json.loads(r.stdout)["tuned"]["stability"]      # the margins tune reports on the fitted twin
    assert st["stable"], st
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
