"""``distctrl linuxcnc``: LinuxCNC's plasmac in closed loop on distctrl's plate (docs/linuxcnc.md)."""
from __future__ import annotations

import base64
import dataclasses
import html
import io
from pathlib import Path

import click
from rich.console import Console

from ..errors import DistCtrlError
from ..linuxcnc.bench import bench as run_bench
from ..linuxcnc.config import HAL_FILE, POSTGUI_FILE, write_config
from ..linuxcnc.hal_env import COMPONENTS, LinuxCNCError, build_component, sudo_command
from ..linuxcnc.ini import external_offset_limits, read_ini
from ..linuxcnc.thc import ThcConfig
from ..params import load_list
from .common import Finite, emit_json, fail

__all__ = ["linuxcnc", "format_text", "write_html"]


def _parse_set(values: tuple) -> dict:
    """``--set PIN=VALUE`` options as {pin: number} (an int when written without a point)."""
    out = {}
    for item in values:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            fail(f"--set {item!r}: expected PIN=VALUE (a plasmac input, e.g. --set pid-p-gain=5)")
        try:
            value = float(raw)
        except ValueError:
            fail(f"--set {item!r}: the value {raw!r} is not a number")
        if value != value or value in (float("inf"), float("-inf")):
            fail(f"--set {item!r}: the value must be finite")
        out[key.strip()] = int(value) if value.is_integer() and "." not in raw and "e" not in raw.lower() else value
    return out


def _thc_setp(list_file: str | None, set_dist: float, arc_v0: float, arc_k: float, ini_file: str | None,
              cap: bool, as_json: bool) -> None:
    if list_file is None:
        fail("linuxcnc thc-setp needs an axis parameter LIST (kernel format, e.g. examples/scenarios/z_plasma_plate.lis)")
    if not Path(list_file).is_file():
        fail(f"linuxcnc thc-setp: the axis parameter list {list_file!r} does not exist or is not a file "
             "(a .lis file, e.g. examples/scenarios/z_plasma_plate.lis)")
    warnings, notes = [], []
    try:
        cfg = ThcConfig.from_params(load_list(list_file).params, set_dist=set_dist, arc_v0=arc_v0, arc_k=arc_k)
        if ini_file is None:
            warnings.append("v-max and a-max are not checked against the machine's external-offset limits: "
                            "give --ini YOUR.ini")
        else:
            lim = external_offset_limits(read_ini(ini_file))
            pairs = (("v-max", cfg.v_max, lim.v_max), ("a-max", cfg.a_max, lim.a_max))
            over = [(k, v, m) for k, v, m in pairs if v > m]
            if over and not cap:
                fail(f"{list_file}: " + ", ".join(f"{k} {v:g}" for k, v, _ in over)
                     + f" above the external-offset limits ({lim.describe()}): lower them in the list, "
                     "or give --cap to write the limits")
            if over:
                cfg = dataclasses.replace(cfg, v_max=min(cfg.v_max, lim.v_max),
                                          a_max=min(cfg.a_max, lim.a_max))
                warnings += [f"{k} {v:g} of {list_file} capped to {m:g} (the external-offset limit, "
                             f"{lim.source})" for k, v, m in over]
            notes.append("v-max, a-max within " + lim.describe())
        lines = cfg.setp_document(0.001, list_file, notes=tuple(notes + [f"warning: {w}" for w in warnings]))
    except (LinuxCNCError, DistCtrlError) as exc:
        fail(str(exc))
    if as_json:
        emit_json({"command": "linuxcnc thc-setp", "list": list_file, "ini": ini_file, "warnings": warnings,
                   "lines": lines})
    else:
        for w in warnings:
            click.echo(f"warning: {w}", err=True)
        click.echo("\n".join(lines))


def _config(out: str | None, from_dir: str | None, ini_name: str | None, list_file: str | None, thc: str,
            laser: bool, as_json: bool) -> None:
    if out is None:
        fail("linuxcnc config needs an OUTDIR (a new directory for the configuration)")
    try:
        r = write_config(out, from_dir, ini_name=ini_name, list_file=list_file, laser=laser, thc=thc)
    except (LinuxCNCError, DistCtrlError) as exc:
        fail(str(exc))
    if as_json:
        emit_json({"command": "linuxcnc config", "out": str(r.out), "ini": str(r.ini),
                   "source": str(r.source), "hal_section_file": str(r.hal_section_file), "sim_torch": r.sim, "thc": thc,
                   "warnings": r.notes, "files": [HAL_FILE, POSTGUI_FILE]})
        return
    for n in r.notes:
        click.echo(f"warning: {n}", err=True)
    click.echo(f"wrote {r.out} from {r.source}: {HAL_FILE}, {POSTGUI_FILE}, two [HAL] lines in "
               f"{r.hal_section_file.name}"
               + (", the sim torch and the prefs' THC switches" if r.sim else ""))
    click.echo(f"start it: linuxcnc {r.ini}")
    click.echo(f"needs the components: {sudo_command()} (once)")


def _build(force: bool, as_json: bool) -> None:
    try:
        built = [build_component(name, force=force) for name in COMPONENTS]
    except LinuxCNCError as exc:
        fail(str(exc))
    if as_json:
        emit_json({"command": "linuxcnc build", "modules": [str(p) for p, _ in built],
                   "built": [str(p) for p, b in built if b],
                   "up_to_date": [str(p) for p, b in built if not b]})
    else:
        for p, b in built:
            click.echo(f"built and installed {p}" if b else
                       f"up to date: {p} (built from this very source, same SHA-256; --force rebuilds it)")


@click.command()
@click.argument("action", type=click.Choice(["bench", "build", "thc-setp", "config"]))
@click.argument("plate", required=False, metavar="[PLATE|LIST|OUTDIR]", type=click.Path())
@click.option("--set-dist", type=Finite(0.001, 100.0), default=1.5, show_default=True,
              help="thc-setp: SET_DIST, the cut height (mm).")
@click.option("--arc-v0", type=Finite(0.0, 400.0), default=95.0, show_default=True,
              help="thc-setp: the arc voltage's linearisation, V at zero height.")
@click.option("--arc-k", type=Finite(0.5, 50.0), default=6.0, show_default=True,
              help="thc-setp: the arc voltage's linearisation, V per mm.")
@click.option("--ini", "ini_file", type=click.Path(dir_okay=False), default=None,
              help="thc-setp: the machine's INI: v-max/a-max are checked against [AXIS_Z]'s external-offset "
                   "limits (MAX_VELOCITY, MAX_ACCELERATION x OFFSET_AV_RATIO) and refused above them.")
@click.option("--from", "from_dir", type=click.Path(file_okay=False), default=None,
              help="config: your QtPlasmaC configuration directory (default: Debian's installed "
                   "QtPlasmaC sim); it is read, not changed.")
@click.option("--thc", "thc", type=click.Choice(["distctrl", "plasmac"]), default="distctrl",
              show_default=True,
              help="config: plasmac = the sim baseline, plasmac's own THC on the height-dependent sim torch.")
@click.option("--laser", is_flag=True, help="config: a capacitive laser height control (not built yet).")
@click.option("--list", "list_file", type=click.Path(dir_okay=False), default=None,
              help="config: distctrl_thc's Z parameter list (default: the QtPlasmaC template).")
@click.option("--cap", is_flag=True,
              help="thc-setp with --ini: write the limits instead of refusing (with a warning).")
@click.option("--force", is_flag=True,
              help="build: rebuild even if the installed module is from the same source.")
@click.option("--repeat", default=1, show_default=True, type=click.IntRange(1, 50),
              help="Run every contestant N times and report the spread.")
@click.option("--set", "settings", multiple=True, metavar="PIN=VALUE",
              help="Override one of plasmac's settings (its input pin without 'plasmac.'), e.g. pid-p-gain=5.")
@click.option("--max-time", type=Finite(0.1, 3600.0), default=None,
              help="Stop a plasmac run after this many seconds of machine time (default: the plate's duration).")
@click.option("--html", "html_dir", type=click.Path(file_okay=False), default=None,
              help="Write an HTML report with plots into this directory (index.html).")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object (bench: plate, runs [{controller, functions, min_distance_mm, ...}]).")
def linuxcnc(action: str, plate: str | None, set_dist: float, arc_v0: float, arc_k: float,
             ini_file: str | None, from_dir: str | None, thc: str, laser: bool, list_file: str | None, cap: bool,
             force: bool, repeat: int, settings: tuple, max_time: float | None, html_dir: str | None,
             as_json: bool) -> None:
    """LinuxCNC's plasmac (halrun) in closed loop on distctrl's PLATE, side by side with distctrl and its HAL component.

    \b
    distctrl linuxcnc bench PLATE.toml   plasmac, distctrl_thc in halrun and distctrl, locks on and off
    distctrl linuxcnc build              build and install the HAL components (halcompile)
    distctrl linuxcnc thc-setp LIST.lis --ini MACHINE.ini   distctrl_thc's setp lines (named, commented)
    distctrl linuxcnc config OUTDIR [--from CONFIGDIR]  a QtPlasmaC configuration with distctrl_thc

    The bench refuses to run while LinuxCNC or another HAL runs on this PC: it never touches a HAL it
    did not start. Do not run it beside a machine controller.
    """
    if action == "build":
        _build(force, as_json)
        return
    if action == "thc-setp":
        _thc_setp(plate, set_dist, arc_v0, arc_k, ini_file, cap, as_json)
        return
    if action == "config":
        _config(plate, from_dir, ini_file, list_file, thc, laser, as_json)
        return
    if plate is None:
        fail("linuxcnc bench needs a PLATE (a plate scenario, e.g. examples/scenarios/plasma_plate_short.toml)")
    if not Path(plate).is_file():
        fail(f"linuxcnc bench: the plate scenario {plate!r} does not exist or is not a file (a .toml plate, "
             "e.g. examples/scenarios/plasma_plate_short.toml)")
    _bench(plate, repeat, settings, max_time, html_dir, as_json)


def _bench(plate: str, repeat: int, settings: tuple, max_time: float | None, html_dir: str | None,
           as_json: bool) -> None:
    overrides = _parse_set(settings)
    console = Console(stderr=True, quiet=as_json)
    try:
        doc = run_bench(plate, repeat=repeat, overrides=overrides, max_time=max_time,
                        progress=lambda msg: console.print(f"[dim]{msg}[/dim]"))
    except (LinuxCNCError, DistCtrlError) as exc:
        fail(str(exc))
    if html_dir is not None:
        doc["html"] = str(write_html(doc, html_dir))
    for r in doc["runs"]:
        r.pop("trace", None)
    if as_json:
        emit_json(doc)
    else:
        click.echo(format_text(doc))


def _fmt(v, digits=2) -> str:
    return "n/a" if v is None else f"{v:.{digits}f}" if isinstance(v, float) else str(v)


def _rows(doc: dict) -> list[list[str]]:
    rows = []
    for r in doc["runs"]:
        sp = r.get("spread", {})
        d = r["dives"]
        md = sp.get("min_distance_mm", {})
        rows.append([r["controller"], ", ".join(r["functions"]) or "-",
                     _fmt(r["min_distance_mm"]) + (f" ±{md['spread'] / 2:.2f}" if md.get("spread") else ""),
                     _fmt(r["time_below_half_s"], 3), str(r["collisions"]),
                     f"{d['corner']}/{d['hole_kerf']}/{d['other']}", "yes" if r.get("completed") else "no",
                     str(r["late_periods"]), str(r["missed_periods"])])
    return rows


_HEAD = ["controller", "functions", "min distance on metal (mm)", "time below half (s)", "collisions",
         "dives corner/hole-kerf/other", "completed", "late periods", "missed periods"]


def format_text(doc: dict) -> str:
    """The bench's table as text (one line per contestant)."""
    lines = [f"{doc['scenario']}: cut height {doc['cut_height_mm']:g} mm at {doc['cut_feed_mm_min']:g} mm/min, "
             f"{doc['repeat']} run(s) each, plasmac lock-step at {doc['servo_period_s'] * 1000:g} ms"]
    rows = [_HEAD] + _rows(doc)
    widths = [max(len(r[i]) for r in rows) for i in range(len(_HEAD))]
    for n, r in enumerate(rows):
        lines.append("  ".join(c.ljust(w) for c, w in zip(r, widths)))
        if n == 0:
            lines.append("  ".join("-" * w for w in widths))
    for r in doc["runs"]:
        if r.get("note"):
            lines.append(f"note ({r['controller']}): {r['note']}")
        for w in r.get("warnings", []):
            lines.append(f"warning ({r['controller']}): {w}")
    return "\n".join(lines)


def write_html(doc: dict, out_dir: str | Path) -> Path:
    """index.html: the table and, per run in halrun (plasmac, distctrl-hal), the nozzle's height over the surface and the arc voltage."""
    # matplotlib (the [sim] extra) costs about a second of import: loaded only for --html
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # after use("Agg"): no display needed

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    imgs = []
    for r in doc["runs"]:
        t = r.get("trace")
        if not t or not t["rows"]:
            continue
        cols = {c: [row[i] for row in t["rows"]] for i, c in enumerate(t["columns"])}
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 5), sharex=True)
        dist = [z - s if s > -5 + min(cols["surface"]) else float("nan")
                for z, s in zip(cols["z_nozzle"], cols["surface"])]
        a1.plot(cols["t"], dist, lw=0.8, label="nozzle over the surface (mm)")
        a1.axhline(doc["cut_height_mm"], color="g", lw=0.6, ls="--", label="cut height")
        a1.axhline(0.5 * doc["cut_height_mm"], color="r", lw=0.6, ls=":", label="half the cut height")
        a1.set_ylim(-1, 20)
        a1.legend(loc="upper right", fontsize=7)
        a2.plot(cols["t"], cols["arc_voltage"], lw=0.6, label="arc voltage (V)")
        a2.plot(cols["t"], [40 * v for v in cols["cornerlock_is_locked"]], lw=0.6, label="corner lock (40 = locked)")
        a2.plot(cols["t"], [60 * v for v in cols["voidlock_is_locked"]], lw=0.6, label="void lock (60 = locked)")
        a2.set_xlabel("t (s)")
        a2.legend(loc="upper right", fontsize=7)
        fig.suptitle(f"{r['controller']}, {', '.join(r['functions']) or 'no corner/void lock'}", fontsize=9)
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=90)
        plt.close(fig)
        imgs.append(base64.b64encode(buf.getvalue()).decode())
    head = "".join(f"<th>{html.escape(h)}</th>" for h in _HEAD)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in _rows(doc))
    pics = "".join(f'<p><img alt="run in halrun" src="data:image/png;base64,{b}"></p>' for b in imgs)
    page = (f"<!doctype html><html><head><meta charset='utf-8'><title>distctrl linuxcnc bench</title></head><body>"
            f"<h1>{html.escape(doc['scenario'])}</h1><p>plasmac (LinuxCNC, halrun, lock-step at "
            f"{doc['servo_period_s'] * 1000:g} ms) and distctrl on the same plate; {doc['repeat']} run(s) each.</p>"
            f"<table border='1'><tr>{head}</tr>{body}</table>{pics}</body></html>")
    path = out / "index.html"
    path.write_text(page, encoding="utf-8")
    return path
