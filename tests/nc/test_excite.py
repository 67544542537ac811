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
    # 0.05 mm at 150 Hz would need 44 m/s²: above 90 Hz the amplitude falls (80 % of a_max), said once
    assert len(warnings) == 1 and "falls as 1/f²" in warnings[0] and "above 90.0 Hz" in warnings[0], warnings


def test_the_chirp_stays_within_the_axis_acceleration_and_says_so():
    """issue 28: excite refuses or avoids what the axis limits it was given forbid; the acceleration limit
    --a-max was not checked (0.05 mm at 150 Hz needs 44 m/s²)."""
    import numpy as np

    e = Excitation(**{**BASE, "step": None, "ramp": None, "large_step": 0.0, "a_max": 5000.0})
    text, warnings = program(e)
    z = np.array([float(m) for m in re.findall(r"^Z(-?[0-9.]+)", text, flags=re.M)])
    feeds = np.array([float(m) for m in re.findall(r"^Z-?[0-9.]+ F([0-9.]+)", text, flags=re.M)])
    assert len(feeds) == len(z)                              # every chirp block has its own feed
    lines = [ln for ln in text.splitlines() if ln.startswith("Z")]
    # rebuild the position per cycle: each block's time is its distance / its feed
    per_cycle, prev = [], 31.5
    for zk, fk in zip(z, feeds):
        n = int(round(abs(zk - prev) / (fk / 60.0) / 0.001))
        per_cycle += list(np.linspace(prev, zk, n + 1)[1:]) if n > 1 else [zk]
        prev = zk
    acc = np.diff(np.array(per_cycle), 2) / 0.001 ** 2
    assert np.quantile(np.abs(acc), 0.99) < 5000.0, np.abs(acc).max()
    assert len(lines) > 500
    assert any("falls as 1/f²" in w for w in warnings)
    assert "falling as 1/f^2 above" in text


def test_chirp_amplitude_and_band():
    text, _ = program(Excitation(**{**BASE, "step": None, "ramp": None, "large_step": 0.0}))
    z = [p for p in positions(text) if abs(p - 31.5) < 1]
    assert max(z) == pytest.approx(31.55, abs=1e-4) and min(z) == pytest.approx(31.45, abs=1e-4)


@pytest.mark.parametrize("change, match", [
    ({"max_pos": 42.0}, "beyond the axis limit --max 42"),                 # the large step at the safe height
    ({"amplitude": 0.2, "surface": 31.0}, "at or below the surface"),
    ({"amplitude": 1.0, "v_max": 100.0, "surface": None}, "beyond the axis's v_max"),
    ({"chirp": (1.0, 900.0)}, "half the cycle rate"),
    ({"ramp": (24.0, 32.0), "surface": None}, "beyond the axis limit --min 25"),
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
    assert err["outcome"] == "error" and "beyond the axis limit --max 41" in err["error"]
    assert not (tmp_path / "x.nc").exists()


# ---------------------------------------------------------------- the chirp is played at its written rate
def _play(text: str, a_max: float, cycle_time: float = 0.001):
    """Run the program on distctrl's virtual machine (the NC and interpolator `distctrl serve` runs): the
    programmed Z of every cycle and the NC line of every cycle."""
    import numpy as np

    from distctrl.sim.machine import Machine
    from distctrl.sim.scenario import scenario_from_dict

    sc = scenario_from_dict({"cycle_time": cycle_time, "program_text": text, "duration": 120.0,
                             "axes": {"Z": {"start": 40.0, "v_max": 300.0, "a_max": a_max}}})
    m = Machine(sc, parse_program(text))
    z, lines = [], []
    while m.nc.running and len(z) < 120 / cycle_time:
        m.step()
        z.append(m.interp.position["Z"])
        lines.append(m.nc.line if m.nc.line is not None else -1)
    return np.array(z), np.array(lines)


def _upward_crossings(t, x):
    """Times (s) where x crosses 0 upwards, linearly interpolated (zeros of a staircase skipped)."""
    import numpy as np

    nz = np.flatnonzero(x != 0.0)
    a, b = nz[:-1], nz[1:]
    up = (x[a] < 0) & (x[b] > 0)
    a, b = a[up], b[up]
    return t[a] + (t[b] - t[a]) * (-x[a]) / (x[b] - x[a])


@pytest.mark.parametrize("band, amplitude, a_max", [
    ((1.0, 150.0), 0.02, 20000.0),      # the commissioning loop's axis (tests/client): up to the cycle's limit
    ((1.0, 60.0), 0.1, 20000.0),        # steps of up to 0.038 mm per cycle: more than a_max x T^2
    ((5.0, 100.0), 0.05, 5000.0),       # the acceleration bounds the amplitude above 50 Hz
])
def test_the_chirp_is_played_at_the_written_rate(band, amplitude, a_max):
    """issue 28: one G1 block per cycle must be played at one block per cycle, so that the chirp's frequency
    over time is the one written (before: about 1.5-3 cycles per block, a 1-150 Hz chirp swept ~0.3-50 Hz)."""
    import numpy as np

    seconds = 2.0
    e = Excitation(axis="Z", work=31.5, safe=40.0, min_pos=25.0, max_pos=50.0, a_max=a_max, v_max=300.0,
                   step=None, large_step=0.0, ramp=None, chirp=band, chirp_seconds=seconds, amplitude=amplitude)
    text, _ = program(e)
    lines = text.splitlines()
    first = next(i for i, ln in enumerate(lines) if ln.startswith("; chirp")) + 2     # the first chirp block's line
    last = next(i for i, ln in enumerate(lines) if i > first and ln.startswith("N") and " G0 " in ln)
    z, nc_line = _play(text, a_max)
    run = np.flatnonzero((nc_line >= first) & (nc_line <= last))
    t = (np.arange(len(z)) - run[0]) * 0.001           # 0: the cycle the chirp's first block starts in
    f0, f1 = band
    k = (f1 - f0) / seconds
    written_end = seconds
    played_end = t[run[-1]]
    assert played_end == pytest.approx(written_end, rel=0.02), \
        f"the {seconds} s chirp took {played_end:.3f} s"
    tc = _upward_crossings(t[run], z[run] - 31.5)
    tc = tc[(tc > 0.12) & (tc < seconds - 0.12)]         # outside the 0.1 s fade in and out
    f_played = 1.0 / np.diff(tc)
    t_mid = 0.5 * (tc[1:] + tc[:-1])
    f_written = f0 + k * t_mid
    rel = np.abs(f_played / f_written - 1.0)
    assert np.quantile(rel, 0.9) < 0.03 and np.median(rel) < 0.01, \
        (f"played {f_played.min():.1f}-{f_played.max():.1f} Hz for the written {f0:g}-{f1:g} Hz; "
         f"median error {np.median(rel):.3f}")
