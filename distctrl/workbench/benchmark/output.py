"""The benchmark's outputs of a :class:`~.run.BenchmarkResult` (``result``): the CSV of every run, one plot
per plate (its headline figure against the feed, every contestant, one panel per process / sensor /
drive), the HTML report (the workbench's report page and macros, :mod:`distctrl.workbench.pages`) and the
text summary.
"""
from __future__ import annotations

import base64
import csv
import math
from io import BytesIO
from pathlib import Path

from ..pages import render
from .metrics import FIGURE_UNITS, FIGURES
from .suite import PLATE_NAMES

__all__ = ["HEADLINE", "write_csv", "write_plots", "write_report", "text_summary", "CSV_COLUMNS"]

#: per plate: the figure its plot shows against the feed, and how it is read
HEADLINE = {
    "flat": ("steady_sd_mm", "steady sd of the distance error [mm]"),
    "ramp_2deg": ("steady_mean_mm", "|steady mean error| [mm]"),
    "ramp_5deg": ("steady_mean_mm", "|steady mean error| [mm]"),
    "wavy": ("steady_sd_mm", "steady sd of the distance error [mm]"),
    "edge": ("void_excursion_mm", "Z excursion into the void [mm]"),
    "holes": ("void_excursion_mm", "Z excursion into the holes [mm]"),
    "kerfs": ("void_excursion_mm", "Z excursion into the kerfs [mm]"),
    "corners": ("min_feature_distance_mm", "least distance at the corners [mm]"),
    "warp": ("steady_max_mm", "steady max |error| [mm]"),
}
CSV_COLUMNS = ("plate", "process", "sensor", "feedforward", "feed_m_min", "contestant", "outcome",
               "errors") + FIGURES
#: the figures of the report's per-plate table, in its column order (before collisions, time below half)
_TABLE_FIGURES = ("steady_mean_mm", "steady_sd_mm", "steady_max_mm", "drive_lag_mm", "void_excursion_mm",
                  "min_feature_distance_mm", "approach_undershoot_mm", "approach_time_s")
_STYLE = {"distctrl_examples": ("C0", "o", "-"), "distctrl_examples_pf": ("C2", "s", "--"),
          "simple_pid": ("C3", "^", ":")}


def write_csv(result, path) -> None:
    """One line per run; a figure that does not apply is empty."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(CSV_COLUMNS)
        for r in result.rows:
            vals = []
            for c in CSV_COLUMNS:
                v = r.get(c)
                if c == "errors":
                    v = ";".join(str(e["id"]) for e in v) if v else ""
                elif v is None or (isinstance(v, float) and not math.isfinite(v)):
                    v = ""
                vals.append(v)
            w.writerow(vals)


def _panels(rows) -> list[tuple]:
    keys = sorted({(r["process"], r["sensor"], r["feedforward"]) for r in rows},
                  key=lambda k: (k[0] != "laser", k[1], k[2]))
    return keys


def plot_plate(result, plate: str):
    """The figure of one plate (matplotlib, Agg): its headline figure against the feed, per panel."""
    # matplotlib only while a figure is drawn (a --json run without plots does not load it)
    from matplotlib.figure import Figure

    rows = [r for r in result.rows if r["plate"] == plate]
    key, label = HEADLINE[plate]
    panels = _panels(rows)
    fig = Figure(figsize=(3.6 * max(1, len(panels)), 3.4), layout="constrained")
    axes = fig.subplots(1, max(1, len(panels)), squeeze=False)[0]
    for ax, (process, sensor, ff) in zip(axes, panels):
        sel = [r for r in rows if (r["process"], r["sensor"], r["feedforward"]) == (process, sensor, ff)]
        for c in sorted({r["contestant"] for r in sel}):
            pts = sorted((r["feed_m_min"], r[key]) for r in sel
                         if r["contestant"] == c and r[key] is not None)
            if not pts:
                continue
            colour, marker, ls = _STYLE.get(c, ("k", "x", "-"))
            ys = [abs(v) if key == "steady_mean_mm" else v for _, v in pts]
            ax.plot([f for f, _ in pts], ys, marker=marker, ls=ls, color=colour, label=c)
        if key == "steady_mean_mm":      # the drive's lag alone, v tan(a) (1 - ff) / kv
            lag = sorted((r["feed_m_min"], abs(r["drive_lag_mm"])) for r in sel
                         if r["contestant"] == "distctrl_examples" and r["drive_lag_mm"] is not None)
            if lag and ff < 1.0:
                ax.plot([f for f, _ in lag], [v for _, v in lag], color="0.5", lw=1, ls="-.",
                        label="drive lag v·tan/kv")
        ax.set_title(f"{process} {sensor}, ff {ff:g}", fontsize=9)
        ax.set_xlabel("feed [m/min]")
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel(label, fontsize=9)
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{plate}: {label} against feed", fontsize=10)
    return fig


def write_plots(result, out_dir) -> dict:
    """``<plate>.png`` per plate of the result in ``out_dir``; returns plate -> path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {}
    for plate in _plates(result):
        fig = plot_plate(result, plate)
        path = out / f"{plate}.png"
        fig.savefig(path, dpi=90)
        paths[plate] = str(path)
    return paths


def _plates(result) -> list[str]:
    present = {r["plate"] for r in result.rows}
    return [p for p in PLATE_NAMES if p in present]


def _fmt(v, digits=4):
    if v is None:
        return "–"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def _met(m) -> str:
    return "not measured" if m is None else ("met" if m else "NOT met")


def write_report(result, out_dir) -> str:
    """The HTML report (``out_dir/index.html``): contestants, the reproduction check, the goals, per
    plate its plot and its table."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plates = []
    for plate in _plates(result):
        fig = plot_plate(result, plate)
        buf = BytesIO()
        fig.savefig(buf, format="png", dpi=80)
        key, label = HEADLINE[plate]
        rows = [(r["process"], r["sensor"], r["feedforward"], r["feed_m_min"], r["contestant"], r["outcome"],
                 *(_fmt(r[k]) for k in _TABLE_FIGURES),
                 r["collisions"], _fmt(r["time_below_half_s"]))
                for r in result.rows if r["plate"] == plate]
        plates.append({"name": plate, "label": label, "b64": base64.b64encode(buf.getvalue()).decode("ascii"),
                       "rows": rows})
    check = [(i["feedforward"], i["issue_41_mm"], _fmt(i["measured_mm"]), _fmt(i["drive_lag_mm"]),
              _met(i["ok"])) for i in result.check.get("items", [])]
    goals = [(g["goal"], _fmt(g["value"]), g["unit"], _fmt(g["limit"]), _met(g["met"]), g["where"] or "–")
             for g in result.goal_rows]
    contestants = [(c["name"], "yes" if c["run"] else "no", c["what"] or c["why_not"])
                   for c in result.contestants()]
    html = render("benchmark_report.html.j2", title="distctrl benchmark: height error against feed",
                  subtitle=f"{'quick suite' if result.quick else 'full suite'}, {len(result.rows)} runs, "
                           f"cycle {result.params.cycle_time * 1000:g} ms, drive kv {result.params.kv:g} 1/s",
                  nav=[("contestants", "Contestants"), ("check", "Check"), ("goals", "Goals")]
                  + [(p["name"], p["name"]) for p in plates],
                  contestants=contestants, check=check, check_what=result.check.get("what", ""), goals=goals,
                  plates=plates, units=FIGURE_UNITS)
    path = out / "index.html"
    path.write_text(html, encoding="utf-8")
    return str(path)


def text_summary(result) -> str:
    """The console summary: per plate the headline figure per contestant and feed, the check, the goals."""
    lines = [f"distctrl benchmark ({'quick' if result.quick else 'full'} suite): {len(result.rows)} runs, "
             f"{result.mode}, {result.workers} worker(s)"]
    for c in result.contestants():
        lines.append(f"  contestant {c['name']}: " + (c["what"] if c["run"] else f"not run ({c['why_not']})"))
    for plate in _plates(result):
        key, label = HEADLINE[plate]
        lines.append(f"{plate}: {label}")
        rows = [r for r in result.rows if r["plate"] == plate]
        for process, sensor, ff in _panels(rows):
            sel = [r for r in rows if (r["process"], r["sensor"], r["feedforward"]) == (process, sensor, ff)]
            feeds = sorted({r["feed_m_min"] for r in sel})
            lines.append(f"  {process} {sensor} ff {ff:g}   feed [m/min]: "
                         + " ".join(f"{f:>7g}" for f in feeds))
            for c in sorted({r["contestant"] for r in sel}):
                vals = []
                for f in feeds:
                    r = next((r for r in sel if r["contestant"] == c and r["feed_m_min"] == f), None)
                    v = None if r is None else r[key]
                    vals.append(f"{_fmt(abs(v) if key == 'steady_mean_mm' and v is not None else v, 3):>7}")
                lines.append(f"    {c:<22}" + " ".join(vals))
    lines.append("check: " + result.check.get("what", ""))
    for i in result.check.get("items", []):
        lines.append(f"  ff {i['feedforward']:g}: issue 41 {i['issue_41_mm']} mm, "
                     f"measured {_fmt(i['measured_mm'])} mm "
                     f"(drive lag {_fmt(i['drive_lag_mm'])} mm): {_met(i['ok'])}")
    lines.append("issue 41's goals (distctrl with the examples' list; 'distctrl tuned' is not run yet):")
    for g in result.goal_rows:
        lines.append(f"  {g['goal']}: {_fmt(g['value'])} {g['unit']} "
                     f"(limit {_fmt(g['limit'])}): {_met(g['met'])}"
                     + (f" [worst: {g['where']}]" if g["where"] else ""))
    return "\n".join(lines) + "\n"
