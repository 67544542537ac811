"""``distctrl machine show | record | write``: a TwinCAT CNC (or ``distctrl serve``) read, recorded
and written over ADS through its distance-control CNC objects (docs/commissioning.md). The client
code is in :mod:`distctrl.client`; here are only the options, the tables and the exit codes."""
from __future__ import annotations

from pathlib import Path

import click

from ..client import MachineError
from ..client.axes import Unit, describe_unit, format_list_text, probe_axes, probe_channels, read_parameters, state_name
from ..client.recorder import make_signal
from ..client.recorder import record as do_record
from ..client.journal import WriteJournal
from ..client.recorder import cut_message, summary, tracking_figures, write_trace
from ..client.target import AMS_TCP_PORT, Target, parse_target, quiet_adslib
from ..client.writer import ORDER, default_backup_path, execute, plan_write
from ..errors import ExitCode
from .common import Finite, check_output, check_writable, emit_json, fail


def _target_options(f):
    f = click.option("--timeout", default=2.0, show_default=True, type=Finite(0.05, 60.0),
                     help="Seconds each ADS request may take (pyads' timeout) and the TCP connect may wait.")(f)
    f = click.option("--port", "tcp_port", default=AMS_TCP_PORT, show_default=True,
                     type=click.IntRange(1, 65535),
                     help="The target's AMS/TCP port (TwinCAT's router: 48898; `distctrl serve --port N`: "
                          "N).")(f)
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


def _open(ads: str, ip: str | None, timeout: float, tcp_port: int = AMS_TCP_PORT):
    quiet_adslib()
    net_id, port, host = parse_target(ads, ip)
    return Target(net_id, port, host, timeout=timeout, connect_timeout=max(timeout, 1.0),
                  tcp_port=tcp_port).open()


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
def show(ads: str, ip: str | None, tcp_port: int, timeout: float, axes: tuple[str, ...], out: str | None,
         as_json: bool) -> None:
    """The axes and 3D channels whose distance-control objects answer: state and every parameter the
    CNC objects expose, in the parameter lists' units (as `distctrl params` prints them), with ranges;
    for kp, i_tn, d_tv, v_max, a_max the value in effect and a value distctrl wrote that is pending."""
    journal = WriteJournal()
    try:
        with _open(ads, ip, timeout, tcp_port) as target:
            units = [_parse_axis(a) for a in axes] if axes else probe_axes(target)
            rows = [_describe(target, u, journal) for u in units]
            channels = [_describe(target, c, journal) for c in probe_channels(target)]
            if out:
                if not units:
                    fail("--out: the target has no axis with distance-control objects")
                values = read_parameters(target, units[0])
                values.update({f: v["in_effect"] for f, v in rows[0]["values"].items()})
                text = format_list_text(units[0], values,
                                        f"{units[0].label} of {target.address} (distctrl machine show; "
                                        f"the values in effect)")
                Path(out).write_text(text, encoding="utf-8")
    except MachineError as exc:
        _fail_machine(exc)
    result = {"command": "machine show", "outcome": "ok", "target": ads, "port": tcp_port,
              "axes": rows, "channels": channels, "out": out, "journal": str(journal.path)}
    if as_json:
        emit_json(result)
        return
    if not axes and rows:
        click.echo("every axis_id whose distance-control objects answer is listed: the CNC objects do not "
                   "say which axes have distance control configured (P-AXIS-00328 "
                   "lr_param.distance_control_on is not among them, FCT-M3 §9.4)")
    for r in rows + channels:
        kind = "axis" if r["kind"] == "axis" else "channel"
        click.echo(f"{kind} {r['name']} (index {r['index']}): state {r['state']}"
                   + (" (distance control active)" if r["active"] else ""))
        width = max(len(d["key"]) for d in r["details"].values())
        for f, v in r["parameters"].items():
            d = r["details"][f]
            val = r["values"].get(f)
            text = f"{v:.12g}" if isinstance(v, float) else str(v)
            line = f"  {d['key']:<{width}}  {text:>14} {d['unit']:<6} {d['id']:<13} {d['range']}"
            if not d["writable"]:
                line += "  (read-only)"
            elif val is not None and val["pending"] is not None:
                line += (f"  in effect; written {_text(val['pending'])} {val['written_at']} by distctrl; "
                         f"pending unless the CNC restarted since")
            else:
                line += "  in effect"
            click.echo(line)
    if not rows and not channels:
        click.echo("no axis or channel with distance-control objects answered")
    if any(v["pending"] is not None for r in rows + channels for v in r["values"].values()):
        click.echo(f"pending: written by distctrl from this PC (the journal {journal.path}); the CNC "
                   f"takes them at the next INACTIVE→ACTIVE or FREEZE→ACTIVE (FCT-M3 §9.4); the objects "
                   f"cannot confirm that they still wait (a CNC restart drops them): `machine write` "
                   f"writes them again")
    if out:
        click.echo(f"written: {out}")


def _text(v) -> str:
    return f"{v:.12g}" if isinstance(v, float) else str(v)


def _describe(target, unit, journal: WriteJournal) -> dict:
    """describe_unit and, for the writable values, what is in effect and what distctrl wrote pending."""
    row = describe_unit(target, unit)
    readings = {f: row["parameters"][f] for f in ORDER}
    row["values"] = journal.resolve(target, unit, readings, row["state_code"])
    row["parameters"].update({f: v["in_effect"] for f, v in row["values"].items()})   # what is in effect
    row["pending"] = {f: v["pending"] for f, v in row["values"].items() if v["pending"] is not None}
    return row


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
              help="The trace (.csv, with its .meta.json sidecar) that identify, filters --recording and plot read.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object: rows, samples, lost, late.")
def record(ads, ip, tcp_port, timeout, axis, seconds, signals, cycle_ms, max_delay_ms, mm_per_increment, out,
           as_json):
    """Record CNC objects of one axis at the CNC cycle (cyclic device notifications with the target's
    timestamps) into a trace. Lost and late samples are counted and reported; a lost sample is NaN
    in the trace, never filled in. A target that stops sending before --seconds are up makes the
    recording incomplete: said, counted, the trace written, exit code 4. Ctrl-C ends early and keeps
    what was recorded (exit code 130)."""
    unit = _parse_axis(axis)
    names = [s.strip() for s in signals.split(",") if s.strip()]
    if not names:
        fail("--signals: name at least one signal")
    check_output(out, "--out", (".csv",))
    try:
        sigs = [make_signal(n, mm_per_increment) for n in names]
        with _open(ads, ip, timeout, tcp_port) as target:
            rec = do_record(target, unit, sigs, seconds, cycle_ms * 1e-3, max_delay_ms * 1e-3)
    except MachineError as exc:
        _fail_machine(exc)
    write_trace(rec, out, {"target": ads, "axis": unit.name, "axis_id": unit.number,
                           "actual_sampled": "start"})
    s = summary(rec)
    cut = cut_message(rec) if rec.rows else None
    outcome = "interrupted" if rec.interrupted else "incomplete" if cut else "ok"
    result = {"command": "machine record", "outcome": outcome, "out": out, "columns": rec.columns, **s,
              "tracking": tracking_figures(rec)}
    if cut:
        result.update(exit_code=int(ExitCode.CHECK_FAILED), error=cut)
    if as_json:
        emit_json(result)
    else:
        lost = ", ".join(f"{k} {v}" for k, v in rec.lost.items() if v)
        click.echo(f"recorded {s['rows']} cycles ({s['seconds']:.3f} s) of {', '.join(rec.columns[1:])}: "
                   f"{s['samples']} samples, lost: {lost or 'none'}, late: {rec.late}"
                   + (" (Ctrl-C)" if rec.interrupted else ""))
        if cut:
            click.echo(f"cut off: the target stopped sending after {s['stopped_after_s']:.1f} s of "
                       f"{s['requested_s']:g} s (about {s['cut_cycles']} cycles; not counted as lost)")
        tr = result["tracking"]
        if tr is not None:
            click.echo(f"tracking: RMS {_fmt(tr['rms_mm'])} mm, max {_fmt(tr['max_abs_mm'])} mm of "
                       f"DIST_CTRL::target_deviation over {tr['activations']} activation(s) that started in "
                       f"the recording, each after its first {tr['skip_s'] * 1e3:g} ms "
                       f"({tr['cycles']} cycles)")
        click.echo(f"written: {out}")
        if s["lost_total"] or rec.late:
            click.echo("warning: lost samples are NaN in the trace (a gap, not data)", err=True)
    if rec.interrupted:
        raise SystemExit(int(ExitCode.INTERRUPTED))
    if rec.rows == 0:
        fail("no sample arrived: does the target send cyclic notifications on these objects?")
    if cut:
        fail(cut, ExitCode.CHECK_FAILED)


def _fmt(v) -> str:
    return "n/a" if v is None else f"{v:.4f}"


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
def write(ads, ip, tcp_port, timeout, axis, channel, list_file, yes, pending, backup, as_json):
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
            return Target(net_id, port, host, timeout=timeout, connect_timeout=max(timeout, 1.0),
                          tcp_port=tcp_port).open()

        journal = WriteJournal()
        with _open(ads, ip, timeout, tcp_port) as target:
            plan = plan_write(target, unit, list_file, journal)
            result = {"command": "machine write", "target": ads, "port": tcp_port, "unit": unit.label,
                      "list": list_file, "state": plan.state, "active": plan.active, "ignored": plan.ignored,
                      "unchanged": plan.unchanged,
                      "unverifiable": plan.unverifiable, "values": plan.values,
                      "yes_refused": bool(plan.active and plan.changes and not pending)}
            if not yes:
                result.update(outcome="planned", written=False, changes=[c.as_dict() for c in plan.changes])
                _show_plan(plan, result, as_json, written=False)
                return
            bpath = Path(backup) if backup else default_backup_path(list_file, unit)
            if plan.changes:
                check_writable(str(bpath), "--backup")
            done = execute(plan, target, bpath, pending=pending, reconnect=reconnect, journal=journal)
            result.update(outcome="written" if plan.changes else "unchanged", written=bool(plan.changes),
                          changes=[c.as_dict() for c in plan.changes],
                          backup=done["backup"] if plan.changes else None, pending=done["pending"],
                          values=done.get("values", plan.values))
            _show_plan(plan, result, as_json, written=True)
    except MachineError as exc:
        _fail_machine(exc)


def _show_plan(plan, result: dict, as_json: bool, written: bool) -> None:
    if as_json:
        emit_json(result)
        return
    click.echo(f"{plan.unit.label}: state {state_name(plan.state)}")
    if not plan.changes:
        click.echo("nothing to change: the target has these values in effect")
    for c in plan.changes:
        status = f"  [{c.status}]" if written else ""
        if c.again:
            was = f" (written again: the journal had it pending since {c.pending_since})"
        elif c.pending is not None:
            was = f" (written {_text(c.pending)} by distctrl {c.pending_since}, pending until now)"
        else:
            was = ""
        click.echo(f"  {c.key:<22} {_text(c.old):>14} -> {_text(c.new):<14} {c.unit:<6} ({c.object})"
                   f"{status}{was}")
    for i in plan.ignored:
        click.echo(f"  {i['key']:<22} ignored: {i['reason']}")
    for u in plan.unverifiable:
        click.echo(f"  warning: {u} cannot be read over the CNC objects: check that the CNC's parameter list "
                   f"has this value, or the machine runs the gains with another low-pass")
    if not written:
        if plan.changes and result.get("yes_refused"):
            click.echo(f"nothing written: distance control is {state_name(plan.state)}, so --yes will be "
                       f"refused (the running process would keep the old values); write when it is "
                       f"inactive, or give --yes --pending to write now and have the values wait for the next "
                       f"activation")
        elif plan.changes:
            click.echo("nothing written: add --yes to write these values (a backup of the old ones is written first)")
        return
    if plan.changes:
        click.echo(f"backup of the values in effect: {result['backup']} (restore: the same command with it "
                   f"and --yes)")
        if result["pending"]:
            click.echo(f"written, pending until the next activation of distance control (INACTIVE→ACTIVE "
                       f"or FREEZE→ACTIVE, FCT-M3 §9.4): {', '.join(result['pending'])}; the values in "
                       f"effect stay until then (`machine show` shows both)")
