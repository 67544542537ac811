"""The demo job: part programs with distance control on the virtual machine.

* a laser head in CONST_DIST 1 mm above a sheet with waviness, a thickness step and the 2.8 mm
  obstacle of FCT-M3 §4, at 6 m/min (examples/scenarios/const_dist_sheet.toml), run with both
  encoders (P-AXIS-00500, as in the documents' example list) and without;
* the documents' SET_POS example %DIST_1 (examples/scenarios/dist_1.toml);
* issue 16's plasma plate (examples/scenarios/plasma_plate.toml) with and without the cutting-process
  functions (touch-off, corner lock, void lock, lift; docs/process.md "The two plates").

Prints summary tables and writes traces and plots to ``out/demo/``.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import click
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from ..sim import run
from ..sim.plates import TARGET_MIN_SHARE, compare
from ..sim.scenario import load_scenario
from .common import check_writable, emit_json

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def plain_const_dist_scenario():
    """The sheet scenario with P-AXIS-00500 switched off: the documents' warning example, a loop that
    oscillates into the sheet (a limit cycle; docs/run.md "Collisions", docs/margins.md)."""
    sc = load_scenario(EXAMPLES / "const_dist_sheet.toml")
    z = sc.axes["Z"]
    axes = dict(sc.axes)
    axes["Z"] = dataclasses.replace(z, params=z.params.replace(use_both_encoders=False))
    return dataclasses.replace(sc, axes=axes, name=sc.name + " (plain CONST_DIST)")


def probe_footnote(label: str, result, scenario) -> str | None:
    """One line that says why a run's true distance went below 0 mm without a collision: its tool is a
    tactile probe riding on the sheet, pressed into its stroke (the scenario's ``sensor.collision_depth``);
    a contact counts only beyond it (docs/run.md "Collisions"). ``None`` when that is not the case."""
    m = result.metrics
    depth = scenario.sensor.collision_depth if scenario.sensor is not None else 0.0
    low = m["min_distance_mm"]
    if not depth or low is None or low >= 0.0 or m["collisions"]:
        return None
    return (f"{label}: min true distance {low:.3f} mm with 0 collisions: the tool is a tactile probe riding "
            f"on the sheet, its tip pressed {-low * 1000:.0f} µm into its {depth:g} mm stroke (at or below "
            f"0 mm for {m['time_below_zero_s']:.2f} s); a collision counts only beyond −{depth:g} mm "
            f"(the scenario's sensor.collision_depth, docs/run.md \"Collisions\").")


def _mm(value, digits: int) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}"


def main(out_dir: str | Path = "out/demo", plate: str | None = "plasma_plate", as_json: bool = False) -> list:
    """Run the demo and print its tables (``as_json``: print nothing but one JSON object with the
    tables' figures, :func:`figures`); returns the three runs' results."""
    console = Console(quiet=True) if as_json else Console()
    results, plate_res = run_demo(out_dir, plate, console, progress=not as_json)
    if as_json:
        emit_json(figures(results, plate_res, out_dir, plate))
    return [r for _, _, r in results]


def figures(results: list, plate_res: dict | None, out_dir: str | Path, plate: str | None) -> dict:
    """``distctrl demo --json``: the figures the demo's tables print, per run and for the plate."""
    out = Path(out_dir)
    runs = [{"label": label, "scenario": r.name, "outcome": r.outcome, "exit_code": r.exit_code,
             "metrics": r.metrics, "errors": r.errors, "warnings": r.warnings,
             "trace": str(out / f"{stem}.csv"), "plot": str(out / f"{stem}.png"),
             "report": str(out / f"{stem}_report" / "index.html")} for label, stem, r in results]
    doc = {"command": "demo", "out_dir": str(out), "runs": runs, "plate": None}
    if plate_res is not None:
        keys = ("functions", "min_distance_mm", "min_cut_distance_mm", "time_below_half_s", "collisions",
                "path_time_s", "set_distance_mm", "completed", "errors", "lifts")
        doc["plate"] = {"scenario": plate, "with": {k: plate_res["with"].get(k) for k in keys},
                        "without": {k: plate_res["without"].get(k) for k in keys},
                        "lift_path_time_increase": plate_res.get("lift_path_time_increase")}
    return doc


def run_demo(out_dir: str | Path, plate: str | None, console, progress: bool = True) -> tuple[list, dict | None]:
    """The demo's runs and tables on ``console``: ``([(label, stem, result), ...], plate figures or None)``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cases = [("CONST_DIST 1 mm, both encoders", "sheet", load_scenario(EXAMPLES / "const_dist_sheet.toml")),
             ("CONST_DIST 1 mm, plain (WARNING EXAMPLE)", "sheet_plain", plain_const_dist_scenario()),
             ("SET_POS 30 mm (%DIST_1)", "dist_1", load_scenario(EXAMPLES / "dist_1.toml"))]
    from ..workbench.report import write_report  # jinja2: loaded only when a report is written

    results, footnotes = [], []
    for label, stem, sc in cases:
        console.print(f"running {label} ...")
        r = run(sc, trace=out / f"{stem}.csv", progress=progress)
        r.plot(out / f"{stem}.png")
        write_report(r, sc, out / f"{stem}_report")
        results.append((label, stem, r))
        footnotes.append(probe_footnote(label, r, sc))
    # one column per run (the table fits an 80-column terminal)
    table = Table(title="distctrl demo — distance control on the virtual machine")
    table.add_column("")
    for label, _, _ in results:
        table.add_column(escape(label))
    rows = {"outcome": [], "distance error RMS [mm]": [], "max |error| [mm]": [], "settle time": [],
            "oscillation (last 1 s)": [], "min true distance [mm]": [], "collisions": [], "errors / warnings": []}
    for _, _, r in results:
        m = r.metrics
        ids = [e["id"] for e in r.errors + r.warnings]
        hits = m["collisions"]
        for key, text in zip(rows, (
                r.outcome_text, _mm(m["distance_error_rms"], 4), _mm(m["distance_error_max"], 3),
                "never" if m["settle_time"] is None else f"{m['settle_time']:.3f} s",
                "none" if m["oscillation_frequency_hz"] is None else
                f"{m['oscillation_frequency_hz']:.1f} Hz, ±{m['oscillation_amplitude_mm']:.2f} mm",
                _mm(m["min_distance_mm"], 3), f"[bold red]{hits}[/]" if hits else "0",
                escape(", ".join(f"{i}×{ids.count(i)}" if ids.count(i) > 1 else str(i)
                                 for i in dict.fromkeys(ids)) or "none"))):
            rows[key].append(text)
    for key, cells in rows.items():
        table.add_row(escape(key), *cells)
    console.print(table)
    for note in filter(None, footnotes):
        console.print(escape(note))
    console.print(escape(
        "Both encoders (P-AXIS-00500): the one collision is the obstacle's vertical 2.8 mm wall at X = 250 mm, "
        "which a head at 1 mm cannot clear at 6 m/min (the max error is that edge). Plain CONST_DIST is the "
        "documents' warning example: without both encoders the loop oscillates into the sheet (a limit "
        "cycle; its oscillation and collisions are shown: warnings 900032 and 900030). "
        f"Traces, plots and HTML reports: {out}/ (open {out}/sheet_report/index.html)"))
    plate_res = plate_table(console, plate) if plate is not None else None
    return results, plate_res


def plate_table(console, plate: str = "plasma_plate") -> dict:
    """Run the plasma plate (``plate``: a scenario stem in examples/scenarios/, the tests take the
    shortened one) with and without its process functions and print the figures, with units."""
    console.print("running the plasma plate (issue 16) with and without the cutting-process functions ...")
    sc = load_scenario(EXAMPLES / f"{plate}.toml")
    res = compare(sc)
    w, wo = res["with"], res["without"]
    table = Table(title=escape(sc.name))
    table.add_column("")
    table.add_column(escape("with " + ", ".join(w["functions"])))
    table.add_column("without")
    for label, key, fmt in (("min. true distance", "min_distance_mm", "{:.3f} mm"),
                            ("… while cutting (G1)", "min_cut_distance_mm", "{:.3f} mm"),
                            ("time below ½ the set distance in force", "time_below_half_s", "{:.3f} s"),
                            ("collisions", "collisions", "{}"), ("path time", "path_time_s", "{:.3f} s")):
        cells = []
        for f in (w, wo):
            v = f[key]
            text = "n/a" if v is None else fmt.format(v)
            if key == "collisions" and v:
                text = f"[bold red]{v}[/]"
            cells.append(text)
        table.add_row(escape(label), *cells)
    table.add_row("SET_DIST", f"{w['set_distance_mm']:g} mm", f"{wo['set_distance_mm']:g} mm")
    console.print(table)
    inc = res.get("lift_path_time_increase")
    console.print(escape(
        f"Target with the functions: at least {TARGET_MIN_SHARE:.0%} of SET_DIST "
        f"({TARGET_MIN_SHARE * w['set_distance_mm']:.2f} mm) and no collision; "
        + (f"the lift over {w['lifts']} rapids changes the path time by {inc:+.1%} (target ≤ +5 %). "
           if inc is not None else "")
        + "The whole run's minimum includes the touch-off's probe (down to 0.5 mm). "
        "Without them the torch dives at the corners (the arc voltage rises as the path slows), into "
        "the kerfs and holes, and the warp brings the plate up to it. Simulated figures: docs/process.md, "
        "\"The two plates\"."))
    return res


@click.command("demo")
@click.option("--out", "out_dir", default="out/demo", show_default=True, type=click.Path(file_okay=False),
              help="The folder the traces, plots and reports are written to.")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object with the tables' figures (per run: outcome, metrics, events, files; "
                   "the plate with and without its functions) instead of the tables.")
def demo_cmd(out_dir: str, as_json: bool) -> None:
    """Run the demo job: CONST_DIST and SET_POS over an uneven sheet, and the plasma plate with and
    without the cutting-process functions, with summary tables.
    Traces, plots and reports: --out (out/demo/)."""
    check_writable(out_dir, "output folder (--out)", directory=True)      # before the runs, in one line
    main(out_dir, as_json=as_json)
