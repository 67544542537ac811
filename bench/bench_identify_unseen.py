"""Pass rates of ``distctrl identify`` on random plants it was not designed around (issue 26).

    python bench/bench_identify_unseen.py [--n 30] [--first-seed 0] [--out bench/identify_unseen.json]

Per seed: a random plant and its three recordings (steps, chirp 1-150 Hz 0.05 mm, slow ramp; 10-20 s
each) from tests/workbench/unseen_plants.py (its own integration, not distctrl.sim), written as CSV,
loaded and identified with ``--surface``; every quantity is scored against the tolerances of issue
26. Writes the per-quantity pass rates, the time per identification and every plant's truth and
estimate to bench/identify_unseen.json.
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

from distctrl.workbench.identify import identify, load_signals  # noqa: E402
from tests.workbench.unseen_plants import TOL, random_plant, score, write_recordings  # noqa: E402

QUANTITIES = ("kv", "dead_time", "resonance_hz", "damping", "delay", "noise_std", "characteristic")


def run_one(seed: int, tmp: pathlib.Path) -> dict:
    plant = random_plant(seed)
    paths = write_recordings(plant, seed, tmp, prefix=f"{seed}_")
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sigs = [load_signals(p, command="set_pos", actual="act_pos", sensor="sensor") for p in paths]
        res = identify(sigs, surface=plant.surface)
    elapsed = time.perf_counter() - t0
    ok = score(plant, res.drive, res.sensor)
    est = {k: res.drive.get(k) for k in ("kv", "dead_time", "v_max", "a_max", "resonance_hz", "damping")}
    est.update({k: res.sensor.get(k) for k in ("delay", "noise_std")})
    truth = plant.describe()
    return {"seed": seed, "pass": ok, "seconds": round(elapsed, 3), "estimate": est,
            "truth": {k: truth[k] for k in ("kv", "dead_time", "v_max", "a_max", "resonance_hz", "damping", "delay",
                                            "noise_std", "shape")},
            "uncertainty": getattr(res, "uncertainty", None), "warnings": list(res.warnings)}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=30)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--out", default=str(ROOT / "bench" / "identify_unseen.json"))
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for seed in range(args.first_seed, args.first_seed + args.n):
            r = run_one(seed, pathlib.Path(d))
            rows.append(r)
            bad = [k for k, v in r["pass"].items() if not v]
            print(f"seed {seed:3d}: {r['seconds']:5.2f} s  {'all ok' if not bad else 'FAIL ' + ', '.join(bad)}",
                  flush=True)
    rates = {q: sum(r["pass"][q] for r in rows) / len(rows) for q in QUANTITIES}
    # how honest the uncertainties are: |error| / standard deviation per quantity (median, 90th pct)
    ratios = {}
    for q in ("kv", "dead_time", "resonance_hz", "damping", "delay", "noise_std"):
        group = "sensor" if q in ("delay", "noise_std") else "drive"
        vals = []
        for r in rows:
            sd = ((r.get("uncertainty") or {}).get(group) or {}).get(q)
            est = r["estimate"].get(q)
            if sd and est is not None:
                vals.append(abs(est - r["truth"][q]) / sd)
        if vals:
            vals.sort()
            ratios[q] = {"median": round(vals[len(vals) // 2], 2), "p90": round(vals[int(0.9 * (len(vals) - 1))], 2)}
    out = {"plants": len(rows), "seeds": [args.first_seed, args.first_seed + args.n - 1], "tolerances": TOL,
           "pass_rate": {k: round(v, 3) for k, v in rates.items()},
           "error_over_sd": ratios,
           "all_within": round(sum(all(r["pass"].values()) for r in rows) / len(rows), 3),
           "seconds_max": max(r["seconds"] for r in rows),
           "seconds_median": sorted(r["seconds"] for r in rows)[len(rows) // 2], "per_plant": rows}
    pathlib.Path(args.out).write_text(json.dumps(out, indent=1, default=str) + "\n", encoding="utf-8")
    print("pass rates: " + ", ".join(f"{k} {100 * v:.0f} %" for k, v in rates.items()))
    print(f"all quantities within tolerance: {100 * out['all_within']:.0f} % of {len(rows)} plants; "
          f"identify {out['seconds_median']:.2f} s median, {out['seconds_max']:.2f} s max")
    return out


if __name__ == "__main__":
    main()
