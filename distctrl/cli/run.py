"""``distctrl run SCENARIO``: the NC program on the virtual machine, with its summary, trace, plot and report."""
from __future__ import annotations

import shutil
import sys
from pathlib import Path

import click

from ..errors import DistCtrlError
from ..errors.config import ConfigError
from ..sim.plates import CutWatch, select_functions
from ..sim.runner import run as run_scenario
from ..sim.scenario import load_scenario
from ..errors.files import PLOT_SUFFIXES, TABLE_SUFFIXES
from .common import check_output, emit_json, fail, human_bytes


@click.command("run")
@click.argument("scenario", type=click.Path(dir_okay=False))
@click.option("--trace", "trace_path", type=click.Path(dir_okay=False),
              help="Write the per-cycle trace to this CSV file (units in FILE.meta.json), or to a .parquet file.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object with the result instead of a summary.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Save a plot of the run (.png, .svg or .pdf).")
@click.option("--report", "report_dir", type=click.Path(file_okay=False),
              help="Write a self-contained HTML report (plots embedded) into this folder.")
@click.option("--record", "record", default="",
              help="Also record these values behind the CNC objects per axis, comma-separated "
                   "(e.g. a_max_int,v_max_int,kp,m_actual_offset); columns <axis>.dc.<name>.")
@click.option("--stop-on-collision", is_flag=True,
              help="End the run at the first collision (true distance at or below -sensor.collision_depth) "
                   "with error 900030 and exit code 2, instead of recording it as a warning.")
@click.option("--decimate", type=click.IntRange(min=1), default=1, show_default=True,
              help="Record every N-th cycle only (metrics and events still see every cycle).")
@click.option("--max-rows", type=click.IntRange(min=1), default=None,
              help="Keep only the last N rows, like a scope's ring buffer (the trace file is written at the end).")
@click.option("--no-process", is_flag=True,
              help="Run without the scenario's [[process]] functions (touch-off, corner lock, void lock, lift, ...), "
                   "as the demo's 'without' column; a program that asks for the touch-off (variable IHS) runs with "
                   "IHS = 0.")
@click.option("--process", "process_only", default=None, metavar="NAMES",
              help="Run only these of the scenario's [[process]] functions, comma-separated "
                   "(e.g. corner_lock,void_lock); the others are off.")
def run(scenario: str, trace_path: str | None, as_json: bool, plot_path: str | None, report_dir: str | None,
        record: str, stop_on_collision: bool, decimate: int, max_rows: int | None, no_process: bool,
        process_only: str | None) -> None:
    """Run SCENARIO.toml: the NC program on the virtual machine with distance control.

    Exit codes (docs/run.md): 0 the program ran to its end, 1 invalid input (the message names the
    file, line or key and what is allowed), 2 a control error aborted it, 3 stopped at the time limit
    (duration) before the program ended, 130 Ctrl-C.
    """

    records = tuple(record.split(",")) if record else ()
    check_output(trace_path, "trace", TABLE_SUFFIXES)
    check_output(plot_path, "plot", PLOT_SUFFIXES)
    check_output(report_dir, "report folder", directory=True)
    try:
        sc = _select_processes(load_scenario(scenario), scenario, no_process, process_only)
        watch = _cut_watch(sc)
        # a plot or a report needs the trace in memory: thinned to PLOT_ROWS rows, never the whole run
        wants_trace = plot_path is not None or report_dir is not None
        result = run_scenario(sc, trace=trace_path, keep_trace=wants_trace, progress=not as_json, record=records,
                              stop_on_collision=stop_on_collision, decimate=decimate, max_rows=max_rows,
                              keep_at_most=PLOT_ROWS if wants_trace and max_rows is None else None,
                              on_start=(lambda size: _say_trace_size(size, trace_path)) if trace_path else None,
                              plc_program=watch)
    except DistCtrlError as exc:
        fail(str(exc))
    cut = watch.figures(sc.cycle_time) if watch is not None and watch.applies else None
    if cut is not None and not cut["set_distance_mm"] > 0.0:
        cut["time_below_half_s"] = None          # no set distance held (SET_POS): nothing to be half of
    processes = [p.function for p in sc.processes]
    selected = no_process or process_only is not None
    if plot_path:
        result.plot(plot_path)
    if report_dir:
        from ..workbench.report import write_report  # jinja2: loaded only for --report

        page = write_report(result, sc, report_dir)
        if not as_json:
            click.echo(f"  report: {page}")
    if as_json:
        emit_json({**result.to_dict(), "processes": processes, "cut": cut})
    else:
        _print_summary(result, trace_path, plot_path, cut, processes, selected)
    sys.exit(result.exit_code)

def _select_processes(sc, path: str, no_process: bool, process_only: str | None):
    """The scenario with the [[process]] functions ``run`` was asked for (--no-process, --process)."""

    if no_process and process_only is not None:
        raise ConfigError("--process", process_only, "one of --no-process and --process NAMES",
                          "--no-process switches every function off")
    if no_process:
        return select_functions(sc, functions=False)
    if process_only is None:
        return sc
    names = tuple(n.strip() for n in process_only.split(",") if n.strip())
    have = [p.function for p in sc.processes]
    unknown = [n for n in names if n not in have]
    if unknown or not names:
        allowed = ", ".join(have) if have else "none (the scenario has no [[process]] tables)"
        raise ConfigError("--process", ", ".join(unknown) if unknown else process_only,
                          f"the [[process]] functions of {path}: {allowed}", "not a [[process]] function of the scenario:")
    return select_functions(sc, only=names)

def _cut_watch(sc):
    """The figures of the demo's plate table for a run whose distance sensor is on an axis (None
    for a scenario without one)."""

    if sc.sensor is None or not sc.sensor.axis:
        return None
    return CutWatch(sc.sensor.axis)

#: rows of the trace kept for --plot / --report (thinned evenly beyond: bounded memory for any run)
PLOT_ROWS = 200_000

#: a trace estimate above this is announced before the run
TRACE_NOTICE_BYTES = 100e6

def _say_trace_size(est: dict, trace_path: str) -> None:
    """The size of the trace before the run: always when large, a warning when the disk is smaller."""
    parquet = str(trace_path).lower().endswith(".parquet")
    size = est["memory_bytes"] if parquet else est["csv_bytes"]
    text = (f"trace {trace_path}: up to {est['rows']:,} rows x {est['columns']} columns, about "
            f"{human_bytes(size)} ({'in memory until the end' if parquet else 'CSV'}) if the run goes "
            f"to its time limit of {est['time_limit_s']:g} s")
    try:
        free = shutil.disk_usage(Path(trace_path).resolve().parent).free
    except OSError:
        free = None
    if free is not None and size > free:
        click.echo(f"warning: {text}: more than the {human_bytes(free)} free there; --decimate N or "
                   "--max-rows N make it smaller", err=True)
    elif size > TRACE_NOTICE_BYTES:
        click.echo(f"note: {text}; --decimate N or --max-rows N make it smaller", err=True)

#: collision warnings printed in the summary (a limit cycle hits the sheet every period)
MAX_COLLISIONS_SHOWN = 5

COLLISION_ID = 900030

def _print_summary(result, trace_path, plot_path, cut=None, processes=(), selected=False) -> None:
    m = result.metrics
    status = result.outcome_text
    click.echo(f"{result.name}: {status} after {result.cycles} cycles ({result.cycles * result.cycle_time:.3f} s), "
               f"distance control {result.final_state}")
    if m.get("distance_error_rms") is not None:
        settle = "not reached" if m["settle_time"] is None else f"{m['settle_time']:.3f} s"
        click.echo(f"  distance error while tracking: RMS {m['distance_error_rms']:.4f} mm, "
                   f"max {m['distance_error_max']:.4f} mm, settle time {settle}")
        if m.get("oscillation_frequency_hz") is not None:
            click.echo(f"  OSCILLATING in the last second of tracking: {m['oscillation_frequency_hz']:.1f} Hz, "
                       f"amplitude {m['oscillation_amplitude_mm']:.3f} mm")
    if m.get("min_distance_mm") is not None:
        click.echo(f"  true tool distance: min {m['min_distance_mm']:.3f} mm, {m['time_below_zero_s']:.3f} s "
                   f"at or below 0 mm, {m['collisions']} collision(s)")
    if cut is not None and cut["path_time_s"] is not None:
        cut_min = "-" if cut["min_cut_distance_mm"] is None else f"{cut['min_cut_distance_mm']:.3f} mm"
        click.echo(f"  while cutting (G1): min true distance {cut_min}; path time {cut['path_time_s']:.3f} s")
        if cut["time_below_half_s"] is not None:
            # counted over every cycle distance control ran against the set distance then in force (a
            # touch-off's back-off to its pierce height too), not over the cuts alone: docs/process.md
            click.echo(f"  while distance control ran: {cut['time_below_half_s']:.3f} s below ½ the set distance "
                       f"in force (½ of the cut's {cut['set_distance_mm']:g} mm: {0.5 * cut['set_distance_mm']:g} mm)")
    if processes or selected:
        click.echo("  process functions: " + (", ".join(processes) if processes else
                                              "none (--no-process)" if selected else "none"))
    for e in result.errors:
        click.echo(f"  error {e['id']} at t = {e['t']:.3f} s, line {e['line']}: {e['message']}")
    shown_collisions = 0
    for w in result.warnings:
        if w["id"] == COLLISION_ID:
            shown_collisions += 1
            if shown_collisions > MAX_COLLISIONS_SHOWN:
                continue
        click.echo(f"  warning {w['id']} at t = {w['t']:.3f} s, line {w['line']}: {w['message']}")
    if shown_collisions > MAX_COLLISIONS_SHOWN:
        click.echo(f"  ... and {shown_collisions - MAX_COLLISIONS_SHOWN} more collision warnings (all of them in "
                   "--json, the trace's .meta.json and the report)")
    for n in result.notes:
        click.echo(f"  note: {n}")
    if trace_path:
        click.echo(f"  trace: {trace_path}")
    if plot_path:
        click.echo(f"  plot: {plot_path}")
