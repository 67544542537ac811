"""``distctrl sweep`` and ``distctrl tune`` (click commands; distctrl/cli/__init__.py registers them (LAZY_COMMANDS)).

Progress and notes (``compiling the batch kernels ...``, the tuner's rounds) go to stderr; with ``--json`` stdout
carries one JSON object and nothing else (docs/tuning.md).
"""
from __future__ import annotations

import math
from pathlib import Path

import click

from ..errors import DistCtrlError
from ..errors.files import PLOT_SUFFIXES, TABLE_SUFFIXES
from ..tuning.metrics import METRIC_NAMES
from ..tuning.runner import DEFAULT_CHUNK, Evaluator
from ..tuning.columns import COLUMN_FIELDS, columns_of, drop_inert_columns, random_columns
from ..tuning.space import build_sets, drop_inert_d_tv, grid_points, parse_grid
from ..tuning.tune import tune
from .common import SEED, Finite, check_output, check_writable, emit_json, fail, freeze_loaded_objects


def _errors() -> tuple:
    from ..batch.closed_loop import ClosedLoopError     # numba: loaded only when the kernel runs

    return (DistCtrlError, ClosedLoopError)


__all__ = ["sweep", "tune_cmd"]


def _say(message: str) -> None:
    click.echo(message, err=True)


def _announce_cold_kernels() -> None:
    """One line on stderr before anything else when the batch kernels are not compiled for this machine
    yet (the first sweep / tune after installing the extras compiles them for 30-80 s; audit R17)."""
    from ..batch.warm import announce_if_cold     # numba: loaded only when the kernels run

    announce_if_cold(_say)


def _sets_text(sets: int, requested: int, merged: int, rejected: int) -> str:
    """``9992 of 10000 sets (8 merged: ...)``: what became of every set asked for."""
    if sets == requested:
        return f"{sets} sets"
    why = [f"{merged} merged: equal to another set once d_tv is 0 at kp >= 1"] if merged else []
    why += [f"{rejected} rejected: out of range"] if rejected else []
    return f"{sets} of {requested} sets ({'; '.join(why)})"


def _mode(local: bool, scheduler: str | None) -> dict:
    if local and scheduler:
        raise click.UsageError("--local and --scheduler exclude each other")
    return {"mode": "local" if local else "cluster", "scheduler": scheduler}


def _weights(sat_weight: float | None, chatter_weight: float | None) -> dict:
    out = {}
    for name, v in (("sat_weight", sat_weight), ("chatter_weight", chatter_weight)):
        if v is not None:
            if not (math.isfinite(v) and v >= 0):
                raise click.UsageError(f"--{name.replace('_', '-')} {v!r}: a finite number >= 0")
            out[name] = float(v)
    return out


_SAT_HELP = ("Weight (mm) of sat_share, the share of cycles the offset runs at the limiter's velocity / "
             "acceleration limit (P-AXIS-00415/00416), in the cost [default: 0.05].")
_CHATTER_HELP = "Weight of offset_hf_rms, the offset's motion above 20 Hz, in the cost [default: 0.25]."


@click.command()
@click.argument("scenario", type=click.Path(dir_okay=False, exists=True))
@click.option("--grid", help="Grid to evaluate, e.g. 'kp=0.1:1.0:10,d_tv=0,0.01,filter_type=MOVING_AVERAGE,"
                             "n_cycles=4,8,16' (a:b:n ranges, a:b:n:log, lists).")
@click.option("--random", "n_random", type=click.IntRange(1, 10**8), help="Evaluate N random points of the default search space.")
@click.option("--seed", default=0, show_default=True, type=SEED, help="Seed of --random.")
@click.option("--cycles", type=click.IntRange(1, 10**8), help="Cycles to replay (default: to the next command after the select).")
@click.option("--out", "out", default="sweep.csv", show_default=True, type=click.Path(dir_okay=False),
              help="Results table: .csv, or .parquet (needs pyarrow).")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Save a heatmap (two swept parameters) or parallel-coordinates plot (.png, .svg or .pdf).")
@click.option("--metric", default="rms_error", show_default=True, help="Metric of the plot and the ranking.")
@click.option("--sat-weight", type=Finite(0.0, 1e6), default=None, help=_SAT_HELP)
@click.option("--chatter-weight", type=Finite(0.0, 1e6), default=None, help=_CHATTER_HELP)
@click.option("--scheduler", help="Address of an existing dask scheduler (tcp://host:8786).")
@click.option("--local", is_flag=True, help="Run in this process without dask.")
@click.option("--workers", type=click.IntRange(1, 1024), help="Workers of the embedded LocalCluster (default: all cores).")
@click.option("--chunk", default=256, show_default=True, type=click.IntRange(1, 10**7),
              help="Parameter sets run at once (a cluster task runs several such blocks, docs/tuning.md).")
@click.option("--top", default=10, show_default=True, type=click.IntRange(1, 10**6), help="Rows of the summary table.")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object (the best --top rows with units, throughput, files) instead of the table.")
def sweep(scenario, grid, n_random, seed, cycles, out, plot_path, metric, sat_weight, chatter_weight, scheduler,
          local, workers, chunk, top, as_json):
    """Evaluate a grid (--grid) or a random sample (--random N) of filter/PID settings on SCENARIO.toml
    with the closed-loop batch kernel; write the metrics table and optionally a plot."""
    check_output(out, "table", TABLE_SUFFIXES)          # before the kernels load and the sets run
    check_output(plot_path, "plot", PLOT_SUFFIXES)
    from ..batch.closed_loop import prepare     # numba ([batch] extra): loaded only when a sweep runs

    if (grid is None) == (n_random is None):
        raise click.UsageError("give exactly one of --grid and --random N")
    if metric not in METRIC_NAMES + ("cost",):
        raise click.UsageError(f"--metric {metric!r}: one of cost, {', '.join(METRIC_NAMES)}")
    opts = _mode(local, scheduler)
    weights = _weights(sat_weight, chatter_weight)
    _announce_cold_kernels()
    try:
        expected = n_random if n_random is not None else len(drop_inert_d_tv(grid_points(parse_grid(grid)))[0])
        if opts["mode"] == "cluster" and not scheduler and expected <= (chunk or DEFAULT_CHUNK):
            # one chunk cannot be spread over workers: the embedded cluster would only add its start-up
            opts["mode"] = "local"
            _say(f"{expected} sets fit in one chunk: running in this process (no cluster to start)")
        inputs = prepare(scenario, cycles)
        freeze_loaded_objects()              # before numba loads the kernels (its own full collections)
        # the cluster starts (in the background) while the sets are built
        with Evaluator(inputs, cycles=cycles, n_workers=workers, chunk_size=chunk, log=_say,
                       progress=False if as_json else None, cost_weights=weights, **opts) as ev:
            # the sets as columns (issue 27: no Python per set; checked, designed and packed chunk by chunk
            # where the chunks run); what the columns do not cover goes set by set
            pc = columns_of(grid_points(parse_grid(grid))) if grid is not None else \
                random_columns(n_random, seed, cycle_time=inputs.cycle_time)
            columnar = pc is not None and not set(pc.cols) - COLUMN_FIELDS
            if columnar:
                pc, merged = drop_inert_columns(pc)
            else:
                points = pc.to_points() if pc is not None else grid_points(parse_grid(grid))
                points, merged = drop_inert_d_tv(points)
            if merged:
                what = "grid combinations" if grid is not None else f"of the {n_random} random sets"
                _say(f"{merged} {what} differ from another only in d_tv at kp >= 1, where the D part has no "
                     f"effect (docs/control-law.md): merged, each run once with d_tv 0")
            if columnar:
                res = ev.evaluate_points(inputs.params, pc)
                rejected, n_sets = res.rejected, len(res)
            else:
                sets, points, rejected = build_sets(inputs.params, points, inputs.cycle_time)
                n_sets = len(sets)
            if rejected:
                _say(f"warning: {len(rejected)} of {len(rejected) + n_sets} combinations rejected; "
                     f"first: {rejected[0][1]}")
            if not n_sets:
                raise DistCtrlError("no valid parameter set to evaluate")
            if not columnar:
                res = ev.evaluate(sets, points)
            compile_s = ev.stats["compile_s"]
        path = res.write(out)
        if plot_path:
            res.plot(plot_path, metric)
    except _errors() as exc:
        fail(str(exc))
    info = res.info
    requested = info["sets"] + merged + len(rejected)
    rate = info["sets"] * info["cycles"] / max(info["seconds"], 1e-9)
    if as_json:
        d = res.to_dict(top, key=metric)
        emit_json({"command": "sweep", "scenario": scenario, "metric": d["metric"], "sets": d["sets"],
                   "cycles": d["cycles"], "seconds": d["seconds"], "compile_seconds": compile_s,
                   "set_cycles_per_s": d["set_cycles_per_s"], "mode": d["mode"], "workers": d["workers"],
                   "requested": requested, "merged": merged, "rejected": len(rejected),
                   "table": str(path), "plot": plot_path,
                   "best": d["best"], "units": d["units"], "notes": d["notes"]})
        return
    click.echo(res.render(top, key=metric, plain=True,
                          title=f"best {min(top, len(res))} of {len(res)} sets by {metric}"), nl=False)
    click.echo(f"{_sets_text(info['sets'], requested, merged, len(rejected))} x {info['cycles']} cycles in "
               f"{info['seconds']:.2f} s "
               f"({_rate_text(rate)} set-cycles/s, {info['mode']}, {info['workers']} worker(s)"
               + (f"; compiling took {compile_s:.1f} s before" if compile_s else "")
               + f"); table: {path}" + (f"; plot: {plot_path}" if plot_path else ""))


def _rate_text(rate: float) -> str:
    return f"{rate / 1e6:.1f} M" if rate >= 1e6 else f"{rate / 1e3:.0f} k"


@click.command("tune")
@click.argument("scenario", type=click.Path(dir_okay=False, exists=True))
@click.option("--budget", default=400, show_default=True, type=click.IntRange(2, 10**8), help="Parameter sets to evaluate.")
@click.option("--seed", default=0, show_default=True, type=SEED, help="Seed of the coarse random sweep.")
@click.option("--cycles", type=click.IntRange(1, 10**8), help="Cycles to replay (default: to the next command after the select).")
@click.option("--out", "out_dir", default="tune_out", show_default=True, type=click.Path(file_okay=False),
              help="Folder for tuned.lis, tuned.nc.txt, sweep.csv, before_after.png, report.txt.")
@click.option("--osc-weight", default=1.0, show_default=True, type=Finite(0.0, 1e6),
              help="Weight of the oscillation penalty (hf_rms) in the cost.")
@click.option("--sat-weight", type=Finite(0.0, 1e6), default=None, help=_SAT_HELP)
@click.option("--chatter-weight", type=Finite(0.0, 1e6), default=None, help=_CHATTER_HELP)
@click.option("--no-robustness", is_flag=True, help="Skip the re-check on perturbed scenarios.")
@click.option("--min-gain-margin", default=2.0, show_default=True, type=Finite(1.0, 1e6),
              help="Margin constraint: the gain margin (factor) every chosen set has on the plant and its variants.")
@click.option("--min-phase-margin", default=30.0, show_default=True, type=Finite(0.0, 90.0),
              help="Margin constraint: the phase margin (deg) every chosen set has on the plant and its variants.")
@click.option("--no-margin-constraint", is_flag=True,
              help="Choose by cost alone, without the margin constraint (the margins are still reported).")
@click.option("--scheduler", help="Address of an existing dask scheduler (tcp://host:8786).")
@click.option("--local", is_flag=True, help="Run in this process without dask.")
@click.option("--workers", type=click.IntRange(1, 1024), help="Workers of the embedded LocalCluster (default: all cores).")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object (metrics with units before/after, tuned values, list, NC block, files) "
                   "instead of the report.")
def tune_cmd(scenario, budget, seed, cycles, out_dir, osc_weight, sat_weight, chatter_weight, no_robustness,
             min_gain_margin, min_phase_margin, no_margin_constraint, scheduler, local, workers, as_json):
    """Find good filter/PID settings for SCENARIO.toml: a coarse sweep, a local refinement, the rounded set
    run again, a robustness check; print them as an axis parameter list and an NC DIST_CTRL block."""

    opts = _mode(local, scheduler)
    weights = _weights(sat_weight, chatter_weight)
    if budget < 2:
        raise click.UsageError("--budget: at least 2")
    check_writable(out_dir, "output folder", directory=True)
    _announce_cold_kernels()
    try:
        res = tune(scenario, budget=budget, seed=seed, cycles=cycles, osc_weight=osc_weight,
                   robustness=not no_robustness, n_workers=workers, log=_say,
                   margin_constraint=not no_margin_constraint, min_gain_margin=min_gain_margin,
                   min_phase_margin=min_phase_margin,
                   progress=False if as_json else None, **weights, **opts)
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        (out / "tuned.lis").write_text(res.param_list)
        objects_file = out / "tuned-objects.lis"
        if res.objects_list is not None:
            # the tuned set changes the filter: what machine write can write over the CNC objects
            objects_file.write_text(res.objects_list)
        elif objects_file.exists():
            objects_file.unlink()          # a stale one from an earlier run in this folder would mislead
        (out / "tuned.nc.txt").write_text(res.nc_block + "\n")
        res.sweep.write(out / "sweep.csv")
        res.plot(out / "before_after.png")
        text = res.report()
        (out / "report.txt").write_text(text)
    except _errors() as exc:
        fail(str(exc))
    names = ("tuned.lis",) + (("tuned-objects.lis",) if res.objects_list is not None else ()) + \
        ("tuned.nc.txt", "sweep.csv", "before_after.png", "report.txt")
    files = [str(out / f) for f in names]
    if as_json:
        emit_json({"command": "tune", "scenario": scenario, "budget": budget, "seed": seed, **res.to_dict(),
                   "files": files})
        return
    click.echo(text, nl=False)
    click.echo(f"written: {out}/{', '.join(names)}")
