"""Benchmark: issue 16's two plates with and without the cutting-process functions.

Runs examples/scenarios/plasma_plate.toml and laser_sheet.toml (tools/make_plates.py) once with their
``[[process]]`` tables and once without, and reports per run: the minimum true distance (mm), the time
below half the set distance while distance control ran (s), the collisions (count) and the path time
(s) (distctrl.sim.plates), and once with the functions but the lift (the lift's share of the path
time). Targets (issue 16): with the functions the head never comes closer than 30 % of the set
distance and never collides; the lift adds at most 5 % to the path time; without the functions the
same plate shows the dive. Writes
bench/process.json (all figures) and merges a summary into bench/results.json and a section into
bench/RESULTS.md (bench/_results.py).

    .venv/bin/python bench/bench_process.py [--out DIR] [--short]

``--short`` runs the shortened plates the tests use (a smoke test, a few seconds).
"""
from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))   # bench/, also when loaded by path

from _results import merge_results  # noqa: E402

from distctrl.sim.plates import EXAMPLES, PLATES, TARGET_LIFT_INCREASE, TARGET_MIN_SHARE, compare  # noqa: E402


def _fmt(v, digits=3):
    return "n/a" if v is None else f"{v:.{digits}f}"


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "bench")
    ap.add_argument("--short", action="store_true", help="the shortened plates (the first part of each)")
    args = ap.parse_args(argv)
    plates = [p + "_short" for p in PLATES] if args.short else list(PLATES)
    data, lines = {}, ["", "## cutting-process functions on issue 16's plates", "",
                       "| plate | functions | min true distance (cuts only) | time below ½ set | collisions | path time | "
                       "target |", "|---|---|---:|---:|---:|---:|---|"]
    all_ok = True
    for name in plates:
        t0 = time.perf_counter()
        res = compare(EXAMPLES / f"{name}.toml")
        wall = time.perf_counter() - t0
        w, wo = res["with"], res["without"]
        ok_with = w["completed"] and w["collisions"] == 0 and w["min_distance_mm"] is not None \
            and w["min_distance_mm"] >= TARGET_MIN_SHARE * w["set_distance_mm"]
        dive = wo["min_distance_mm"] is not None and wo["min_distance_mm"] < w["min_distance_mm"] and \
            (wo["collisions"] > 0 or wo["min_distance_mm"] < TARGET_MIN_SHARE * wo["set_distance_mm"])
        inc = res.get("lift_path_time_increase")
        ok_lift = inc is not None and inc <= TARGET_LIFT_INCREASE
        all_ok &= ok_with and dive and (ok_lift or "no_lift" not in res)
        data[name] = {**res, "ok_with": ok_with, "dive_without": dive, "ok_lift": ok_lift, "wall_s": round(wall, 2)}
        for label, f, verdict in ((", ".join(w["functions"]), w, "PASS" if ok_with else "FAIL"),
                                  ("none", wo, "dive shown" if dive else "NO DIVE")):
            lines.append(f"| {name} (set {f['set_distance_mm']:g} mm) | {label} | {_fmt(f['min_distance_mm'])} mm "
                         f"({_fmt(f['min_cut_distance_mm'])} mm) | "
                         f"{_fmt(f['time_below_half_s'])} s | {f['collisions']} | {_fmt(f['path_time_s'])} s | "
                         f"{verdict} |")
        if "no_lift" in res:
            nl = res["no_lift"]
            lines.append(f"| {name} (set {nl['set_distance_mm']:g} mm) | {', '.join(nl['functions'])} (no lift) | "
                         f"{_fmt(nl['min_distance_mm'])} mm ({_fmt(nl['min_cut_distance_mm'])} mm) | "
                         f"{_fmt(nl['time_below_half_s'])} s | {nl['collisions']} | "
                         f"{_fmt(nl['path_time_s'])} s | lift: {w['lifts']} rapids, path time {inc:+.1%} "
                         f"({'PASS' if ok_lift else 'FAIL'}, ≤ {TARGET_LIFT_INCREASE:.0%}) |")
        print(f"{name}: with {_fmt(w['min_distance_mm'])} mm, {w['collisions']} collisions; without "
              f"{_fmt(wo['min_distance_mm'])} mm, {wo['collisions']} collisions ({wall:.1f} s)", flush=True)
    lines += ["", f"Targets (issue 16): with the functions min true distance ≥ {TARGET_MIN_SHARE:.0%} of the set "
              "distance and no collision; without them the dive (lower minimum, and collisions or below "
              f"{TARGET_MIN_SHARE:.0%}); the lift adds ≤ {TARGET_LIFT_INCREASE:.0%} to the path time against the same "
              f"functions without it. All: {'PASS' if all_ok else 'FAIL'}. Plates: examples/scenarios/"
              "plasma_plate.toml, laser_sheet.toml (docs/process.md, \"The two plates\")."]
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "process.json").write_text(json.dumps(data, indent=2))
    summary = {f"process_{name}_{k}_{m}": data[name][k][m] for name in data for k in ("with", "without")
               for m in ("min_distance_mm", "min_cut_distance_mm", "time_below_half_s", "collisions", "path_time_s")}
    summary.update({f"process_{name}_lift_path_time_increase": data[name].get("lift_path_time_increase")
                    for name in data})
    summary["process_ok"] = all_ok
    merge_results(args.out, summary, lines)
    print("\n".join(lines[1:]))
    return data


if __name__ == "__main__":
    main()
