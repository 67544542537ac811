"""``distctrl identify``: the plant fitted to recordings (docs/identify.md).

:mod:`distctrl.cli` registers the command (LAZY_COMMANDS).
"""
from __future__ import annotations

import warnings

import click

from ..errors import DistCtrlError, ExitCode
from ..workbench.identify import (IdentifyError, format_summary, identify, load_signals,
                                  write_report, write_scenario)
from .common import COORDINATE, Finite, emit_json, fail, output_error_text


@click.command("identify")
@click.argument("recordings", nargs=-1, required=True, metavar="REC.csv [REC2.csv ...]")
@click.option("--time", "time_col", default=None,
              help="Time column (default: 't' of a trace, the channels' own time column of a TwinCAT Scope "
                   "export, the first column of a plain CSV).")
@click.option("--command", "command_col", required=True,
              help="Set position sent to the drive (TwinCAT: the NC axis' set position, e.g. fPosSet).")
@click.option("--actual", "actual_col", required=True,
              help="Actual position of the motor encoder (TwinCAT: the axis' actual position, e.g. fPosAct).")
@click.option("--sensor", "sensor_col", required=True,
              help="Height sensor: the V.E. distance variable, or encoder 2 (Scope: the SymbolName or Name).")
@click.option("--time-unit", default=None, help="Unit of the time column: s, ms or us (default: s; ms for a "
                                                "Scope export; a trace's own unit).")
@click.option("--value-unit", default="mm", show_default=True, help="Unit of command and actual: mm, um or inc.")
@click.option("--sensor-unit", default=None, help="Unit of the sensor: mm, um or inc (default: --value-unit).")
@click.option("--mm-per-increment", type=Finite(0.0, 1e3, min_open=True), default=None, help="Scale for the unit inc.")
@click.option("--sensor-sign", type=click.Choice(["auto", "+1", "-1"]), default="auto", show_default=True,
              help="+1: the sensor reads nozzle - surface (a distance); -1: surface - nozzle (encoder 2, s = -d); "
                   "auto: from the correlation with the motor.")
@click.option("--actual-sampled", type=click.Choice(["auto", "start", "end"]), default="auto", show_default=True,
              help="When a row's actual position is sampled: start of the cycle (TwinCAT's input mapping) or end "
                   "(distctrl traces); auto: end for a distctrl trace, start otherwise.")
@click.option("--surface", type=COORDINATE, default=None,
              help="Surface height in the actual position's coordinates [mm] (the actual position where the nozzle "
                   "touches the sheet): fixes the zero of the true distance for the characteristic.")
@click.option("--calibrated-at", type=Finite(0.0, 1e3, min_open=True), default=None,
              help="Instead of --surface: the distance [mm] at which the sensor reads true (where it was taught in).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object (drive, sensor, fit, warnings).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Write the fitted plant as scenario TOML (fitted.toml) and a report (report.html, identify.png).")
@click.option("--template", type=click.Path(dir_okay=False), default=None,
              help="Scenario whose program, surface and other keys the written scenario keeps (default: a "
                   "CONST_DIST run over a sheet with a 0.5 mm step).")
@click.option("--validate", "validate_paths", multiple=True, type=click.Path(dir_okay=False), metavar="REC.csv",
              help="A recording NOT used for the fit (repeatable): the fitted plant's prediction error on it is "
                   "reported (\"validation\" in --json).")
@click.option("--axis", default="Z", show_default=True, help="The identified axis in the written scenario.")
def identify_cmd(recordings, time_col, command_col, actual_col, sensor_col, time_unit, value_unit, sensor_unit,
                 mm_per_increment, sensor_sign, actual_sampled, surface, calibrated_at, as_json, out_dir, template,
                 validate_paths, axis) -> None:
    """Identify the drive and the sensor from recordings of the machine (TwinCAT Scope CSV export,
    a plain CSV with a header row, or a distctrl trace) at the interpolation cycle.

    \b
    What to record (TwinCAT Scope, sample time = the NC task's cycle, distance control OFF,
    above a flat sheet), each 5-20 s (docs/identify.md):
      1. steps of the set position of 0.2-0.5 mm, 0.5 s apart (NC G0 moves or raw steps),
         and one of several mm at a safe height; v_max / a_max show only where the drive
         saturates, else they are reported as lower bounds (what the command reached);
      2. a chirp of the set position 1-150 Hz, 0.02-0.05 mm amplitude, 20 s;
      3. a slow ramp (0.2-0.5 mm/s) over the sensor's range, then 1 s at standstill.
    Signals: the set position sent to the drive, the actual position of the motor encoder,
    the sensor (the V.E. distance variable, or encoder 2).

    \b
    Prints kv [1/s], dead time [s], v_max [mm/s], a_max [mm/s^2], resonance [Hz], damping,
    sensor delay [s], noise std [mm] and characteristic [[true mm, reported mm], ...]; a
    figure the recordings cannot determine is '-' (null) with a warning saying what to record.
    --out DIR writes DIR/fitted.toml for distctrl run/tune/step/margins and DIR/report.html.
    Exit code 1 with a message for missing files or columns, too short recordings, too poor
    excitation, a non-uniform time base or a trace recorded with distance control on; exit code 4
    (nothing written) when the sensor is not explained by the motor (the open-loop check).
    """

    try:
        if surface is not None and calibrated_at is not None:
            raise IdentifyError("--surface and --calibrated-at: give one of them")
        if template is not None and out_dir is None:
            raise IdentifyError("--template needs --out DIR (where the scenario is written)")
        with warnings.catch_warnings(record=True):   # the warnings are in res.warnings, printed below
            warnings.simplefilter("always")
            sigs = [load_signals(p, time=time_col, command=command_col, actual=actual_col, sensor=sensor_col,
                                 time_unit=time_unit, value_unit=value_unit, sensor_unit=sensor_unit,
                                 mm_per_increment=mm_per_increment, actual_at=actual_sampled)
                    for p in recordings + validate_paths]
            sign = None if sensor_sign == "auto" else float(sensor_sign)
            n = len(recordings)
            res = identify(sigs[:n], sensor_sign=sign, surface=surface, calibrated_at=calibrated_at,
                           validate=sigs[n:])
        scenario = report = None
        open_loop = res.extra.get("open_loop", {}).get("passed", True)
        if out_dir is not None and not open_loop:
            res.warnings.append(f"--out {out_dir}: nothing written: the recordings failed the open-loop check")
        elif out_dir is not None:
            path, notes = write_scenario(res, out_dir, template=template, axis=axis)
            res.warnings.extend(notes)
            scenario = str(path)
            report = str(write_report(res, out_dir, scenario=scenario))
    except DistCtrlError as exc:
        fail(str(exc))
    except OSError as exc:
        fail(output_error_text(exc, getattr(exc, "filename", None) or out_dir, "output"))
    if as_json:
        emit_json(res.to_dict(scenario=scenario, report=report))
    else:
        for w in res.warnings:
            click.echo(f"warning: {w}", err=True)
        click.echo(format_summary(res), nl=False)
        if scenario:
            click.echo(f"scenario: {scenario}")
            click.echo(f"report: {report}")
    if not open_loop:
        raise SystemExit(int(ExitCode.CHECK_FAILED))
