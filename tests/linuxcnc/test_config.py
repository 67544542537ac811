"""`distctrl linuxcnc config` (issue 40): a QtPlasmaC configuration with distctrl_thc, written from
Debian's installed QtPlasmaC sim, started headless (Xvfb) in a real LinuxCNC - milltask, motion,
halui, the qtvcp GUI and the sim panel - and driven through a program with a rising, warped plate, a
hole and four corners (qtplasmac_cut.ngc) on the height-dependent sim torch (hal/distctrl_simtorch.comp).

Asserted on the samples (~100 Hz, LinuxCNC's Python modules): the program completes; while distctrl_thc
controls, the torch's height over the plate (the sim torch's own `height`) stays within its band; it is
never below half the cut height while the arc burns; no monitoring error at all, in particular no 70329 at
torch off; the locks follow QtPlasmaC's anti-dive switches and lock (the void lock over the hole, the corner
lock at the corners); QtPlasmaC's arc-voltage display shows the arc voltage and its THC-active LED
distctrl_thc's state; plasmac's own THC stays off. One LinuxCNC session (~1-2 min)."""
from __future__ import annotations

import csv
import json
import shutil
import statistics
from pathlib import Path

import pytest
from click.testing import CliRunner

from distctrl.cli.linuxcnc import linuxcnc
from distctrl.linuxcnc.config import DEBIAN_SIM, HAL_FILE, POSTGUI_FILE, SimTorch
from distctrl.linuxcnc.hal_env import install_component
from distctrl.linuxcnc.sim import LinuxCNCRun

HERE = Path(__file__).resolve().parent
PROGRAM = HERE / "qtplasmac_cut.ngc"
CUT_HEIGHT = 1.5
PINS = ["plasmac.state-out", "plasmac.torch-on", "plasmac.arc-ok-out", "plasmac.arc-voltage-out",
        "plasmac.thc-enabled", "distctrl-thc.0.thc-enable", "distctrl-thc.0.state", "distctrl-thc.0.error-id",
        "distctrl-thc.0.offset", "distctrl-thc.0.set-dist", "distctrl-thc.0.cornerlock-enable",
        "distctrl-thc.0.voidlock-enable", "distctrl-thc.0.cornerlock-is-locked",
        "distctrl-thc.0.voidlock-is-locked", "distctrl-simtorch.0.height", "distctrl-simtorch.0.arc-ok",
        "distctrl-simtorch.0.arc-loss", "plasmac.thc-active", "plasmac.cornerlock-is-locked",
        "plasmac.voidlock-is-locked",
        "qtplasmac.arc_voltage", "qtplasmac.led_thc_enabled", "qtplasmac.led_thc_active"]


def _rows(path: Path) -> list[dict]:
    conv = {"True": 1.0, "False": 0.0}
    with open(path, newline="") as f:
        return [{k: conv.get(v, None) if v in conv else float(v) for k, v in r.items()}
                for r in csv.DictReader(f, delimiter="\t")]


def test_config_writes_beside_the_source_and_refuses_what_it_cannot(tmp_path):
    out = tmp_path / "cfg"
    r = CliRunner().invoke(linuxcnc, ["config", str(out), "--json"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["sim_torch"] and doc["ini"] == str(out / "qtplasmac_l_metric.ini")
    inc = (out / "qtplasmac_metric_ini.inc").read_text()
    # the two [HAL] lines: distctrl_thc.hal right after qtplasmac_comp.hal, its post-GUI file last
    hal = [ln.split("=", 1)[1].strip() for ln in inc.splitlines()
           if ln.startswith(("HALFILE", "POSTGUI_HALFILE"))]
    assert hal[hal.index("qtplasmac_comp.hal") + 1] == HAL_FILE and hal[-1] == POSTGUI_FILE
    text = (out / HAL_FILE).read_text()
    assert "net plasmac:arc_voltage_out plasmac.arc-voltage-out => distctrl-thc.0.arc-voltage-in" in text
    assert "net plasmac:cornerlock-enable => distctrl-thc.0.cornerlock-enable" in text
    assert "net plasmac:voidlock-enable => distctrl-thc.0.voidlock-enable" in text
    assert "setp distctrl-thc.0.v-max 60.0" in text and "setp distctrl-thc.0.a-max 600.0" in text
    # only distctrl's own modules are loaded (no module another HAL file loads: no TWOPASS needed)
    loads = [ln.split()[1] for ln in text.splitlines() if ln.startswith("loadrt")]
    assert all(m.startswith("distctrl_") for m in loads) and len(loads) == len(set(loads))
    # the source is read, not changed; OUTDIR must be new
    assert "distctrl" not in (DEBIAN_SIM / "qtplasmac_metric_ini.inc").read_text()
    again = CliRunner().invoke(linuxcnc, ["config", str(out)])
    assert again.exit_code == 1 and "not empty" in again.output
    inside = CliRunner().invoke(linuxcnc, ["config", str(out / "sub"), "--from", str(out)])
    assert inside.exit_code == 1 and "inside the source configuration" in inside.output
    laser = CliRunner().invoke(linuxcnc, ["config", str(tmp_path / "l"), "--laser"])
    assert laser.exit_code == 1 and "--laser is not built yet" in laser.output


def test_config_from_a_users_qtplasmac_config_leaves_it_as_it_was(tmp_path):
    """--from: the user's configuration is read, the new one written beside it; no sim torch there."""
    user = tmp_path / "my_plasma"
    shutil.copytree(DEBIAN_SIM, user)
    before = {p.name: p.read_bytes() for p in user.iterdir() if p.is_file()}
    many = CliRunner().invoke(linuxcnc, ["config", str(tmp_path / "x"), "--from", str(user)])
    assert many.exit_code == 1 and "QtPlasmaC INI files" in many.output and "--ini" in many.output
    r = CliRunner().invoke(linuxcnc, ["config", str(tmp_path / "my_plasma_distctrl"), "--from", str(user),
                                      "--ini", "qtplasmac_p_metric.ini", "--json"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert not doc["sim_torch"] and doc["ini"].endswith("my_plasma_distctrl/qtplasmac_p_metric.ini")
    out = tmp_path / "my_plasma_distctrl"
    assert "distctrl_simtorch" not in (out / HAL_FILE).read_text()
    assert "simtorch" not in (out / POSTGUI_FILE).read_text()
    assert "distctrl_thc.hal" in (out / "qtplasmac_metric_ini.inc").read_text()
    assert {p.name: p.read_bytes() for p in user.iterdir() if p.is_file()} == before


def _cut_in_linuxcnc(tmp_path_factory, name: str, thc: str = "distctrl", **drive) -> tuple[dict, list[dict]]:
    """`distctrl linuxcnc config` from Debian's sim, started headless, qtplasmac_cut.ngc run and sampled."""
    for comp in ("distctrl_thc", "distctrl_qtplasmac", "distctrl_simtorch"):
        install_component(comp)
    base = tmp_path_factory.mktemp(name)
    r = CliRunner().invoke(linuxcnc, ["config", str(base / "cfg"), "--thc", thc])
    assert r.exit_code == 0, r.output
    # the sim torch's voltage net is the last POSTGUI line of both: the configuration is up
    ini = base / "cfg" / "qtplasmac_l_metric.ini"
    with LinuxCNCRun(ini, base / "run", ready_signal="dthc:sim-voltage") as run:
        run.wait_ready()
        summary = run.drive(PROGRAM, base / "run" / "samples.tsv", PINS, **drive)
    return summary, _rows(base / "run" / "samples.tsv")


@pytest.fixture(scope="module")
def sim_run(tmp_path_factory):
    return _cut_in_linuxcnc(tmp_path_factory, "lcnc", max_seconds=240)


def test_the_generated_config_cuts_in_linuxcnc_and_holds_the_height(sim_run):
    summary, rows = sim_run
    assert summary["started"] and summary["completed"], summary
    assert not summary["errors"], summary["errors"]
    burning = [r for r in rows if r["distctrl-simtorch.0.arc-ok"] and r["plasmac.state-out"] == 11]
    active = [r for r in rows if r["distctrl-thc.0.state"] == 4]
    assert len(active) > 0.5 * len(burning) > 200
    h = [r["distctrl-simtorch.0.height"] for r in active]
    dev = sorted(abs(x - CUT_HEIGHT) for x in h)
    # the plate rises 2 mm and warps +-0.5 mm under the cut: held within +-0.15 mm in 95 % of the samples
    print(f"\nLinuxCNC run: {summary['seconds']} s, {len(rows)} samples; ACTIVE_CONST_DIST {len(active)}: "
          "height "
          f"{min(h):.3f}..{max(h):.3f} mm, median {statistics.median(h):.3f}, 95 % within "
          f"{dev[int(0.95 * len(dev))]:.3f} mm of {CUT_HEIGHT}; while burning min "
          f"{min(r['distctrl-simtorch.0.height'] for r in burning):.3f} mm")
    assert dev[int(0.95 * len(dev))] < 0.15 and max(dev) < 0.5, (min(h), max(h), statistics.median(h))
    assert min(r["distctrl-simtorch.0.height"] for r in burning) > 0.5 * CUT_HEIGHT
    offsets = [r["distctrl-thc.0.offset"] for r in active]
    assert max(offsets) - min(offsets) > 1.5            # it did move Z (the rise), not plasmac
    assert all(r["plasmac.thc-enabled"] == 0.0 for r in rows)


def test_torch_off_ends_control_without_an_error(sim_run):
    _, rows = sim_run
    assert {r["distctrl-thc.0.error-id"] for r in rows} == {0.0}
    assert 5.0 not in {r["distctrl-thc.0.state"] for r in rows}          # never ERROR
    # both cuts: ACTIVE_CONST_DIST, then TURNING_OFF / INACTIVE when the torch goes off
    states = [r["distctrl-thc.0.state"] for r in rows]
    starts = sum(1 for a, b in zip(states, states[1:]) if a == 0 and b == 4)
    assert starts == 2
    off = [r for r in rows if not r["plasmac.torch-on"]]
    assert all(r["distctrl-thc.0.thc-enable"] == 0.0 for r in off)


def test_the_locks_follow_qtplasmacs_switches_and_lock(sim_run):
    _, rows = sim_run
    assert all(r["distctrl-thc.0.cornerlock-enable"] and r["distctrl-thc.0.voidlock-enable"] for r in rows)
    torch = SimTorch()
    void = [r for r in rows if r["distctrl-thc.0.voidlock-is-locked"]]
    assert void and all(torch.hole_x0 - 5 <= r["x"] <= torch.hole_x0 + torch.hole_width + 15 for r in void)
    assert any(r["distctrl-thc.0.cornerlock-is-locked"] for r in rows)


def test_qtplasmacs_display_and_leds_show_the_truth(sim_run):
    _, rows = sim_run
    cut = [r for r in rows if r["distctrl-thc.0.state"] == 4]
    shown = [r["qtplasmac.arc_voltage"] for r in cut]
    assert statistics.median(shown) > 95.0                       # the display shows the burning arc
    same = sum(abs(r["qtplasmac.arc_voltage"] - r["plasmac.arc-voltage-out"]) < 3.0 for r in cut)
    assert same > 0.9 * len(cut)
    assert all(r["qtplasmac.led_thc_enabled"] for r in rows)
    lit = [r["qtplasmac.led_thc_active"] for r in rows if r["distctrl-thc.0.state"] == 4]
    assert sum(lit) > 0.95 * len(lit)
    assert not any(r["qtplasmac.led_thc_active"] for r in rows if r["distctrl-thc.0.state"] == 0)


@pytest.fixture(scope="module")
def arc_loss_run(tmp_path_factory):
    """The same configuration and program; the arc goes out mid-cut (the sim torch's arc-loss pin at X 300
    on the first cut) and does not light again."""
    return _cut_in_linuxcnc(tmp_path_factory, "lcnc-arc-loss", max_seconds=120,
                            actions=[{"x": 300.0, "setp": ["distctrl-simtorch.0.arc-loss", 1]}])


def test_arc_loss_mid_cut_ends_safe(arc_loss_run):
    """No dive: the torch stays above half the cut height from the arc loss on, distctrl_thc holds (ERROR
    70329: the distance jumped, which is what an arc loss is) and runs its offset out when plasmac drops the
    torch; plasmac pauses the program ("valid arc lost") and raises the torch; distctrl_thc ends INACTIVE."""
    summary, rows = arc_loss_run
    assert summary["started"] and summary["paused"] and not summary["completed"], summary
    assert any("arc lost" in e for e in summary["errors"]), summary["errors"]
    lost = next(i for i, r in enumerate(rows) if r["distctrl-simtorch.0.arc-loss"])
    before, after = rows[lost - 1], rows[lost:]
    assert before["plasmac.torch-on"] and before["distctrl-thc.0.state"] == 4      # mid-cut, under control
    assert min(r["distctrl-simtorch.0.height"] for r in after) > 0.5 * CUT_HEIGHT
    assert {r["distctrl-thc.0.error-id"] for r in after} <= {0.0, 70329.0}
    assert after[-1]["distctrl-thc.0.state"] == 0 and after[-1]["distctrl-thc.0.offset"] == 0.0
    assert after[-1]["distctrl-simtorch.0.height"] > 10.0                          # raised
    print(f"\narc loss at X {rows[lost]['x']:.1f}: distctrl_thc states after it "
          f"{sorted({r['distctrl-thc.0.state'] for r in after})}, error-ids "
          f"{sorted({r['distctrl-thc.0.error-id'] for r in after})}, min height "
          f"{min(r['distctrl-simtorch.0.height'] for r in after):.3f} mm; {summary['errors']}")


def test_plasmac_runs_on_the_same_sim_torch_as_the_baseline(tmp_path_factory):
    """`config --thc plasmac`: plasmac's own THC (the material's 104 V, no auto volts) on the same
    height-dependent torch, plate and program. Asserted: its THC closes the loop on the sim torch (the point
    of the torch: Debian's sim-torch gives no height) - before the hole it holds 1.5 mm within 0.25 mm.
    What it does at the hole is measured and printed, not asserted (docs/linuxcnc.md)."""
    summary, rows = _cut_in_linuxcnc(tmp_path_factory, "lcnc-plasmac", thc="plasmac", max_seconds=240)
    assert summary["started"], summary
    first = [r for r in rows if r["plasmac.thc-active"] and r["y"] < 50]
    before_hole = [r["distctrl-simtorch.0.height"] for r in first if r["x"] < SimTorch().hole_x0 - 5]
    assert len(before_hole) > 50
    steady = before_hole[len(before_hole) // 4:]                  # after its THC has settled
    assert max(abs(h - CUT_HEIGHT) for h in steady) < 0.25, (min(steady), max(steady))
    burning = [r["distctrl-simtorch.0.height"] for r in rows
               if r["distctrl-simtorch.0.arc-ok"] and r["plasmac.state-out"] == 11]
    void = sum(bool(r["plasmac.voidlock-is-locked"]) for r in rows)
    print(f"\nplasmac's THC on the sim torch: before the hole {min(steady):.3f}..{max(steady):.3f} mm; "
          f"lowest while burning {min(burning):.3f} mm; void lock {void} samples; run: completed "
          f"{summary['completed']}, paused {summary['paused']}, {summary['errors']}")
