"""Command-line interface: ``distctrl COMMAND`` (click). Errors at this edge are messages; the exit
codes are one table for every command (:class:`~distctrl.errors.ExitCode`, docs/run.md)."""
from __future__ import annotations

import sys

import click

from ..errors import DistCtrlError
from ..sim.scenario import CYCLE_TIME_MAX, CYCLE_TIME_MIN
from .common import PORT, DistctrlGroup, Finite

#: the commands that live beside what they serve, imported when used
LAZY_COMMANDS = {
    "calibrate": "distctrl.workbench.calibrate_cli:calibrate_cmd",
    "filters": "distctrl.workbench.filters_cli:filters",
    "identify": "distctrl.workbench.identify_cli:identify_cmd",
    "linuxcnc": "distctrl.cli.linuxcnc:linuxcnc",
    "margins": "distctrl.workbench.margins_cli:margins",
    "plot": "distctrl.workbench.plot_cli:plot",
    "step": "distctrl.workbench.step_cli:step",
    "sweep": "distctrl.tuning.cli:sweep",
    "tune": "distctrl.tuning.cli:tune_cmd",
    "ui": "distctrl.ui.cli:ui_cmd",
}


@click.group(cls=DistctrlGroup, lazy_commands=LAZY_COMMANDS)
@click.version_option(package_name="distctrl")
def main() -> None:
    """distctrl: CNC distance (height) control — the ISG-kernel control law as a pure cycle core."""


#: keys that only a channel list (3D distance control, FCT-M3 §12.8) has
_CHANNEL_KEY_PREFIXES = ("dist_ctrl[", "configuration.")


def _list_kind(path: str) -> str:
    """'channel' when the list's first parameter key is a channel key, else 'axis'."""
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            for raw in f:
                line = raw.split("#", 1)[0].strip()
                if line:
                    return "channel" if line.startswith(_CHANNEL_KEY_PREFIXES) else "axis"
    except OSError:
        pass
    return "axis"


@main.command()
@click.argument("list_file", type=click.Path(dir_okay=False))
@click.option("--all", "show_all", is_flag=True, help="Show every parameter, not only the ones that differ from the defaults.")
@click.option("--cycle-time", default=0.001, show_default=True, type=Finite(CYCLE_TIME_MIN, CYCLE_TIME_MAX),
              help="GEO cycle time (s) the list is checked against (the low-pass cut-off must lie below 1/(2T)).")
@click.option("--kind", type=click.Choice(["auto", "axis", "channel"]), default="auto", show_default=True,
              help="An axis list (P-AXIS-, FCT-M3 §9) or a channel list of 3D distance control (P-CHAN-, "
                   "FCT-M3 §12.8); auto: by the first key (dist_ctrl[..] or configuration.* = channel).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object: kind, file, parameters, warnings.")
def params(list_file: str, show_all: bool, cycle_time: float, kind: str, as_json: bool) -> None:
    """Load and validate a parameter LIST_FILE (kernel format, axis or channel list) and print it back."""
    from ..control.controller import AxisDistanceController
    from ..errors import ParameterError
    from ..params import format_list, load_list
    from ..params.channel import CHANNEL_LIST, load_channel_list
    from ..params.listfile import AXIS_LIST, list_entries
    from .common import emit_json, fail

    kind = _list_kind(list_file) if kind == "auto" else kind
    try:
        if kind == "channel":
            pl = load_channel_list(list_file)
            checked, fmt = pl.params.to_axis_parameters(), CHANNEL_LIST
            key, fg_id = "dist_ctrl[0].low_pass_filter_fg_f0", "P-CHAN-00817"
        else:
            pl = load_list(list_file)
            checked, fmt = pl.params, AXIS_LIST
            key, fg_id = "kenngr.distc.low_pass_filter_fg_f0", "P-AXIS-00508"
        try:
            AxisDistanceController(checked, cycle_time)        # what only the cycle time can decide
        except ParameterError as exc:
            fg = exc.param_id == "P-AXIS-00508"        # the low-pass cut-off against Nyquist
            message = str(exc).replace("P-AXIS-00508", fg_id) if fg else str(exc)
            raise ParameterError(message, file=list_file, line=pl.lines.get(key) if fg else None,
                                 key=key if fg else exc.key, param_id=fg_id if fg else exc.param_id,
                                 value=exc.value, allowed=exc.allowed) from None
    except DistCtrlError as exc:
        fail(str(exc))
    except OSError as exc:
        fail(f"cannot read {list_file}: {exc.strerror or exc}")
    if as_json:
        emit_json({"file": list_file, "kind": kind, "cycle_time_s": cycle_time, "valid": True,
                   "only_changed": not show_all, "warnings": list(pl.warnings),
                   "parameters": list_entries(pl.params, only_changed=not show_all, fmt=fmt)})
        return
    for w in pl.warnings:
        click.echo(f"warning: {w}", err=True)
    click.echo(format_list(pl.params, only_changed=not show_all, fmt=fmt), nl=False)


@main.command()
@click.argument("scenario", type=click.Path(dir_okay=False))
@click.option("--trace", "trace_path", type=click.Path(dir_okay=False),
              help="Write the per-cycle trace to this CSV file (units in FILE.meta.json), or to a .parquet file.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object with the result instead of a summary.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), help="Save a plot of the run (PNG or SVG).")
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
    from ..sim.runner import run as run_scenario
    from ..sim.scenario import load_scenario
    from .common import check_writable, emit_json, fail

    records = tuple(record.split(",")) if record else ()
    for path, what, is_dir in ((trace_path, "trace", False), (plot_path, "plot", False),
                               (report_dir, "report folder", True)):
        if path:
            check_writable(path, what, directory=is_dir)
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
        from ..workbench.report import write_report

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
    from ..sim.config_errors import ConfigError
    from ..sim.plates import select_functions

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
    from ..sim.plates import CutWatch

    if sc.sensor is None or not sc.sensor.axis:
        return None
    return CutWatch(sc.sensor.axis)


#: rows of the trace kept for --plot / --report (thinned evenly beyond: bounded memory for any run)
PLOT_ROWS = 200_000
#: a trace estimate above this is announced before the run
TRACE_NOTICE_BYTES = 100e6


def _say_trace_size(est: dict, trace_path: str) -> None:
    """The size of the trace before the run: always when large, a warning when the disk is smaller."""
    import shutil
    from pathlib import Path

    from .common import human_bytes

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
        below = "" if cut["time_below_half_s"] is None else \
            f"{cut['time_below_half_s']:.3f} s below ½ SET_DIST ({0.5 * cut['set_distance_mm']:g} mm); "
        click.echo(f"  while cutting (G1): min true distance {cut_min}; {below}path time {cut['path_time_s']:.3f} s")
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


@main.command()
@click.argument("scenario", required=False, type=click.Path(dir_okay=False))
@click.option("--axis", "axis_filter", help="Only this axis (name).")
@click.option("--cycles", default=0, show_default=True, type=click.IntRange(min=0),
              help="Run the scenario this many cycles first, so the values are live.")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object (with --watch: one object per line and refresh).")
@click.option("--watch", is_flag=True,
              help="Read the objects over ADS from a running `distctrl serve` and refresh the table "
                   "(SCENARIO, if given, names the axes; Ctrl-C stops).")
@click.option("--host", default="127.0.0.1", show_default=True, help="--watch: address of the served machine.")
@click.option("--port", "ads_port", default=48898, show_default=True, type=click.IntRange(1, 65535),
              help="--watch: the AMS/TCP port it is served on (`serve --port`); pyads's router connects to "
                   "HOST:PORT.")
@click.option("--net-id", default="127.0.0.1.1.1", show_default=True, help="--watch: its AMS NetId.")
@click.option("--interval", default=0.5, show_default=True, type=Finite(min=0.02, max=3600.0),
              help="--watch: seconds between refreshes.")
@click.option("--count", default=0, show_default=True, type=click.IntRange(min=0),
              help="--watch: stop after this many refreshes (0: until Ctrl-C).")
def objects(scenario: str | None, axis_filter: str | None, cycles: int, as_json: bool, watch: bool, host: str,
            ads_port: int, net_id: str, interval: float, count: int) -> None:
    """List the CNC objects of distance control like the object browser (FCT-M3 §7.6): per axis the
    raw value in the object's unit, the value in mm / mm/s / mm/s² and the state names.

    With SCENARIO the axes (axis_id from 1 in X Y Z A B C order) and their parameter lists come from
    it; without, one axis with default parameters. Index group 0x120300, offset (axis_id << 16) | 0x3xxx,
    task GEO, ADS port 551. With --watch the values are read over ADS from `distctrl serve`.
    """
    from ..objects.browser import format_rows, json_rows, local_rows
    from .common import emit_json, fail

    if watch:
        _watch_objects(scenario, axis_filter, as_json, host, ads_port, net_id, interval, count)
        return
    from ..control import AxisDistanceController, CycleOutput
    from ..objects.registry import AxisObjectContext

    try:
        if scenario is None:
            from ..params import AxisParameters

            contexts = {1: AxisObjectContext(1, "Z", AxisDistanceController(AxisParameters()), CycleOutput())}
        else:
            from ..sim.machine import Machine
            from ..sim.runner import load_program
            from ..sim.scenario import load_scenario

            sc = load_scenario(scenario)
            machine = Machine(sc, load_program(sc))
            for _ in range(cycles):
                machine.step()
            contexts = {i + 1: AxisObjectContext(i + 1, n, machine.controllers[n], machine.outputs[n],
                                                 sc.axes[n].resolution or 1e-4)
                        for i, n in enumerate(machine.axis_names)}
    except DistCtrlError as exc:
        fail(str(exc))
    if axis_filter:
        contexts = {k: c for k, c in contexts.items() if c.axis_name == axis_filter}
        if not contexts:
            fail(f"no axis {axis_filter!r}")
    rows = local_rows(contexts)
    if as_json:
        emit_json({"scenario": scenario, "cycles": cycles, "objects": json_rows(rows)})
    else:
        click.echo(format_rows(rows), nl=False)


def _ads_address(host: str, port: int) -> str:
    """The address pyads's router connects to: HOST for the standard port 48898, else HOST:PORT (the
    router of pyads, Beckhoff's ADS library on Linux, splits a port off the address; [v6]:PORT)."""
    if port == 48898:
        return host
    return f"[{host}]:{port}" if ":" in host and not host.startswith("[") else f"{host}:{port}"


def _watch_objects(scenario, axis_filter, as_json, host, port, net_id, interval, count) -> None:
    """``objects --watch``: the table of a served machine, refreshed every ``interval`` seconds."""
    import time

    from ..objects.browser import format_rows, json_rows, remote_rows
    from ..objects.registry import BY_NAME, index_offset
    from .common import fail, json_text

    try:
        import pyads
    except ImportError:
        fail("--watch needs pyads (pip install pyads), the ADS client it reads the served machine with")
    names: dict[int, str] = {}
    resolution = 1e-4
    if scenario is not None:
        from ..sim.scenario import load_scenario

        try:
            sc = load_scenario(scenario)
        except DistCtrlError as exc:
            fail(str(exc))
        names = {i + 1: n for i, n in enumerate(sc.axes)}        # the scenario keeps X Y Z A B C order
        resolution = next((a.resolution for a in sc.axes.values() if a.resolution), 1e-4)
    conn = pyads.Connection(net_id, 551, _ads_address(host, port))
    try:
        conn.open()
        if not names:                        # ask the server: axis ids answer until 0x703 (no such axis)
            kp = BY_NAME["DIST_CTRL::kp"]
            for axis_id in range(1, 33):
                try:
                    conn.read(kp.index_group, index_offset(axis_id, kp), pyads.PLCTYPE_LREAL)
                except pyads.ADSError:
                    break
                names[axis_id] = f"axis{axis_id}"
        if axis_filter:
            names = {i: n for i, n in names.items() if n == axis_filter}
            if not names:
                fail(f"no axis {axis_filter!r}")
        shown = 0
        while count == 0 or shown < count:
            rows = remote_rows(conn, names, resolution)
            shown += 1
            if as_json:
                click.echo(json_text({"host": host, "port": port, "net_id": net_id, "refresh": shown,
                                      "objects": json_rows(rows)}).replace("\n", " "))
            else:
                if sys.stdout.isatty():
                    click.echo("\x1b[2J\x1b[H", nl=False)         # clear the terminal, like watch(1)
                click.echo(f"{net_id} at {host}:{port}, refresh {shown} (every {interval:g} s; Ctrl-C stops)")
                click.echo(format_rows(rows), nl=False)
            if count == 0 or shown < count:
                time.sleep(interval)
    except pyads.ADSError as exc:
        fail(f"ADS {host}:{port} ({net_id}): {exc}")
    finally:
        conn.close()


@main.command()
@click.argument("scenario", type=click.Path(dir_okay=False))
@click.option("--host", default="127.0.0.1", show_default=True, help="Address to listen on (ADS and the --ui page).")
@click.option("--port", default=48898, show_default=True, type=PORT, help="AMS/TCP port (0: a free port).")
@click.option("--allow", "allowed", multiple=True, default=["127.0.0.0/8"], show_default=True,
              help="Client address or network allowed to connect (like an ADS route; also to the --ui page); "
                   "repeat for more.")
@click.option("--net-id", default="127.0.0.1.1.1", show_default=True, help="AMS NetId of the served CNC.")
@click.option("--duration", type=Finite(0.0, min_open=True), default=None,
              help="Stop after this many seconds (default: until Ctrl-C or SIGTERM).")
@click.option("--no-discovery", is_flag=True,
              help="Do not answer route discovery and add-route on UDP 48899 (answered by default, "
                   "to the --allow networks).")
@click.option("--ui", "with_ui", is_flag=True,
              help="Also serve the live page (scope, object browser, PLC panel, machine view; docs/ui.md).")
@click.option("--ui-port", default=8050, show_default=True, type=click.IntRange(0, 65535),
              help="--ui: HTTP port of the live page (0: a free port).")
@click.option("--export-dir", default=".", show_default=True, type=click.Path(file_okay=False),
              help="--ui: folder the scope's Export CSV writes its trace files to.")
@click.option("--rt-priority", default=10, show_default=True, type=click.IntRange(0, 99),
              help="Run the 1 ms cycle thread with the real-time policy SCHED_FIFO at this priority where the "
                   "OS allows it (root, CAP_SYS_NICE or an rtprio limit; otherwise one warning and normal "
                   "priority); 0: normal priority.")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object at the end (addresses, page sessions, cycle lateness in µs).")
def serve(scenario: str, host: str, port: int, allowed: tuple[str, ...], net_id: str, duration: float | None,
          no_discovery: bool, with_ui: bool, ui_port: int, export_dir: str, rt_priority: int, as_json: bool) -> None:
    """Run SCENARIO.toml in real time and serve it over ADS (CNC objects on AMS port 551, the PLC
    interface and V.E. variables by symbol name on port 851; route discovery and add-route on UDP
    48899); with --ui also the live page. Reports the cycle jitter at the end."""
    from ..ui.cli import serve_session

    serve_session(scenario, host=host, port=port, allowed=allowed, net_id=net_id, duration=duration,
                  no_discovery=no_discovery, ui=with_ui, ui_port=ui_port, export_dir=export_dir, as_json=as_json,
                  rt_priority=rt_priority)


@main.command(short_help="The diagnosis block of distance control (layout of FCT-M3 Fig. 56).")
@click.argument("scenario", type=click.Path(dir_okay=False))
@click.option("--seconds", default=1.0, show_default=True, type=Finite(min=0.0, max=3600.0),
              help="Run the scenario this long first [s].")
@click.option("--axis", "axis_filter", help="Only this axis (name).")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object: the blocks with every value as a number and its unit.")
def diag(scenario: str, seconds: float, axis_filter: str | None, as_json: bool) -> None:
    """The diagnosis block of distance control (FCT-M3 Fig. 56 layout) after running SCENARIO
    for --seconds: parameters in use, state, set values, offset, sensor, filter, limits, last error."""
    from ..objects.diag import diag_3d, diag_axis
    from ..sim.machine import Machine
    from ..sim.runner import load_program
    from ..sim.scenario import load_scenario
    from .common import emit_json, fail

    try:
        sc = load_scenario(scenario)
        machine = Machine(sc, load_program(sc))
        for _ in range(int(round(seconds / sc.cycle_time))):
            machine.step()
    except DistCtrlError as exc:
        fail(str(exc))
    events = [ev for _, ev in machine.events]
    blocks = []
    if machine.ch3d is not None and axis_filter is None:
        blocks.append(diag_3d(machine.channel3d_values(), sc.channel_params, channel=1, events=events))
    axes = [n for n in machine.dc_axes if axis_filter in (None, n)]
    if not axes and not blocks:
        fail(f"no distance-controlled axis {axis_filter or ''}".rstrip())
    blocks += [diag_axis(machine.controllers[n], machine.outputs[n], n,
                         axis_index=machine.axis_names.index(n) + 1, events=events) for n in axes]
    if as_json:
        emit_json({"scenario": scenario, "seconds": seconds, "blocks": [b.to_dict() for b in blocks]})
        return
    for b in blocks:
        click.echo(b.text())


@main.command()
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object with the tables' figures (per run: outcome, metrics, events, files; "
                   "the plate with and without its functions) instead of the tables.")
def demo(as_json: bool) -> None:
    """Run the demo job: CONST_DIST and SET_POS over an uneven sheet, and the plasma plate with and
    without the cutting-process functions, with summary tables. Traces, plots and reports: out/demo/."""
    from .demo import main as run_demo

    run_demo(as_json=as_json)


if __name__ == "__main__":
    main()
