"""Benchmark: ``machine record`` keeps every 1 ms sample (issue 28, "Speed").

``distctrl serve examples/scenarios/serve_z.toml`` runs in its own process (on a loopback address of
its own, TCP 48898 where pyads connects); this process records 5 signals of axis Z (axis_id 1) at
the 1 ms cycle for 60 s with :func:`distctrl.client.recorder.record`, exactly what ``distctrl machine
record`` does, and measures its own CPU time (getrusage of this process: the pyads receive thread and
the callbacks, the assembly and the trace file). Targets: 0 samples lost, CPU < 30 % of one core.

How the samples reach Python: one cyclic notification (ADSTRANS_SERVERCYCLE, cycle 1 ms) per signal,
max delay 50 ms, so the target sends ~20 frames per second, each carrying every stamp (cycle) of the
last 50 ms; pyads' AdsLib calls the Python callback once per sample (5000 calls/s), which appends a
tuple to a list; decoding is done once at the end with numpy.

``--seconds`` (default 60), ``--out DIR`` (default bench/): figures merged into results.json (keys
``record_*``) and a section appended to RESULTS.md.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import random
import resource
import socket
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

from _results import merge_results  # noqa: E402

from distctrl.client.axes import Unit  # noqa: E402
from distctrl.client.recorder import DEFAULT_SIGNALS, make_signal, record, summary, write_trace  # noqa: E402
from distctrl.client.target import Target  # noqa: E402

CPU_TARGET = 0.30


def free_loopback() -> str:
    rng = random.Random()
    for _ in range(200):
        host = f"127.{rng.randint(1, 254)}.{rng.randint(0, 254)}.{rng.randint(1, 254)}"
        with socket.socket() as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                s.bind((host, 48898))
            except OSError:
                continue
        return host
    raise SystemExit("no free loopback address for TCP 48898")


def cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "bench")
    args = ap.parse_args()
    host = free_loopback()
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    server = subprocess.Popen([sys.executable, "-m", "distctrl", "serve", str(ROOT / "examples/scenarios/serve_z.toml"),
                               "--host", host, "--port", "48898", "--net-id", f"{host}.1.1", "--no-discovery",
                               "--rt-priority", "0", "--duration", str(args.seconds + 60)],
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                socket.create_connection((host, 48898), timeout=1).close()
                break
            except OSError:
                if time.monotonic() > deadline or server.poll() is not None:
                    raise SystemExit(f"distctrl serve did not start: {server.stderr.read() if server.poll() is not None else ''}")
                time.sleep(0.2)
        target = Target(f"{host}.1.1", 551, host, timeout=5.0).open()
        sigs = [make_signal(n, 1e-4) for n in DEFAULT_SIGNALS]
        load0 = os.getloadavg()
        c0, t0 = cpu(), time.monotonic()
        rec = record(target, Unit("axis", 2, "Z"), sigs, args.seconds)
        c1, t1 = cpu(), time.monotonic()
        with tempfile.TemporaryDirectory() as tmp:
            write_trace(rec, pathlib.Path(tmp) / "rec.csv", {"bench": "bench_record"})
        c2, t2 = cpu(), time.monotonic()
        target.close()
        load1 = os.getloadavg()
    finally:
        server.terminate()
        try:
            server.wait(timeout=30)
        except subprocess.TimeoutExpired:
            server.kill()
    s = summary(rec)
    share = (c1 - c0) / (t1 - t0)
    expected = int(round(args.seconds * 1000))
    ok_lost = s["lost_total"] == 0 and rec.late == 0
    res = {"record_seconds": args.seconds, "record_rows": s["rows"], "record_expected_rows": expected,
           "record_samples": s["samples"], "record_lost": s["lost_total"], "record_late": rec.late,
           "record_cpu_share": share, "record_write_trace_s": t2 - t1, "record_write_trace_cpu_s": c2 - c1,
           "record_load_before": load0, "record_load_after": load1}
    lines = ["", "## machine record (bench/bench_record.py)", "",
             f"- served machine: `distctrl serve examples/scenarios/serve_z.toml` in its own process; recorded: "
             f"{', '.join(DEFAULT_SIGNALS)} of axis Z at the 1 ms cycle for {args.seconds:g} s (cyclic notifications, "
             f"max delay 50 ms)",
             f"- load average before / after: {tuple(round(x, 2) for x in load0)} / {tuple(round(x, 2) for x in load1)}",
             "",
             "| measurement | value | unit | target | result |", "|---|---:|---|---:|---|",
             f"| rows (cycles) recorded | {s['rows']} | | ~{expected} | - |",
             f"| (cycles the served machine ran in the {args.seconds:g} s: fewer than {expected} when it "
             f"fell behind real time under load; not lost samples) | | | | |",
             f"| samples | {s['samples']} | | 5 × rows | {'PASS' if s['samples'] == 5 * s['rows'] else 'FAIL'} |",
             f"| lost samples | {s['lost_total']} | | 0 | {'PASS' if s['lost_total'] == 0 else 'FAIL'} |",
             f"| late (out of order / repeated) samples | {rec.late} | | 0 | {'PASS' if rec.late == 0 else 'FAIL'} |",
             f"| CPU of the recording process | {100 * share:.1f} | % of one core | < {100 * CPU_TARGET:.0f} | "
             f"{'PASS' if share < CPU_TARGET else 'FAIL'} |",
             f"| writing the trace afterwards | {t2 - t1:.2f} | s ({c2 - c1:.2f} s CPU) | | - |"]
    merge_results(args.out, res, lines)
    print("\n".join(lines))
    return 0 if ok_lost and share < CPU_TARGET else 1


if __name__ == "__main__":
    sys.exit(main())
