"""``distctrl filters``: compare sensor-filter configurations (docs/workbench-filters.md).

:mod:`distctrl.cli` registers the command (LAZY_COMMANDS).
"""
from __future__ import annotations

import math
import sys
import warnings

import click

from ..errors import DistCtrlError
from ..errors.files import PLOT_SUFFIXES
from ..workbench.filters import (DEFAULT_SPECS, WorkbenchError, compare, default_configs,
                                 find_edges, format_table, load_recording, obstacle_signal,
                                 parse_filter_specs, plot_overlay, results_dicts, signal_noise_rms,
                                 write_results_csv)
from .common import SEED, Finite, check_output, emit_json, fail, output_error_text


def _edges_option(values: tuple[str, ...]) -> list[float] | str | None:
    if not values:
        return None
    if len(values) == 1 and values[0].strip().lower() == "auto":
        return "auto"
    out = []
    for v in values:
        try:
            out.append(float(v))
        except ValueError:
            raise WorkbenchError(f"--edge {v!r}: not a number; allowed: a time in s (repeat for the second "
                                 "edge) or 'auto'") from None
    return out


@click.command("filters")
@click.argument("specs", nargs=-1, metavar="[SPEC]...")
@click.option("--recording", type=click.Path(dir_okay=False), default=None,
              help="Sensor recording (CSV with a header row, or a distctrl trace CSV) instead of the built-in "
                   "obstacle signal.")
@click.option("--time-column", default=None, help="Time column of the recording (default: first numeric column; "
                                                  "'t' for a trace).")
@click.option("--value-column", default=None, help="Value column (default: second numeric column; the *.dc.sensor "
                                                   "column of a trace).")
@click.option("--time-unit", default="s", show_default=True, help="Unit of the time column: s, ms or us.")
@click.option("--value-unit", default="mm", show_default=True, help="Unit of the values: mm, um or inc.")
@click.option("--mm-per-increment", type=Finite(0.0, 1e3, min_open=True), default=None, help="Scale for --value-unit inc.")
@click.option("--cycle-time", type=Finite(0.0, 10.0, min_open=True), default=None,
              help="Cycle time [s] (default 0.001; for a recording its median sample interval).")
@click.option("--edge", "edge_values", multiple=True, metavar="T|auto",
              help="Obstacle edge time [s] on the signal's time axis (repeat for the falling edge), or 'auto' to "
                   "detect them. The built-in signal knows its edges.")
@click.option("--noise", type=Finite(0.0, 100.0), default=0.05, show_default=True,
              help="Noise std [mm] of the built-in obstacle signal.")
@click.option("--seed", type=SEED, default=1, show_default=True, help="Noise seed of the built-in signal.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), default=None,
              help="Save the overlay plot (.png, .svg or .pdf).")
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False), default=None,
              help="Write the metrics table as CSV (one row per configuration).")
@click.option("--plain", is_flag=True, help="Plain fixed-width table instead of rich.")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object (signal, edges, metrics per configuration) instead of the table.")
def filters(specs: tuple[str, ...], recording: str | None, time_column: str | None, value_column: str | None,
            time_unit: str, value_unit: str, mm_per_increment: float | None, cycle_time: float | None,
            edge_values: tuple[str, ...], noise: float, seed: int, plot_path: str | None, csv_path: str | None,
            plain: bool, as_json: bool) -> None:
    """Compare sensor filters on a recorded or synthetic signal (FCT-M3 ch. 4, Figs. 9-17).

    SPEC is TYPE[:key=value[,value...][,key=...]], e.g. MOVING_AVERAGE:n_cycles=10,20,40 or
    KALMAN_MA:n_cycles=30,kalman_sigma=100,1000 (a list of values expands into one configuration
    each; several keys with lists give their product). Types: DEFAULT, MOVING_AVERAGE, EXPO_MEAN,
    LOWPASS, KALMAN_MA, KALMAN_EXPO. Keys: n_cycles, smoothing_factor (smooth_fact), kalman_sigma
    (sigma), order, fg_f0. Without SPEC: {default_set}.

    The default signal is the documents' test: a 2.8 mm obstacle crossed by the sensor, with
    Gaussian noise. Prints noise RMS, delay (50 %), dead time (10 %) and overshoot per
    configuration. Exit code 1 with a message for invalid input.
    """

    caught: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            if cycle_time is not None and not (cycle_time > 0.0 and math.isfinite(cycle_time)):
                raise WorkbenchError(f"--cycle-time {cycle_time!r}: allowed: a finite number > 0 s")
            check_output(plot_path, "plot", PLOT_SUFFIXES)
            check_output(csv_path, "table")                 # always CSV, whatever its name
            edges_opt = _edges_option(edge_values)
            if recording:
                rec = load_recording(recording, time_column=time_column, value_column=value_column,
                                     time_unit=time_unit, value_unit=value_unit,
                                     mm_per_increment=mm_per_increment, cycle_time=cycle_time)
                t, x = rec.t, rec.values
                T = rec.cycle_time
                if cycle_time is not None:
                    if abs(cycle_time - T) > 0.01 * T and rec.time_column is not None:
                        warnings.warn(f"--cycle-time {cycle_time:g} s differs from the recording's sample "
                                      f"interval {T:g} s; the filters use {cycle_time:g} s")
                    T = cycle_time
                edges = find_edges(t, x) if edges_opt == "auto" else edges_opt
                if edges_opt == "auto" and not edges:
                    warnings.warn("--edge auto: no clear edge found; only the noise is measured")
                source = f"{rec.path}: column {rec.value_column!r}, {x.size} samples"
                title = f"{rec.path} ({rec.value_column})"
            else:
                T = cycle_time if cycle_time is not None else 0.001
                t, x, builtin_edges = obstacle_signal(T, noise_std=noise, seed=seed)
                edges = builtin_edges.tolist() if edges_opt is None else (
                    find_edges(t, x) if edges_opt == "auto" else edges_opt)
                source = (f"built-in obstacle signal: 2.8 mm step at t = {builtin_edges[0]:g} s and back at "
                          f"{builtin_edges[1]:g} s, noise std {noise:g} mm (seed {seed})")
                title = f"2.8 mm obstacle, noise {noise:g} mm"
            configs = parse_filter_specs(list(specs) if specs else list(DEFAULT_SPECS), T)
            results = compare(x, t, configs, T, edges or None)
            raw = signal_noise_rms(x, t, edges or None, 50)
    except DistCtrlError as exc:
        _fail(str(exc), caught)
    for w in caught:
        click.echo(f"warning: {w.message}", err=True)
    # the files first: a reader that stops early (`| head`) must not cost them
    for path, what, write in ((plot_path, "plot", lambda: plot_overlay(t, x, results, path=plot_path,
                                                                       edges=edges or None, title=title)),
                              (csv_path, "table", lambda: write_results_csv(results, csv_path))):
        if not path:
            continue
        try:
            write()
        except DistCtrlError as exc:
            _fail(str(exc), [])
        except OSError as exc:
            _fail(output_error_text(exc, path, what), [])
    if as_json:
        emit_json({"command": "filters", "source": source, "recording": recording, "cycle_time_s": T,
                   "edges_s": list(edges) if edges else [], "raw_noise_rms_mm": raw,
                   "results": results_dicts(results), "plot": plot_path, "csv": csv_path,
                   "warnings": [str(w.message) for w in caught]})
        return
    click.echo(source)
    edge_txt = ", ".join(f"{e:g}" for e in edges) + " s" if edges else "none (delay and overshoot need --edge)"
    click.echo(f"cycle time {T * 1e3:g} ms; edges: {edge_txt}; raw noise RMS "
               f"{'-' if not math.isfinite(raw) else f'{raw:.4f}'} mm")
    click.echo(format_table(results, plain=plain), nl=False)
    if plot_path:
        click.echo(f"plot: {plot_path}")
    if csv_path:
        click.echo(f"table: {csv_path}")


def _default_set_text() -> str:
    """The help's "Without SPEC" sentence, made from DEFAULT_SPECS (what the command runs)."""

    return (f"the {len(default_configs(0.001))} configurations of " + "; ".join(DEFAULT_SPECS))


filters.help = (filters.help or "").replace("{default_set}", _default_set_text())


def _fail(message: str, caught) -> None:
    for w in caught or []:
        click.echo(f"warning: {w.message}", err=True)
    fail(message)
