"""Benchmark of the cycle core: one CPython ``update()``, the numba-compiled law, and a peer.

Run with ``make bench`` (or ``.venv/bin/python bench/bench_core.py``); writes bench/results.json
and bench/RESULTS.md (overwritten each run). ``--profile`` additionally prints a cProfile of
``update()``; ``--quick`` shrinks every measurement (for a smoke test). See bench/README.md.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import gc
import json
import math
import os
import platform
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))        # run from a checkout without installing

import numpy as np  # noqa: E402

from distctrl.control import (Action, AxisDistanceController, Command, CycleInput, CycleOutput,  # noqa: E402
                              FilterType, Result, law)
from distctrl.control.filters import FilterConfig, design_coefficients  # noqa: E402
from distctrl.params import AxisParameters  # noqa: E402

T = 0.001                 # GEO cycle time, s
PROG = 40.0               # programmed Z, mm
SET_POS = 40.0            # SET_POS, mm
TARGETS = {               # what the project promises (see bench/README.md)
    "cpython_update_median_us": 5.0,
    "cpython_update_p99_us": 20.0,
    "numba_ns_per_cycle": 50.0,
}


def bench_params() -> AxisParameters:
    """KALMAN_MA (n 20, sigma 1000), PID kp 0.5 / i_tn 0.5 s / d_tv 0.01 s, default limits."""
    return AxisParameters(enabled=True, filter_type=FilterType.KALMAN_MA, n_cycles=20, kalman_sigma=1000.0,
                          kp=0.5, i_tn=0.5, d_tv=0.01,
                          optimized_scheduling=True,
                          max_act_value_change=1000.0,           # 1 µm/cycle noise must not trip 70329
                          encoder_resolution_num=1, encoder_resolution_denom=10000)   # 1 mm / increment


def bench_surface(n: int, seed: int = 1) -> np.ndarray:
    """A 2 Hz, ±0.5 mm wave (6.3 mm/s peak > v_max 5 mm/s: the limiter clips) plus 2 µm noise."""
    k = np.arange(n)
    rng = np.random.default_rng(seed)
    return SET_POS + 0.5 * np.sin(2 * np.pi * 2.0 * k * T) + rng.normal(0.0, 0.002, n)


def _stats_ns(samples) -> dict:
    a = np.asarray(samples, dtype=np.float64)
    return {"n": int(a.size), "median_ns": float(np.median(a)), "p99_ns": float(np.percentile(a, 99)),
            "mean_ns": float(a.mean()), "min_ns": float(a.min()), "max_ns": float(a.max())}


def timer_overhead_ns(n: int = 100_000) -> float:
    pc = time.perf_counter_ns
    d = [0] * n
    for i in range(n):
        t0 = pc()
        t1 = pc()
        d[i] = t1 - t0
    return float(np.median(d))


# ----------------------------------------------------------------------------- CPython update()

def bench_cpython_update(n_cycles: int, warmup: int) -> tuple[dict, np.ndarray, np.ndarray]:
    """Time every update() individually in the closed loop (ideal drive, noisy surface)."""
    params = bench_params()
    ctrl = AxisDistanceController(params, T)
    surface = bench_surface(warmup + n_cycles).tolist()
    inp, out = CycleInput(programmed_position=PROG), CycleOutput()
    inp.commands.append(Command(Action.ON, set_pos=SET_POS))
    times = [0] * n_cycles
    offsets = [0.0] * (warmup + n_cycles)
    velocities = [0.0] * (warmup + n_cycles)
    not_ok = 0
    act = PROG
    pc = time.perf_counter_ns
    update = ctrl.update
    for k in range(warmup + n_cycles):
        inp.actual_position = act
        inp.sensor_increments = surface[k] - act
        t0 = pc()
        r = update(inp, out)
        t1 = pc()
        if k >= warmup:
            times[k - warmup] = t1 - t0
        if r != Result.OK:
            not_ok += 1
        act = out.command_position
        offsets[k] = out.offset
        velocities[k] = out.offset_velocity
    st = _stats_ns(times)
    v = np.asarray(velocities)
    st["cycles_not_ok"] = not_ok
    st["final_hli_state"] = int(out.hli_state)
    st["cycles_at_v_max"] = int(np.sum(np.abs(v) >= params.v_max * (1 - 1e-9)))
    st["cycles_at_a_max"] = int(np.sum(np.abs(np.diff(v)) >= params.a_max_effective * T * (1 - 1e-9)))
    return st, np.asarray(offsets), np.asarray(surface)


def profile_update(n_cycles: int = 50_000) -> str:
    """cProfile of update() in the benchmark loop; the text of the top entries."""
    import cProfile
    import io
    import pstats

    params = bench_params()
    ctrl = AxisDistanceController(params, T)
    surface = bench_surface(n_cycles).tolist()
    inp, out = CycleInput(programmed_position=PROG), CycleOutput()
    inp.commands.append(Command(Action.ON, set_pos=SET_POS))
    act = PROG
    prof = cProfile.Profile()
    prof.enable()
    for k in range(n_cycles):
        inp.actual_position = act
        inp.sensor_increments = surface[k] - act
        ctrl.update(inp, out)
        act = out.command_position
    prof.disable()
    buf = io.StringIO()
    pstats.Stats(prof, stream=buf).sort_stats("tottime").print_stats(20)
    return buf.getvalue()


# ----------------------------------------------------------------------------- law.filter_step from CPython

def bench_filter_step(n: int) -> float:
    """ns of one CPython law.filter_step (KALMAN_MA n 20), best of 7 rounds, to show registering
    with numba does not change the CPython path."""
    fc = design_coefficients(FilterConfig(FilterType.KALMAN_MA, 20, 0.7, 1000.0), T)
    fs, buf = [0.0] * law.FS_LEN, [0.0] * law.MAX_N
    law.filter_seed(fc, fs, buf, 40.0)
    xs = bench_surface(n).tolist()
    step = law.filter_step
    pc = time.perf_counter_ns
    rounds = []
    for _ in range(7):
        t0 = pc()
        for x in xs:
            step(fc, fs, buf, x)
        rounds.append((pc() - t0) / n)
    return float(min(rounds))


# ----------------------------------------------------------------------------- numba

def bench_numba(n_cycles: int, repeats: int, ref_surface: np.ndarray, ref_offsets: np.ndarray) -> dict:
    t0 = time.perf_counter()
    from distctrl.batch import kernel as K
    import_s = time.perf_counter() - t0
    params = bench_params()
    fc, prm = K.pack_params(params, T, SET_POS, PROG)
    t0 = time.perf_counter()
    K.run_setpos_loop(fc, prm, ref_surface[:10], 10)
    K.run_setpos_loop_into(fc, prm, ref_surface[:10], np.empty(10), np.empty(10))
    compile_s = time.perf_counter() - t0
    # the compiled law must be the law: same offsets as the CPython run above
    o_check, _ = K.run_setpos_loop(fc, prm, ref_surface, len(ref_surface))
    max_diff = float(np.max(np.abs(o_check - ref_offsets)))

    surface = bench_surface(n_cycles, seed=2)
    # the loop itself: outputs owned by the caller, pages already touched
    out_o, out_v = np.zeros(n_cycles), np.zeros(n_cycles)
    K.run_setpos_loop_into(fc, prm, surface[:10], out_o[:10], out_v[:10])
    per_cycle = []
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        K.run_setpos_loop_into(fc, prm, surface, out_o, out_v)
        per_cycle.append((time.perf_counter_ns() - t0) / n_cycles)
    # the convenience call: allocates 2 x n_cycles float64 (fresh pages) each call
    alloc = []
    for _ in range(max(2, repeats // 2)):
        t0 = time.perf_counter_ns()
        K.run_setpos_loop(fc, prm, surface, n_cycles)
        alloc.append((time.perf_counter_ns() - t0) / n_cycles)

    # batch: many parameter sets in parallel (informative, no target)
    n_sets, n_batch = 64, max(1000, n_cycles // 100)
    kps = np.linspace(0.2, 1.0, n_sets)
    packed = [K.pack_params(params.replace(kp=float(kp)), T, SET_POS, PROG) for kp in kps]
    fc2 = np.stack([a for a, _ in packed])
    prm2 = np.stack([b for _, b in packed])
    sb = surface[:n_batch]
    t0 = time.perf_counter()
    K.run_setpos_batch(fc2, prm2, sb[:10], 10)
    batch_compile_s = time.perf_counter() - t0
    batch = []
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        K.run_setpos_batch(fc2, prm2, sb, n_batch)
        batch.append((time.perf_counter_ns() - t0) / (n_sets * n_batch))
    import numba

    return {"n_cycles": n_cycles, "repeats": repeats, "ns_per_cycle_median": float(statistics.median(per_cycle)),
            "ns_per_cycle_min": float(min(per_cycle)), "ns_per_cycle_all": per_cycle,
            "alloc_ns_per_cycle_median": float(statistics.median(alloc)),
            "import_s": import_s, "compile_s": compile_s, "max_abs_diff_vs_cpython_mm": max_diff,
            "checked_cycles": int(len(ref_surface)),
            "batch_sets": n_sets, "batch_cycles": n_batch, "batch_compile_s": batch_compile_s,
            "batch_ns_per_set_cycle_median": float(statistics.median(batch)),
            "numba_threads": int(numba.get_num_threads())}


# ----------------------------------------------------------------------------- simple-pid peer

def bench_simple_pid(n: int, warmup: int) -> dict:
    from simple_pid import PID

    pid = PID(1.0, 0.1, 0.05, setpoint=1.0, sample_time=None)
    for _ in range(warmup):
        pid(0.5)
    pc = time.perf_counter_ns
    times = [0] * n
    for i in range(n):
        t0 = pc()
        pid(0.5)
        t1 = pc()
        times[i] = t1 - t0
    return _stats_ns(times)


# ----------------------------------------------------------------------------- report

def _versions() -> dict:
    import importlib.metadata as md

    def ver(name):
        try:
            return md.version(name)
        except md.PackageNotFoundError:
            return None

    return {"python": platform.python_version(), "implementation": platform.python_implementation(),
            "numba": ver("numba"), "numpy": ver("numpy"), "simple_pid": ver("simple-pid"),
            "distctrl": ver("distctrl")}


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sizes (smoke test, figures not meaningful)")
    ap.add_argument("--profile", action="store_true", help="also print a cProfile of update()")
    ap.add_argument("--out", type=Path, default=HERE, help="directory for results.json / RESULTS.md")
    args = ap.parse_args(argv)
    n_cpy, warm, n_nb, reps, n_pid = (200_000, 20_000, 10_000_000, 5, 200_000) if not args.quick else \
        (5_000, 500, 100_000, 2, 5_000)
    started = time.perf_counter()
    load_before = os.getloadavg() if hasattr(os, "getloadavg") else None

    overhead = timer_overhead_ns()
    # CPython first: numba must not be imported yet (also the baseline of law.filter_step)
    assert "numba" not in sys.modules
    cpy, ref_offsets, ref_surface = bench_cpython_update(n_cpy, warm)
    fstep_before = bench_filter_step(20_000 if not args.quick else 2_000)
    pid = bench_simple_pid(n_pid, 10_000 if not args.quick else 500)
    try:
        nb = bench_numba(n_nb, reps, ref_surface, ref_offsets)
        nb_error = None
    except ImportError as exc:
        nb, nb_error = None, str(exc)
    fstep_after = bench_filter_step(20_000 if not args.quick else 2_000)
    profile_text = profile_update() if args.profile else None
    total_s = time.perf_counter() - started

    rows = [
        ("CPython update() median", cpy["median_ns"] / 1e3, "µs", TARGETS["cpython_update_median_us"]),
        ("CPython update() p99", cpy["p99_ns"] / 1e3, "µs", TARGETS["cpython_update_p99_us"]),
        ("CPython update() mean", cpy["mean_ns"] / 1e3, "µs", None),
        ("numba closed loop per cycle (median)", nb["ns_per_cycle_median"] if nb else float("nan"), "ns",
         TARGETS["numba_ns_per_cycle"]),
        ("numba incl. output allocation (median)", nb["alloc_ns_per_cycle_median"] if nb else float("nan"),
         "ns", None),
        ("numba batch, 64 sets, per set-cycle", nb["batch_ns_per_set_cycle_median"] if nb else float("nan"),
         "ns", None),
        ("simple_pid PID.__call__ median (peer)", pid["median_ns"] / 1e3, "µs", None),
        ("simple_pid PID.__call__ p99 (peer)", pid["p99_ns"] / 1e3, "µs", None),
        ("law.filter_step CPython, before numba (best)", fstep_before / 1e3, "µs", None),
        ("law.filter_step CPython, after numba (best)", fstep_after / 1e3, "µs", None),
    ]
    table = []
    for name, value, unit, target in rows:
        if target is None:
            verdict = "-"
        elif not math.isfinite(value):
            verdict = "FAIL"
        else:
            verdict = "PASS" if value <= target else "FAIL"
        table.append({"name": name, "value": value, "unit": unit, "target": target, "verdict": verdict})

    env = {"date": _dt.datetime.now().astimezone().isoformat(timespec="seconds"), **_versions(),
           "cpu_count": os.cpu_count(), "cpu": _cpu_model(), "platform": platform.platform(),
           "loadavg_before": load_before,
           "loadavg_after": os.getloadavg() if hasattr(os, "getloadavg") else None,
           "timer_overhead_ns": overhead, "quick": args.quick, "total_s": total_s}
    results = {"env": env, "targets": TARGETS, "table": table, "cpython_update": cpy, "numba": nb,
               "numba_error": nb_error, "simple_pid": pid,
               "law_filter_step_cpython_ns": {"before_numba_import": fstep_before,
                                              "after_numba_import": fstep_after}}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "results.json").write_text(json.dumps(results, indent=2) + "\n")
    md = _markdown(results)
    (args.out / "RESULTS.md").write_text(md)

    print(_text_table(table, env))
    if nb:
        print(f"numba: import {nb['import_s']:.1f} s, compile {nb['compile_s']:.1f} s (batch "
              f"{nb['batch_compile_s']:.1f} s); max |offset - CPython| over {nb['checked_cycles']} cycles: "
              f"{nb['max_abs_diff_vs_cpython_mm']:.3g} mm")
    else:
        print(f"numba: not available ({nb_error})")
    print(f"closed loop: {cpy['cycles_at_v_max']} cycles at v_max, {cpy['cycles_at_a_max']} at a_max, "
          f"{cpy['cycles_not_ok']} cycles not OK; timer overhead {overhead:.0f} ns (included)")
    print(f"written: {args.out / 'results.json'}, {args.out / 'RESULTS.md'} ({total_s:.0f} s)")
    if profile_text:
        print(profile_text)
    return 0


def _text_table(table, env) -> str:
    lines = [f"distctrl bench  {env['date']}  Python {env['python']}  numba {env['numba']}  "
             f"{env['cpu_count']} CPUs ({env['cpu']})  load {env['loadavg_before']}",
             f"{'measurement':46s} {'value':>10s} {'unit':4s} {'target':>8s}  result"]
    for r in table:
        target = f"<= {r['target']:g}" if r["target"] is not None else ""
        lines.append(f"{r['name']:46s} {r['value']:10.3f} {r['unit']:4s} {target:>8s}  {r['verdict']}")
    return "\n".join(lines)


def _markdown(res) -> str:
    env, cpy, nb, pid = res["env"], res["cpython_update"], res["numba"], res["simple_pid"]
    out = ["# Benchmark results", "",
           "Generated by `make bench` (bench/bench_core.py); overwritten on every run. See bench/README.md.", "",
           f"- date: {env['date']}",
           f"- Python {env['python']} ({env['implementation']}), numba {env['numba']}, numpy {env['numpy']}, "
           f"simple-pid {env['simple_pid']}",
           f"- CPU: {env['cpu_count']} × {env['cpu']}; {env['platform']}",
           f"- load average before / after: {env['loadavg_before']} / {env['loadavg_after']}",
           f"- perf_counter_ns overhead (included in per-call figures): {env['timer_overhead_ns']:.0f} ns",
           f"- whole run: {env['total_s']:.0f} s" + (" (--quick: figures not meaningful)" if env["quick"] else ""),
           "", "| measurement | value | unit | target | result |", "|---|---:|---|---:|---|"]
    for r in res["table"]:
        target = f"≤ {r['target']:g}" if r["target"] is not None else ""
        out.append(f"| {r['name']} | {r['value']:.3f} | {r['unit']} | {target} | {r['verdict']} |")
    out += ["", "## Details", "",
            f"- CPython `AxisDistanceController.update()`: {cpy['n']} calls timed one by one after "
            f"a warm-up; KALMAN_MA (n 20, sigma 1000), kp 0.5, i_tn 0.5 s, d_tv 0.01 s, ACTIVE SET_POS, "
            f"ideal drive, 2 Hz ±0.5 mm surface + 2 µm noise; {cpy['cycles_at_v_max']} cycles at v_max, "
            f"{cpy['cycles_at_a_max']} at a_max; min {cpy['min_ns'] / 1e3:.2f} µs, max {cpy['max_ns'] / 1e3:.1f} µs; "
            f"{cpy['cycles_not_ok']} cycles not OK."]
    if nb:
        out.append(f"- numba `run_setpos_loop_into`: same law, same scenario, {nb['n_cycles']:,} cycles per call "
                   f"into preallocated outputs, median of {nb['repeats']} calls "
                   f"(min {nb['ns_per_cycle_min']:.1f} ns); `run_setpos_loop`, which allocates its two "
                   f"output arrays per call: {nb['alloc_ns_per_cycle_median']:.1f} ns. Import "
                   f"{nb['import_s']:.1f} s, first-call compile {nb['compile_s']:.1f} s. Offsets equal the "
                   f"CPython run to {nb['max_abs_diff_vs_cpython_mm']:.3g} mm over {nb['checked_cycles']:,} cycles.")
        out.append(f"- numba `run_setpos_batch`: {nb['batch_sets']} parameter sets × {nb['batch_cycles']:,} "
                   f"cycles, prange over {nb['numba_threads']} threads: "
                   f"{nb['batch_ns_per_set_cycle_median']:.1f} ns per set and cycle.")
    else:
        out.append(f"- numba: not available ({res['numba_error']})")
    out.append(f"- peer: `simple_pid.PID(1.0, 0.1, 0.05, setpoint=1.0, sample_time=None)(0.5)`, {pid['n']} calls "
               f"timed one by one: median {pid['median_ns'] / 1e3:.3f} µs, p99 {pid['p99_ns'] / 1e3:.3f} µs. "
               "It is a bare PID (no filter, limiter, states or monitoring): a floor for a Python call "
               "doing PID arithmetic, not a like-for-like competitor.")
    fb = res["law_filter_step_cpython_ns"]
    out.append(f"- `law.filter_step` called from CPython before / after the numba kernel registered it: "
               f"{fb['before_numba_import']:.0f} / {fb['after_numba_import']:.0f} ns per call "
               "(register_jitable hands back the plain function).")
    out.append("")
    return "\n".join(out)


if __name__ == "__main__":
    gc.collect()
    raise SystemExit(main())
