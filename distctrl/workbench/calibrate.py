"""``distctrl calibrate``: the capacitive calibration run on the virtual machine, the linearisation
table from its records, and the repeatability check (docs/process.md, *Calibration run*).

The PLC side is :class:`distctrl.plc.process.Calibrate` (it drives the head down and up and records
axis position and reading); this module is the engineering side that reads the records:

* :func:`calibration_table`: the true distance is ``axis − surface`` (``surface``: the axis position
  where the nozzle touches the sheet); the samples of each run are binned along the true distance
  with ``distctrl identify``'s characteristic fit
  (:func:`distctrl.workbench.identify.fit.characteristic_points`; bins of ``bin_width``, 0.1 mm with
  ``distctrl calibrate``, 0.25 mm by default here as in ``identify``; a straight line
  through each bin's samples); the bins of all runs together give the table (reading → distance),
  the bins of each run alone give that run's table;
* the **repeatability** is the largest difference between the runs' tables, in µm of distance, over
  the readings every run covers (each run's table evaluated at the final table's readings);
* :func:`run_calibration`: the scenario's machine stepped until the calibrate function has ended.
"""
from __future__ import annotations

import csv
import dataclasses
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import DistCtrlError, ExitCode
from ..errors.config import ConfigError
from ..plc.linearisation import DistanceLinearisation
from ..plc.process import process_configs
from ..sim.machine import Machine
from ..sim.runner import load_program
from .identify.fit import CHAR_BIN, characteristic_points

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["CalibrationError", "CalibrationTable", "calibration_table", "run_calibration", "CalibrationRun",
           "table_toml", "REPEATABILITY_TOLERANCE_UM"]

#: µm: the runs' tables may differ by this much (``--tolerance``)
REPEATABILITY_TOLERANCE_UM = 10.0
#: a bin whose reading grows less than this share of the median slope is saturated (out of range)
_SATURATED_SLOPE = 0.2


class CalibrationError(DistCtrlError, ValueError):
    """The records cannot give a table (too few, saturated, not monotonic), or the run failed."""

@dataclass
class CalibrationTable:
    """``table``: (reading mm, distance mm) pairs, readings strictly increasing; ``run_tables`` the
    same per run; ``repeatability_um`` the largest difference between the runs' tables (None with
    one run); ``distance_range`` the true distances the table covers (mm)."""

    table: list[tuple[float, float]]
    run_tables: list[list[tuple[float, float]]]
    repeatability_um: float | None
    distance_range: tuple[float, float]
    surface: float
    samples: int
    noise_um: float | None = None
    dropped: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        """What ``distctrl calibrate --json`` prints of the table: the points ``[reading_mm,
        distance_mm]``, their number, the distances covered, the repeatability and noise (µm) and the
        notes (bins left out)."""
        return {"table": [list(p) for p in self.table], "points": len(self.table),
                "distance_range_mm": list(self.distance_range), "repeatability_um": self.repeatability_um,
                "noise_um": self.noise_um, "notes": self.dropped}

    def to_csv(self, path: str | os.PathLike) -> Path:
        """The table as CSV: ``reading_mm``, ``distance_mm``, one row per point."""
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        with open(p, "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(("reading_mm", "distance_mm"))
            w.writerows((repr(float(rd)), repr(float(dd))) for rd, dd in self.table)
        return p

    def plot(self, path: str | os.PathLike | None = None, title: str | None = None) -> "Figure":
        """The sensor's non-linearity: reading − distance (µm) over the distance (mm), one line per run
        and the table's points. A Figure on an Agg canvas, saved to ``path`` too when given."""
        # matplotlib is imported here only: it stays off the import path of the run and the CLI
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        fig = Figure(figsize=(9, 5), layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.subplots()
        for n, t in enumerate(self.run_tables, 1):
            a = np.asarray(t, dtype=float)
            ax.plot(a[:, 1], (a[:, 0] - a[:, 1]) * 1e3, lw=0.8, alpha=0.7, label=f"run {n}")
        a = np.asarray(self.table, dtype=float)
        ax.plot(a[:, 1], (a[:, 0] - a[:, 1]) * 1e3, "o", ms=3, color="k", label="table")
        ax.set_xlabel("distance [mm]")
        ax.set_ylabel("reading − distance [µm]")
        ax.grid(True, alpha=0.4)
        ax.legend(loc="best", fontsize="small")
        rep = "-" if self.repeatability_um is None else f"{self.repeatability_um:.2f} µm"
        ax.set_title(title if title is not None else
                     f"calibration: {len(self.table)} points, repeatability {rep}", fontsize="medium")
        if path is not None:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            fig.savefig(path, dpi=110)
        return fig


def _points(x: np.ndarray, y: np.ndarray, bin_width: float, what: str, dropped: list[str]):
    """(distance, reading) points of a monotonic table from samples (x true distance, y reading)."""
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size < 60:
        raise CalibrationError(f"{what}: only {x.size} samples with a finite reading; the head must move over "
                               "the sensor's range (is the sensor selected, SENSOR_SOURCE=VARIABLE?)")
    pts, resid, slopes = characteristic_points(x, y, bin_width)
    if len(pts) < 2 or not slopes:
        raise CalibrationError(f"{what}: the samples cover only {float(np.ptp(x)):.3f} mm of distance; at least "
                               f"two bins of {bin_width:g} mm are needed")
    # a bin of a saturated reading (beyond the sensor's range) has no slope: drop it, from the ends
    med = float(np.median(slopes)) if slopes else 1.0
    if not med > 0.0:
        raise CalibrationError(f"{what}: the reading does not grow with the distance (median slope {med:.3g}); "
                               "is it a distance (not a probe's s = -d)?")
    # the local slope between neighbouring points finds the saturated ends
    xs = np.array([p[0] for p in pts])
    ys = np.array([p[1] for p in pts])
    local = np.gradient(ys, xs)
    lo, hi = 0, xs.size
    while lo < hi and local[lo] < _SATURATED_SLOPE * med:
        lo += 1
    while hi > lo and local[hi - 1] < _SATURATED_SLOPE * med:
        hi -= 1
    if lo or hi < xs.size:
        dropped.append(f"{what}: {lo + xs.size - hi} bin(s) at the ends where the reading does not change "
                       "(out of the sensor's range) left out")
    xs, ys = xs[lo:hi], ys[lo:hi]
    if xs.size < 2:
        raise CalibrationError(f"{what}: the reading never changes with the distance (saturated)")
    bad = np.flatnonzero(np.diff(ys) <= 0.0)
    if bad.size:
        i = int(bad[0])
        raise CalibrationError(f"{what}: the reading is not monotonic: {ys[i]:.4f} mm at {xs[i]:.3f} mm, "
                               f"{ys[i + 1]:.4f} mm at {xs[i + 1]:.3f} mm; a table cannot linearise it")
    rr = np.concatenate(resid) if resid else np.zeros(0)
    return xs, ys, rr, med


def calibration_table(record, surface: float, bin_width: float = CHAR_BIN) -> CalibrationTable:
    """The linearisation table and the repeatability from a :class:`~distctrl.plc.process.CalibrationRecord`
    (module docstring). ``surface``: the axis position (mm) where the nozzle touches the sheet."""
    a = np.asarray(record.axis, dtype=float)
    r = np.asarray(record.reading, dtype=float)
    run = np.asarray(record.run, dtype=int)
    if a.size == 0:
        raise CalibrationError("nothing was recorded")
    dropped: list[str] = []
    d = a - surface
    xs, ys, rr, slope = _points(d, r, bin_width, "all runs", dropped)
    table = [(round(float(y), 6), round(float(x), 6)) for x, y in zip(xs, ys)]
    run_tables = []
    for k in sorted(set(run.tolist())):
        m = run == k
        rx, ry, _, _ = _points(d[m], r[m], bin_width, f"run {k}", dropped)
        run_tables.append([(float(y), float(x)) for x, y in zip(rx, ry)])
    rep = None
    if len(run_tables) >= 2:
        lo = max(t[0][0] for t in run_tables)
        hi = min(t[-1][0] for t in run_tables)
        grid = np.array([p[0] for p in table if lo <= p[0] <= hi])
        if grid.size == 0:
            raise CalibrationError("the runs cover no common range of readings: they cannot be compared")
        vals = np.array([np.interp(grid, [p[0] for p in t], [p[1] for p in t]) for t in run_tables])
        rep = float(np.max(np.ptp(vals, axis=0))) * 1000.0
    noise = float(np.sqrt(np.mean(rr * rr))) / slope * 1000.0 if rr.size else None
    return CalibrationTable(table, run_tables, rep, (float(xs[0]), float(xs[-1])), float(surface), int(a.size),
                            noise, dropped)


def table_toml(result: CalibrationTable, header: list[str]) -> str:
    """The table as TOML, ``linearisation = [[reading_mm, distance_mm], ...]`` (what ``[sensor]
    linearisation = "FILE"`` reads), with ``header`` as comment lines."""
    lines = [f"# {h}" for h in header]
    lines.append("linearisation = [")
    lines += [f"    [{rd:.6f}, {dd:.6f}]," for rd, dd in result.table]
    lines.append("]")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------- the run on the virtual machine
@dataclass
class CalibrationRun:
    """How the run on the virtual machine ended: ``function`` the calibrate function (its
    ``completed`` record), ``machine``; ``error`` (None when it ended DONE) and its ``exit_code``."""

    function: object
    machine: object
    surface: float
    surface_source: str
    time: float
    error: str | None = None
    exit_code: int = 0


def _with_calibrate(scenario, runs: int | None, speed: float | None, bottom: float | None):
    """The scenario with one calibrate function on the sensor's axis (its own table, or a new one with
    the defaults) and no other process function; runs/speed/bottom override its keys."""

    sensor = scenario.sensor
    if sensor is None or sensor.kind != "distance":
        kind = "no [sensor]" if sensor is None else f"[sensor] kind = {sensor.kind!r}"
        raise CalibrationError(f"{scenario.name}: the calibration run linearises a distance sensor "
                               f"([sensor] kind = 'distance', e.g. capacitive); the scenario has {kind}")
    cal = [p for p in scenario.processes if p.function == "calibrate"]
    raw = {"function": "calibrate", "axis": sensor.axis}
    if cal:
        raw.update(cal[0].params)
        raw["axis"] = cal[0].axis
    for k, v in (("runs", runs), ("speed", speed), ("bottom", bottom)):
        if v is not None:
            raw[k] = v
    try:
        (pc,) = process_configs([raw], scenario.axes, sensor, scenario.cycle_time, False)
    except ConfigError as exc:              # name the option, or the scenario's own table
        name = exc.key.rsplit(".", 1)[-1]
        given = {"runs": runs, "speed": speed, "bottom": bottom}
        key = f"--{name}" if given.get(name) is not None else \
            exc.key.replace("process[0]", f"process[{cal[0].index}]" if cal else "calibrate")
        raise exc.rekeyed(key) from None
    return dataclasses.replace(scenario, processes=(pc,))


def run_calibration(scenario, *, runs: int | None = None, speed: float | None = None, bottom: float | None = None,
                    surface: float | None = None, progress=None) -> CalibrationRun:
    """Run ``scenario`` with the calibrate function until it has ended (module docstring). The NC
    program must select the sensor (``SENSOR_SOURCE=VARIABLE``) and leave the head above the sheet.
    ``surface`` (axis coordinates, mm): where the nozzle touches the sheet; default the scenario's
    surface under the head (a simulation knows it; on a machine, touch off)."""

    sc = _with_calibrate(scenario, runs, speed, bottom)
    pc = sc.processes[0]
    m = Machine(sc, load_program(sc))
    f = m.process_program.functions[0]
    p = pc.params
    T = sc.cycle_time
    rng = sc.sensor.range_max
    # time the run needs at most: each run down and up over the sensor's range, the dwells, margin
    need = p["runs"] * (2.0 * rng / p["speed"] + 3.0 * p["settle"]) + 10.0
    limit = max(sc.duration, need)
    n_max = int(round(limit / T))
    depth = sc.sensor.collision_depth
    error, code = None, int(ExitCode.OK)
    while f.phase not in ("DONE", "FAILED"):
        if m.cycle >= n_max:
            error, code = (f"the calibration did not end within {limit:g} s (phase {f.phase}, run {f.run_no}); "
                           "does the NC program leave the head at rest above the sheet?"), int(ExitCode.TIME_LIMIT)
            break
        m.step()
        if m.true_distance <= -depth and f.phase != "WAITING":
            error, code = (f"the head touched the sheet at t = {m.cycle * T:.3f} s (true distance "
                           f"{m.true_distance:.4f} mm, run {f.run_no}): raise bottom (now {f.bottom:g} mm)"), \
                int(ExitCode.ABORTED)
            break
        if progress is not None and m.cycle % 1000 == 0:
            progress(m.cycle * T, f)
    if error is None and f.phase == "FAILED":
        errs = [f"{ev.id} ({ev.message})" for _, ev in m.events if ev.severity == "error"]
        error = f"the calibrate function failed: {f.error}" + (f"; errors: {', '.join(errs)}" if errs else "")
        code = int(ExitCode.ABORTED)
    source = "option"
    if surface is None:
        x0, y0 = getattr(m, "true_xy", (0.0, 0.0))
        surface = float(sc.surface.height(x0, y0))
        source = "scenario"
    return CalibrationRun(f, m, float(surface), source, m.cycle * T, error, code)


def model_check_um(scenario, table: CalibrationTable, x: float = 0.0, y: float = 0.0) -> float:
    """Simulation only: the largest |table(ideal reading(d)) − d| in µm over the distances the table
    covers, with the scenario's sensor model free of noise (how well the table linearises it)."""

    sc = scenario
    sensor = sc.sensor.make_sensor(sc.cycle_time, sc.axes[sc.sensor.axis].params, sc.surface)
    lin = DistanceLinearisation(table.table)
    lo, hi = table.distance_range
    ds = np.linspace(lo, hi, 400)
    surface = table.surface
    readings = np.array([sensor.ideal(surface + d, surface, x, y) for d in ds])
    return float(np.max(np.abs(lin.distance(readings) - ds))) * 1000.0


def default_out(scenario) -> Path:
    """``<scenario stem>_linearisation.toml`` beside the scenario file (cwd for one without a file)."""
    path = getattr(scenario, "path", None)
    if path is None:
        return Path("linearisation.toml")
    path = Path(path)
    return path.with_name(path.stem + "_linearisation.toml")


def finite(v):
    return v if v is None or math.isfinite(v) else None
