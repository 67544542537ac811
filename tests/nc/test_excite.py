"""distctrl.nc.excite / ``distctrl excite``: the excitation program for identify (issue 28)."""
from __future__ import annotations

import json
import re

import pytest
from click.testing import CliRunner

from distctrl.cli import main
from distctrl.nc import parse_program
from distctrl.nc.excite import Excitation, ExciteError, program

BASE = dict(axis="Z", work=31.5, safe=40.0, min_pos=25.0, max_pos=50.0, a_max=20000.0, v_max=300.0,
            chirp_seconds=1.0, ramp=(31.0, 32.0), surface=30.0)


def positions(text: str) -> list[float]:
    return [float(m) for m in re.findall(r"\bZ(-?[0-9.]+)", text)]


def test_program_parses_stays_within_limits_and_keeps_distance_control_off():
    text, warnings = program(Excitation(**BASE))
    prog = parse_program(text)
    assert len(prog.blocks) > 1000                 # one block per cycle of the 1 s chirp
    z = positions(text)
    assert min(z) >= 25.0 and max(z) <= 50.0
    assert z[0] == 40.0 and z[-1] == 40.0          # safe approach and retract
    assert "DIST_CTRL" not in text.replace("distance control", "")
    assert text.rstrip().endswith("M30")
    assert warnings == []


def test_chirp_amplitude_and_band():
    text, _ = program(Excitation(**{**BASE, "step": None, "ramp": None, "large_step": 0.0}))
    z = [p for p in positions(text) if abs(p - 31.5) < 1]
    assert max(z) == pytest.approx(31.55, abs=1e-4) and min(z) == pytest.approx(31.45, abs=1e-4)


@pytest.mark.parametrize("change, match", [
    ({"max_pos": 42.0}, "beyond the axis limits"),                 # the large step at the safe height
    ({"amplitude": 0.2, "surface": 31.0}, "at or below the surface"),
    ({"amplitude": 1.0, "v_max": 100.0, "surface": None}, "beyond the axis's v_max"),
    ({"chirp": (1.0, 900.0)}, "half the cycle rate"),
    ({"ramp": (24.0, 32.0), "surface": None}, "beyond the axis limits"),
])
def test_refuses_beyond_the_limits(change, match):
    with pytest.raises(ExciteError, match=match):
        program(Excitation(**{**BASE, **change}))


def test_warns_outside_the_recommended_amplitudes():
    _, warnings = program(Excitation(**{**BASE, "amplitude": 0.08, "step": 1.0}))
    assert any("--amplitude 0.08" in w for w in warnings) and any("--steps 1.0" in w for w in warnings)


def test_cli_writes_the_program_and_refuses_with_exit_1(tmp_path):
    out = tmp_path / "excite.nc"
    args = ["excite", "--work", "31.5", "--safe", "40", "--min", "25", "--max", "50", "--chirp-seconds", "1",
            "--out", str(out), "--json"]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["blocks"] > 1000 and out.is_file()
    r = CliRunner().invoke(main, [*args[:-3], "--max", "41", "--out", str(tmp_path / "x.nc"), "--json"])
    assert r.exit_code == 1
    err = json.loads(r.stdout)
    assert err["outcome"] == "error" and "beyond the axis limits" in err["error"]
    assert not (tmp_path / "x.nc").exists()
