"""`distctrl linuxcnc config`'s QtPlasmaC wiring of distctrl_thc, loaded in halrun as written: LinuxCNC's
motion module and plasmac, the sample configs' qtplasmac_comp.hal (installed by linuxcnc-uspace; without
its halui and debounce lines), then the generated distctrl_thc.hal (parameters and wiring). The full
session (task, halui, the GUI) is tests/linuxcnc/test_config.py."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from distctrl.linuxcnc.hal_env import HalSession, install_component

ROOT = Path(__file__).resolve().parents[2]
QTPLASMAC_COMP = Path("/usr/share/linuxcnc/hallib/qtplasmac_comp.hal")


def test_the_generated_distctrl_thc_hal_loads_in_halrun(tmp_path):
    """`distctrl linuxcnc config`'s distctrl_thc.hal (docs/linuxcnc.md "A QtPlasmaC configuration") after
    motmod, plasmac and the installed qtplasmac_comp.hal, as LinuxCNC loads it before the GUI."""
    for name in ("distctrl_thc", "distctrl_qtplasmac", "distctrl_simtorch"):
        install_component(name)
    out = tmp_path / "cfg"
    made = subprocess.run([sys.executable, "-m", "distctrl", "linuxcnc", "config", str(out)],
                          capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert made.returncode == 0, made.stderr
    comp_lines = [ln for ln in QTPLASMAC_COMP.read_text().splitlines()
                  if ln.strip() and not ln.lstrip().startswith("#") and "halui" not in ln and "db_" not in ln]
    base = ["loadrt trivkins coordinates=xyyz",   # motmod creates the servo thread
            "loadrt homemod", "loadrt tpmod",   # the linuxcnc script loads them before motmod (2.9)
            "loadrt motmod servo_period_nsec=1000000 num_joints=4 num_spindles=3", "loadrt plasmac",
            "addf motion-command-handler servo-thread", "addf motion-controller servo-thread",
            "addf plasmac servo-thread",
            # sim_no_stepgen.tcl's Z joint connection, which the wiring's plasmac:axis-position uses
            "net plasmac:axis-position joint.3.pos-fb => plasmac.axis-z-position"]
    with HalSession() as hs:
        hs.cmd(*base, *comp_lines)
        hs.cmd(*(out / "distctrl_thc.hal").read_text().splitlines())    # as written, comments and all
        assert hs.getp("distctrl-thc.0.kp") == "0.1" and hs.getp("distctrl-thc.0.v-max") == "60"
        assert "dthc:z-offset-counts" in hs.cmd("show pin axis.z.eoffset-counts")
        assert "plasmac:arc_voltage_out" in hs.cmd("show pin distctrl-thc.0.arc-voltage-in")
        assert "plasmac:cornerlock-enable" in hs.cmd("show pin distctrl-thc.0.cornerlock-enable")
        # the corner lock's reference: F times the override (motion.feed-upm, as plasmac's)
        assert "plasmac:feed-upm" in hs.cmd("show pin distctrl-thc.0.feed-upm")
        thread = hs.cmd("show thread servo-thread")
        funcs = [ln.split()[-1] for ln in thread.splitlines() if re.match(r"\s+\d+\s+\S", ln)]
        assert funcs.index("plasmac") < funcs.index("distctrl-qtplasmac.0") < funcs.index("distctrl-thc.0")
        assert "motion-controller" in funcs
