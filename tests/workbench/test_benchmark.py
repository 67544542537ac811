"""distctrl benchmark (issue 41, docs/benchmark.md): the figures on tracks with a known answer, made by
plants integrated here (not by the simulator), and the command's smoke test, JSON, CSV and exit codes."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from distctrl.cli.main import main
from distctrl.workbench.benchmark import run as bench_run
from distctrl.workbench.benchmark.contestants import Track
from distctrl.workbench.benchmark.metrics import FIGURES, measure
from distctrl.workbench.benchmark.suite import PLATE_NAMES, RunSpec, SuiteParams, plates, runs


def _no_nan(text: str):
    """Strict JSON: NaN and infinities are refused."""
    def refuse(name):
        raise AssertionError(f"{name} in the JSON")
    return json.loads(text, parse_constant=refuse)


def _lagged_head(spec: RunSpec, kv: float, substeps: int = 50) -> Track:
    """A head that follows surface + set through a first-order lag of gain ``kv`` (1/s), the nozzle moving
    along X at the feed from the start of the path after the dwell (no acceleration), integrated here with
    ``substeps`` Euler steps per cycle: the plant of the known answer v tan(a) / kv, written without
    distctrl's drive model."""
    plate = spec.plate_obj()
    T = spec.params.cycle_time
    v = spec.feed * 1000.0 / 60.0
    x_end = plate.path[-1][0]
    dwell = int(round(spec.params.dwell_s / T))
    n = dwell + int(x_end / v / T) + 1
    t = np.arange(n) * T
    x = np.where(np.arange(n) < dwell, 0.0, (np.arange(n) - dwell) * T * v)
    start, end, rise = (plate.surface["features"][0][k] for k in ("start", "end", "height"))

    def surface(xx):
        return rise * min(1.0, max(0.0, (xx - start) / (end - start)))

    z = np.empty(n)
    zk = surface(0.0) + spec.set_mm
    h = T / substeps
    for k in range(n):
        z[k] = zk
        for j in range(substeps):          # dz/dt = kv (surface(x(t)) + set - z)
            xt = x[k] + (v * h * j if k >= dwell else 0.0)
            zk += h * kv * (surface(xt) + spec.set_mm - zk)
    return Track(t, x, np.zeros(n), z, 0, dwell, n - 1, "completed", [])


@pytest.mark.parametrize("feed", [10.0, 30.0])
def test_a_ramp_behind_a_drive_lag_measures_v_tan_over_kv(feed):
    """The steady error of a head lagging 1/kv behind a 2 degree ramp is -v tan(2 deg) / kv, and the
    figure named drive_lag_mm is the same (feed-forward 0): both within 2 %."""
    spec = RunSpec("ramp_2deg", "laser", "1kHz", 0.0, feed, "distctrl_examples", SuiteParams())
    kv = spec.params.kv
    expected = -(feed * 1000.0 / 60.0) * math.tan(math.radians(2.0)) / kv
    m = measure(_lagged_head(spec, kv), spec, spec.plate_obj())
    assert m["steady_cycles"] > 50
    assert m["steady_mean_mm"] == pytest.approx(expected, rel=0.02)
    assert m["drive_lag_mm"] == pytest.approx(expected, rel=0.02)
    assert abs(m["beyond_lag_mm"]) < 0.02 * abs(expected)
    assert m["steady_sd_mm"] < 0.01 * abs(expected) + 1e-4
    assert m["collisions"] == 0 and m["approach_undershoot_mm"] == 0.0


def test_a_faster_drive_halves_the_lag():
    """The same plant with twice the gain: half the error, measured."""
    spec = RunSpec("ramp_2deg", "laser", "1kHz", 0.0, 20.0, "distctrl_examples", SuiteParams())
    slow = measure(_lagged_head(spec, 60.0), spec, spec.plate_obj())["steady_mean_mm"]
    fast = measure(_lagged_head(spec, 120.0), spec, spec.plate_obj())["steady_mean_mm"]
    assert fast == pytest.approx(slow / 2, rel=0.03)


def test_the_approach_figures_of_a_known_approach():
    """A head coming down from 3 mm as set + 2 exp(-t/tau) is in position (0.1 mm, held 20 ms) at
    tau ln 20, without undershoot; one that dips 0.3 mm below the set distance undershoots 0.3 mm."""
    spec = RunSpec("flat", "laser", "1kHz", 0.0, 10.0, "distctrl_examples", SuiteParams())
    T, tau, n = 0.001, 0.04, 600
    t = np.arange(n) * T
    z = spec.set_mm + 2.0 * np.exp(-t / tau)
    track = Track(t, np.zeros(n), np.zeros(n), z, 0, n - 1, n - 1, "completed", [])
    m = measure(track, spec, spec.plate_obj())
    assert m["approach_time_s"] == pytest.approx(tau * math.log(20.0), abs=1.5 * T)
    assert m["approach_undershoot_mm"] == 0.0
    dip = z - 0.3 * np.exp(-((t - 0.45) / 0.02) ** 2)      # at 0.45 s the approach is within 0.1 um
    m = measure(Track(t, np.zeros(n), np.zeros(n), dip, 0, n - 1, n - 1, "completed", []), spec,
                spec.plate_obj())
    assert m["approach_undershoot_mm"] == pytest.approx(0.3, abs=0.01)


def test_a_dive_into_a_hole_is_the_void_excursion_and_a_collision_counts_once():
    """A head that drops 2 mm while over the first hole (and holds the set distance elsewhere): void
    excursion 2 mm, least height above the sheet set - 2 mm; ending in the hole's far wall is one
    collision (the head below the sheet, back on the metal)."""
    spec = RunSpec("holes", "laser", "1kHz", 0.0, 10.0, "distctrl_examples", SuiteParams())
    plate = spec.plate_obj()
    v = spec.feed * 1000.0 / 60.0
    T = 0.001
    n = int(plate.path[-1][0] / v / T)
    x = np.arange(n) * T * v
    c = plate.surface["features"][0]["centers"][0][0]
    z = np.full(n, spec.set_mm)
    inside = np.abs(x - c) < 3.0
    z[inside] -= 2.0
    track = Track(np.arange(n) * T, x, np.zeros(n), z, 0, 0, n - 1, "completed", [])
    m = measure(track, spec, plate)
    assert m["void_excursion_mm"] == pytest.approx(2.0)
    assert m["min_feature_distance_mm"] == pytest.approx(spec.set_mm - 2.0)
    assert m["collisions"] == 0                       # over the hole the surface is 40 mm down
    z2 = z.copy()
    z2[(x > c + 5.0) & (x < c + 6.0)] = -0.5          # into the metal beyond the hole
    m = measure(Track(np.arange(n) * T, x, np.zeros(n), z2, 0, 0, n - 1, "completed", []), spec, plate)
    assert m["collisions"] == 1 and m["min_distance_mm"] == pytest.approx(-0.5)


def test_the_suite_is_what_the_docs_say():
    """9 plates; laser 6 feeds x 2 sensors, plasma 5 feeds x 1, 2 drives, 3 contestants; every plate's
    path stays inside the examples' lists' offset range (ramps and warp rise at most 8 mm)."""
    p = SuiteParams()
    assert len(runs(p)) == 9 * (6 * 2 + 5) * 2 * 3
    for process, feeds in (("laser", p.laser_feeds), ("plasma", p.plasma_feeds)):
        for feed in feeds:
            names = [pl.name for pl in plates(p, process, feed)]
            assert tuple(names) == PLATE_NAMES
            for pl in plates(p, process, feed):
                rises = [f.get("height", 0.0) for f in pl.surface["features"] if f["type"] == "ramp"]
                assert all(0 < r <= p.ramp_rise_max_mm for r in rises)


@pytest.fixture(scope="module")
def quick_json():
    result = CliRunner().invoke(main, ["benchmark", "--quick", "--json"])
    return result


def test_quick_smoke_json_no_nan_and_the_check(quick_json):
    """`distctrl benchmark --quick --json`: exit 0, one strict JSON object (no NaN: null), every run has
    every figure, the not-run contestants are named, issue 41's drive lag is reproduced."""
    assert quick_json.exit_code == 0, quick_json.output
    out = _no_nan(quick_json.stdout)
    assert out["command"] == "benchmark" and out["outcome"] == "completed" and out["exit_code"] == 0
    assert out["runs"] and all(set(FIGURES) <= set(r) for r in out["runs"])
    names = {c["name"]: c for c in out["contestants"]}
    assert names["simple_pid"]["run"] and names["distctrl_examples"]["run"]
    for later in ("distctrl_tuned", "plasmac_defaults", "plasmac_tuned"):
        assert names[later]["run"] is False and names[later]["why_not"]
    assert out["check"]["ok"] is True
    measured = {i["feedforward"]: i["measured_mm"] for i in out["check"]["items"]}
    assert measured[0.0] == pytest.approx(0.326, abs=0.01)
    assert measured[1.0] == pytest.approx(0.035, abs=0.01)
    # the list alone runs out of its offset range over a hole (70331, max_deviation): a result, named
    for r in out["runs"]:
        if r["contestant"] != "distctrl_examples" or r["plate"] != "holes":
            assert r["outcome"] == "completed", r
        elif r["outcome"] != "completed":
            assert [e["id"] for e in r["errors"]] == [70331]


def test_csv_plots_and_report(tmp_path):
    csv_path, plots, report = tmp_path / "b.csv", tmp_path / "plots", tmp_path / "rep"
    res = CliRunner().invoke(main, ["benchmark", "--quick", "--plates", "ramp_2deg", "--process", "laser",
                                    "--csv", str(csv_path), "--plots", str(plots), "--report", str(report)])
    assert res.exit_code == 0, res.output
    text = csv_path.read_text()
    assert "nan" not in text.lower() and text.splitlines()[0].startswith("plate,process")
    assert len(text.splitlines()) == 1 + 2 * 2 * 3          # 2 feeds x 2 drives x 3 contestants
    assert (plots / "ramp_2deg.png").stat().st_size > 1000
    html = (report / "index.html").read_text()
    assert "ramp_2deg" in html and "data:image/png;base64," in html and "plasmac_tuned" in html


def test_exit_codes(tmp_path, monkeypatch):
    """1: an unknown plate, an output that cannot be written (JSON error object on stdout); 4: the
    reproduction check fails (here: issue 41's figure made wrong)."""
    res = CliRunner().invoke(main, ["benchmark", "--quick", "--plates", "moon", "--json"])
    assert res.exit_code == 1
    err = _no_nan(res.stdout)
    assert err["outcome"] == "error" and "moon" in err["error"]
    res = CliRunner().invoke(main, ["benchmark", "--quick", "--csv", "/dev/full/x.csv"])
    assert res.exit_code == 1 and "cannot write the table /dev/full/x.csv" in res.output
    res = CliRunner().invoke(main, ["benchmark", "--workers", "0"])
    assert res.exit_code == 1
    monkeypatch.setattr(bench_run, "ISSUE_41_FIGURES", {0.0: 0.5, 1.0: 0.035})
    res = CliRunner().invoke(main, ["benchmark", "--quick", "--plates", "ramp_2deg", "--process", "laser",
                                    "--json"])
    assert res.exit_code == 4
    out = _no_nan(res.stdout)
    assert out["outcome"] == "check_failed" and out["check"]["ok"] is False


def test_without_simple_pid_the_baseline_is_named_not_run(monkeypatch):
    """simple-pid is a test dependency, not one of distctrl's: where it is missing the PID is left out and
    named, with the reason, instead of a traceback."""
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "simple_pid" else real(name, *a))
    result = bench_run.run_suite(quick=True, plates=("ramp_2deg",), processes=("laser",))
    assert {r["contestant"] for r in result.rows} == {"distctrl_examples", "distctrl_examples_pf"}
    pid = next(c for c in result.contestants() if c["name"] == "simple_pid")
    assert pid["run"] is False and "simple-pid" in pid["why_not"]
