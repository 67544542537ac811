"""Issue 16's plates: the targets asserted on the shortened plates (the first part of each, the same
features, a few seconds), the full plates' layout checked against the issue, and the generator in
step with the committed files. The full plates' figures: bench/bench_process.py (`make bench`)."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from distctrl.sim.plates import EXAMPLES, TARGET_LIFT_INCREASE, TARGET_MIN_SHARE, compare
from distctrl.sim.scenario import load_scenario
from distctrl.sim.surface import Holes, Sine, Step

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module", params=["plasma_plate_short", "laser_sheet_short"])
def figures(request):
    return request.param, compare(EXAMPLES / f"{request.param}.toml")


def test_with_the_functions_the_head_keeps_30_percent_and_never_collides(figures):
    name, f = figures
    w = f["with"]
    assert w["functions"] == ["touch_off", "corner_lock", "void_lock", "lift"]
    assert w["completed"] and not w["errors"], name
    assert w["collisions"] == 0, name
    assert w["min_distance_mm"] >= TARGET_MIN_SHARE * w["set_distance_mm"], (name, w)


def test_the_lift_adds_at_most_5_percent_to_the_path_time(figures):
    name, f = figures
    assert f["with"]["lifts"] >= 1 and f["no_lift"]["lifts"] == 0, name
    assert f["no_lift"]["functions"] == ["touch_off", "corner_lock", "void_lock"]
    assert f["lift_path_time_increase"] <= TARGET_LIFT_INCREASE, (name, f["lift_path_time_increase"])


def test_without_the_functions_the_same_plate_shows_the_dive(figures):
    name, f = figures
    w, wo = f["with"], f["without"]
    assert wo["functions"] == []
    assert wo["min_distance_mm"] < w["min_distance_mm"] - 0.3, (name, wo)
    assert wo["collisions"] >= 1 or wo["min_distance_mm"] < TARGET_MIN_SHARE * wo["set_distance_mm"]
    assert wo["time_below_half_s"] > w["time_below_half_s"]
    # the locks hold the height, they do not slow the path: the touch-off's probe (under a second)
    # is the difference
    assert 0.0 <= w["path_time_s"] - wo["path_time_s"] < 1.0
    # the minimum of the run with the functions is the touch-off's probe (down to its 0.5 mm detect);
    # the cuts stay higher
    assert w["min_cut_distance_mm"] >= w["min_distance_mm"] and w["min_cut_distance_mm"] > 0.45


def _crossings(nc_text: str, kerfs: list[float]) -> tuple[int, int]:
    """(kerf crossings, 90° corners) of the G1 moves of a plate's program."""
    x = y = None
    crossings = corners = 0
    last_dir = None
    for line in nc_text.splitlines():
        mx, my = re.search(r"\bX(-?[\d.]+)", line), re.search(r"\bY(-?[\d.]+)", line)
        nx = float(mx.group(1)) if mx else x
        ny = float(my.group(1)) if my else y
        if " G1 " in f" {line} " and x is not None:
            crossings += sum(1 for k in kerfs if min(x, nx) < k < max(x, nx))
            d = "X" if nx != x else "Y"
            if last_dir is not None and d != last_dir:
                corners += 1
            last_dir = d
        elif " G0 " in f" {line} " or "DIST_CTRL OFF" in line:
            last_dir = None                          # a rapid or the end: the next cut starts afresh
        x, y = nx, ny
    return crossings, corners


def test_the_full_plates_have_what_the_issue_asks_for():
    sc = load_scenario(EXAMPLES / "plasma_plate.toml")
    kerfs = [f.at for f in sc.surface.features if isinstance(f, Step)]
    holes = [f for f in sc.surface.features if isinstance(f, Holes)][0]
    sines = [f for f in sc.surface.features if isinstance(f, Sine)]
    assert len(holes.centers) == 40
    crossings, corners = _crossings((EXAMPLES / "plasma_plate.nc").read_text(), kerfs)
    assert crossings == 60 and corners == 15        # + 5 closing corners back at each start: 20 per plate
    assert sum(2 * s.amplitude for s in sines) == pytest.approx(4.0)          # 4 mm warp
    assert "F5000" in (EXAMPLES / "plasma_plate.nc").read_text()              # 5 m/min
    assert sc.sensor.kind == "arc_voltage" and sc.sensor.arc_speed_volts > 0
    laser = load_scenario(EXAMPLES / "laser_sheet.toml")
    edge = [f for f in laser.surface.features if isinstance(f, Step) and f.width is None]
    assert len(edge) == 1 and laser.sensor.kind == "distance" and laser.sensor.footprint_radius > 0
    assert sum(2 * s.amplitude for s in laser.surface.features if isinstance(s, Sine)) == pytest.approx(0.5)
    assert [f for f in laser.surface.features if isinstance(f, Holes)][0].centers
    assert "F20000" in (EXAMPLES / "laser_sheet.nc").read_text()              # 20 m/min


def test_the_committed_plates_are_what_the_generator_writes(tmp_path):
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "make_plates.py"), "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    for p in sorted(tmp_path.iterdir()):
        assert p.read_text() == (EXAMPLES / p.name).read_text(), f"{p.name}: run tools/make_plates.py"
