"""distctrl step: the documents' step-response tuning method (FCT-M3 ch. 3) on the virtual machine.

Metrics are checked on synthetic traces with known answers; the documents' claims on short runs of
the simulation (a few hundred ms of machine time each).
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from distctrl.errors import DistCtrlError
from distctrl.sim.scenario import scenario_from_dict
from distctrl.trace import Trace
from distctrl.workbench.step import (DEFAULT_AXIS_LIST, StepError, StepMetrics, StepResult, StepSetting,
                                     StepSettingError, format_table, hints, measure, parse_settings,
                                     plot_steps, run_steps, step_scenario)
from distctrl.cli.step import step as step_cmd

ROOT = Path(__file__).resolve().parents[2]
SHEET = ROOT / "examples" / "scenarios" / "const_dist_sheet.toml"
T = 0.001
#: short runs: step after 50 ms, 300 ms in all
FAST = {"t_step": 0.05, "duration": 0.3}


def synthetic(y_of_t, t_step=0.1, duration=1.0, baseline=2.0, step=1.0):
    """A trace: ``Z.dc.offset = baseline`` before ``t_step``, ``baseline + step·y(t - t_step)`` after."""
    t = np.arange(int(round(duration / T)) + 1) * T
    tt = t - t_step
    y = np.where(tt >= -T / 2, baseline + step * y_of_t(np.maximum(tt, 0.0)), baseline)
    return Trace(["t", "Z.dc.offset"], np.column_stack((t, y)), {"t": "s", "Z.dc.offset": "mm"})


def with_params(sc, **changes):
    """``sc`` with its Z axis's parameters changed (AxisParameters.replace)."""
    z = sc.axes["Z"]
    return dataclasses.replace(sc, axes={"Z": dataclasses.replace(z, params=z.params.replace(**changes))})


# ------------------------------------------------------------------------------------------------------
# settings
# ------------------------------------------------------------------------------------------------------
def test_parse_settings_is_the_cartesian_product_kp_outermost():
    s = parse_settings(kp="0.2,0.5,1", i_tn="0", d_tv="0,0.01")
    assert [(x.kp, x.i_tn, x.d_tv) for x in s] == [(0.2, 0, 0), (0.2, 0, 0.01), (0.5, 0, 0), (0.5, 0, 0.01),
                                                   (1.0, 0, 0), (1.0, 0, 0.01)]
    assert s[1].label == "KP=0.2 I_TN=0 D_TV=0.01" and s[1].kind == "PD"
    assert parse_settings([0.5, 0.5], 5, (0, 0.01))[1] == StepSetting(0.5, 5.0, 0.01)   # duplicates dropped
    assert StepSetting(1.0, 5.0, 0.01).kind == "PID" and StepSetting(1.0).nc_words() == "KP=1 I_TN=0 D_TV=0"


@pytest.mark.parametrize("kw, needle", [
    ({"kp": "0"}, "0 < KP <= 2"), ({"kp": "2.5"}, "0 < KP <= 2"),
    ({"kp": "0.2,abc"}, "'abc' is not a number"),
    ({"kp": ""}, "empty value"), ({"kp": "0.2,,1"}, "empty value"), ({"kp": []}, "at least one value"),
    ({"i_tn": "-1"}, "0 <= I_TN <= 50 s"), ({"i_tn": "51"}, "0 <= I_TN <= 50 s"),
    ({"d_tv": "2.01"}, "0 <= D_TV <= 2 s"), ({"d_tv": "nan"}, "0 <= D_TV <= 2 s"),
])
def test_bad_settings_raise_a_distctrl_error_saying_what_is_allowed(kw, needle):
    with pytest.raises(StepSettingError) as exc:
        parse_settings(**kw)
    assert isinstance(exc.value, DistCtrlError) and isinstance(exc.value, StepError)
    assert needle in str(exc.value) and "allowed" in str(exc.value)


def test_step_setting_validates_itself():
    with pytest.raises(StepSettingError, match="0 < KP <= 2"):
        StepSetting(3.0)
    with pytest.raises(StepSettingError, match="not a number"):
        StepSetting(True)


# ------------------------------------------------------------------------------------------------------
# metrics on synthetic traces
# ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("step", [1.0, -0.5])
def test_first_order_response_rise_time_is_tau_ln9_without_overshoot(step):
    tau = 0.02
    tr = synthetic(lambda x: 1.0 - np.exp(-x / tau), step=step)
    m = measure(tr, 0.1, step)
    assert m.rise_time_s == pytest.approx(tau * math.log(9), abs=2e-5)
    assert m.settling_time_s == pytest.approx(tau * math.log(50), abs=2e-5)   # |err| = e^(-t/τ) = 2 %
    assert m.overshoot_mm == 0.0 and m.overshoot_pct == 0.0 and m.peak_time_s is None
    assert m.oscillation == 0 and m.settled
    assert m.steady_state_error_mm == pytest.approx(0.0, abs=1e-12)
    assert m.step_mm == step


def test_damped_oscillation_overshoot_peak_time_and_swings():
    zeta, wn = 0.358, 200.0
    wd = wn * math.sqrt(1 - zeta ** 2)

    def y(x):
        c = zeta / math.sqrt(1 - zeta ** 2)
        return 1 - np.exp(-zeta * wn * x) * (np.cos(wd * x) + c * np.sin(wd * x))
    tr = synthetic(y, step=0.8)
    m = measure(tr, 0.1, 0.8)
    M = math.exp(-math.pi * zeta / math.sqrt(1 - zeta ** 2))                      # ≈ 0.30
    assert m.overshoot_pct == pytest.approx(100 * M, abs=0.05)
    assert m.overshoot_mm == pytest.approx(0.8 * M, abs=5e-4)
    assert m.peak_time_s == pytest.approx(math.pi / wd, abs=T)
    # extrema after the first peak: -M², +M³, -M⁴ ...; counted while beyond ±1 %:
    # M² = 9 %, M³ = 2.7 % (M⁴ = 0.8 %)
    assert m.oscillation == 2 and m.periods == 1
    assert m.settled and m.rise_time_s < math.pi / wd
    # settling: the envelope e^(-ζωn t)/sqrt(1-ζ²) drops below 2 % after at most this long
    assert m.settling_time_s < -math.log(0.02 * math.sqrt(1 - zeta ** 2)) / (zeta * wn)


def test_a_response_that_keeps_oscillating_is_not_settled():
    tr = synthetic(lambda x: 1 + 0.1 * np.sin(2 * np.pi * 50 * x))
    m = measure(tr, 0.1, 1.0)
    assert not m.settled and m.settling_time_s is None
    assert m.oscillation > 50 and m.overshoot_pct == pytest.approx(10.0, abs=0.1)


def test_ramp_reference_and_steady_state_error():
    # the response follows a 2 mm/s ramp 0.05 mm behind: the steady-state error is 0.05 mm
    tr = synthetic(lambda x: (1 - np.exp(-x / 0.01)) + 2.0 * x - 0.05 * (1 - np.exp(-x / 0.01)))
    m = measure(tr, 0.1, 1.0, ramp_mm_s=2.0)
    assert m.steady_state_error_mm == pytest.approx(0.05, abs=1e-6)
    assert measure(synthetic(lambda x: 0.9 * (1 - np.exp(-x / 0.01))), 0.1, 1.0).steady_state_error_mm \
        == pytest.approx(0.1, abs=1e-9)


def test_measure_rejects_bad_input():
    tr = synthetic(lambda x: 1 - np.exp(-x / 0.02))
    with pytest.raises(StepError, match="step != 0"):
        measure(tr, 0.1, 0.0)
    with pytest.raises(StepError, match="outside the trace"):
        measure(tr, 5.0, 1.0)
    with pytest.raises(StepError, match="no column"):
        measure(tr, 0.1, 1.0, column="X.dc.offset")
    with pytest.raises(StepError, match="dc.offset"):
        measure(Trace(["t", "a"], np.zeros((5, 2))), 0.001, 1.0)


# ------------------------------------------------------------------------------------------------------
# the scenario
# ------------------------------------------------------------------------------------------------------
def test_step_scenario_programs_the_setting_and_a_sensor_jump():
    sc = step_scenario(None, StepSetting(0.5, 0, 0.01), 1.0, t_step=0.5, duration=2.0)
    assert "Z[DIST_CTRL ON CONST_DIST SET_DIST=1 KP=0.5 I_TN=0 D_TV=0.01]" in sc.program_text
    assert sc.duration == 2.0 and list(sc.axes) == ["Z"] and sc.axes["Z"].start == 1.0
    assert sc.axes["Z"].params.enabled and not sc.axes["Z"].params.use_both_encoders
    (ev,) = sc.events
    assert ev.t == 0.5 and ev.kind == "sensor_fault" and ev.data == {"kind": "jump", "value": 1.0}
    sp = step_scenario(None, StepSetting(0.2), -0.5, mode="set_pos", t_step=0.1, duration=0.3)
    assert "Z[DIST_CTRL ON SET_POS=0 KP=0.2 I_TN=0 D_TV=0]" in sp.program_text
    assert sp.events[0].data["value"] == -0.5
    ramp = step_scenario(None, StepSetting(0.2), 0.5, t_step=0.1, duration=0.3, ramp_mm_s=2.0)
    assert [e.data for e in ramp.events] == [{"kind": "jump", "value": 0.5}, {"kind": "drift", "rate": 2.0}]


def test_step_scenario_takes_axis_list_drive_and_sensor_of_a_base_scenario():
    sc = step_scenario(SHEET, StepSetting(0.2), 1.0, **FAST)
    z = sc.axes["Z"]
    assert z.params.use_both_encoders and z.params.n_cycles == 4 and z.params.kp == 0.5   # z_laser.lis
    assert z.params_file.name == "z_laser.lis" and z.kv == 60.0 and z.start == 1.0
    assert sc.sensor.kind == "encoder" and sc.sensor.delay_cycles == 1 and sc.sensor.noise_std == 0.002
    assert "KP=0.2" in sc.program_text                 # the setting wins over the list's kp


def test_step_scenario_with_a_distance_sensor_selects_its_variable_and_inverts_the_jump():
    base = with_params(scenario_from_dict({"program_text": "M30\n", "axes": {"Z": {}}, "sensor": {
        "axis": "Z", "kind": "distance", "variable": "GAP", "range_max": 5.0}}),
        enabled=True, max_act_value_change=1e5, v_max=200.0, a_max=20000.0)
    sc = step_scenario(base, StepSetting(0.05), 0.5, set_dist=2.0, **FAST)
    assert "SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.GAP" in sc.program_text and "SET_DIST=2 " in sc.program_text
    assert sc.events[0].data["value"] == -0.5          # the sensor reports d: a rising surface lowers it
    (r,) = run_steps([StepSetting(0.05)], base, step_mm=0.5, set_dist=2.0, progress=False, t_step=0.05,
                     duration=0.6)
    assert r.trace.meta["errors"] == [] and r.metrics.settled and abs(r.metrics.steady_state_error_mm) < 1e-3


@pytest.mark.parametrize("kw, needle", [
    ({"mode": "FOO"}, "CONST_DIST, SET_POS"),
    ({"step_mm": 0.0}, "step != 0"),
    ({"step_mm": 20.0}, "is out of range"),                       # beyond the probe's window
    ({"t_step": 0.5, "duration": 0.3}, "0 < t_step < duration"),
    ({"duration": 100.0}, "0 < duration <= 60"),
    ({"set_dist": 12.0}, "outside the sensor window"),
    ({"ramp_mm_s": 50.0}, "lower the ramp"),
])
def test_step_scenario_rejects_bad_input(kw, needle):
    args = {"step_mm": 1.0, **FAST, **kw}
    with pytest.raises(StepError, match=needle.replace("(", r"\(").replace(")", r"\)")):
        step_scenario(None, StepSetting(0.5), **args)


def test_step_scenario_rejects_an_axis_without_distance_control_and_a_too_fast_jump():
    base = scenario_from_dict({"program_text": "M30\n", "axes": {"Z": {}},
                               "sensor": {"axis": "Z", "kind": "encoder"}})
    with pytest.raises(StepError, match="P-AXIS-00328"):
        step_scenario(base, StepSetting(0.5), 1.0, **FAST)
    enabled = with_params(base, enabled=True)          # P-AXIS-00417 keeps its default 5 mm/s
    with pytest.raises(StepError, match="P-AXIS-00417"):
        step_scenario(enabled, StepSetting(0.5), 1.0, **FAST)


# ------------------------------------------------------------------------------------------------------
# the documents' claims on the virtual machine
# ------------------------------------------------------------------------------------------------------
def test_larger_kp_is_faster_and_overshoots_more():
    res = run_steps(parse_settings("0.2,0.5,1.0"), progress=False, **FAST)
    assert [r.setting.kp for r in res] == [0.2, 0.5, 1.0]
    rise = [r.metrics.rise_time_s for r in res]
    assert rise[0] > rise[1] >= rise[2] and rise[0] > 1.5 * rise[2]
    p02, p05, _ = (r.metrics for r in res)
    assert p02.overshoot_pct < 2.0 and p02.settled                     # the documents' safe start value
    assert p05.overshoot_pct > 10.0 and p05.settled and p05.oscillation <= 4   # recognisable, decays fast
    for r in res:                                                   # a step leaves no error (P integrates)
        assert isinstance(r, StepResult) and r.trace.meta["step"]["t_step"] == FAST["t_step"]
        s, m, tr = r
        assert tr.meta["errors"] == [] and abs(m.steady_state_error_mm) < 1e-3


@pytest.fixture
def slow_drive(tmp_path):
    """A laser head whose Z drive lags (kv 100 1/s, no feed-forward): the loop the D part is made for."""
    (tmp_path / "z.lis").write_text(DEFAULT_AXIS_LIST, encoding="utf-8")
    (tmp_path / "slow.toml").write_text(
        'program_text = "M30\\n"\n[axes.Z]\nparams = "z.lis"\nkv = 100.0\nv_max = 1000.0\na_max = 100000.0\n'
        '[sensor]\naxis = "Z"\nkind = "encoder"\n', encoding="utf-8")
    return tmp_path / "slow.toml"


def test_d_part_damps_the_overshoot_of_a_kp_that_overshoots(slow_drive):
    without, with_d = run_steps(parse_settings("0.2", "0", "0,0.01"), slow_drive, progress=False, **FAST)
    assert without.metrics.overshoot_pct > 30 and without.metrics.oscillation >= 2
    assert with_d.metrics.overshoot_pct < 0.9 * without.metrics.overshoot_pct
    assert with_d.metrics.oscillation < without.metrics.oscillation
    assert with_d.metrics.settled and with_d.metrics.settling_time_s < without.metrics.settling_time_s
    assert any("D_TV=0.01 reduces the overshoot" in h for h in hints([without, with_d]))


def test_the_chapter_3_start_settings_settle_on_the_default_machine():
    """FCT-M3 ch. 3 / P-AXIS-00765: D_TV = 0.01 s is 'a low initial value to avoid instability' and the
    D part 'stabilises controller behaviour and reduces oscillations' (SPEC §5). On the default machine
    the start settings (KP 0.2, T_n 0 or 5 s, T_v 0.01 s) settle, and where the P loop overshoots
    (KP 0.3, 0.5) D_TV = 0.01 s lowers the overshoot."""
    res = run_steps(parse_settings("0.2,0.3,0.5", "0,5", "0,0.01"), progress=False)
    by = {(r.setting.kp, r.setting.i_tn, r.setting.d_tv): r.metrics for r in res}
    for (kp, i_tn, d_tv), m in by.items():
        assert m.settled and m.oscillation <= 4, (kp, i_tn, d_tv)
    for kp in (0.3, 0.5):
        assert by[(kp, 0.0, 0.0)].overshoot_pct > 2.0
        assert by[(kp, 0.0, 0.01)].overshoot_pct < by[(kp, 0.0, 0.0)].overshoot_pct


def test_i_part_removes_the_permanent_deviation_of_a_ramp():
    # a step alone leaves no error (see above); a surface rising at v leaves e = v·T/KP for a P controller
    v, kp = 5.0, 0.2
    p, pi = run_steps(parse_settings(kp, "0,0.05"), progress=False, step_mm=0.5, ramp_mm_s=v, t_step=0.05,
                      duration=0.8)
    assert p.metrics.steady_state_error_mm == pytest.approx(v * T / kp, rel=0.05)
    assert abs(pi.metrics.steady_state_error_mm) < 0.1 * p.metrics.steady_state_error_mm
    assert any("permanent control deviation: add I" in h for h in hints([p, pi]))


def test_set_pos_mode_and_a_base_scenario_run():
    (sp,) = run_steps([StepSetting(0.5)], mode="SET_POS", progress=False, **FAST)
    assert sp.metrics.settled and abs(sp.metrics.steady_state_error_mm) < 1e-3
    assert sp.trace.meta["step"]["mode"] == "SET_POS" and sp.trace["Z.dc.state"][-1] == 1   # ACTIVE
    res = run_steps(parse_settings("0.1,0.2"), SHEET, progress=False, **FAST)
    assert all(r.metrics.settled and abs(r.metrics.steady_state_error_mm) < 0.01 for r in res)
    assert res[0].metrics.rise_time_s > res[1].metrics.rise_time_s


# ------------------------------------------------------------------------------------------------------
# presentation
# ------------------------------------------------------------------------------------------------------
def _fake(setting, **metrics):
    m = StepMetrics(**{"step_mm": 1.0, "rise_time_s": 0.01, "overshoot_mm": 0.0, "overshoot_pct": 0.0,
                       "settling_time_s": 0.02, "steady_state_error_mm": 0.0, "oscillation": 0, **metrics})
    return StepResult(setting, m, Trace(["t"], np.zeros((1, 1)), meta={"errors": []}))


def test_hints_follow_the_documents_method():
    res = [_fake(StepSetting(0.2)),
           _fake(StepSetting(1.0), overshoot_pct=12.0, overshoot_mm=0.12, oscillation=4),
           _fake(StepSetting(1.5), overshoot_pct=40.0, overshoot_mm=0.4, oscillation=9),
           _fake(StepSetting(2.0), overshoot_pct=60.0, overshoot_mm=0.6, oscillation=90,
                 settling_time_s=None),
           _fake(StepSetting(0.1), steady_state_error_mm=0.05),
           _fake(StepSetting(0.7), overshoot_pct=78.0, overshoot_mm=0.78, oscillation=4),
           _fake(StepSetting(0.05), settling_time_s=None, rise_time_s=None)]
    h = hints(res)
    assert "KP=0.2 I_TN=0 D_TV=0: no recognisable overshoot" in h[0] and "raised" in h[0]
    assert h[1] == ("KP=1 I_TN=0 D_TV=0: overshoot 12 % decaying in 2 periods — recognisable but rapidly "
                    "decaying: a good P setting")
    assert "more oscillation than 'rapidly decaying': lower KP" in h[2]
    assert "not settled" in h[3] and "lower KP" in h[3]
    assert "permanent control deviation: add I (T_n from 5 s" in h[4]
    assert "a large overshoot (above 40 %): lower KP or add D" in h[5]
    assert "not settled" in h[6] and "without oscillating" in h[6] and "rise time - ms" in h[6]
    assert h[-1].startswith("suggested P setting: KP=1 ")


def test_format_table_lists_every_setting_and_metric():
    res = run_steps(parse_settings("0.2,0.5", "0", "0,0.001"), progress=False, **FAST)
    for plain in (False, True):
        text = format_table(res, title="steps", plain=plain)
        for head in ("rise 10-90 % [ms]", "overshoot [%]", "settling [ms]", "band ± [mm]",
                     "steady-state error [mm]", "oscillation", "at limiter [%]"):
            assert head in text
        for r in res:
            assert r.setting.label in text


def test_plot_steps_overlays_the_responses_and_saves_by_suffix(tmp_path):
    res = run_steps(parse_settings("0.2,0.5"), progress=False, **FAST)
    fig = plot_steps(res)
    (ax,) = fig.axes
    assert ax.get_xlabel() == "t − t_step [s]" and ax.get_ylabel() == "offset response [mm]"
    labels = [ln.get_label() for ln in ax.get_lines()]
    assert "KP=0.2 I_TN=0 D_TV=0" in labels and "KP=0.5 I_TN=0 D_TV=0" in labels
    assert "±2 % band" in labels and any(lbl.startswith("step 1 mm") for lbl in labels)
    assert all(ln.get_linestyle() == "--" for ln in ax.get_lines() if not ln.get_label().startswith("KP="))
    plot_steps(res, tmp_path / "s.png")
    assert (tmp_path / "s.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    plot_steps(res, tmp_path / "s.svg")
    assert b"<svg" in (tmp_path / "s.svg").read_bytes()[:2000]
    with pytest.raises(StepError, match=r"\.png, \.svg"):
        plot_steps(res, tmp_path / "s.jpg")


# ------------------------------------------------------------------------------------------------------
# the command
# ------------------------------------------------------------------------------------------------------
CLI_FAST = ["--t-step", "0.05", "--duration", "0.3"]


def test_cli_prints_the_table_for_all_settings_and_hints():
    res = CliRunner().invoke(step_cmd, ["--kp", "0.2,0.5,1.0", "--i-tn", "0", "--d-tv", "0,0.001", *CLI_FAST])
    assert res.exit_code == 0, res.output
    for kp in ("0.2", "0.5", "1"):
        for tv in ("0", "0.001"):
            assert f"KP={kp} I_TN=0 D_TV={tv}" in res.output
    assert "rise 10-90 % [ms]" in res.output and "hints (FCT-M3 ch. 3):" in res.output
    assert "a good P setting" in res.output


def test_cli_plot_writes_a_file_and_a_scenario_can_be_given(tmp_path):
    out = tmp_path / "steps.png"
    res = CliRunner().invoke(step_cmd, [str(SHEET), "--kp", "0.2", "--step", "0.5", "--plot", str(out),
                                        *CLI_FAST])
    assert res.exit_code == 0, res.output
    assert out.stat().st_size > 10_000 and f"plot: {out}" in res.output
    assert str(SHEET) in res.output


@pytest.mark.parametrize("args, needle", [
    (["--kp", "3"], "0 < KP <= 2"), (["--kp", "abc"], "not a number"), (["--i-tn", "-1"], "I_TN"),
    (["--mode", "DIST"], "CONST_DIST, SET_POS"), (["--step", "x"], "--step"),
    (["--step", "50"], "out of range"),
    (["no/such/file.toml"], "cannot read"), (["--plot", "out.bmp"], "suffix"),
])
def test_cli_bad_input_exits_1_with_a_message(args, needle):
    res = CliRunner().invoke(step_cmd, [*args, *CLI_FAST])
    assert res.exit_code == 1
    assert "error:" in res.output and needle in res.output


def test_the_command_registers_as_step_on_a_group():
    import click

    group = click.Group("distctrl")
    group.add_command(step_cmd)                        # as distctrl.cli registers it (LAZY_COMMANDS)
    res = CliRunner().invoke(group, ["step", "--help"])
    assert res.exit_code == 0 and "--kp" in res.output and "--plot" in res.output


def test_hints_never_offer_d_tv_at_kp_1_or_above():
    """new-user audit M6: the D part has no room at KP >= 1 (docs/control-law.md, 'no D for kp >= 1'),
    so a hint there names KP alone and says that D_TV does nothing, never 'lower D_TV' or 'add D'."""
    osc = {"overshoot_pct": 60.0, "overshoot_mm": 0.6, "oscillation": 90, "settling_time_s": None}
    res = [_fake(StepSetting(1.0), **osc), _fake(StepSetting(1.0, 0.0, 0.01), **osc),
           _fake(StepSetting(1.5, 0.0, 0.01), overshoot_pct=50.0, overshoot_mm=0.5, oscillation=3)]
    h = hints(res)
    per_setting = h[:3]
    for text in per_setting:
        assert "D_TV" not in text.split(": ", 1)[1].replace("D_TV has no effect", ""), text
        assert "add D" not in text, text
        assert "lower KP" in text, text
    assert "D_TV has no effect at KP >= 1" in per_setting[1]
    comparison = [t for t in h if t.startswith("KP=1 I_TN=0: D_TV=0.01")]
    assert comparison and "no effect at KP >= 1" in comparison[0] and "lower D_TV" not in comparison[0]


def test_hints_below_kp_1_still_offer_the_d_part():
    osc = {"overshoot_pct": 60.0, "overshoot_mm": 0.6, "oscillation": 90, "settling_time_s": None}
    h = hints([_fake(StepSetting(0.9), **osc), _fake(StepSetting(0.9, 0.0, 0.01), **osc)])
    assert "lower KP or add D" in h[0] and "lower KP or D_TV" in h[1]


def test_plot_time_axis_follows_the_settling_responses_and_marks_the_others(tmp_path):
    """new-user audit R1: the README's example (KP 0.2, 0.5, 1.0) drew KP 1's limit cycle over the whole
    run and the responses that settle in 6-16 ms were invisible. The main panel's time axis now ends a
    few settling times after the slowest settling response; a response that does not settle says so in
    the legend, and a second panel shows the whole run."""
    res = run_steps(parse_settings("0.2,0.5,1.0"), progress=False, t_step=0.05, duration=1.0)
    settled = [r for r in res if r.metrics.settled]
    assert len(settled) == 2 and not res[2].metrics.settled
    fig = plot_steps(res)
    main, whole = fig.axes
    slowest = max(r.metrics.settling_time_s for r in settled)
    lo, hi = main.get_xlim()
    assert slowest < hi <= 0.1 and hi < 0.2 * (1.0 - 0.05), (slowest, hi)
    labels = [ln.get_label() for ln in main.get_lines() if ln.get_label().startswith("KP=")]
    assert "KP=1 I_TN=0 D_TV=0 (does not settle)" in labels
    assert "KP=0.2 I_TN=0 D_TV=0" in labels and "KP=0.5 I_TN=0 D_TV=0" in labels
    assert whole.get_xlim()[1] >= 0.9                      # the whole run after the step
    plot_steps(res, tmp_path / "s.png")


def test_a_step_result_has_the_result_face_to_dict_plot_to_csv(tmp_path):
    """Like python-control's results: one object answers to_dict, plot and to_csv."""
    from distctrl.workbench.step import results_json

    (r,) = run_steps(parse_settings("0.3"), progress=False, **FAST)
    d = r.to_dict()
    assert d == results_json([r])["results"][0]
    assert d["setting"]["kp"] == 0.3 and d["metrics"]["settled"] == r.metrics.settled
    fig = r.plot(tmp_path / "one.png")
    assert (tmp_path / "one.png").stat().st_size > 0 and fig.axes
    r.to_csv(tmp_path / "one.csv")
    back = Trace.from_csv(tmp_path / "one.csv")
    assert back.rows == r.trace.rows and list(back.columns) == list(r.trace.columns)
