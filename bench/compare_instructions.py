"""Compare two checkouts of distctrl by the instructions their hot paths execute (valgrind cachegrind).

Wall-clock benchmarks on a shared VM scatter by 10-40 % between rounds of the same code (bench/README.md,
"Reading the figures"), so a 5 % change cannot be told from them. The number of instructions a run
executes does not depend on the load. This script counts them, under ``valgrind --tool=cachegrind
--cache-sim=no``, for the paths that `make bench` times in CPython:

* ``run``: bench/bench_run.py's 3-axis scenario, trace kept in memory (rigid Z drive and with the 40 Hz
  resonance) and streamed to CSV;
* ``update``: bench/bench_core.py's loop of ``AxisDistanceController.update()`` calls, each timed;
* ``process``: a whole run of the short plasma plate (examples/scenarios/plasma_plate_short.toml): the
  process functions (touch-off, corner lock, void lock, lift) as PLC programs every cycle;
* ``served``: ``ServedMachine.step()`` of the served machine (the cycle of ``serve``, session log included);
* ``page``: the same with the live page's recorder (``MachineHub``) after every cycle.

Each case runs twice per checkout, with a short and a long workload in the same process after a
warm-up, and the difference is divided by the extra cycles: the start-up (imports, loading the
scenario) drops out, and what remains is instructions per cycle. Usage::

    .venv/bin/python bench/compare_instructions.py BASE_DIR HEAD_DIR [--cases run,update,served]

``BASE_DIR`` and ``HEAD_DIR`` are checkouts (e.g. ``git worktree add /tmp/base <rev>``). Both run with
this interpreter. Needs ``valgrind`` (Debian package); about 5 minutes on 2 cores. Instruction counts
are not time (a cache miss or a branch costs more than an add), but a change in them is a change in
the work the code does.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

#: the harness run in each checkout: argv = checkout, case, size
HARNESS = r'''
import os, sys
d, case, size = sys.argv[1], sys.argv[2], int(sys.argv[3])
sys.path[:0] = [d, os.path.join(d, "bench")]
import distctrl
assert distctrl.__file__.startswith(d), distctrl.__file__
if case in ("run_rigid", "run_resonant", "run_csv"):
    import bench_run
    sc = bench_run.scenario(3, resonant=case == "run_resonant")
    kw = {"trace": os.path.join(os.environ["CMP_TMP"], "t.csv"), "keep_trace": False} if case == "run_csv" else {}
    for _ in range(1 + size):                    # the first run warms up
        r = bench_run.run(sc, **kw)
    print("cycles", r.cycles)
elif case == "update":
    import bench_core
    bench_core.bench_cpython_update(size, 1000)
    print("cycles", size)
elif case == "run_process":
    from distctrl.sim.runner import run
    from distctrl.sim.scenario import load_scenario
    sc = load_scenario(os.path.join(d, "examples", "scenarios", "plasma_plate_short.toml"))
    for _ in range(1 + size):
        r = run(sc)
    print("cycles", r.cycles)
elif case.startswith("served"):
    from distctrl.sim.scenario import load_scenario
    if os.path.isdir(os.path.join(d, "distctrl", "serve")):
        from distctrl.serve.machine import ServedMachine
    else:                                        # before the serving layer had its own package
        from distctrl.ads.machine import ServedMachine
    served = ServedMachine(load_scenario(os.path.join(d, "examples", "scenarios", "const_dist_sheet.toml")))
    if case == "served_page":                    # the live page's recorder after every cycle
        from distctrl.ui.hub import MachineHub
        hub = MachineHub(served)
    for _ in range(500 + size):
        served.step()
    print("cycles", size)
'''

#: case -> (short size, long size): run counts whole runs, the others cycles
SIZES = {"run_rigid": (0, 2), "run_resonant": (0, 2), "run_csv": (0, 2), "run_process": (0, 1),
         "update": (10_000, 40_000), "served": (2_000, 8_000), "served_page": (2_000, 8_000)}
GROUPS = {"run": ("run_rigid", "run_resonant", "run_csv"), "process": ("run_process",), "update": ("update",),
          "served": ("served",), "page": ("served_page",)}


def count(checkout: str, case: str, size: int, tmp: str) -> tuple[int, int]:
    """(instructions, cycles of the last workload) of one harness run under cachegrind."""
    out = os.path.join(tmp, f"cg.{os.getpid()}.{abs(hash((checkout, case, size)))}")
    # one thread each: OpenBLAS's idle workers spin (blas_thread_server), which counts millions of
    # instructions that depend on the scheduler, not on the code; a fixed hash seed for the same reason
    env = {**os.environ, "CMP_TMP": tmp, "PYTHONHASHSEED": "0", "OPENBLAS_NUM_THREADS": "1",
           "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
    proc = subprocess.run(["valgrind", "--tool=cachegrind", "--cache-sim=no", f"--cachegrind-out-file={out}",
                           sys.executable, "-c", HARNESS, checkout, case, str(size)],
                          capture_output=True, text=True, env=env, timeout=3600)
    refs = re.search(r"I\s+refs:\s+([\d,]+)", proc.stderr)
    cycles = re.search(r"cycles (\d+)", proc.stdout)
    if proc.returncode != 0 or refs is None or cycles is None:
        raise RuntimeError(f"{case} in {checkout} failed (exit {proc.returncode}):\n{proc.stderr[-2000:]}")
    return int(refs.group(1).replace(",", "")), int(cycles.group(1))


def per_cycle(checkout: str, case: str, tmp: str) -> dict:
    short, long = SIZES[case]
    with ThreadPoolExecutor(2) as pool:
        a, b = pool.map(lambda n: count(checkout, case, n, tmp), (short, long))
    extra = (long - short) * b[1] if case.startswith("run") else long - short     # runs x cycles, or cycles
    return {"instructions_short": a[0], "instructions_long": b[0], "extra_cycles": extra,
            "instructions_per_cycle": (b[0] - a[0]) / extra}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("base", help="the checkout before (a directory with distctrl/ and bench/)")
    ap.add_argument("head", help="the checkout after")
    ap.add_argument("--cases", default="run,process,update,served,page",
                    help="comma-separated: run, process, update, served, page")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    ap.add_argument("--out", help="also write the figures, with both checkouts' commits, to this JSON file")
    args = ap.parse_args(argv)
    if shutil.which("valgrind") is None:
        print("compare_instructions: valgrind is not installed (apt-get install valgrind)", file=sys.stderr)
        return 1
    cases = [c for g in args.cases.split(",") for c in GROUPS[g.strip()]]
    res = {}
    with tempfile.TemporaryDirectory() as tmp:
        for case in cases:
            base = per_cycle(os.path.abspath(args.base), case, tmp)
            head = per_cycle(os.path.abspath(args.head), case, tmp)
            res[case] = {"base": base, "head": head,
                         "change_pct": 100.0 * (head["instructions_per_cycle"] / base["instructions_per_cycle"] - 1)}
            if not args.json:
                print(f"{case:14s} base {base['instructions_per_cycle']:10,.0f} instr/cycle   "
                      f"head {head['instructions_per_cycle']:10,.0f} instr/cycle   {res[case]['change_pct']:+.1f} %",
                      flush=True)
    if args.json:
        print(json.dumps(res, indent=2))
    if args.out:
        record = {"base_commit": _commit(args.base), "head_commit": _commit(args.head), "cases": res}
        with open(args.out, "w", encoding="utf-8") as f:
            json.dump(record, f, indent=2)
    return 0


def _commit(checkout: str) -> str | None:
    proc = subprocess.run(["git", "-C", checkout, "rev-parse", "HEAD"], capture_output=True, text=True)
    return proc.stdout.strip() if proc.returncode == 0 else None


if __name__ == "__main__":
    sys.exit(main())
