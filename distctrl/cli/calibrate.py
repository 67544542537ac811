"""``distctrl calibrate``: the capacitive calibration run, the linearisation table, the
repeatability check (docs/process.md, *Calibration run*; docs/cli.md).

:mod:`distctrl.cli` registers the command (LAZY_COMMANDS).
"""
from __future__ import annotations

import sys

import click

from ..errors import DistCtrlError, ExitCode
from ..sim.scenario import load_scenario
from ..workbench.calibrate import (REPEATABILITY_TOLERANCE_UM, CalibrationError, calibration_table,
                                   default_out, model_check_um, run_calibration, table_toml)
from .common import COORDINATE, Finite, check_writable, emit_json, fail, output_error_text


@click.command("calibrate")
@click.argument("scenario", type=click.Path(dir_okay=False))
@click.option("--out", "out_path", type=click.Path(dir_okay=False), default=None,
              help="Write the table here (TOML, linearisation = [[reading_mm, distance_mm], ...]); default "
                   "<scenario>_linearisation.toml beside the scenario.")
@click.option("--runs", type=click.IntRange(1, 10), default=None,
              help="Calibration runs (down and up each) compared for repeatability [default: the scenario's, else 2].")
@click.option("--speed", type=Finite(0.0, 20.0, min_open=True), default=None,
              help="Speed of the descent and ascent [mm/s] (default: the scenario's, else 1).")
@click.option("--bottom", type=Finite(0.0, 1e3, min_open=True), default=None,
              help="Measured distance the head goes down to [mm] (default: the scenario's, else 0.3).")
@click.option("--surface", type=COORDINATE, default=None,
              help="Axis position where the nozzle touches the sheet [mm]: the zero of the true distance "
                   "(default: the scenario's sheet under the head).")
@click.option("--tolerance", type=Finite(0.0, 1e3, min_open=True), default=None,
              help="Largest difference between the runs' tables [µm]  [default: 10].")
@click.option("--bin", "bin_width", type=Finite(0.01, 1.0), default=0.1, show_default=True,
              help="Width of the distance bins, one table point each [mm].")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of a summary.")
def calibrate_cmd(scenario, out_path, runs, speed, bottom, surface, tolerance, bin_width, as_json) -> None:
    """Calibrate the distance sensor of SCENARIO.toml (a capacitive sensor over a flat sheet).

    \b
    The scenario's NC program puts the head above the sheet, selects the sensor
    (Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]) and waits (#TIME) or ends; the PLC's
    calibrate function ([[process]] function = "calibrate", added with its defaults if the scenario
    has none) then drives the head down to BOTTOM and back up, RUNS times, and records the reading
    against the axis position. The table (reading -> distance) is written for [sensor]
    linearisation = "FILE"; the runs' tables must agree within the tolerance.

    \b
    Exit codes: 0 the table is written; 1 invalid input (nothing ran); 2 the run failed (an error,
    the head touched the sheet, the records give no monotonic table); 3 it did not end in time;
    4 the runs differ by more than the tolerance (no table written).
    """

    tol = REPEATABILITY_TOLERANCE_UM if tolerance is None else tolerance
    try:
        sc = load_scenario(scenario)
        out = out_path or str(default_out(sc))
        check_writable(out, "table")
        run = run_calibration(sc, runs=runs, speed=speed, bottom=bottom, surface=surface)
    except DistCtrlError as exc:
        fail(str(exc))
    f = run.function
    info = {"scenario": sc.name, "file": str(scenario), "axis": f.axis, "variable": f.variable,
            "runs": f.runs, "speed_mm_s": f.speed, "bottom_mm": f.bottom, "surface_mm": run.surface,
            "surface_source": run.surface_source, "time_s": round(run.time, 6),
            "samples": len(f.completed) if f.completed is not None else 0,
            "bin_mm": bin_width, "tolerance_um": tol}
    res = None
    error, code = run.error, run.exit_code
    if error is None:
        try:
            res = calibration_table(f.completed, run.surface, bin_width)
        except CalibrationError as exc:
            error, code = str(exc), int(ExitCode.ABORTED)
    repeatable = None
    if res is not None:
        repeatable = res.repeatability_um is None or res.repeatability_um <= tol
        if not repeatable:
            error = (f"the runs differ by {res.repeatability_um:.1f} µm (tolerance {tol:g} µm): the sensor is not "
                     "repeatable (noise, drift, a loose sheet?); no table written")
            code = int(ExitCode.CHECK_FAILED)
    written = None
    check = None
    if res is not None:
        try:
            check = model_check_um(sc, res, *getattr(run.machine, "true_xy", (0.0, 0.0)))
        except DistCtrlError:
            check = None
    if res is not None and repeatable:
        header = [f"distctrl calibrate {sc.name}: the PLC's linearisation of the sensor reading (V.E.{f.variable[4:]})",
                  "[reading_mm, distance_mm]; use it with [sensor] linearisation = \"<this file>\"",
                  f"{f.runs} run(s) at {f.speed:g} mm/s down to {f.bottom:g} mm; surface {run.surface:.4f} mm "
                  f"({run.surface_source}); distance {res.distance_range[0]:.3f} .. {res.distance_range[1]:.3f} mm",
                  "repeatability: " + ("-" if res.repeatability_um is None else f"{res.repeatability_um:.2f} µm")
                  + f" (tolerance {tol:g} µm)"]
        try:
            with open(out, "w", encoding="utf-8") as fh:
                fh.write(table_toml(res, header))
        except OSError as exc:
            fail(output_error_text(exc, out, "table"))
        written = out
    table = res.to_dict() if res is not None else {"table": None, "points": 0, "distance_range_mm": None,
                                                     "repeatability_um": None, "noise_um": None, "notes": []}
    payload = dict(info)
    payload.update({
        "ok": error is None, "exit_code": code, "error": error,
        "table": table["table"], "points": table["points"], "distance_range_mm": table["distance_range_mm"],
        "repeatability_um": table["repeatability_um"], "repeatable": repeatable, "noise_um": table["noise_um"],
        "model_check_um": check, "notes": table["notes"], "out": written,
    })
    if as_json:
        emit_json(payload)
        sys.exit(code)
    _summary(payload)
    if error is not None:
        click.echo(f"error: {error}", err=True)
    sys.exit(code)


def _num(v, fmt: str, unit: str) -> str:
    return "-" if v is None else f"{v:{fmt}} {unit}"


def _summary(p: dict) -> None:
    click.echo(f"calibration of {p['variable']} on axis {p['axis']} ({p['scenario']})")
    click.echo(f"  runs: {p['runs']} at {p['speed_mm_s']:g} mm/s down to {p['bottom_mm']:g} mm, "
               f"{p['samples']} samples in {p['time_s']:.3f} s")
    click.echo(f"  surface: {p['surface_mm']:.4f} mm ({p['surface_source']})")
    if p["table"] is not None:
        lo, hi = p["distance_range_mm"]
        click.echo(f"  table: {p['points']} points, distance {lo:.3f} .. {hi:.3f} mm")
        click.echo(f"  repeatability: {_num(p['repeatability_um'], '.2f', 'µm')} (tolerance {p['tolerance_um']:g} µm)")
        click.echo(f"  noise: {_num(p['noise_um'], '.2f', 'µm')}")
        click.echo(f"  model check (simulation): {_num(p['model_check_um'], '.2f', 'µm')} largest error of the "
                   "table on the noise-free sensor model")
    for n in p["notes"]:
        click.echo(f"  note: {n}")
    if p["out"]:
        click.echo(f"  written: {p['out']}  (use it: [sensor] linearisation = \"{p['out']}\")")
