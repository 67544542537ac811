"""distctrl step cannot mislead (issue 13): a response the slope limiter (P-AXIS-00415 v_max, P-AXIS-00416
a_max) decided is said so and never suggested; the default step keeps the loop out of the limiter; the
settling band widens to the offset's own noise; ``--json``; the plot is written before the table."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from distctrl.trace import Trace
from distctrl.workbench.step import (LIMITED_SHARE, auto_step, hints, measure, parse_settings, run_steps,
                                     suggested_kp)
from distctrl.cli.step import step as step_cmd

ROOT = Path(__file__).resolve().parents[2]
SHEET = ROOT / "examples" / "scenarios" / "const_dist_sheet.toml"
#: the audit's command, shortened: step 0.1 s into a 0.6 s run
SHORT = {"t_step": 0.1, "duration": 0.6}


def test_a_1_mm_step_on_the_sheet_is_limiter_bound_and_no_kp_is_suggested():
    """The audit: `distctrl step const_dist_sheet.toml --kp 0.3,0.6,1.5` with the 1 mm step gave the same
    rise and overshoot for every KP (the limiter's) and suggested one of them."""
    res = run_steps(parse_settings("0.3,0.6,1.5"), SHEET, step_mm=1.0, progress=False, **SHORT)
    h = hints(res)
    assert not any(line.startswith("suggested P setting") for line in h), h
    assert suggested_kp(res) is None
    for r in res:
        assert r.metrics.limiter_bound and r.metrics.limited_share >= LIMITED_SHARE, r.setting.label
    for line, r in zip(h, res):
        assert "P-AXIS-00415/00416" in line and "a good P setting" not in line, line
    assert "response limited by P-AXIS-00415/00416" in h[0] and "smaller --step" in h[0]


def test_a_small_step_is_not_limiter_bound_and_kps_differ():
    res = run_steps(parse_settings("0.3,0.6"), SHEET, step_mm=0.04, progress=False, **SHORT)
    assert all(r.metrics.limited_share < LIMITED_SHARE for r in res)
    assert res[0].metrics.rise_time_s > 1.3 * res[1].metrics.rise_time_s
    assert res[1].metrics.overshoot_pct > 2 * res[0].metrics.overshoot_pct


def test_a_kp_that_did_not_settle_is_never_suggested():
    res = run_steps(parse_settings("0.2,0.5,1"), None, step_mm=0.02, progress=False, **SHORT)
    one = res[2].metrics
    assert not one.settled
    best = suggested_kp(res)
    assert best is not None and best.setting.kp == 0.5


def test_auto_step_keeps_the_first_cycle_inside_the_limiter_and_above_the_noise():
    step, why = auto_step(parse_settings("0.2,0.5,1"))
    assert 0.005 <= step <= 0.05 and "P-AXIS-00415/00416" in why          # default machine: no noise
    res = run_steps(parse_settings("0.2,0.5,1"), None, step_mm="auto", progress=False, **SHORT)
    assert res[0].trace.meta["step"]["step_mm"] == step
    assert all(r.metrics.limited_share == 0.0 for r in res)
    sheet_step, why = auto_step(parse_settings("0.3,0.6"), SHEET)
    assert sheet_step == 0.04 and "noise" in why                          # 20 x 2 µm of probe noise


def test_the_settling_band_widens_to_the_offsets_noise_before_the_step():
    rng = np.random.default_rng(1)
    T, t_step, step = 0.001, 0.5, 0.04
    t = np.arange(2001) * T
    y = np.where(t >= t_step, step * (1 - np.exp(-np.maximum(t - t_step, 0) / 0.005)), 0.0)
    y = y + rng.normal(0.0, 0.001, t.size)                   # 1 µm of noise: 2.5 % of the step
    tr = Trace(["t", "Z.dc.offset"], np.column_stack((t, y)), {"t": "s", "Z.dc.offset": "mm"})
    m = measure(tr, t_step, step)
    assert m.band_mm > 0.02 * step and abs(m.band_mm - 5 * 0.001) < 0.001
    assert m.settled and m.settling_time_s < 0.05 and m.oscillation <= 4


# ------------------------------------------------------------------------------------------------------
# the command
# ------------------------------------------------------------------------------------------------------
def test_cli_default_step_is_out_of_the_limiter_for_the_audits_kps():
    res = CliRunner().invoke(step_cmd, [str(SHEET), "--kp", "0.3,0.6", "--t-step", "0.1", "--duration", "0.6"])
    assert res.exit_code == 0, res.output
    assert "step 0.04 mm (auto" in res.output
    assert "P-AXIS-00415/00416 decided" not in res.output and "response limited" not in res.output


def test_cli_json_is_one_object_with_metrics_and_no_table():
    res = CliRunner().invoke(
        step_cmd, [str(SHEET), "--kp", "0.3,0.6,1.5", "--step", "1", "--t-step", "0.1", "--duration", "0.6",
                   "--json"])
    assert res.exit_code == 0, res.stderr
    obj = json.loads(res.stdout)
    assert obj["command"] == "step" and obj["step_mm"] == 1.0 and obj["suggested_kp"] is None
    assert [r["setting"]["kp"] for r in obj["results"]] == [0.3, 0.6, 1.5]
    m = obj["results"][0]["metrics"]
    assert m["limiter_bound"] is True and 0 < m["limited_share"] <= 1 and m["band_mm"] == 0.02
    assert obj["results"][0]["limiter"]["v_max_mm_s"] == 200.0
    assert any("P-AXIS-00415/00416" in h for h in obj["hints"])


def test_cli_help_types_the_numbers():
    res = CliRunner().invoke(step_cmd, ["--help"])
    for opt in ("--t-step FLOAT", "--duration FLOAT", "--set-dist FLOAT", "--ramp FLOAT", "--step MM|auto",
                "--kp LIST"):
        assert opt in res.output, opt


def test_a_plot_is_written_even_when_the_reader_stops_early(tmp_path):
    """`distctrl step ... --plot p.png | head -2` lost the plot (BrokenPipe before it was written); a reader
    that reads nothing (`head -n 0`) makes that certain."""
    out = tmp_path / "p.png"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    cmd = (f"'{sys.executable}' -m distctrl step --kp 0.2,0.5 --t-step 0.05 --duration 0.3 --plot '{out}' "
           f"| head -n 0")
    proc = subprocess.run(["bash", "-c", cmd], capture_output=True, text=True, env=env,
                          cwd=tmp_path, timeout=120)
    assert out.exists() and out.read_bytes()[:4] == b"\x89PNG", proc.stderr
    assert "Traceback" not in proc.stderr
