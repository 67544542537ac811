"""``distctrl objects [SCENARIO]``: the CNC objects of distance control like the object browser, local or
read over ADS from a running ``distctrl serve`` (``--watch``)."""
from __future__ import annotations

import sys
import time

import click

from ..control import AxisDistanceController, CycleOutput
from ..errors import DistCtrlError
from ..objects.browser import format_rows, json_rows, local_rows, remote_rows
from ..objects.registry import BY_NAME, AxisObjectContext, index_offset
from ..params import AxisParameters
from ..sim.machine import Machine
from ..sim.runner import load_program
from ..sim.scenario import load_scenario
from .common import Finite, emit_json, fail, json_text


@click.command("objects")
@click.argument("scenario", required=False, type=click.Path(dir_okay=False))
@click.option("--axis", "axis_filter", help="Only this axis: its name; with --watch and no SCENARIO its "
              "axis_id (2) or axis2.")
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

    if watch:
        _watch_objects(scenario, axis_filter, as_json, host, ads_port, net_id, interval, count)
        return

    try:
        if scenario is None:
            contexts = {1: AxisObjectContext(1, "Z", AxisDistanceController(AxisParameters()), CycleOutput())}
        else:
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

def _watch_objects(scenario, axis_filter, as_json, host, port, net_id, interval, count) -> None:
    """``objects --watch``: the table of a served machine, refreshed every ``interval`` seconds. The
    connection is the machine commands' (:class:`distctrl.client.target.Target`): a bounded TCP connect
    first, one line for every failure, AdsLib's own log lines kept off the terminal."""
    try:
        import pyads  # the [ads] extra: only --watch needs it, so objects works without it
    except ImportError:
        fail("--watch needs pyads, the ADS client it reads the served machine with, which is not installed: "
             "pip install 'distctrl[ads]'")
    # the machine commands' ADS connection: only --watch needs it (and its pyads)
    from ..client.target import CNC_PORT, MachineError, Target, quiet_adslib

    names: dict[int, str] = {}
    resolution = 1e-4
    if scenario is not None:
        try:
            sc = load_scenario(scenario)
        except DistCtrlError as exc:
            fail(str(exc))
        names = {i + 1: n for i, n in enumerate(sc.axes)}        # the scenario keeps X Y Z A B C order
        resolution = next((a.resolution for a in sc.axes.values() if a.resolution), 1e-4)
    quiet_adslib()
    target = Target(net_id, CNC_PORT, host, timeout=2.0, connect_timeout=2.0, tcp_port=port)
    try:
        target.open()
        conn = target.conn
        if not names:                        # ask the server: axis ids answer until 0x703 (no such axis)
            kp = BY_NAME["DIST_CTRL::kp"]
            for axis_id in range(1, 33):
                try:
                    conn.read(kp.index_group, index_offset(axis_id, kp), pyads.PLCTYPE_LREAL)
                except pyads.ADSError:
                    break
                names[axis_id] = f"axis{axis_id}"
        if axis_filter:
            names = _pick_axis(names, axis_filter, scenario is not None)
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
    except MachineError as exc:
        fail(str(exc))
    except pyads.ADSError as exc:
        fail(f"ADS {host}:{port} ({net_id}): {exc}")
    finally:
        target.close()


def _pick_axis(names: dict[int, str], wanted: str, named: bool) -> dict[int, str]:
    """--axis by name, or by its axis_id (``2``); one line naming the axes there are otherwise."""
    picked = {i: n for i, n in names.items() if n == wanted or (wanted.isdigit() and int(wanted) == i)}
    if picked:
        return picked
    have = ", ".join(names.values()) or "none"
    if named:
        fail(f"--axis {wanted!r}: no such axis in the SCENARIO; its axes: {have}")
    fail(f"--axis {wanted!r}: without a SCENARIO the axes are named by their axis_id ({have}): give the "
         f"axis_id, e.g. --axis 2, or the SCENARIO the server runs to name them (objects SCENARIO --watch "
         f"--axis {wanted})")
