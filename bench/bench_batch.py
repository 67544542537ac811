"""Benchmark: the numba closed-loop batch kernel beside its C reference (gcc -O2) and its SIMD anchor.

Targets (issue): >= 100 M parameter-set-cycles per second per core for the full closed loop with a
MOVING_AVERAGE filter; the numba kernel within 1.5x of the C reference per core; a 10 000-set x
10 000-cycle sweep in under a minute on this 2-core machine; the scaling from 1 to 2 workers is
reported.

``run_batch`` runs MOVING_AVERAGE sets in vectorised blocks (distctrl.batch.soa); the bench also
times it with ``vectorised=False`` (one set after the other through closed_loop), which is the C
reference's structure.

The C reference is bench/batch_c/closed_loop.c: the loop of distctrl.batch.closed_loop.closed_loop
with the law inlined by hand, operation for operation (MOVING_AVERAGE; SET_POS and CONST_DIST). It
is compiled here with ``gcc -O2 -fno-fast-math -ffp-contract=off`` into bench/batch_c/build/ and
called through ctypes with the very arrays the kernel gets; the benchmark first checks that both
give the same offsets and distances (max |difference|, normally exactly 0).

The SIMD anchor (issue 27) is bench/batch_c/closed_loop_simd.c: the same law (it includes
closed_loop.c's functions) across 8 sets at once on a structure-of-arrays layout, each step a loop over
the sets that ``gcc -O3 -march=native`` vectorises (no fast math, no contraction: bit for bit equal,
checked here and in tests/batch/test_c_simd.py). Target: numba within 1.5x of it per core.

Results are merged into bench/results.json (keys ``batch_*``) and appended to bench/RESULTS.md
(own section), as bench_run.py does. ``--quick``: small sizes, a smoke test.
"""
from __future__ import annotations

import argparse
import ctypes
import os
import pathlib
import shutil
import subprocess
import sys
import threading
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))   # bench/, also when loaded by path
from _results import merge_results  # noqa: E402

C_SOURCE = ROOT / "bench" / "batch_c" / "closed_loop.c"
BUILD_DIR = ROOT / "bench" / "batch_c" / "build"
#: the issue's compiler setting; no contraction / fast math so the numbers equal numba's
CFLAGS = ("-O2", "-fno-fast-math", "-ffp-contract=off")
#: the SIMD anchor (issue 27): the same law across sets, vectorised by gcc; no contraction / fast math, so
#: bit for bit equal too (-fno-math-errno: sqrt and floor as vector instructions, correctly rounded either way;
#: -fno-trapping-math: gcc may compute both sides of a select, as the lane loops need; no value changes)
C_SIMD_SOURCE = ROOT / "bench" / "batch_c" / "closed_loop_simd.c"
CFLAGS_SIMD = ("-O3", "-march=native", "-fno-fast-math", "-ffp-contract=off", "-fno-math-errno", "-fno-trapping-math")
SCENARIO = ROOT / "examples" / "scenarios" / "const_dist_sheet.toml"
N_CYCLES = 10_000
TARGET_RATE = 100e6            # set-cycles / s per core
TARGET_RATE_RESONANT = 50e6    # the same with the drive's mechanical resonance (issue 15)
TARGET_RATIO = 1.5             # numba time / C time
TARGET_SWEEP_S = 60.0          # 10 000 x 10 000


# ----------------------------------------------------------------------------- the C reference

def build_c(out_dir: pathlib.Path = BUILD_DIR, flags=CFLAGS, name: str = "libclosed_loop.so",
            source: pathlib.Path = C_SOURCE) -> pathlib.Path:
    """Compile the C reference (or ``source``: the SIMD anchor) into a shared library in ``out_dir``; the
    path of the library."""
    cc = shutil.which("gcc")
    if cc is None:
        raise RuntimeError("gcc not found: the C reference needs it")
    out_dir.mkdir(parents=True, exist_ok=True)
    lib = out_dir / name
    subprocess.run([cc, *flags, "-Wall", "-shared", "-fPIC", "-o", str(lib), str(source), "-lm"],
                   check=True, capture_output=True, text=True)
    return lib


class CReference:
    """The compiled C loop, called with the kernel's arrays (ctypes releases the GIL)."""

    def __init__(self, lib_path, entry: str = "closed_loop_batch"):
        from distctrl.batch import closed_loop as CL
        from distctrl.control import law
        from distctrl.errors import ErrorId

        self.lib = ctypes.CDLL(str(lib_path))
        p, i64 = ctypes.c_void_p, ctypes.c_int64
        self.entry = getattr(self.lib, entry)         # closed_loop_batch, or closed_loop_simd_batch
        self.entry.argtypes = [i64, i64, p, p, p, p, p, i64, p, p, p, p]
        self.entry.restype = None
        layout = np.zeros(5, dtype=np.int64)
        self.lib.closed_loop_layout(layout.ctypes.data_as(p))
        want = [law.FC_LEN, CL.Q_LEN, CL.PL_LEN, law.MAX_N, CL.PACKED_LEN]
        if layout.tolist() != want:
            raise RuntimeError(f"closed_loop.c layout {layout.tolist()} != the kernel's {want}: "
                               "update the C code")
        self.err_ids = np.array([ErrorId.SENSOR_JUMP, ErrorId.SENSOR_RUN_OUT_MAX, ErrorId.SENSOR_RUN_OUT_MIN,
                                 ErrorId.MAX_DEVIATION, ErrorId.SW_LIMIT], dtype=np.int64)

    def run(self, inputs, packed, cycles: int | None = None, threads: int = 1, out=None):
        """``(offset, distance, errors)`` like ``run_batch(..., return_errors=True)``; ``threads``
        OS threads, each running a contiguous block of sets. errors[i, 0] == -2: the set's filter is
        not MOVING_AVERAGE (not in the C reference). ``out``: (offset, distance) C-contiguous arrays
        to write into, as for run_batch."""
        packed = np.ascontiguousarray(packed, dtype=np.float64)
        n = inputs.n_cycles if cycles is None else int(cycles)
        n_sets = packed.shape[0]
        if out is None:
            off = np.empty((n_sets, n))
            dist = np.empty((n_sets, n))
        else:
            off, dist = out
            assert off.shape == dist.shape == (n_sets, n) and off.flags.c_contiguous and dist.flags.c_contiguous
        err = np.empty((n_sets, 2), dtype=np.int64)
        arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in
                  (inputs.plant, inputs.prog, inputs.surface, inputs.noise)]
        ptr = [a.ctypes.data for a in (packed, *arrays)]
        outs = [off.ctypes.data, dist.ctypes.data, err.ctypes.data, self.err_ids.ctypes.data]

        def block(first, count):
            self.entry(first, count, *ptr, n, *outs)

        bounds = np.linspace(0, n_sets, max(1, threads) + 1).astype(int)
        if threads <= 1:
            block(0, n_sets)
        else:
            ts = [threading.Thread(target=block, args=(int(a), int(b - a)))
                  for a, b in zip(bounds, bounds[1:])]
            for t in ts:
                t.start()
            for t in ts:
                t.join()
        return off, dist, err


# ----------------------------------------------------------------------------- scenario and sets

#: the point distance sensor in place of the probe (issue 15: what distctrl identify writes), with a
#: characteristic (reported vs true mm) and the probe's noise and dead time
DISTANCE_SENSOR = ('[sensor]\naxis = "Z"\nkind = "distance"\nvariable = "SENSOR"\nrange_max = 10.0\n'
                   'characteristic = [[0.0, -0.01], [0.5, 0.51], [1.0, 1.03], [2.0, 2.09], [4.0, 4.2], '
                   '[7.6, 7.97], [10.0, 10.55]]\n')


def scenario(seconds: float = 12.0, resonant: bool = False, distance: bool = False):
    """const_dist_sheet.toml (CONST_DIST 1 mm, both encoders, probe with 2 µm noise and a 1-cycle
    dead time, sine + step + obstacle surface) with a straight program long enough for ``seconds``;
    ``resonant``: the Z drive with a 40 Hz, zeta 0.05 mechanical resonance (issue 15); ``distance``:
    the point distance sensor with a characteristic (:data:`DISTANCE_SENSOR`, SENSOR_SOURCE=VARIABLE)."""
    from distctrl.sim.scenario import scenario_from_text

    length = 100.0 * seconds                      # F6000 = 100 mm/s
    text = SCENARIO.read_text()
    if resonant:
        text = text.replace("a_max = 20000.0\n", "a_max = 20000.0\nresonance_hz = 40.0\ndamping = 0.05\n", 1)
    source = ""
    if distance:
        text = text.replace('[sensor]\naxis = "Z"\nkind = "encoder"\n', DISTANCE_SENSOR, 1)
        source = " SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR"
    text = text.replace(
        'program = "const_dist_sheet.nc"',
        'program_text = """\nN10 G90 G0 X0 Y0 Z31\nN20 Z[DIST_CTRL ON CONST_DIST SET_DIST=1' + source + ']\n'
        f'N30 G1 X{length:g} F6000\nN40 Z[DIST_CTRL OFF]\nN60 M30\n"""').replace(
        "duration = 10.0", f"duration = {seconds + 5:g}")
    return scenario_from_text(text, base_dir=SCENARIO.parent, source="bench")


def param_sets(inputs, n_sets: int, seed: int = 1):
    """``n_sets`` packed MOVING_AVERAGE sets: n_cycles 2 ... 30 (packed once each), kp 0.2 ... 1.5 and
    d_tv 0 ... 4 ms drawn per set and written into the plain columns (as docs/batch.md shows)."""
    from distctrl.batch import closed_loop as CL
    from distctrl.control import FilterType, law

    base = inputs.params.replace(filter_type=FilterType.MOVING_AVERAGE)
    ns = list(range(2, 31))
    by_n = CL.pack_sets(inputs, [base.replace(n_cycles=n) for n in ns])
    rng = np.random.default_rng(seed)
    packed = by_n[rng.integers(0, len(ns), n_sets)]
    packed[:, law.FC_LEN + CL.Q_KP] = rng.uniform(0.2, 1.5, n_sets)
    d_tv = rng.uniform(0.0, 0.004, n_sets)                                  # s
    packed[:, law.FC_LEN + CL.Q_D_GAIN] = [law.derivative_gain(kp, tv, inputs.cycle_time)
                                           for kp, tv in zip(packed[:, law.FC_LEN + CL.Q_KP], d_tv)]
    return packed


# ----------------------------------------------------------------------------- measurements

def best_of(fn, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def dask_sweep_scaling(inputs, n_sets: int, chunk: int) -> dict:
    """Seconds for one sweep of ``n_sets`` MOVING_AVERAGE sets (kernel and metrics, as `distctrl
    sweep` runs it) on an embedded LocalCluster of 1 and of 2 workers, after a warm-up sweep that
    compiles the kernels on every worker."""
    from distctrl.control import FilterType
    from distctrl.tuning.runner import Evaluator

    rng = np.random.default_rng(3)
    base = inputs.params.replace(filter_type=FilterType.MOVING_AVERAGE)
    sets = [base.replace(n_cycles=int(rng.integers(2, 31)), kp=float(rng.uniform(0.2, 1.5))) for _ in range(n_sets)]
    out = {}
    for workers in (1, 2):
        with Evaluator(inputs, mode="cluster", n_workers=workers, chunk_size=chunk, progress=False) as ev:
            ev.evaluate(sets[:2 * chunk * workers])                    # compile on every worker
            t0 = time.perf_counter()
            ev.evaluate(sets)
            out[workers] = time.perf_counter() - t0
    return out


def main(argv=None) -> dict:
    from distctrl.batch import closed_loop as CL

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sizes (smoke test, figures not meaningful)")
    ap.add_argument("--sets", type=int, default=1024, help="sets of the per-core measurements (default 1024)")
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "bench",
                    help="directory of results.json / RESULTS.md")
    args = ap.parse_args(argv)
    quick = args.quick
    n_sets = 16 if quick else args.sets
    n_cycles = 2000 if quick else N_CYCLES
    repeats = 1 if quick else 5
    sweep_sets, sweep_cycles = (500, 2000) if quick else (10_000, N_CYCLES)

    t0 = time.perf_counter()
    inputs = CL.prepare(scenario(n_cycles / 1000.0 + 2.0), cycles=n_cycles)
    t_prepare = time.perf_counter() - t0
    packed = param_sets(inputs, n_sets)
    t0 = time.perf_counter()
    lib = build_c()
    t_gcc = time.perf_counter() - t0
    cref = CReference(lib)
    csimd = CReference(build_c(flags=CFLAGS_SIMD, name="libclosed_loop_simd.so", source=C_SIMD_SOURCE),
                       entry="closed_loop_simd_batch")
    t0 = time.perf_counter()
    CL.run_batch(inputs, packed[:1], cycles=10)                        # compile the kernel
    t_jit = time.perf_counter() - t0

    # same numbers?
    off_n, dist_n, err_n = CL.run_batch(inputs, packed, threads=1, return_errors=True)
    off_c, dist_c, err_c = cref.run(inputs, packed)
    same_err = bool(np.array_equal(err_n, err_c))
    d_off = float(np.nanmax(np.abs(off_n - off_c)))
    d_dist = float(np.nanmax(np.abs(dist_n - dist_c)))
    nan_same = bool(np.array_equal(np.isnan(off_n), np.isnan(off_c)))
    n_err = int(np.sum(err_n[:, 0] >= 0))
    match = same_err and nan_same and d_off <= 1e-12 and d_dist <= 1e-12
    identical = bool(np.array_equal(off_n, off_c, equal_nan=True)
                     and np.array_equal(dist_n, dist_c, equal_nan=True))
    off_v, dist_v, err_v = csimd.run(inputs, packed)
    identical_simd = bool(np.array_equal(off_n, off_v, equal_nan=True) and np.array_equal(dist_n, dist_v, equal_nan=True)
                          and np.array_equal(err_n, err_v))
    del off_v, dist_v
    del off_n, dist_n, off_c, dist_c

    # per core and 2 workers: the kernels write into outputs allocated once (as bench_core's numba
    # figure; a sweep chunk's metrics take far longer than its allocation), and run_batch's own
    # allocation per call is measured beside
    work = n_sets * n_cycles
    out = (np.empty((n_sets, n_cycles)), np.empty((n_sets, n_cycles)))
    t_n1 = best_of(lambda: CL.run_batch(inputs, packed, threads=1, out=out), repeats)
    t_a1 = best_of(lambda: CL.run_batch(inputs, packed, threads=1), repeats)
    t_s1 = best_of(lambda: CL.run_batch(inputs, packed, threads=1, vectorised=False, out=out), repeats)
    t_c1 = best_of(lambda: cref.run(inputs, packed, threads=1, out=out), repeats)
    t_v1 = best_of(lambda: csimd.run(inputs, packed, threads=1, out=out), repeats)
    t_n2 = best_of(lambda: CL.run_batch(inputs, packed, threads=2, out=out), repeats)
    t_c2 = best_of(lambda: cref.run(inputs, packed, threads=2, out=out), repeats)
    # the drive with a mechanical resonance (issue 15): the same sets on the resonant plant, and the
    # rigid figure again beside it (this VM's speed drifts by up to 10 % from minute to minute)
    res_inputs = CL.prepare(scenario(n_cycles / 1000.0 + 2.0, resonant=True), cycles=n_cycles)
    assert res_inputs.plant[CL.PL_RESONANT] == 1.0
    CL.run_batch(res_inputs, packed[:1], cycles=10)
    t_r1 = best_of(lambda: CL.run_batch(res_inputs, packed, threads=1, out=out), repeats)
    t_n1b = best_of(lambda: CL.run_batch(inputs, packed, threads=1, out=out), repeats)
    # the point distance sensor with a characteristic (issue 15), on the rigid and the resonant drive
    dist_inputs = CL.prepare(scenario(n_cycles / 1000.0 + 2.0, distance=True), cycles=n_cycles)
    dres_inputs = CL.prepare(scenario(n_cycles / 1000.0 + 2.0, resonant=True, distance=True), cycles=n_cycles)
    assert dist_inputs.plant[CL.PL_SENSOR] == CL.SENSOR_DISTANCE and dres_inputs.plant[CL.PL_RESONANT] == 1.0
    CL.run_batch(dist_inputs, packed[:1], cycles=10)
    t_d1 = best_of(lambda: CL.run_batch(dist_inputs, packed, threads=1, out=out), repeats)
    t_dr1 = best_of(lambda: CL.run_batch(dres_inputs, packed, threads=1, out=out), repeats)
    del out
    r_r1, r_n1b = work / t_r1, work / t_n1b
    r_d1, r_dr1 = work / t_d1, work / t_dr1
    r_n1, r_c1, r_n2, r_c2 = work / t_n1, work / t_c1, work / t_n2, work / t_c2
    r_s1, r_a1 = work / t_s1, work / t_a1
    ratio = t_n1 / t_c1
    r_v1 = work / t_v1
    ratio_simd = t_n1 / t_v1
    ratio_scalar = t_s1 / t_c1

    # the same kind of sweep through dask (kernel + metrics per chunk), 1 and 2 workers
    dask_sets = 64 if quick else 1024
    t_dask = dask_sweep_scaling(inputs, dask_sets, chunk=16 if quick else 128)

    # the sweep: 10 000 sets x 10 000 cycles, numba, all cores (outputs 2 x 0.8 GB allocated per call)
    sweep_inputs = inputs if sweep_cycles == n_cycles else CL.prepare(scenario(sweep_cycles / 1000.0 + 2.0),
                                                                      cycles=sweep_cycles)
    t0 = time.perf_counter()
    sweep_packed = param_sets(sweep_inputs, sweep_sets, seed=2)
    t_pack = time.perf_counter() - t0
    t0 = time.perf_counter()
    out = CL.run_batch(sweep_inputs, sweep_packed)
    t_sweep = time.perf_counter() - t0
    del out
    sweep_rate = sweep_sets * sweep_cycles / t_sweep
    sweep_label = (f"{sweep_sets:,} x {sweep_cycles:,} sweep, numba, 2 threads "
                   "(measured, incl. output allocation)")
    if quick:
        t_sweep_full = t_sweep * (10_000 * N_CYCLES) / (sweep_sets * sweep_cycles)
        sweep_label = "10,000 x 10,000 sweep, EXTRAPOLATED from a " + \
            f"{sweep_sets:,} x {sweep_cycles:,} run (--quick)"
    else:
        t_sweep_full = t_sweep

    res = {
        "batch_sets": n_sets, "batch_cycles": n_cycles, "batch_repeats": repeats,
        "batch_mode": "CONST_DIST (both encoders), MOVING_AVERAGE n 2..30",
        "batch_cflags": " ".join(CFLAGS),
        "batch_numba_c_max_abs_diff_offset_mm": d_off, "batch_numba_c_max_abs_diff_distance_mm": d_dist,
        "batch_numba_c_errors_equal": same_err, "batch_sets_with_error": n_err, "batch_numba_c_match": match,
        "batch_numba_c_bit_identical": identical,
        "batch_simd_cflags": " ".join(CFLAGS_SIMD), "batch_numba_simd_c_bit_identical": identical_simd,
        "batch_simd_c_1t_set_cycles_per_s": r_v1, "batch_numba_over_simd_c_time": ratio_simd,
        "batch_numba_1t_set_cycles_per_s": r_n1, "batch_c_1t_set_cycles_per_s": r_c1,
        "batch_numba_1t_alloc_set_cycles_per_s": r_a1,
        "batch_numba_over_c_time": ratio, "batch_numba_scalar_1t_set_cycles_per_s": r_s1,
        "batch_numba_scalar_over_c_time": ratio_scalar,
        "batch_numba_2t_set_cycles_per_s": r_n2, "batch_c_2t_set_cycles_per_s": r_c2,
        "batch_numba_scaling_1_to_2": r_n2 / r_n1, "batch_c_scaling_1_to_2": r_c2 / r_c1,
        "batch_sweep_sets": sweep_sets, "batch_sweep_cycles": sweep_cycles, "batch_sweep_s": t_sweep,
        "batch_sweep_10k_x_10k_s": t_sweep_full, "batch_sweep_extrapolated": quick,
        "batch_sweep_set_cycles_per_s": sweep_rate, "batch_sweep_pack_s": t_pack,
        "batch_prepare_s": t_prepare, "batch_gcc_s": t_gcc, "batch_numba_compile_s": t_jit,
        "batch_cpu_count": os.cpu_count(),
        "batch_dask_sets": dask_sets, "batch_dask_1_worker_s": t_dask[1], "batch_dask_2_workers_s": t_dask[2],
        "batch_dask_scaling_1_to_2": t_dask[1] / t_dask[2],
        "batch_resonant_1t_set_cycles_per_s": r_r1, "batch_rigid_beside_resonant_1t_set_cycles_per_s": r_n1b,
        "batch_resonance_cost": r_n1b / r_r1 - 1.0,
        "batch_distance_sensor_1t_set_cycles_per_s": r_d1,
        "batch_distance_sensor_resonant_1t_set_cycles_per_s": r_dr1,
    }
    rows = [
        ("numba == C reference: max abs offset difference", d_off, "mm", "<= 1e-12, same errors",
         "PASS" if match else "FAIL"),
        ("numba kernel (run_batch: vectorised blocks), 1 thread", r_n1 / 1e6, "M set-cycles/s", ">= 100",
         "PASS" if r_n1 >= TARGET_RATE else "FAIL"),
        ("the same, run_batch allocating its outputs on every call", r_a1 / 1e6, "M set-cycles/s", "", "-"),
        ("numba, one set after the other (closed_loop), 1 thread", r_s1 / 1e6, "M set-cycles/s", "", "-"),
        ("C reference (gcc -O2, one set after the other), 1 thread", r_c1 / 1e6, "M set-cycles/s", "", "-"),
        ("numba time / C time, 1 thread (run_batch)", ratio, "x", "<= 1.5",
         "PASS" if ratio <= TARGET_RATIO else "FAIL"),
        ("numba time / C time, 1 thread (both one set after the other)", ratio_scalar, "x", "(<= 1.5)",
         "PASS" if ratio_scalar <= TARGET_RATIO else "FAIL"),
        ("SIMD C anchor (gcc -O3 -march=native, 8 sets per vector loop), 1 thread", r_v1 / 1e6,
         "M set-cycles/s", "", "PASS (bit for bit)" if identical_simd else "FAIL (numbers differ)"),
        ("numba time / SIMD C time, 1 thread (issue 27)", ratio_simd, "x", "<= 1.5",
         "PASS" if ratio_simd <= TARGET_RATIO else "FAIL"),
        ("numba kernel, 2 threads", r_n2 / 1e6, "M set-cycles/s", "", "-"),
        ("numba scaling 1 -> 2 threads", r_n2 / r_n1, "x", "", "-"),
        ("C reference, 2 threads", r_c2 / 1e6, "M set-cycles/s", "", "-"),
        ("C scaling 1 -> 2 threads", r_c2 / r_c1, "x", "", "-"),
        (sweep_label, t_sweep_full, "s", "< 60", "PASS" if t_sweep_full < TARGET_SWEEP_S else "FAIL"),
        (f"dask sweep, {dask_sets} sets x {n_cycles} cycles with metrics, LocalCluster 1 worker", t_dask[1], "s",
         "", "-"),
        ("the same, 2 workers", t_dask[2], "s", "", "-"),
        ("dask scaling 1 -> 2 workers", t_dask[1] / t_dask[2], "x", "", "-"),
        ("numba kernel, Z drive with a 40 Hz resonance, 1 thread", r_r1 / 1e6, "M set-cycles/s", ">= 50",
         "PASS" if r_r1 >= TARGET_RATE_RESONANT else "FAIL"),
        ("the same rigid, measured beside it, 1 thread", r_n1b / 1e6, "M set-cycles/s", "", "-"),
        ("cost of the resonance (rigid rate / resonant rate - 1)", 100.0 * (r_n1b / r_r1 - 1.0), "%", "", "-"),
        ("numba kernel, distance sensor with a characteristic (rigid drive), 1 thread", r_d1 / 1e6,
         "M set-cycles/s", "", "-"),
        ("the same on the drive with the 40 Hz resonance, 1 thread", r_dr1 / 1e6, "M set-cycles/s", "", "-"),
    ]
    for a, b, c, d, e in rows:
        print(f"{a:<80} {b:>12,.4g} {c:<15} {d:<22} {e}")
    lines = ["", "## Batch closed loop vs C reference (bench/bench_batch.py)", "",
             f"- scenario: examples/scenarios/const_dist_sheet.toml with a straight {n_cycles}-cycle path; "
             "CONST_DIST 1 mm with both encoders, probe with 2 µm noise and a 1-cycle dead time, drive kv 60 "
             "with 1-cycle bus delay and 0.1 µm encoder",
             f"- {n_sets} MOVING_AVERAGE sets (n_cycles 2 … 30, kp 0.2 … 1.5, d_tv 0 … 4 ms) × {n_cycles} "
             "cycles, "
             f"best of {repeats}; {n_err} sets ran into a controller error (both stop at the same cycle)",
             "- numba and C write into the same output arrays, allocated once before the timing "
             "(`run_batch(..., out=...)`); the row below the kernel's has run_batch allocate 2 x "
             f"{n_sets * n_cycles * 8 / 2**20:.0f} MiB per call (page faults and zeroing of fresh memory)",
             f"- C reference bench/batch_c/closed_loop.c, `gcc {' '.join(CFLAGS)}`, called through ctypes "
             "(2 threads: two OS threads, each a half of the sets); numba via `run_batch(threads=...)`",
             f"- SIMD anchor bench/batch_c/closed_loop_simd.c (the same law across 8 sets per vector loop, "
             f"every branch computed and selected), `gcc {' '.join(CFLAGS_SIMD)}`; bit for bit equal to numba: "
             f"{identical_simd}",
             f"- max abs offset difference {d_off:.3g} mm, max abs distance difference {d_dist:.3g} mm, "
             f"errors equal: {same_err}, bit for bit identical: {identical}",
             f"- sweep: packing {sweep_sets} sets {t_pack:.2f} s (not in the sweep time); "
             f"prepare {t_prepare:.2f} s, "
             f"gcc {t_gcc:.2f} s, numba compile {t_jit:.1f} s", "",
             "| measurement | value | unit | target | result |", "|---|---:|---|---:|---|"]
    lines += [f"| {a} | {b:,.4g} | {c} | {d} | {e} |" for a, b, c, d, e in rows]
    merge_results(args.out, res, lines)
    return res


if __name__ == "__main__":
    main()
    if "--quick" not in sys.argv:
        # the sweep's start-up, first and second call (numba's disk cache): bench/bench_startup.py
        import bench_startup

        bench_startup.main(["--out", sys.argv[sys.argv.index("--out") + 1]] if "--out" in sys.argv else [])
