"""``distctrl step``: the documents' step-response tuning method on the virtual machine (click command).

distctrl/cli/__init__.py registers it (LAZY_COMMANDS). Bad input (a KP / I_TN /
D_TV out of its range, an unreadable scenario, a step that does not fit the sensor, a plot suffix)
is a message on stderr and exit code 1. docs/workbench-step.md describes the output.
"""
from __future__ import annotations

import math
import sys

import click

from ..errors import DistCtrlError

__all__ = ["step"]


def _number(option: str, text: str, allowed: str) -> float:
    from .step import StepError

    try:
        value = float(text)
    except ValueError:
        raise StepError(f"{option} {text!r} is not a number; allowed: {allowed}") from None
    if not math.isfinite(value):
        raise StepError(f"{option} {text!r} is not finite; allowed: {allowed}")
    return value


@click.command("step")
@click.argument("scenario", required=False, type=click.Path(dir_okay=False))
@click.option("--kp", default="0.2,0.5,1.0", show_default=True,
              help="KP values, comma-separated (0 < KP <= 2). The method starts at 0.2 and raises it.")
@click.option("--i-tn", "i_tn", default="0", show_default=True,
              help="I_TN values in s (0 = no I part; 0 <= I_TN <= 50). The method starts at 5 and lowers it.")
@click.option("--d-tv", "d_tv", default="0", show_default=True,
              help="D_TV values in s (0 = no D part; 0 <= D_TV <= 2). The method starts at 0.01.")
@click.option("--step", "step_mm", default="1.0", show_default=True,
              help="Height of the distance step in mm (> 0: the surface rises).")
@click.option("--mode", default="CONST_DIST", show_default=True,
              help="Distance-control mode: CONST_DIST (SET_DIST) or SET_POS.")
@click.option("--set-dist", "set_dist", default="1.0", show_default=True,
              help="SET_DIST (mm) the axis holds.")
@click.option("--ramp", "ramp", default="0", show_default=True,
              help="After the step the surface keeps rising at this rate (mm/s): a permanent control "
                   "deviation for P, which the I part removes.")
@click.option("--t-step", "t_step", default="0.5", show_default=True, help="Time of the step (s).")
@click.option("--duration", default="2.0", show_default=True, help="Length of each run (s).")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Save the overlaid responses (PNG or SVG by suffix).")
def step(scenario: str | None, kp: str, i_tn: str, d_tv: str, step_mm: str, mode: str, set_dist: str,
         ramp: str, t_step: str, duration: str, plot_path: str | None) -> None:
    """Step response of distance control for every KP x I_TN x D_TV setting (FCT-M3 ch. 3).

    The axis holds SET_DIST; at --t-step the sensor sees the surface rise by --step. Each setting is
    programmed as Z[DIST_CTRL ON CONST_DIST SET_DIST=.. KP=.. I_TN=.. D_TV=..]. Without SCENARIO the
    default virtual machine is used, with it the scenario's Z axis (parameter list, drive, sensor).
    Prints rise time, overshoot, settling time, steady-state error and oscillation per setting, and
    hints along the documents' method.
    """
    from .step import check_plot_path, format_table, hints, parse_settings, plot_steps, run_steps

    try:
        settings = parse_settings(kp, i_tn, d_tv)
        step_v = _number("--step", step_mm, "a step height != 0 in mm")
        set_dist_v = _number("--set-dist", set_dist, "a distance > 0 in mm")
        ramp_v = _number("--ramp", ramp, "a rate in mm/s (0: no ramp)")
        t_step_v = _number("--t-step", t_step, "0 < t_step < duration (s)")
        duration_v = _number("--duration", duration, "0 < duration <= 60 s")
        if plot_path:
            check_plot_path(plot_path)
        results = run_steps(settings, scenario, step_mm=step_v, mode=mode, t_step=t_step_v,
                            duration=duration_v, set_dist=set_dist_v, ramp_mm_s=ramp_v)
    except DistCtrlError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(1)
    machine = scenario if scenario else "default virtual machine (docs/workbench-step.md)"
    ramp_text = f", then {ramp_v:g} mm/s ramp" if ramp_v else ""
    title = (f"Step response on {machine}: {mode.upper()}, step {step_v:g} mm at t = {t_step_v:g} s"
             f"{ramp_text}, {duration_v:g} s per run")
    click.echo(format_table(results, title=title), nl=False)
    click.echo("hints (FCT-M3 ch. 3):")
    for line in hints(results):
        click.echo(f"  - {line}")
    if plot_path:
        try:
            plot_steps(results, plot_path)
        except (DistCtrlError, OSError) as exc:
            click.echo(f"error: {exc}", err=True)
            sys.exit(1)
        click.echo(f"plot: {plot_path}")
