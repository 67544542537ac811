"""The demo job: part programs with distance control on the virtual machine.

* a laser head in CONST_DIST 1 mm above a sheet with waviness, a thickness step and the 2.8 mm
  obstacle of FCT-M3 §4, at 6 m/min (examples/scenarios/const_dist_sheet.toml), run with both
  encoders (P-AXIS-00500, as in the documents' example list) and without;
* the documents' SET_POS example %DIST_1 (examples/scenarios/dist_1.toml).

Prints a summary table and writes traces and plots to ``out/demo/``.
"""
from __future__ import annotations

from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "scenarios"


def _plain_const_dist():
    """The sheet scenario with P-AXIS-00500 switched off (the loop that can overshoot)."""
    import dataclasses

    from .sim.scenario import load_scenario

    sc = load_scenario(EXAMPLES / "const_dist_sheet.toml")
    z = sc.axes["Z"]
    axes = dict(sc.axes)
    axes["Z"] = dataclasses.replace(z, params=z.params.replace(use_both_encoders=False))
    return dataclasses.replace(sc, axes=axes, name=sc.name + " (plain CONST_DIST)")


def main(out_dir: str | Path = "out/demo") -> list:
    from rich.console import Console
    from rich.table import Table

    from .sim import run
    from .sim.scenario import load_scenario

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    console = Console()
    cases = [("CONST_DIST 1 mm, both encoders", "sheet", load_scenario(EXAMPLES / "const_dist_sheet.toml")),
             ("CONST_DIST 1 mm, plain", "sheet_plain", _plain_const_dist()),
             ("SET_POS 30 mm (%DIST_1)", "dist_1", load_scenario(EXAMPLES / "dist_1.toml"))]
    from .workbench.report import write_report

    results = []
    for label, stem, sc in cases:
        console.print(f"running {label} ...")
        r = run(sc, trace=out / f"{stem}.csv", progress=True)
        r.plot(out / f"{stem}.png")
        write_report(r, sc, out / f"{stem}_report")
        results.append((label, stem, r))
    table = Table(title="distctrl demo — distance control on the virtual machine")
    for col in ("run", "cycles", "completed", "distance error RMS [mm]", "max |error| [mm]", "settle [s]",
                "errors / warnings"):
        table.add_column(col)
    for label, stem, r in results:
        m = r.metrics
        settle = "-" if m["settle_time"] is None else f"{m['settle_time']:.3f}"
        events = ", ".join(str(e["id"]) for e in r.errors + r.warnings) or "none"
        table.add_row(label, str(r.cycles), "yes" if r.completed else "NO", f"{m['distance_error_rms']:.4f}",
                      f"{m['distance_error_max']:.3f}", settle, events)
    console.print(table)
    console.print("The max error is the 2.8 mm obstacle edge itself (a vertical step under a moving head). "
                  f"Traces, plots and HTML reports: {out}/ (open {out}/sheet_report/index.html)")
    return [r for _, _, r in results]
