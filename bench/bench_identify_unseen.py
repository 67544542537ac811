"""Pass rates of ``distctrl identify`` on random plants it was not designed around (issue 26).

    python bench/bench_identify_unseen.py [--n 30] [--first-seed 0] [--out bench/identify_unseen.json]
    python bench/bench_identify_unseen.py --tune [--budget 40] [--n 30] [--out bench/tune_unseen.json]
    python bench/bench_identify_unseen.py --recheck [--out bench/tune_unseen.json]

Per seed: a random plant and its three recordings (steps, chirp 1-150 Hz 0.05 mm, slow ramp; 10-20 s
each) from tests/workbench/unseen_plants.py (its own integration, not distctrl.sim), written as CSV,
loaded and identified with ``--surface``; every quantity is scored against the tolerances of issue
26. Writes the per-quantity pass rates, the time per identification and every plant's truth and
estimate to bench/identify_unseen.json.

``--tune`` (issue 26, "tuning stays safe on the fitted plant"): per seed ``distctrl identify --out`` writes
the fitted twin, ``distctrl tune`` (``--budget``, local, no robustness re-runs) tunes it, and the tuned
list goes into the TRUE plant (the fitted scenario with the generator's own figures,
``unseen_plants.true_scenario_text``), whose margins ``distctrl margins`` computes (``analyse``). Passes
when the true plant's loop is stable with gain margin > 1 and phase margin > 0 (``-`` where a margin
does not exist counts as met). Writes the pass rate and every plant's margins.
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
from tests.workbench.unseen_plants import (TOL, random_plant, score, true_scenario_text,  # noqa: E402
                                            write_recordings)

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


def margins_ok(m: dict) -> bool:
    """Stable, gain margin > 1 and phase margin > 0 (a margin that does not exist is met)."""
    return bool(m.get("stable")) and (m.get("gain_margin") is None or m["gain_margin"] > 1.0) \
        and (m.get("phase_margin_deg") is None or m["phase_margin_deg"] > 0.0)


def _fitted_twin(seed: int, folder: pathlib.Path):
    """The unseen plant of ``seed``, its recordings in ``folder`` and ``distctrl identify --out folder/fitted``:
    ``(plant, folder, fitted folder, None)``, or the command's last output as the 4th item where it failed."""
    from click.testing import CliRunner

    from distctrl.cli import main as cli_main

    plant = random_plant(seed)
    folder.mkdir()
    files = write_recordings(plant, seed, folder)
    fitted = folder / "fitted"
    r = CliRunner().invoke(cli_main, ["identify", *map(str, files), "--command", "set_pos", "--actual", "act_pos",
                                      "--sensor", "sensor", "--surface", str(plant.surface), "--out", str(fitted)])
    return plant, folder, fitted, (r.output[-400:] if r.exit_code != 0 else None)


def tune_one(seed: int, tmp: pathlib.Path, budget: int) -> dict:
    """identify -> fitted twin -> tune -> the tuned list's margins on the true plant."""
    import shutil
    import tomllib

    from distctrl.tuning.tune import tune
    from distctrl.workbench.margins import analyse, loop_model

    plant, folder, fitted, error = _fitted_twin(seed, tmp / f"t{seed}")
    if error is not None:
        return {"seed": seed, "pass": False, "error": error}
    scenario = fitted / "fitted.toml"
    doc = tomllib.loads(scenario.read_text())
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = tune(str(scenario), budget=budget, mode="local", robustness=False)
    seconds = time.perf_counter() - t0
    (fitted / doc["axes"]["Z"]["params"]).write_text(res.param_list)
    true = fitted / "true.toml"
    true.write_text(true_scenario_text(plant, scenario.read_text()))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = analyse(loop_model(str(true))).to_dict()
    keep = ("stable", "gain_margin", "phase_margin_deg", "gain_crossover_hz", "phase_crossover_hz", "kp_limit")
    shutil.rmtree(folder, ignore_errors=True)
    return {"seed": seed, "pass": margins_ok(m), "true_plant": {k: m.get(k) for k in keep},
            "twin": {k: res.stability.get(k) for k in keep}, "tuned": res.tuned_values(),
            "tuned_cost": float(res.best_metrics["cost"]), "tuned_rms": float(res.best_metrics["rms_error"]),
            "tune_seconds": round(seconds, 2), "binding": getattr(res, "binding", None),
            "plant": {k: getattr(plant, k) for k in ("resonance_hz", "damping", "kv", "dead_cycles", "delay")}}


def recheck_one(row: dict, tmp: pathlib.Path) -> dict:
    """The margins of a row's tuned settings (``row["tuned"]``, as tune wrote them) on the true plant,
    recomputed with the current ``distctrl margins`` (identify --out again for the fitted scenario; tune is
    not rerun: its margin constraint evaluates the loop on its own)."""
    import shutil

    from distctrl.sim.scenario import load_scenario
    from distctrl.tuning.tune import param_list
    from distctrl.workbench.margins import analyse, loop_model

    seed = int(row["seed"])
    plant, folder, fitted, error = _fitted_twin(seed, tmp / f"r{seed}")
    if error is not None:
        return dict(row, error=error, **{"pass": False})
    scenario = fitted / "fitted.toml"
    sc = load_scenario(str(scenario))
    params = sc.axes["Z"].params.replace(**row["tuned"])
    (fitted / "z_axis.lis").write_text(param_list(params))
    true = fitted / "true.toml"
    true.write_text(true_scenario_text(plant, scenario.read_text()))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = analyse(loop_model(str(true))).to_dict()
    keep = ("stable", "gain_margin", "phase_margin_deg", "gain_crossover_hz", "phase_crossover_hz", "kp_limit")
    shutil.rmtree(folder, ignore_errors=True)
    out = dict(row)
    out["true_plant_before_margins_fix"] = row.get("true_plant")
    out["true_plant"] = {k: m.get(k) for k in keep}
    out["pass"] = margins_ok(m)
    return out


def main_recheck(args) -> dict:
    """``--recheck``: the stored tuned settings of ``--out``'s ``after`` block, margins recomputed."""
    path = pathlib.Path(args.out)
    doc = json.loads(path.read_text(encoding="utf-8"))
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for row in doc["after"]["per_plant"]:
            r = recheck_one(row, pathlib.Path(d))
            rows.append(r)
            tp, old = r.get("true_plant") or {}, r.get("true_plant_before_margins_fix") or {}
            print(f"seed {r['seed']:3d}: {'ok  ' if r['pass'] else 'FAIL'} gm {tp.get('gain_margin')} "
                  f"pm {tp.get('phase_margin_deg')} (before: gm {old.get('gain_margin')} pm "
                  f"{old.get('phase_margin_deg')})", flush=True)
    after = dict(doc["after"], per_plant=rows, pass_rate=round(sum(r["pass"] for r in rows) / len(rows), 3),
                 failed_seeds=[r["seed"] for r in rows if not r["pass"]],
                 margins_recheck="true-plant margins recomputed with distctrl margins evaluated factor by factor "
                                 "(the low-pass by its sections; before: the multiplied-out polynomials, e.g. "
                                 "seed 217 gain margin 2.6e9 and no phase margin); tuned settings unchanged")
    doc["after"] = after
    path.write_text(json.dumps(doc, indent=1, default=str) + "\n", encoding="utf-8")
    print(f"true plant stable with positive margins: {100 * after['pass_rate']:.0f} % of {len(rows)} plants "
          f"(failed: {after['failed_seeds']})")
    return doc


def main_tune(args) -> dict:
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for seed in range(args.first_seed, args.first_seed + args.n):
            r = tune_one(seed, pathlib.Path(d), args.budget)
            rows.append(r)
            tp = r.get("true_plant") or {}
            print(f"seed {seed:3d}: {'ok  ' if r['pass'] else 'FAIL'} true plant gm {tp.get('gain_margin')} "
                  f"pm {tp.get('phase_margin_deg')} tuned {r.get('tuned')}", flush=True)
    out = {"plants": len(rows), "seeds": [args.first_seed, args.first_seed + args.n - 1], "budget": args.budget,
           "pass_rate": round(sum(r["pass"] for r in rows) / len(rows), 3),
           "failed_seeds": [r["seed"] for r in rows if not r["pass"]], "per_plant": rows}
    pathlib.Path(args.out).write_text(json.dumps(out, indent=1, default=str) + "\n", encoding="utf-8")
    print(f"tuned on the fitted twin, margins positive on the true plant: {100 * out['pass_rate']:.0f} % of "
          f"{len(rows)} plants (failed: {out['failed_seeds']})")
    return out


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=30)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--out", default=None)
    ap.add_argument("--tune", action="store_true", help="the tune stage instead of the identification scores")
    ap.add_argument("--budget", type=int, default=40)
    ap.add_argument("--recheck", action="store_true",
                    help="recompute the true-plant margins of the tuned settings stored in --out (no tuning)")
    args = ap.parse_args(argv)
    if args.recheck:
        args.out = args.out or str(ROOT / "bench" / "tune_unseen.json")
        return main_recheck(args)
    if args.tune:
        args.out = args.out or str(ROOT / "bench" / "tune_unseen.json")
        return main_tune(args)
    args.out = args.out or str(ROOT / "bench" / "identify_unseen.json")
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
