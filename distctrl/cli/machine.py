"""``distctrl machine show | record | write``: a TwinCAT CNC (or ``distctrl serve``) read, recorded
and written over ADS through its distance-control CNC objects (docs/commissioning.md). The client
code is in :mod:`distctrl.client`; here are only the options, the tables and the exit codes."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import click

from ..client import MachineError
from ..client.axes import Unit, describe_unit, format_list_text, probe_axes, probe_channels, read_parameters, state_name
from ..client.recorder import make_signal
from ..client.recorder import record as do_record
from ..client.recorder import summary, write_trace
from ..client.target import Target, parse_target
from ..client.writer import default_backup_path, execute, plan_write
from ..errors import ExitCode
from .common import Finite, check_writable, emit_json, fail


def _target_options(f):
    f = click.option("--timeout", default=2.0, show_default=True, type=Finite(0.05, 60.0),
                     help="Seconds each ADS request may take (pyads' timeout) and the TCP connect may wait.")(f)
    f = click.option("--ip", default=None, help="IP address or host name of the target (default: the NetId's "
                     "first four numbers). A route to this machine must exist on the target "
                     "(docs/commissioning.md).")(f)
    f = click.option("--ads", "ads", required=True, metavar="NETID[:PORT]",
                     help="AMS NetId of the CNC, e.g. 5.12.34.56.1.1 (port default 551, the GEO task's CNC objects).")(f)
    return f


def _axis_option(required: bool):
    return click.option("--axis", "axis", required=required, metavar="NAME=ID|ID",
                        help="The axis: its name and axis_id (from 1, the A_ID of the index offset), "
                             "e.g. Z=3; or the axis_id alone.")


def _parse_axis(text: str):
    name, sep, ident = text.partition("=")
    if not sep:
        name, ident = (text, text) if text.isdigit() else (text, "")
    if not ident.isdigit() or not 1 <= int(ident) <= 0xFFFF:
        n = name if name and not name.isdigit() else "Z"
        fail(f"--axis {text!r}: the CNC objects carry no axis names (FCT-M3 §9.4 and TF5200 §7.5 address an "
             f"axis by its index, the A_ID of the index offset 0x<A_ID>3xxx): give --axis {n}=<index>, e.g. "
             f"--axis {n}=3, the axis's index from 1 (gpAx[index] in the PLC; 1 to 65535); "
             "`distctrl machine show --ads ...` lists the indexes whose distance-control objects answer")
    return Unit("axis", int(ident), name or ident)


def _quiet_adslib() -> None:
    """pyads' AdsLib logs on the process's stderr (``Info: connection closed by remote``, ``Error: write
    frame failed``); our own one-line message says what happened. In a real process (stderr is file
    descriptor 2) Python's stderr moves to a copy of it and descriptor 2 to /dev/null, unless
    DISTCTRL_ADS_LOG=1 asks for the library's lines."""
    if os.environ.get("DISTCTRL_ADS_LOG") == "1" or getattr(_quiet_adslib, "done", False):
        return
    try:
        if sys.stderr.fileno() != 2:
            return
        sys.stderr.flush()
        saved = os.dup(2)
        sys.stderr = os.fdopen(saved, "w", buffering=1, encoding=sys.stderr.encoding, errors="backslashreplace")
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 2)
        os.close(null)
    except (AttributeError, OSError, ValueError):
        return
    _quiet_adslib.done = True


def _open(ads: str, ip: str | None, timeout: float):
    _quiet_adslib()
    net_id, port, host = parse_target(ads, ip)
    return Target(net_id, port, host, timeout=timeout, connect_timeout=max(timeout, 1.0)).open()


def _fail_machine(exc) -> None:
    fail(str(exc), getattr(exc, "exit_code", ExitCode.INVALID_INPUT))


@click.group()
def machine() -> None:
    """A TwinCAT CNC over ADS: show, record and write the distance-control objects (docs/commissioning.md)."""


@machine.command()
@_target_options
@click.option("--axis", "axes", multiple=True, metavar="NAME=ID|ID",
              help="Show these axes (repeat); default: every axis_id from 1 whose objects answer.")
@click.option("--out", type=click.Path(dir_okay=False), default=None,
              help="Also write the (first) axis's parameters as a parameter list (kernel format).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object: target, axes, channels.")
def show(ads: str, ip: str | None, timeout: float, axes: tuple[str, ...], out: str | None, as_json: bool) -> None:
    """The axes and 3D channels with distance control: state and every parameter the CNC objects
    expose, in the parameter lists' units (as `distctrl params` prints them), with ranges."""
    try:
        with _open(ads, ip, timeout) as target:
            units = [_parse_axis(a) for a in axes] if axes else probe_axes(target)
            rows = [describe_unit(target, u) for u in units]
            channels = [describe_unit(target, c) for c in probe_channels(target)]
            if out:
                if not units:
                    fail("--out: the target has no axis with distance-control objects")
                text = format_list_text(units[0], read_parameters(target, units[0]),
                                        f"{units[0].label} of {target.address} (distctrl machine show)")
                Path(out).write_text(text, encoding="utf-8")
    except MachineError as exc:
        _fail_machine(exc)
    result = {"command": "machine show", "outcome": "ok", "target": ads,
              "axes": rows, "channels": channels, "out": out}
    if as_json:
        emit_json(result)
        return
    for r in rows + channels:
        kind = "axis" if r["kind"] == "axis" else "channel"
        click.echo(f"{kind} {r['name']} (index {r['index']}): state {r['state']}"
                   + (" (distance control active)" if r["active"] else ""))
        width = max(len(d["key"]) for d in r["details"].values())
        for f, v in r["parameters"].items():
            d = r["details"][f]
            text = f"{v:.12g}" if isinstance(v, float) else str(v)
            click.echo(f"  {d['key']:<{width}}  {text:>14} {d['unit']:<6} {d['id']:<13} {d['range']}"
                       + ("" if d["writable"] else "  (read-only)"))
    if not rows and not channels:
        click.echo("no axis or channel with distance-control objects answered")
    if out:
        click.echo(f"written: {out}")


@machine.command()
@_target_options
@_axis_option(True)
@click.option("--seconds", required=True, type=Finite(0.01, 86400.0), help="How long to record (wall time).")
@click.option("--signals", default="command,actual,sensor,offset,state", show_default=True,
              help="Comma-separated: command (sollw_absolut), program (m_sollw_absolut), actual (dig act pos), "
                   "sensor, offset, feedback, deviation, state, or any CNC object name.")
@click.option("--cycle-ms", default=1.0, show_default=True, type=Finite(0.05, 1000.0),
              help="The CNC's cycle time (the GEO task's), the notifications' cycle.")
@click.option("--max-delay-ms", default=50.0, show_default=True, type=Finite(0.0, 1000.0),
              help="Samples are sent together at the latest after this (fewer frames, the same samples).")
@click.option("--mm-per-increment", default=1e-4, show_default=True, type=Finite(1e-9, 1000.0),
              help="Drive resolution incl. gear ratio, for the objects in increments (actual).")
@click.option("--out", required=True, type=click.Path(dir_okay=False),
              help="The trace (CSV with its .meta.json sidecar) that identify, filters, step and plot read.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object: rows, samples, lost, late.")
def record(ads, ip, timeout, axis, seconds, signals, cycle_ms, max_delay_ms, mm_per_increment, out, as_json):
    """Record CNC objects of one axis at the CNC cycle (cyclic device notifications with the target's
    timestamps) into a trace. Lost and late samples are counted and reported; a lost sample is NaN
    in the trace, never filled in. Ctrl-C ends early and keeps what was recorded (exit code 130)."""
    unit = _parse_axis(axis)
    names = [s.strip() for s in signals.split(",") if s.strip()]
    if not names:
        fail("--signals: name at least one signal")
    check_writable(out, "--out")
    try:
        sigs = [make_signal(n, mm_per_increment) for n in names]
        with _open(ads, ip, timeout) as target:
            rec = do_record(target, unit, sigs, seconds, cycle_ms * 1e-3, max_delay_ms * 1e-3)
    except MachineError as exc:
        _fail_machine(exc)
    write_trace(rec, out, {"target": ads, "axis": unit.name, "axis_id": unit.number,
                           "actual_sampled": "start"})
    s = summary(rec)
    result = {"command": "machine record", "outcome": "interrupted" if rec.interrupted else "ok",
              "out": out, "columns": rec.columns, **s}
    if as_json:
        emit_json(result)
    else:
        lost = ", ".join(f"{k} {v}" for k, v in rec.lost.items() if v) or "none"
        click.echo(f"recorded {s['rows']} cycles ({s['seconds']:.3f} s) of {', '.join(rec.columns[1:])}: "
                   f"{s['samples']} samples, lost: {lost}, late: {rec.late}" + (" (Ctrl-C)" if rec.interrupted else ""))
        click.echo(f"written: {out}")
        if s["lost_total"] or rec.late:
            click.echo("warning: lost samples are NaN in the trace (a gap, not data)", err=True)
    if rec.interrupted:
        raise SystemExit(int(ExitCode.INTERRUPTED))
    if rec.rows == 0:
        fail("no sample arrived: does the target send cyclic notifications on these objects?")


@machine.command()
@_target_options
@_axis_option(False)
@click.option("--channel", type=click.IntRange(1, 255), default=None,
              help="Instead of --axis: the 3D distance control of this channel (a channel list, dist_ctrl[0].*).")
@click.argument("list_file", type=click.Path(dir_okay=False))
@click.option("--yes", is_flag=True, help="Write. Without it only the changes are shown (nothing is written).")
@click.option("--pending", is_flag=True, help="Write even while distance control is active: the values wait "
              "for the next activation (FCT-M3 §9.4) and the running process keeps the old ones.")
@click.option("--backup", type=click.Path(dir_okay=False), default=None,
              help="Where the old values go before the first write (default: beside LIST_FILE, never overwritten).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object: changes, backup, pending.")
def write(ads, ip, timeout, axis, channel, list_file, yes, pending, backup, as_json):
    """Write the writable parameters that LIST_FILE sets (kp, i_tn, d_tv, v_max, a_max) through the
    CNC objects: shows old -> new; with --yes writes a backup first, writes, reads back and verifies,
    and restores the backup when anything fails half way. `machine write ... BACKUP --yes` undoes it."""
    if (axis is None) == (channel is None):
        fail("give --axis NAME=ID or --channel N")
    unit = _parse_axis(axis) if axis else Unit("channel", channel, str(channel))
    if not Path(list_file).is_file():
        fail(f"{list_file}: no such file")
    try:
        net_id, port, host = parse_target(ads, ip)

        def reconnect():
            return Target(net_id, port, host, timeout=timeout, connect_timeout=max(timeout, 1.0)).open()

        with _open(ads, ip, timeout) as target:
            plan = plan_write(target, unit, list_file)
            result = {"command": "machine write", "target": ads, "unit": unit.label, "list": list_file,
                      "state": plan.state, "active": plan.active, "ignored": plan.ignored,
                      "unchanged": plan.unchanged}
            if not yes:
                result.update(outcome="planned", written=False, changes=[c.as_dict() for c in plan.changes])
                _show_plan(plan, result, as_json, written=False)
                return
            bpath = Path(backup) if backup else default_backup_path(list_file, unit)
            if plan.changes:
                check_writable(str(bpath), "--backup")
            done = execute(plan, target, bpath, pending=pending, reconnect=reconnect)
            result.update(outcome="written" if plan.changes else "unchanged", written=bool(plan.changes),
                          changes=[c.as_dict() for c in plan.changes],
                          backup=done["backup"] if plan.changes else None, pending=done["pending"])
            _show_plan(plan, result, as_json, written=True)
    except MachineError as exc:
        _fail_machine(exc)


def _show_plan(plan, result: dict, as_json: bool, written: bool) -> None:
    if as_json:
        emit_json(result)
        return
    click.echo(f"{plan.unit.label}: state {state_name(plan.state)}")
    if not plan.changes:
        click.echo("nothing to change: the target has these values")
    for c in plan.changes:
        status = f"  [{c.status}]" if written else ""
        click.echo(f"  {c.key:<22} {c.old!s:>14} -> {c.new!s:<14} {c.unit:<6} ({c.object}){status}")
    for i in plan.ignored:
        click.echo(f"  {i['key']:<22} ignored: {i['reason']}")
    if not written:
        if plan.changes:
            click.echo("nothing written: add --yes to write these values (a backup of the old ones is written first)")
        return
    if plan.changes:
        click.echo(f"backup of the old values: {result['backup']} (restore: the same command with it and --yes)")
        click.echo(f"pending until the next activation of distance control (INACTIVE→ACTIVE or FREEZE→ACTIVE, "
                   f"FCT-M3 §9.4): {', '.join(result['pending'])}")
