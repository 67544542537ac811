"""Benchmark: how fast a `distctrl sweep` starts, the first time on a machine and the second (issue 13).

numba compiles the batch kernels on first use (tens of seconds) and caches them on disk
(distctrl/batch/jitcache.py); the second call loads them. Target: the second call of a small sweep
in this process (``--local``) is done within 2 s, start-up included. Measured with an empty cache
folder (``NUMBA_CACHE_DIR`` pointed at a fresh temporary folder), so "first" is a real first compile
whatever the in-tree ``__pycache__`` holds; every call is a fresh ``python -m distctrl`` process.

Lines:

* ``--local``, 4 MOVING_AVERAGE sets (``--grid kp=0.1:1:4``): first call, second call (target);
* ``--local``, 4 random sets of the default space (the low-pass design imports scipy.signal, ~1 s);
* the embedded dask LocalCluster (the default mode), same 4 MA sets, second call: worker processes
  start and import distctrl, which no cache can save.

The first call must say "compiling" on stderr, the second must not. Results are merged into
bench/results.json (keys ``startup_*``) and appended to bench/RESULTS.md. `make bench` runs it from
bench/bench_batch.py; alone: ``.venv/bin/python bench/bench_startup.py [--out DIR]``.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import subprocess
import sys
import tempfile
import time
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))   # bench/, also when loaded by path
from _results import merge_results  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "examples" / "scenarios" / "tune_sheet.toml"
TARGET_S = 2.0


def sweep(args: list[str], cache: str, out: str) -> tuple[float, str]:
    """Wall time of one ``python -m distctrl sweep`` process and its stderr."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-m", "distctrl", "sweep", str(SCENARIO), *args, "--out", out]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT, timeout=600)
    dt = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}): {proc.stderr[-2000:]}")
    return dt, proc.stderr


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "bench",
                    help="directory of results.json / RESULTS.md")
    ap.add_argument("--no-cluster", action="store_true", help="skip the LocalCluster line")
    args = ap.parse_args(argv)
    ma = ["--grid", "kp=0.1:1:4"]
    with tempfile.TemporaryDirectory(prefix="distctrl-numba-cache-") as cache, \
            tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "s.csv")
        first, err1 = sweep([*ma, "--local"], cache, out)
        files = sorted(p.name for p in pathlib.Path(cache).rglob("*") if p.suffix in (".nbi", ".nbc"))
        seconds = sorted(sweep([*ma, "--local"], cache, out)[0] for _ in range(3))
        _, err2 = sweep([*ma, "--local"], cache, out)
        random_s = sorted(sweep(["--random", "4", "--local"], cache, out)[0] for _ in range(3))
        default_s = sorted(sweep(ma, cache, out)[0] for _ in range(3))[1]     # a small sweep runs in-process
        # --chunk 2: two chunks, so the default mode really starts its embedded cluster
        cluster_s = None if args.no_cluster else sorted(sweep([*ma, "--chunk", "2"], cache, out)[0]
                                                        for _ in range(2))[0]
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    second = seconds[1]
    res = {"startup_first_local_s": first, "startup_second_local_s": second, "startup_second_default_s": default_s,
           "startup_second_local_random_s": random_s[1], "startup_second_cluster_s": cluster_s,
           "startup_first_says_compiling": "compiling" in err1, "startup_second_says_compiling": "compiling" in err2,
           "startup_cache_files": len(files), "startup_loadavg": load}
    rows = [("first call, --local, 4 MA sets (compiles)", first, "s", "", "-"),
            ("second call, --local, 4 MA sets (median of 3)", second, "s", f"<= {TARGET_S:g}",
             "PASS" if second <= TARGET_S else "FAIL"),
            ("second call, --local, 4 random sets (scipy.signal for the low-pass)", random_s[1], "s", "", "-"),
            ("second call, default mode, 4 MA sets (one chunk: in this process; median of 3)", default_s, "s",
             f"<= {TARGET_S:g}", "PASS" if default_s <= TARGET_S else "FAIL")]
    if cluster_s is not None:
        rows.append(("second call, LocalCluster (2 worker processes, --chunk 2), 4 MA sets (best of 2)",
                     cluster_s, "s", "", "-"))
    rows += [("first call says 'compiling' on stderr", float(res["startup_first_says_compiling"]), "", "1",
              "PASS" if res["startup_first_says_compiling"] else "FAIL"),
             ("second call says 'compiling'", float(res["startup_second_says_compiling"]), "", "0",
              "PASS" if not res["startup_second_says_compiling"] else "FAIL"),
             ("cache files written (.nbi/.nbc)", float(len(files)), "", "> 0", "PASS" if files else "FAIL")]
    for a, b, c, d, e in rows:
        print(f"{a:<75} {b:>8.2f} {c:<3} {d:<8} {e}")
    lines = ["", "## Sweep start-up: numba's disk cache (bench/bench_startup.py)", "",
             "- each call a fresh `python -m distctrl sweep examples/scenarios/tune_sheet.toml ... --out tmp` process, "
             "NUMBA_CACHE_DIR an empty temporary folder before the first call; wall time including Python start, "
             f"imports, recording the scenario and writing the table; load average {load:.2f}", "",
             "| measurement | value | unit | target | result |", "|---|---:|---|---:|---|"]
    lines += [f"| {a} | {b:,.2f} | {c} | {d} | {e} |" for a, b, c, d, e in rows]
    args.out.mkdir(parents=True, exist_ok=True)
    merge_results(args.out, res, lines)
    return res


if __name__ == "__main__":
    main()
