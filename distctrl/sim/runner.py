"""Run a scenario end to end: ``distctrl.sim.run(scenario) -> RunResult``.

The run lasts until the program has ended (M30, its last block, or an error) and the machine has
settled for ``scenario.settle_time``, or until ``scenario.duration``. Every cycle is recorded in a
trace (streamed to CSV when a path is given; kept in memory unless ``keep_trace=False``, so memory
stays flat however long the program is). Tracking metrics are accumulated on the fly.

``run`` is the loop: step the machine, record the row (the columns: ``signals.py``), call the
observers (``observers.py``: tracking metrics, contact and collisions, the progress bar), until the
program has ended and the machine settled.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..control import HliState
from ..errors import DistCtrlError, ExitCode
from ..nc.parser import parse_file, parse_program
from ..trace import TraceRecorder
from ..trace.parquet import require_pyarrow, to_parquet
from .machine import Machine
# the observers and what the run's metrics are made of live in observers.py; the names stay importable here
from .observers import (COLLISION_ID, COLLISION_TEXT, OSCILLATION_ID, OSCILLATION_TEXT, PERIODIC_MIN,  # noqa: F401
                        PERIODIC_PERIODS, PERIODIC_SECONDS, SETTLE_BAND_MM, SETTLE_HOLD_S, ContactObserver,
                        ProgressObserver, TrackingObserver, _Contact, _Metrics)
from .scenario import Scenario, load_scenario
# the trace's columns live in signals.py; RECORDABLE, check_record, trace_columns, row_builder and
# PLOT_3D stay importable from here
from .signals import PLOT_3D, RECORDABLE, check_record, row_builder, trace_columns  # noqa: F401

#: safety cap when a scenario has no duration: one hour of machine time
MAX_RUN_SECONDS = 3600.0
#: what a run can end with: outcome -> (exit code, words); docs/run.md
OUTCOMES = {
    "completed": (ExitCode.OK, "completed"),
    "aborted": (ExitCode.ABORTED, "ABORTED by an error"),
    "time_limit": (ExitCode.TIME_LIMIT, "stopped at the time limit before the program ended"),
    "interrupted": (ExitCode.INTERRUPTED, "interrupted (Ctrl-C)"),
}


@dataclass
class RunResult:
    """What a run produced; can export its trace and plot itself (python-control style)."""

    name: str
    completed: bool                       # the program ran to its end without an error
    aborted: bool
    errors: list[dict]                    # {id, line, t, message} (controller errors and NC runtime errors)
    warnings: list[dict]
    final_state: str                      # HLI state name of the distance-controlled axis (or "n/a")
    cycles: int
    cycle_time: float
    metrics: dict
    trace: object = None                  # distctrl.trace.Trace when kept
    trace_path: str | None = None
    interrupted: bool = False
    notes: list[str] = field(default_factory=list)
    #: what happened, one of :data:`OUTCOMES`
    outcome: str = "completed"
    time_limit: float | None = None       # the run's time limit (s): duration, or MAX_RUN_SECONDS

    @property
    def exit_code(self) -> int:
        return int(OUTCOMES[self.outcome][0])

    @property
    def outcome_text(self) -> str:
        """The outcome in words, as the summary prints it."""
        if self.outcome == "aborted" and not self.errors:
            return "aborted (the program was stopped by a reset)"
        if self.outcome == "time_limit":
            return f"stopped at the time limit (duration {self.time_limit:g} s) before the program ended"
        return OUTCOMES[self.outcome][1]

    def to_dict(self) -> dict:
        return {"name": self.name, "outcome": self.outcome, "exit_code": self.exit_code,
                "completed": self.completed, "errors": self.errors,
                "warnings": self.warnings, "final_state": self.final_state, "cycles": self.cycles,
                "cycle_time": self.cycle_time, "metrics": self.metrics, "trace": self.trace_path,
                "interrupted": self.interrupted, "notes": self.notes}

    def export_csv(self, path) -> None:
        if self.trace is None:
            raise ValueError("the trace was not kept (keep_trace=False); it was streamed to "
                             f"{self.trace_path or 'nowhere'}")
        self.trace.to_csv(path)

    def plot(self, path=None, signals=None):
        if self.trace is None:
            raise ValueError("the trace was not kept (keep_trace=False)")
        if signals is None and "dc3d.offset" in self.trace.columns:
            signals = list(PLOT_3D)          # 3D: offset and compensation (mm), inclination (deg)
        return self.trace.plot(path, signals=signals, title=self.name)


def load_program(scenario):
    if scenario.program_text is not None and scenario.program_file is None:
        return parse_program(scenario.program_text, file=f"{scenario.path or '<scenario>'}:program_text")
    return parse_file(scenario.program_file)


def run(scenario, *, trace: str | Path | None = None, keep_trace: bool = True, progress: bool = False,
        plc_program=None, record=(), stop_on_collision: bool = False, decimate: int = 1,
        max_rows: int | None = None, keep_at_most: int | None = None, on_start=None) -> RunResult:
    """Run ``scenario`` (a Scenario, or a path to a TOML file). Invalid files raise DistCtrlError.

    ``trace``: a CSV path (streamed, with a ``.meta.json`` units sidecar) or a ``.parquet`` path
    (kept in memory and written at the end; needs pyarrow). ``record``: extra values behind the CNC
    objects to record per distance-controlled axis (:data:`RECORDABLE`, e.g. ``("a_max_int", "kp")``).
    ``stop_on_collision``: a collision (900030) is an error that ends the run in its cycle, instead of
    a warning.

    Trace size (docs/run.md "Trace size"): ``decimate=N`` records every N-th cycle; ``max_rows=N`` keeps
    only the last N rows (a ring buffer like a scope; the CSV is written at the end);
    ``keep_at_most=N`` thins the kept ``result.trace`` (not the CSV) to at most N rows, for a plot or
    report of a long run in bounded memory. Metrics and events always see every cycle.
    ``on_start(size)``, if given, is called before the trace is opened with what it will hold at most
    (:func:`estimate_trace`'s dict), e.g. to say so before a long run.

    ``plc_program(machine, cycle)``, if given, runs every cycle before the CNC reads the PLC
    interface: it may write ``machine.hli[axis]`` (command_w + semaphore, cyclic values) and read
    ``state_r``, as a PLC task does."""

    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    program = load_program(scenario)
    machine = Machine(scenario, program, plc_program=plc_program)
    T = scenario.cycle_time
    record = check_record(record)
    columns, units = trace_columns(machine, record)
    parquet_path = Path(trace) if trace is not None and str(trace).lower().endswith(".parquet") else None
    if parquet_path is not None:
        require_pyarrow()                       # fail before the run, not after it
        trace, keep_trace = None, True
        keep_at_most = None                     # the Parquet file is written from the kept rows: all of them
    decimate = _check_count(decimate, "decimate")
    max_rows = None if max_rows is None else _check_count(max_rows, "max_rows")
    limit_s = scenario.duration if scenario.duration is not None else MAX_RUN_SECONDS
    if on_start is not None:
        on_start(_trace_size(len(columns), limit_s, T, decimate, max_rows))
    meta = {"scenario": scenario.name, "cycle_time": T}
    if decimate > 1:
        meta["decimate"] = decimate
    # rows packed as they are built (no Python floats kept alive) in 1024-row chunks (~190 kB), which
    # stay in the CPU caches: buffering 8192 rows of floats (~6 MB) cost ~7 % of the cycle time
    recorder = TraceRecorder(columns, units, csv_path=trace, keep=keep_trace, chunk_rows=1024, packed=True,
                             meta=meta, max_rows=max_rows,
                             keep_at_most=None if keep_at_most is None else _check_count(keep_at_most, "keep_at_most"))
    max_cycles = int(round(limit_s / T))
    settle_cycles = max(1, int(round(scenario.settle_time / T)))
    dc_axis = scenario.sensor.axis if scenario.sensor is not None and scenario.sensor.axis in machine.dc_axes \
        else (machine.dc_axes[0] if machine.dc_axes else None)
    # what the run watches besides the trace (observers.py): metrics, contact, the progress bar
    observers = [TrackingObserver(machine, scenario, dc_axis), ContactObserver(machine, scenario, stop_on_collision)]
    if progress:
        observers.append(ProgressObserver(max_cycles if scenario.duration is not None else None, T))
    after = [o.after_cycle for o in observers if o.after_cycle is not None]
    interrupted = False
    settled_for = 0
    events = machine.event_cursor()              # every error and warning of the run, for its summary
    nc = machine.nc
    append = recorder.append
    build_row = row_builder(machine, record, pack=recorder.pack)    # rows packed at once (no floats kept)
    step = machine.step
    try:
        for k in range(max_cycles):
            step()
            nc = machine.nc                              # a scenario's start event begins another program
            line = nc.line if nc is not None else None
            if decimate == 1 or k % decimate == 0:
                append(build_row(k * T, -1 if line is None else line))
            stop = False
            for after_cycle in after:
                if after_cycle(k, line):
                    stop = True
            if stop:
                break
            if nc is None or not nc.running:
                settled_for = settled_for + 1 if machine.settled() else 0
                if settled_for >= settle_cycles:
                    break
    except KeyboardInterrupt:
        interrupted = True
    finally:
        errors, warnings = [], []
        for t, ev in events.take():
            item = {"id": ev.id, "line": ev.line, "t": round(t, 9), "message": ev.message}
            (warnings if ev.severity == "warning" else errors).append(item)
        for o in observers:
            o.finish()
            errors.extend(o.errors())
            warnings.extend(o.warnings())
        errors.sort(key=lambda e: e["t"])
        warnings.sort(key=lambda e: e["t"])
        # the sidecar keeps them: `distctrl plot` marks them without the run's JSON
        recorder.meta["errors"], recorder.meta["warnings"] = errors, warnings
        program_done = nc is not None and nc.ended and not nc.aborted
        aborted = bool(errors) or (nc is not None and nc.aborted)
        outcome = recorder.meta["outcome"] = _outcome(interrupted, aborted, program_done)
        kept = recorder.close(complete=not interrupted)
        machine.publish_all()
    if parquet_path is not None and kept is not None:
        to_parquet(kept, parquet_path)
        trace = parquet_path
    if machine.ch3d is not None:
        final_state = HliState(machine.out3d.core.hli_state).name
    else:
        final_state = HliState(machine.outputs[dc_axis].hli_state).name if dc_axis is not None else "n/a"
    notes = list(machine.notes)
    run_metrics = {}
    for o in observers:
        run_metrics.update(o.metrics())
        notes.extend(o.notes())
    return RunResult(scenario.name or Path(str(scenario.path or "scenario")).stem, program_done and not errors,
                     aborted, errors, warnings, final_state,
                     machine.cycle, T, run_metrics, kept, str(trace) if trace else None, interrupted, notes,
                     outcome, limit_s)


def _check_count(value, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise DistCtrlError(f"{name} = {value!r}: must be a whole number >= 1")
    return value


#: CSV bytes per value the estimate assumes: '%.17g' numbers average 14-19 characters plus the comma
CSV_BYTES_PER_VALUE = 19


def estimate_trace(scenario, *, record=(), decimate: int = 1, max_rows: int | None = None) -> dict:
    """What the trace of ``scenario`` will hold at most: rows (the time limit's cycles, decimated, or
    the ring buffer), columns, and the CSV and in-memory bytes; the run may end sooner."""

    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    machine = Machine(scenario, load_program(scenario))
    columns, _ = trace_columns(machine, check_record(record))
    limit_s = scenario.duration if scenario.duration is not None else MAX_RUN_SECONDS
    return _trace_size(len(columns), limit_s, scenario.cycle_time, decimate, max_rows)


def _trace_size(n_columns: int, limit_s: float, T: float, decimate: int, max_rows: int | None) -> dict:
    rows = -(-int(round(limit_s / T)) // max(1, decimate))
    if max_rows is not None:
        rows = min(rows, max_rows)
    return {"rows": rows, "columns": n_columns, "csv_bytes": rows * n_columns * CSV_BYTES_PER_VALUE,
            "memory_bytes": rows * n_columns * 8, "time_limit_s": limit_s}


def _outcome(interrupted: bool, aborted: bool, program_done: bool) -> str:
    if interrupted:
        return "interrupted"
    if aborted:
        return "aborted"
    return "completed" if program_done else "time_limit"
