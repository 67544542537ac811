"""distctrl linuxcnc bench: LinuxCNC's plasmac (Debian's linuxcnc-uspace, halrun) in closed loop on a
tiny plate (a cut across two kerfs, one corner), side by side with distctrl (docs/linuxcnc.md).

make test installs linuxcnc-uspace; these tests never skip for it."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from distctrl.cli import main
from distctrl.linuxcnc.plant import Move, OffsetFollower, PathFollower, program_moves

HERE = Path(__file__).resolve().parent
PLATE = HERE / "plate_tiny.toml"
ROOT = HERE.parents[1]


def test_program_moves_reads_the_plate_program():
    moves = program_moves((HERE / "plate_tiny.nc").read_text(), start=(0.0, 0.0))
    assert moves == [Move(0.0, 0.0, 20.0, 30.0, 0.0, False), Move(20.0, 30.0, 200.0, 30.0, 5000 / 60, True),
                     Move(200.0, 30.0, 200.0, 60.0, 5000 / 60, True)]


def test_path_follower_reaches_the_feed_and_stops_exactly_at_the_corner():
    p = PathFollower([Move(0, 0, 100, 0, 50.0, True), Move(100, 0, 100, 10, 50.0, True)], a_max=1000.0,
                     v_rapid=500.0, cycle_time=0.001)
    top, ends = 0.0, 0
    for _ in range(5000):
        ends += p.step(hold=False)
        top = max(top, p.v)
        if p.done:
            break
    assert p.done and ends == 2 and (p.x, p.y) == (100, 10)
    assert top == pytest.approx(50.0)


def test_offset_follower_arrives_exactly_and_keeps_its_limits():
    f = OffsetFollower(v_max=100.0, a_max=2500.0, cycle_time=0.001)
    last_v = 0.0
    for _ in range(2000):
        f.step(-15.345)
        assert abs(f.v) <= 100.0 + 1e-9 and abs(f.v - last_v) <= 2.5 + 1e-9
        last_v = f.v
    assert f.value == -15.345 and f.v == 0.0       # plasmac compares the offset with its target


@pytest.fixture(scope="module")
def bench_doc(tmp_path_factory):
    out = tmp_path_factory.mktemp("lcnc")
    p = subprocess.run([sys.executable, "-m", "distctrl", "linuxcnc", "bench", str(PLATE), "--repeat", "2",
                        "--json", "--html", str(out)], capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    doc = json.loads(p.stdout)
    doc["_out"] = out
    return doc


def _run(doc, controller, functions_on):
    for r in doc["runs"]:
        if r["controller"] == controller and (("corner_lock" in r["functions"]) == functions_on):
            return r
    raise AssertionError(f"no run {controller} {functions_on}")


def test_bench_json_has_the_issues_keys_for_plasmac_and_distctrl(bench_doc):
    assert bench_doc["plate"] == str(PLATE)
    assert {(r["controller"], "corner_lock" in r["functions"]) for r in bench_doc["runs"]} == {
        ("plasmac", True), ("plasmac", False), ("distctrl-hal", True), ("distctrl-hal", False), ("distctrl", True),
        ("distctrl", False)}
    for r in bench_doc["runs"]:
        for key in ("controller", "functions", "min_distance_mm", "time_below_half_s", "collisions",
                    "late_periods", "missed_periods", "dives", "spread", "repeats"):
            assert key in r, key
        assert len(r["repeats"]) == 2
    html = (bench_doc["_out"] / "index.html").read_text()
    assert html.count("data:image/png;base64,") == 4        # one plot per run in halrun


@pytest.mark.parametrize("controller", ["plasmac", "distctrl-hal"])
def test_plasmac_cuts_the_plate_in_lock_step_and_reproducibly(bench_doc, controller):
    for on in (True, False):
        r = _run(bench_doc, controller, on)
        assert r["cut_started"]
        assert r["missed_periods"] == 0               # lock-step: no period ran on stale inputs
        assert isinstance(r["late_periods"], int)     # counted (the wall clock's misses), not hidden
        # in lock-step a run is repeatable: both repeats give the same figures (the spread is 0)
        for key in ("min_distance_mm", "time_below_half_s", "collisions", "dives_total"):
            assert r["spread"][key]["spread"] == 0, key
        if controller == "distctrl-hal" and not on:
            # distctrl_thc without its void lock dives into the first kerf: the float switch trips and
            # plasmac pauses the program
            assert not r["completed"] and "paused" in r["warnings"][0]
            continue
        assert r["completed"], r["warnings"]
        assert r["arc_s"] > 1.5                       # the torch burnt along the cut
        assert 0.5 * bench_doc["cut_height_mm"] < r["min_distance_mm"] < 2.0 * bench_doc["cut_height_mm"]


def test_plasmac_with_its_locks_does_not_dive_where_distctrl_does_not(bench_doc):
    plasmac, dc = _run(bench_doc, "plasmac", True), _run(bench_doc, "distctrl", True)
    assert dc["completed"]
    for where, n in dc["dives"].items():
        if n == 0:
            assert plasmac["dives"][where] == 0, where
    assert plasmac["collisions"] == 0 and dc["collisions"] == 0
    assert plasmac["time_below_half_s"] <= dc["time_below_half_s"] + 1e-9 or dc["time_below_half_s"] == 0
    assert math.isfinite(plasmac["min_distance_mm"])


def test_distctrl_hal_keeps_the_torch_off_the_plate_in_halrun(bench_doc):
    """distctrl's law as the HAL component, in plasmac's cut sequence: no collision on the tiny plate."""
    r = _run(bench_doc, "distctrl-hal", True)
    assert r["collisions"] == 0 and r["min_distance_mm"] > 0.0


def test_bench_text_table_names_every_contestant():
    from distctrl.cli.linuxcnc import format_text

    doc = {"scenario": "s", "cut_height_mm": 1.5, "cut_feed_mm_min": 5000.0, "repeat": 1, "servo_period_s": 0.001,
           "runs": [{"controller": "plasmac", "functions": [], "min_distance_mm": 1.0, "time_below_half_s": 0.0,
                     "collisions": 0, "dives": {"corner": 0, "hole_kerf": 1, "other": 0}, "late_periods": 3,
                     "missed_periods": 0, "spread": {}}]}
    text = format_text(doc)
    assert "plasmac" in text and "0/1/0" in text and "late periods" in text


@pytest.mark.parametrize("setting, words", [("foo=1", "not a plasmac setting"), ("pid-p-gain=x", "not a number"),
                                            ("pid-p-gain=nan", "finite"), ("cornerlock-enable=1", "not a plasmac")])
def test_bench_refuses_a_bad_setting_with_exit_1_before_running(setting, words):
    # in-process (the CLI's exit code, stdout and stderr as a shell sees them; no interpreter start-up each)
    res = CliRunner().invoke(main, ["linuxcnc", "bench", str(PLATE), "--set", setting, "--json"])
    assert res.exit_code == 1
    doc = json.loads(res.stdout)
    assert doc["outcome"] == "error" and words in doc["error"] and "Traceback" not in res.stderr
    assert res.exception is None or isinstance(res.exception, SystemExit)
