"""Pass rates of ``distctrl identify`` per quantity on hidden plants (issue 39).

    python bench/bench_identify_hidden.py [--n 30] [--first-seed 0] [--seconds 12] [--only steps,...]
                                          [--out bench/identify_hidden.json]

Per seed: a random plant of tests/workbench/hidden_plants.py (a generator written from scratch: a drive with
hard velocity and acceleration limits at 10 kHz, fine interpolation and feed-forward or not, a Tustin mode,
sensor delays of 0-5 cycles, quantisation, a clamped sensor range), its three recordings (raw set-position
steps of 2-45 mm and 0.2-0.5 mm, a chirp, a slow ramp) written as CSV and identified as the command line
does. Every quantity is scored against hidden_plants.TOL (decided before the first run). Writes the pass
rate per quantity and every plant's truth, estimate and warnings.
"""
from __future__ import annotations

import argparse
import json
import pathlib
import sys
import tempfile
import time
import warnings

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from distctrl.cli.blas import limit_blas_threads  # noqa: E402

limit_blas_threads()   # as the distctrl command does, before numpy is imported (distctrl/cli/blas.py)

from distctrl.workbench.identify import identify, load_signals  # noqa: E402
from tests.workbench.hidden_plants import (LIMIT_MIN_CYCLES, QUANTITIES, TOL, random_plant,  # noqa: E402
                                           score, write_recordings)


def run_one(seed: int, tmp: pathlib.Path, seconds: float = 12.0, only: tuple = ()) -> dict:
    plant = random_plant(seed)
    paths, seen = write_recordings(plant, seed, tmp, seconds=seconds, only=only)
    t0 = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sigs = [load_signals(p, command="set_pos", actual="act_pos", sensor="sensor") for p in paths]
        res = identify(sigs)
    est = {k: res.drive.get(k) for k in ("kv", "dead_time", "feedforward", "v_max", "a_max", "resonance_hz",
                                         "damping")}
    est.update({k: res.sensor.get(k) for k in ("delay", "noise_std")})
    est["feedforward_sd"] = (res.uncertainty.get("drive") or {}).get("feedforward")
    est["kv_sd"] = (res.uncertainty.get("drive") or {}).get("kv")
    return {"seed": seed, "pass": score(plant, seen, res.drive, res.sensor),
            "cpu_seconds": round(time.process_time() - t0, 3), "truth": plant.describe(), "seen": seen,
            "estimate": est, "open_loop": res.extra.get("open_loop"), "warnings": list(res.warnings)}


def rates(rows: list[dict]) -> dict:
    out = {}
    for q in QUANTITIES + ("rigid_no_mode",):
        marks = [r["pass"].get(q) for r in rows if r["pass"].get(q) is not None]
        out[q] = {"passed": sum(marks), "plants": len(marks),
                  "rate": round(sum(marks) / len(marks), 4) if marks else None}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=30)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--seconds", type=float, default=12.0)
    ap.add_argument("--only", default="",
                    help="recordings to use, comma-separated (steps, chirp, ramp; default all)")
    ap.add_argument("--out", default=str(ROOT / "bench" / "identify_hidden.json"))
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(a.first_seed, a.first_seed + a.n):
            row = run_one(seed, pathlib.Path(tmp), a.seconds, tuple(x for x in a.only.split(",") if x))
            rows.append(row)
            bad = [q for q, ok in row["pass"].items() if ok is False]
            print(f"seed {seed}: {row['cpu_seconds']:.1f} s CPU, failed: {', '.join(bad) or 'none'}",
                  flush=True)
    summary = rates(rows)
    no_ff = rates([r for r in rows if not r["truth"]["feed_forward"]])
    for q in ("kv", "v_max", "a_max"):
        summary[f"{q}_without_feed_forward"] = no_ff[q]
    # the drive's feed-forward told apart: found (ff >= 0.5) on the drives with it, 0 on those without
    marks = [(r["estimate"]["feedforward"] or 0.0) >= 0.5 if r["truth"]["feed_forward"]
             else r["estimate"]["feedforward"] == 0.0 for r in rows if r["estimate"]["kv"] is not None]
    summary["feed_forward_told_apart"] = {"passed": sum(marks), "plants": len(marks),
                                          "rate": round(sum(marks) / len(marks), 4) if marks else None}
    lag1 = [abs(r["open_loop"]["residual_lag1"]) for r in rows
            if r.get("open_loop") and r["open_loop"].get("residual_lag1") is not None]
    for q, s in summary.items():
        print(f"{q:14s} {s['passed']}/{s['plants']}  {100 * (s['rate'] or 0):.0f} %")
    doc = {"plants": a.n, "seeds": [a.first_seed, a.first_seed + a.n - 1], "seconds_per_recording": a.seconds,
           "recordings": a.only or "steps,chirp,ramp",
           "tolerances": TOL, "limit_min_cycles": LIMIT_MIN_CYCLES, "pass_rate": summary,
           "open_loop_residual_lag1_max": max(lag1) if lag1 else None,
           "cpu_seconds_median": sorted(r["cpu_seconds"] for r in rows)[len(rows) // 2], "per_plant": rows}
    pathlib.Path(a.out).write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
