"""``distctrl step``: the documents' step-response tuning method on the virtual machine (click command).

distctrl/cli/__init__.py registers it (LAZY_COMMANDS). Bad input (a KP / I_TN /
D_TV out of its range, an unreadable scenario, a step that does not fit the sensor, a plot suffix)
is a message on stderr and exit code 1. docs/workbench-step.md describes the output.
"""
from __future__ import annotations

import math
from pathlib import Path

import click

from ..errors import DistCtrlError
from ..workbench.step import (MAX_DURATION, StepError, check_plot_path, format_table, hints, parse_settings,
                              plot_steps, results_json, run_steps)
from .common import Finite, check_plot_output, emit_json, fail

__all__ = ["step"]


def _step_value(text: str) -> "float | str":
    """``--step``: a number (mm) or ``auto``."""

    t = str(text).strip()
    if t.lower() == "auto":
        return "auto"
    try:
        v = float(t)
    except ValueError:
        raise StepError(f"--step {text!r} is not a number; allowed: a step != 0 in mm, or auto") from None
    if not math.isfinite(v):
        raise StepError(f"--step {text!r} is not finite; allowed: a step != 0 in mm, or auto")
    return v


@click.command("step")
@click.argument("scenario", required=False, type=click.Path(dir_okay=False))
@click.option("--kp", default="0.2,0.5,1.0", show_default=True, metavar="LIST",
              help="KP values, comma-separated (0 < KP <= 2). The method starts at 0.2 and raises it.")
@click.option("--i-tn", "i_tn", default="0", show_default=True, metavar="LIST",
              help="I_TN values in s, comma-separated (0 = no I part; 0 <= I_TN <= 50). The method starts "
                   "at 5 and lowers it.")
@click.option("--d-tv", "d_tv", default="0", show_default=True, metavar="LIST",
              help="D_TV values in s, comma-separated (0 = no D part; 0 <= D_TV <= 2). The method starts at 0.01.")
@click.option("--step", "step_mm", default="auto", show_default=True, metavar="MM|auto",
              help="Height of the distance step in mm (> 0: the surface rises). auto: the largest step whose "
                   "first cycle every setting answers inside the limiter (P-AXIS-00415 v_max, P-AXIS-00416 "
                   "a_max), at least 20x the sensor noise, at most 1 mm.")
@click.option("--mode", default="CONST_DIST", show_default=True, metavar="CONST_DIST|SET_POS",
              help="Distance-control mode: CONST_DIST (SET_DIST) or SET_POS.")
@click.option("--set-dist", "set_dist", default=1.0, show_default=True, type=Finite(0.0, 1e3, min_open=True),
              help="SET_DIST (mm) the axis holds.")
@click.option("--ramp", "ramp", default=0.0, show_default=True, type=Finite(-1e3, 1e3),
              help="After the step the surface keeps rising at this rate (mm/s): a permanent control "
                   "deviation for P, which the I part removes.")
@click.option("--t-step", "t_step", default=0.5, show_default=True, type=Finite(0.0, MAX_DURATION, min_open=True, max_open=True), help="Time of the step (s).")
@click.option("--duration", default=2.0, show_default=True, type=Finite(0.0, MAX_DURATION, min_open=True), help="Length of each run (s).")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Save the overlaid responses (PNG, SVG or PDF by suffix).")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object (step, metrics per setting, hints, suggested KP) instead of the table.")
def step(scenario: str | None, kp: str, i_tn: str, d_tv: str, step_mm: str, mode: str, set_dist: float,
         ramp: float, t_step: float, duration: float, plot_path: str | None, as_json: bool) -> None:
    """Step response of distance control for every KP x I_TN x D_TV setting (FCT-M3 ch. 3).

    The axis holds SET_DIST; at --t-step the sensor sees the surface rise by --step. Each setting is
    programmed as Z[DIST_CTRL ON CONST_DIST SET_DIST=.. KP=.. I_TN=.. D_TV=..]. Without SCENARIO the
    default virtual machine is used, with it the scenario's Z axis (parameter list, drive, sensor).
    Prints rise time, overshoot, settling time, steady-state error, oscillation and the share of the
    cycles the limiter (P-AXIS-00415/00416) shaped per setting, and hints along the documents'
    method; a response the limiter decided is said so and never suggested.
    """

    if scenario and Path(scenario).suffix.lower() in (".csv", ".parquet"):
        fail(f"{scenario}: step takes a scenario (.toml), not a trace; it simulates the step on the "
             "scenario's machine (a recording goes to identify, filters or plot)")
    for name, value in (("--set-dist", set_dist), ("--ramp", ramp), ("--t-step", t_step), ("--duration", duration)):
        if not math.isfinite(value):
            fail(f"{name} {value!r} is not finite")
    try:
        settings = parse_settings(kp, i_tn, d_tv)
        step_v = _step_value(step_mm)
    except DistCtrlError as exc:
        fail(str(exc))
    check_plot_output(plot_path, check_plot_path)
    try:
        results = run_steps(settings, scenario, step_mm=step_v, mode=mode, t_step=t_step,
                            duration=duration, set_dist=set_dist, ramp_mm_s=ramp, progress=False if as_json else None)
    except DistCtrlError as exc:
        fail(str(exc))
    # the plot first: a reader that stops early (`| head`) must not cost the file
    if plot_path:
        try:
            plot_steps(results, plot_path)
        except DistCtrlError as exc:
            fail(str(exc))
    info = results[0].trace.meta["step"]
    if as_json:
        obj = {"command": "step", "scenario": scenario, **results_json(results), "duration_s": duration,
               "set_dist_mm": set_dist, "plot": plot_path}
        emit_json(obj)
        return
    machine = scenario if scenario else "default virtual machine (docs/workbench-step.md)"
    ramp_text = f", then {ramp:g} mm/s ramp" if ramp else ""
    step_v = info["step_mm"]
    auto = f" ({info['auto']})" if info.get("auto") else ""
    title = (f"Step response on {machine}: {mode.upper()}, step {step_v:g} mm{auto} at t = {t_step:g} s"
             f"{ramp_text}, {duration:g} s per run")
    click.echo(format_table(results, title=title), nl=False)
    click.echo("hints (FCT-M3 ch. 3):")
    for line in hints(results):
        click.echo(f"  - {line}")
    if plot_path:
        click.echo(f"plot: {plot_path}")
