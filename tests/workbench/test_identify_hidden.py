"""distctrl identify on hidden plants (issue 39): tests/workbench/hidden_plants.py, a generator written from
scratch (a drive with hard velocity and acceleration limits at 10 kHz, fine interpolation, feed-forward or
not, a Tustin mode, sensor delays of 0-5 cycles, quantisation, a clamped sensor range; raw set-position
steps of 2-45 mm). The tolerances are hidden_plants.TOL, decided before the first run.

* A drive at its limit is at its limit whatever the command did: a recording of raw steps whose motion
  holds v_max and a_max gives them (before: "v_max and a_max not identified: the motor reached ... without
  saturating", and no kv either: the saturated cycles drowned the loop's).
* A drive with velocity feed-forward follows the chirp almost without lag: the P loop alone read its kv
  as 49, 1750 or 1520 1/s (true 20, 37, 27) or fitted nothing; identify fits the feed-forward too.
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
#: the pass rate each quantity must reach over HIDDEN_SEEDS (the bench's target is 95 % over 30 plants)
MIN_RATE = 0.9
DRIVE = ("kv", "v_max", "a_max")
#: plants with velocity feed-forward (seeds 6, 12, 19 read kv 2.5x, 47x, 55x too high; 20 and 25: no fit)
FEED_FORWARD_SEEDS = (6, 12, 25)


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


@pytest.mark.parametrize("seed", FEED_FORWARD_SEEDS)
def test_a_drive_with_velocity_feed_forward_gives_kv_and_its_limits(seed, tmp_path):
    plant = hp.random_plant(seed)
    assert plant.feed_forward
    paths, seen = hp.write_recordings(plant, seed, tmp_path, seconds=6.0, n_big=1)
    res = _identify(paths)
    marks = hp.score(plant, seen, res.drive, res.sensor)
    assert all(marks[q] for q in DRIVE), (marks, res.drive, res.warnings)
    # the simulator's ff (per cycle) of a full feed-forward at the drive's rate: 1 - kv T/2 and less
    assert 0.8 <= res.drive["feedforward"] <= 1.0
    assert res.uncertainty["drive"]["feedforward"] is not None


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
    marks = [(p, s[quantity]) for p, s, _ in scored if s[quantity] is not None]
    failed = [p for p, ok in marks if not ok]
    assert marks
    assert 1.0 - len(failed) / len(marks) >= MIN_RATE, failed


def test_no_resonance_invented_on_a_rigid_drive_and_every_plant_passes_the_open_loop_check(scored):
    assert all(s["rigid_no_mode"] for p, s, _ in scored if p.resonance_hz is None)
    assert all(res.extra["open_loop"]["passed"] for _, _, res in scored)


def test_a_drive_without_feed_forward_is_fitted_as_the_p_loop_alone(scored):
    assert all(res.drive["feedforward"] == 0.0 for p, _, res in scored if not p.feed_forward)


def test_the_fitted_feed_forward_is_the_simulators(tmp_path):
    """The mapping onto the twin (fitted.toml's axes.Z.feedforward): the simulator's own drive (distctrl/sim)
    with ff 0.6 gives back 0.6, its kv and its bus delay."""
    import numpy as np

    from distctrl.sim.drive import Drive
    from distctrl.workbench.identify import Signals
    from distctrl.workbench.identify.output import fitted_axis

    rng = np.random.default_rng(5)
    sigs = []
    commands = (("steps", hp.steps_command(rng, 4.0, 8.0, 1)), ("chirp", hp.chirp_command(rng, 6.0, 7.0)))
    for name, cmd in commands:
        drv = Drive(hp.T, kv=40.0, v_max=80.0, a_max=3000.0, bus_delay_cycles=2, resolution=1e-4,
                    initial_position=float(cmd[0]), velocity_feedforward=0.6)
        act = np.array([drv.step(float(c)) for c in cmd])
        t = np.arange(cmd.size) * hp.T
        sigs.append(Signals(t=t, command=cmd, actual=act, sensor=act - 5.0, cycle_time=hp.T, path=name,
                            columns=("c", "a", "s"), source="csv", actual_at="end"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify(sigs, sensor_sign=1.0)
    keys, _ = fitted_axis(res)
    assert keys["feedforward"] == pytest.approx(0.6, abs=0.03), res.drive
    assert keys["kv"] == pytest.approx(40.0, rel=0.05) and keys["bus_delay_cycles"] == 2, res.drive
