"""docs/linuxcnc.md's QtPlasmaC wiring of distctrl_thc, loaded in halrun as written: LinuxCNC's motion
module and plasmac, the sample configs' qtplasmac_comp.hal (installed by linuxcnc-uspace; without its
halui and debounce lines), the setp file of `distctrl linuxcnc thc-setp`, the doc's INI and custom.hal."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from distctrl.linuxcnc.hal_env import HalSession, install_component

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "linuxcnc.md"
QTPLASMAC_COMP = Path("/usr/share/linuxcnc/hallib/qtplasmac_comp.hal")


def _block(lang: str) -> str:
    blocks = re.findall(rf"```{lang}\n(.*?)```", DOC.read_text(encoding="utf-8"), re.S)
    assert len(blocks) == 1, f"docs/linuxcnc.md should have one {lang} block"
    return blocks[0]


def test_the_docs_qtplasmac_snippets_load_in_halrun(tmp_path):
    install_component("distctrl_thc")
    ini = tmp_path / "qtplasmac.ini"
    ini.write_text(_block("ini"), encoding="utf-8")
    params = subprocess.run([sys.executable, "-m", "distctrl", "linuxcnc", "thc-setp",
                             str(ROOT / "examples" / "scenarios" / "z_plasma_plate.lis")],
                            capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert params.returncode == 0, params.stderr
    comp_lines = [ln for ln in QTPLASMAC_COMP.read_text().splitlines()
                  if ln.strip() and not ln.lstrip().startswith("#") and "halui" not in ln and "db_" not in ln]
    base = ["loadrt trivkins coordinates=xyyz",   # motmod creates the servo thread
            "loadrt homemod", "loadrt tpmod",   # the linuxcnc script loads them before motmod (2.9)
            "loadrt motmod servo_period_nsec=1000000 num_joints=4 num_spindles=3", "loadrt plasmac",
            "addf motion-command-handler servo-thread", "addf motion-controller servo-thread",
            "addf plasmac servo-thread",
            # sim_no_stepgen.tcl's Z joint connection, which custom.hal's plasmac:axis-position uses
            "net plasmac:axis-position joint.3.pos-fb => plasmac.axis-z-position"]
    custom = [ln for ln in _block("hal").splitlines() if ln.strip()]
    with HalSession() as hs:
        hs.cmd(*base, *comp_lines)
        hs.cmd(*params.stdout.splitlines())          # as printed: its comments are halcmd comments
        hs.cmd(*custom, ini=str(ini))
        assert hs.getp("distctrl-thc.0.set-dist") == "1.5"
        assert hs.getp("distctrl-thc.0.kp") == "0.1"
        pins = hs.cmd("show pin axis.z.eoffset-counts")
        assert "dthc:z-offset-counts" in pins
        # the corner lock's reference: F times the override (motion.feed-upm, as plasmac's), not
        # motion.requested-vel, which does not reflect the override (motion(9))
        assert "plasmac:feed-upm" in hs.cmd("show pin distctrl-thc.0.feed-upm")
        assert hs.getp("distctrl-thc.0.cornerlock-mode") == "0"
        thread = hs.cmd("show thread servo-thread")
        funcs = [ln.split()[-1] for ln in thread.splitlines() if re.match(r"\s+\d+\s+\S", ln)]
        assert funcs.index("distctrl-thc.0") > funcs.index("plasmac")
        assert "motion-controller" in funcs
