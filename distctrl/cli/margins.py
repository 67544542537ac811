"""``distctrl margins``: gain and phase margins of an axis's distance-control loop (click command).

distctrl/cli/__init__.py registers it (LAZY_COMMANDS). The model and its assumptions:
:mod:`distctrl.workbench.margins`, docs/margins.md. Bad input (a scenario that cannot be read, a 3D
scenario, an axis without distance control, a KP out of range, a plot suffix or a plot path that
cannot be written) is one ``error:`` line and exit code 1.
"""
from __future__ import annotations

import click

from ..errors import DistCtrlError
from ..workbench.margins import analyse, check_plot_path, loop_model
from .common import Finite, check_plot_output, emit_json, fail

__all__ = ["margins"]


@click.command("margins")
@click.argument("scenario", type=click.Path(dir_okay=False))
@click.option("--axis", "axis", default=None,
              help="The distance-controlled axis (default: the sensor's axis, or the only one).")
@click.option("--kp", type=Finite(0.0, 2.0, min_open=True), default=None,
              help="Analyse with this KP (0 < KP <= 2) instead of the one in force at the first select.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Save the Bode plot of the open loop, with the Nyquist plot beside it (PNG, SVG or PDF).")
@click.option("--nyquist/--no-nyquist", default=True, show_default=True,
              help="Draw the Nyquist plot beside the Bode plot.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of the text.")
def margins(scenario: str, axis: str | None, kp: float | None, plot_path: str | None, nyquist: bool,
            as_json: bool) -> None:
    """Gain and phase margins of the distance-control loop of SCENARIO's axis (python-control).

    The loop is linearised, limiter-free and for small signals: the list's filter x PID (KP, I_TN,
    D_TV as the core computes them) x the offset integration x the measurement's dead time (the
    machine's read, the sensor's delay_cycles, optimized_scheduling) x the drive (kv, feed-forward,
    bus delay), in the mode of the first select (CONST_DIST with one or both encoders, SET_POS), at
    the scenario's cycle time. Prints the gain margin (factor and dB), the phase margin (deg), the
    crossover frequencies (Hz), the KP at the stability limit and the oscillation frequency there.
    A loop it calls unstable grows until the slope limiter decides a limit cycle (docs/margins.md).
    """

    check_plot_output(plot_path, check_plot_path)
    try:
        result = analyse(loop_model(scenario, axis=axis, kp=kp))
    except DistCtrlError as exc:
        fail(str(exc))
    if plot_path:
        result.plot(plot_path, nyquist=nyquist)
    if as_json:
        out = result.to_dict()
        out["plot"] = plot_path
        emit_json(out)
        return
    click.echo(result.format_text(), nl=False)
    if plot_path:
        click.echo(f"  plot: {plot_path}")
