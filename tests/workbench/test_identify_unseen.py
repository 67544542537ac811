"""distctrl identify on plants it was not designed around (issue 26): recordings from
tests/workbench/unseen_plants.py (its own integration: whole-cycle setpoint delay, sub-cycle drive,
exact first-order-hold mode, sensor quantised to 1 um, non-linear characteristics of several shapes),
written as CSV and read back. The seeds are ones the frequency-response-only fit got wrong (a 66 Hz
and a 68 Hz mode with zeta 0.01-0.02 missed; a square-root characteristic off by 0.4 mm at 0.5 mm).
bench/bench_identify_unseen.py measures the pass rates over many random plants."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from distctrl.workbench.identify import identify, load_signals
from tests.workbench.unseen_plants import TOL, random_plant, recordings, write_csv, write_recordings

SEEDS = (0, 3, 13)


@pytest.fixture(scope="module", params=SEEDS)
def fitted(request, tmp_path_factory):
    seed = request.param
    plant = random_plant(seed)
    d = tmp_path_factory.mktemp(f"unseen{seed}")
    paths = write_recordings(plant, seed, d)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sigs = [load_signals(p, command="set_pos", actual="act_pos", sensor="sensor") for p in paths]
        return plant, identify(sigs, surface=plant.surface)


def test_drive(fitted):
    plant, res = fitted
    assert abs(res.drive["kv"] / plant.kv - 1) <= TOL["kv"]
    assert abs(res.drive["dead_time"] - plant.dead_time) <= TOL["dead_time"]


def test_resonance_and_damping_from_the_sensor_path(fitted):
    plant, res = fitted
    f0, zeta = res.drive["resonance_hz"], res.drive["damping"]
    assert f0 is not None, res.warnings
    assert abs(f0 / plant.resonance_hz - 1) <= TOL["resonance_hz"]
    assert abs(zeta / plant.damping - 1) <= TOL["damping"][0] or abs(zeta - plant.damping) <= TOL["damping"][1]
    assert not any(w.startswith("resonance_hz") for w in res.warnings)


def test_sensor_delay_noise_and_characteristic(fitted):
    plant, res = fitted
    s = res.sensor
    assert abs(s["delay"] - plant.delay) <= TOL["delay"]
    assert abs(s["noise_std"] / plant.noise_std - 1) <= TOL["noise_std"]
    ch = np.asarray(s["characteristic"], float)
    d = np.linspace(0.5, 7.0, 300)
    assert np.max(np.abs(np.interp(d, ch[:, 0], ch[:, 1]) - plant.characteristic(d))) <= TOL["characteristic"]


def test_uncertainty_says_how_sure(fitted):
    """Each figure of the sensor path has a standard deviation; the truth lies within a generous
    multiple of it plus the tolerance's scale (the model is not the generator's)."""
    plant, res = fitted
    u = res.uncertainty
    assert u["drive"]["resonance_hz"] > 0 and u["drive"]["damping"] > 0
    assert u["sensor"]["delay"] > 0 and u["sensor"]["noise_std"] > 0
    assert u["drive"]["resonance_hz"] < 0.05 * res.drive["resonance_hz"]


def test_json_uncertainty_beside_the_pinned_keys_and_validation_on_a_recording_not_fitted(tmp_path):
    """--json: "uncertainty" has the pinned keys of "drive" and "sensor" (null where the figure is null);
    --validate REC.csv: the prediction error on a recording the fit did not use, the sensor's about the
    noise (the complete model explains everything else)."""
    import json

    from click.testing import CliRunner

    from distctrl.cli import main
    from tests.workbench.unseen_plants import chirp_command, simulate

    seed = 5
    plant = random_plant(seed)
    paths = [str(p) for p in write_recordings(plant, seed, tmp_path)]
    other = tmp_path / "chirp_other.csv"
    write_csv(other, *simulate(plant, chirp_command(np.random.default_rng(1), 8.0, plant.surface + 1.3), seed=99))
    r = CliRunner().invoke(main, ["identify", *paths, "--command", "set_pos", "--actual", "act_pos", "--sensor",
                                  "sensor", "--surface", "10", "--json", "--validate", str(other)],
                           catch_exceptions=False)
    assert r.exit_code == 0, r.output
    out = json.loads(r.output)
    for group in ("drive", "sensor"):
        assert set(out["uncertainty"][group]) == set(out[group])
        for k, v in out[group].items():
            sd = out["uncertainty"][group][k]
            assert (sd is None) == (v is None) or (v is not None and k in ("v_max", "a_max"))
    assert out["uncertainty"]["drive"]["resonance_hz"] > 0
    (val,) = out["validation"]["recordings"]
    assert val["path"].endswith("chirp_other.csv")
    assert val["drive_fit_percent"] > 95.0
    assert 0.8 < val["sensor_rms_over_noise"] < 1.3


def test_a_ramp_alone_asks_for_a_chirp_rather_than_calling_the_drive_rigid(tmp_path):
    """A slow ramp excites no mode: the resonance is null with "record a chirp", not "no resonance"."""
    seed = 0
    plant = random_plant(seed)
    p = tmp_path / "ramp.csv"
    write_csv(p, *recordings(plant, seed)["ramp"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify([load_signals(p, command="set_pos", actual="act_pos", sensor="sensor")], surface=plant.surface)
    assert res.drive["resonance_hz"] is None
    (w,) = [w for w in res.warnings if w.startswith("resonance_hz")]
    assert "record a chirp" in w and "rigid" not in w
