"""distctrl identify on hidden plants (issue 39): tests/workbench/hidden_plants.py, a generator written from
scratch (a drive with hard velocity and acceleration limits at 10 kHz, fine interpolation, feed-forward or
not, a Tustin mode, sensor delays of 0-5 cycles, quantisation, a clamped sensor range; raw set-position
steps of 2-45 mm). The tolerances are hidden_plants.TOL, decided before the first run.

* A drive at its limit is at its limit whatever the command did: a recording of raw steps whose motion
  holds v_max and a_max gives them (before: "v_max and a_max not identified: the motor reached ... without
  saturating", and no kv either: the saturated cycles drowned the loop's).
* The pass rate per quantity over HIDDEN_SEEDS (shorter recordings than bench/bench_identify_hidden.py,
  which measures 30 plants: docs/identify.md "Hidden plants").
"""
from __future__ import annotations

import warnings

import pytest

from distctrl.workbench.identify import identify, load_signals
from tests.workbench import hidden_plants as hp

#: seeds of the pass-rate test; each plant 3 recordings of 6 s, one large step
HIDDEN_SEEDS = tuple(range(10))
#: the pass rate each quantity must reach over HIDDEN_SEEDS (the bench's target is 95 % over 30 plants);
#: the drive's figures count the plants without velocity feed-forward (a drive with feed-forward is not the
#: P loop identify fits: docs/identify.md "Hidden plants")
MIN_RATE = 0.9
DRIVE = ("kv", "v_max", "a_max")


def _identify(paths):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sigs = [load_signals(p, command="set_pos", actual="act_pos", sensor="sensor") for p in paths]
        return identify(sigs)


@pytest.mark.parametrize("seed", [3, 11])
def test_a_drive_at_its_limits_gives_them_whatever_the_command_did(seed, tmp_path):
    plant = hp.random_plant(seed)
    paths, seen = hp.write_recordings(plant, seed, tmp_path, seconds=6.0, n_big=2, only=("steps",))
    assert seen["cycles_at_v_max"] >= 50 and seen["cycles_at_a_max"] >= hp.LIMIT_MIN_CYCLES
    res = _identify(paths)
    d = res.drive
    assert d["v_max"] == pytest.approx(plant.v_max, rel=hp.TOL["v_max"]), res.warnings
    assert d["a_max"] == pytest.approx(plant.a_max, rel=hp.TOL["a_max"]), res.warnings
    assert d["kv"] == pytest.approx(plant.kv, rel=hp.TOL["kv"]), res.warnings
    assert not [w for w in res.warnings if "not identified" in w and "v_max" in w]
    assert res.extra["drive_plateau_cycles_velocity"] > 0


@pytest.fixture(scope="module")
def scored(tmp_path_factory):
    rows = []
    for seed in HIDDEN_SEEDS:
        plant = hp.random_plant(seed)
        folder = tmp_path_factory.mktemp(f"h{seed}")
        paths, seen = hp.write_recordings(plant, seed, folder, seconds=6.0, n_big=1)
        res = _identify(paths)
        rows.append((plant, hp.score(plant, seen, res.drive, res.sensor), res))
    return rows


@pytest.mark.parametrize("quantity", hp.QUANTITIES)
def test_pass_rate_per_quantity(scored, quantity):
    marks = [(p, s[quantity]) for p, s, _ in scored if s[quantity] is not None
             and not (quantity in DRIVE and p.feed_forward)]
    failed = [p for p, ok in marks if not ok]
    assert marks
    assert 1.0 - len(failed) / len(marks) >= MIN_RATE, failed


def test_no_resonance_invented_on_a_rigid_drive_and_every_plant_passes_the_open_loop_check(scored):
    assert all(s["rigid_no_mode"] for p, s, _ in scored if p.resonance_hz is None)
    assert all(res.extra["open_loop"]["passed"] for _, _, res in scored)
