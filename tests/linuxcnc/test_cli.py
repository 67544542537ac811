"""`distctrl linuxcnc build` says whether it built or skipped (LinuxCNC audit item 7) and `distctrl
linuxcnc thc-setp` (new-user audit R6, R9; LinuxCNC audit item 6; issue 39): named,
commented pins a user can review, the same values as the component's tests load; a missing list named
in one line; with --ini the Z axis's external-offset limits (MAX_VELOCITY, MAX_ACCELERATION x
OFFSET_AV_RATIO) refuse a list above them, or --cap writes the limits with a warning."""
from __future__ import annotations

import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from distctrl.cli.linuxcnc import linuxcnc
from distctrl.linuxcnc import hal_env
from distctrl.linuxcnc.hal_env import LinuxCNCError
from distctrl.linuxcnc.thc import ThcConfig
from distctrl.params import load_list

ROOT = Path(__file__).resolve().parents[2]
LIST = str(ROOT / "examples" / "scenarios" / "z_plasma_plate.lis")
SIM_INI = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/qtplasmac/qtplasmac_l_metric.ini")


COMP = '''component probe_dc "a probe";
pin out float out;
function _;
license "GPL";
;;
FUNCTION(_) { out = %s; }
'''


def _ini(tmp_path: Path, z: str) -> Path:
    (tmp_path / "axes.inc").write_text(f"[AXIS_X]\nMAX_VELOCITY = 500\n\n[AXIS_Z]\n{z}\n")
    ini = tmp_path / "machine.ini"
    ini.write_text("[DISPLAY]\nDISPLAY = qtvcp\n#INCLUDE axes.inc\n[HAL]\nHALFILE = a.hal\nHALFILE = b.hal\n")
    return ini


def test_thc_setp_prints_named_commented_pins_with_the_same_values():
    r = CliRunner().invoke(linuxcnc, ["thc-setp", LIST, "--ini", str(SIM_INI), "--cap"])
    assert r.exit_code == 0, r.output
    lines = r.stdout.splitlines()
    assert "GENERATED" in lines[0] and any("Do not edit by hand" in ln for ln in lines)
    setp = [ln for ln in lines if ln.startswith("setp ")]
    assert all("    # " in ln for ln in setp)                  # every pin says what it is
    head = "# --- the distance filter: MOVING_AVERAGE (P-AXIS-00782 = 1), n = 20"
    assert any(ln.startswith(head) for ln in lines)
    fc = [ln for ln in setp if ".fc-" in ln]
    assert len(fc) < 20 and "setp distctrl-thc.0.fc-001 20.0    # n (window, periods)" in fc
    assert any(re.match(r"# not used by MOVING_AVERAGE and 0: fc-008\.\.fc-134", ln) for ln in lines)
    # the values: those of setp_lines (which the bit-for-bit tests load), the rest 0
    cfg = ThcConfig.from_params(load_list(LIST).params, v_max=60.0, a_max=600.0)
    want = dict(ln.split()[1:3] for ln in cfg.setp_lines(0.001))
    got = dict(ln.split()[1:3] for ln in setp)
    assert {k: v for k, v in want.items() if k not in got} == {k: "0.0" for k in want if k not in got}
    assert {k: want[k] for k in got} == got


def test_thc_setp_names_a_missing_list_in_one_line():
    r = CliRunner().invoke(linuxcnc, ["thc-setp", "nothere.lis"])
    assert r.exit_code == 1
    assert r.output.strip().count("\n") == 0 and "'nothere.lis' does not exist" in r.output, r.output


def test_thc_setp_refuses_limits_above_the_external_offsets_of_the_ini(tmp_path):
    """The sim's Z: 120 mm/s x 0.5 = 60 mm/s, 1200 mm/s² x 0.5 = 600 mm/s²; the list has 100 and 5000."""
    r = CliRunner().invoke(linuxcnc, ["thc-setp", LIST, "--ini", str(SIM_INI)])
    assert r.exit_code == 1
    msg = r.output.strip()
    assert "\n" not in msg and "v-max 100, a-max 5000" in msg and "= 60 mm/s" in msg and "= 600 mm/s²" in msg
    capped = CliRunner().invoke(linuxcnc, ["thc-setp", LIST, "--ini", str(SIM_INI), "--cap"])
    assert capped.exit_code == 0
    assert "warning: v-max 100" in capped.stderr and "capped to 60" in capped.stderr
    assert "setp distctrl-thc.0.v-max 60.0" in capped.stdout
    assert "setp distctrl-thc.0.a-max 600.0" in capped.stdout
    fast = _ini(tmp_path, "MAX_VELOCITY = 400\nMAX_ACCELERATION = 20000\nOFFSET_AV_RATIO = 0.5")
    ok = CliRunner().invoke(linuxcnc, ["thc-setp", LIST, "--ini", str(fast)])
    assert ok.exit_code == 0 and "setp distctrl-thc.0.v-max 100.0" in ok.stdout and not ok.stderr
    plain = CliRunner().invoke(linuxcnc, ["thc-setp", LIST])
    assert plain.exit_code == 0 and "not checked against the machine's external-offset limits" in plain.stderr


def test_the_ini_reader_follows_includes_and_names_a_bad_value(tmp_path):
    from distctrl.linuxcnc.ini import external_offset_limits, read_ini

    lim = external_offset_limits(read_ini(SIM_INI))
    assert (lim.v_max, lim.a_max) == (60.0, 600.0)
    ini = read_ini(_ini(tmp_path, "MAX_VELOCITY = 100\nMAX_ACCELERATION = 1000\nOFFSET_AV_RATIO = 0.2"))
    assert ini.all("HAL", "HALFILE") == ["a.hal", "b.hal"] and ini.get("AXIS_X", "MAX_VELOCITY") == "500"
    assert (external_offset_limits(ini).v_max, external_offset_limits(ini).a_max) == (20.0, 200.0)
    with pytest.raises(LinuxCNCError, match="OFFSET_AV_RATIO is missing: LinuxCNC applies no external"):
        external_offset_limits(read_ini(_ini(tmp_path, "MAX_VELOCITY = 100\nMAX_ACCELERATION = 1000")))
    with pytest.raises(LinuxCNCError, match=r"axes.inc:7: \[AXIS_Z\]OFFSET_AV_RATIO = 'x'"):
        bad = "MAX_VELOCITY = 100\nMAX_ACCELERATION = 1\nOFFSET_AV_RATIO = x"
        external_offset_limits(read_ini(_ini(tmp_path, bad)))


def test_build_says_up_to_date_when_it_skipped_and_built_when_it_built(tmp_path, monkeypatch):
    from distctrl.cli import linuxcnc as cli

    src_dir, mod_dir = tmp_path / "src", tmp_path / "mod"
    src_dir.mkdir()
    mod_dir.mkdir()
    (src_dir / "probe_dc.comp").write_text(COMP % "3.0")
    monkeypatch.setattr(hal_env, "HAL_DIR", src_dir)
    monkeypatch.setattr(hal_env, "MODULE_DIR", mod_dir)
    monkeypatch.setattr(cli, "COMPONENTS", ("probe_dc",))
    first = CliRunner().invoke(cli.linuxcnc, ["build"])
    assert first.exit_code == 0 and "built and installed" in first.output, first.output
    second = CliRunner().invoke(cli.linuxcnc, ["build"])
    assert second.exit_code == 0 and "up to date" in second.output and "installed" not in second.output
    forced = CliRunner().invoke(cli.linuxcnc, ["build", "--force"])
    assert "built and installed" in forced.output
