"""Soak (issue 8): a long CONST_DIST run with sensor noise, then a run interrupted by SIGINT.

Part 1 - soak: the head holds SET_DIST = 1 mm over one point of the sheet (a dwell, so the surface
under the sensor does not change and nothing explains a drift of the offset) for ``--cycles``
cycles at 1 ms with the probe's noise (std 2 µm). Every ``window`` cycles the mean distance
error, the offset and the process's resident memory are sampled. Pass: the window means of the
distance error stay within ``DRIFT_LIMIT_MM`` of 0, the window-mean offset moves by less than
that between the first and the last window, no error is reported, the resident memory at the
end is within ``RSS_GROWTH_LIMIT`` of the memory after the first window, and the streamed trace
holds exactly one row per cycle (counted in the file, last row's time checked).

Part 2 - interruption: ``distctrl run ... --trace`` in a subprocess, SIGINT at a random moment;
the trace that is left must load with :meth:`Trace.from_csv`, have consecutive cycle times and
a sidecar. Repeated ``--interrupts`` times.

Results: bench/soak.json (and printed). tests/reliability/test_soak.py runs a short version of both
parts in ``make test``.

Resumable (issue 30, ``--state DIR``): part 1 steps the simulated machine itself (no CSV trace: 10^8
rows would be ~10 GB; the trace's streaming is what the 10^7-cycle run without ``--state`` checks)
and pickles the whole machine, the samples and the counters to ``DIR/soak.pkl`` every
``--checkpoint`` cycles and when it stops. Started again with the same ``--state`` it continues from
that cycle; the machine is the same object graph (noise generator included), so the resumed run is
the run that was never stopped. ``--budget S`` stops it after about S seconds (exit 3, the time
limit's code; SIGTERM / SIGINT stop it the same way at the next window), the next call goes on.
Memory is judged per process (segment): the resident memory at every window within
``RSS_GROWTH_LIMIT`` of the segment's first window, and each segment's first window within that of
the first segment's. ``make stress`` runs it with 10^8 cycles.
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import random
import signal
import subprocess
import sys
import tempfile
import time
import pickle

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from distctrl.sim.runner import run  # noqa: E402
from distctrl.sim.scenario import scenario_from_text  # noqa: E402
from distctrl.trace import Trace  # noqa: E402

SCENARIO = ROOT / "examples" / "scenarios" / "const_dist_sheet.toml"
#: a window mean of the distance error beyond this is a drift (noise std is 0.002 mm, so the
#: standard error of a 10^5-cycle window mean is ~1e-5 mm; the bound is generous but catches a
#: creeping integrator or a slow leak of the offset)
DRIFT_LIMIT_MM = 0.005
#: resident memory may grow by at most this factor after the first window (allocator noise)
RSS_GROWTH_LIMIT = 1.10
DEFAULT_OUT = str(ROOT / "bench" / "soak.json")


def soak_scenario(cycles: int):
    """CONST_DIST at X=50 (on the sine of the sheet) for ``cycles`` cycles of 1 ms."""
    dwell = cycles * 0.001
    text = SCENARIO.read_text().replace(
        'program = "const_dist_sheet.nc"',
        'program_text = """\nN10 G90 G0 X50 Y0 Z31\nN20 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]\n'
        f'N30 #TIME {dwell:.3f}\nN40 Z[DIST_CTRL OFF]\nN60 M30\n"""').replace(
        "duration = 10.0", f"duration = {dwell + 5:.3f}")
    return scenario_from_text(text, base_dir=SCENARIO.parent, source="soak")


def rss_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def count_rows(path: pathlib.Path) -> tuple[int, bytes]:
    """Data rows in a CSV trace (lines after the header) and the last line, reading in 16 MB blocks."""
    lines, last = 0, b""
    with open(path, "rb") as f:
        while block := f.read(1 << 24):
            lines += block.count(b"\n")
            last = (last + block)[-4096:]
    return lines - 1, last.rstrip(b"\n").rsplit(b"\n", 1)[-1]


def soak(cycles: int, window: int, trace_dir: str | None) -> dict:
    sc = soak_scenario(cycles)
    samples: list[tuple[int, float, float, int]] = []     # (cycle, mean error, mean offset, rss)
    acc = {"err": 0.0, "off": 0.0, "n": 0}

    def observe(machine, cycle):
        # called every cycle as a PLC task would be; only reads the machine
        out = machine.outputs.get("Z")
        if out is not None and out.hli_state == 4:
            acc["err"] += machine.true_distance - out.set_distance
            acc["off"] += out.offset
            acc["n"] += 1
        if cycle % window == window - 1 and acc["n"]:
            samples.append((cycle + 1, acc["err"] / acc["n"], acc["off"] / acc["n"], rss_bytes()))
            acc.update(err=0.0, off=0.0, n=0)

    with tempfile.TemporaryDirectory(dir=trace_dir) as d:
        path = pathlib.Path(d) / "soak.csv"
        rss_start = rss_bytes()
        t0 = time.perf_counter()
        result = run(sc, trace=path, keep_trace=False, plc_program=observe)
        wall = time.perf_counter() - t0
        rss_after_run = rss_bytes()                # before count_rows' 16 MB read buffers
        rows, last = count_rows(path)
        last_t = float(last.split(b",", 1)[0])
    errors = np.array([s[1] for s in samples])
    offsets = np.array([s[2] for s in samples])
    rss = [s[3] for s in samples]
    drift = float(abs(offsets[-1] - offsets[0])) if len(offsets) > 1 else 0.0
    res = {
        "soak_cycles": result.cycles, "soak_wall_s": wall, "soak_cycles_per_s": result.cycles / wall,
        "soak_windows": len(samples), "soak_window_cycles": window,
        "soak_max_abs_window_mean_error_mm": float(np.max(np.abs(errors))) if len(errors) else None,
        "soak_offset_drift_first_to_last_window_mm": drift,
        "soak_rss_start_mb": rss_start / 1e6, "soak_rss_first_window_mb": rss[0] / 1e6 if rss else None,
        "soak_rss_end_mb": rss_after_run / 1e6, "soak_rss_max_mb": max(rss) / 1e6 if rss else None,
        "soak_trace_rows": rows, "soak_trace_last_t_s": last_t, "soak_errors": result.errors,
    }
    res["soak_pass"] = bool(
        not result.errors and result.completed and len(samples) > 0
        and res["soak_max_abs_window_mean_error_mm"] <= DRIFT_LIMIT_MM and drift <= DRIFT_LIMIT_MM
        and max(rss) <= RSS_GROWTH_LIMIT * rss[0] and rows == result.cycles
        and abs(last_t - (result.cycles - 1) * 0.001) < 1e-6)
    return res


def soak_resumable(cycles: int, window: int, state_dir: pathlib.Path, budget_s: float | None,
                   checkpoint: int = 1_000_000) -> dict:
    """Part 1 without a trace, checkpointed to ``state_dir/soak.pkl`` (module docstring)."""
    from distctrl.sim.machine import Machine
    from distctrl.sim.runner import load_program

    state_dir.mkdir(parents=True, exist_ok=True)
    ckpt = state_dir / "soak.pkl"
    state = None
    if ckpt.exists():
        state = pickle.loads(ckpt.read_bytes())
        if state["target"] != cycles or state["window"] != window:
            raise SystemExit(f"{ckpt}: a soak of {state['target']} cycles (window {state['window']}) is under "
                             f"way; remove the file to start one of {cycles}")
    if state is None:
        sc = soak_scenario(cycles)
        state = {"target": cycles, "window": window, "machine": Machine(sc, load_program(sc)), "cycle": 0,
                 "samples": [], "err": 0.0, "off": 0.0, "n": 0, "segments": [], "nonfinite": 0}
    stop = {"why": None}

    def on_signal(signum, frame):  # noqa: ARG001
        stop["why"] = signal.Signals(signum).name
    old = {s: signal.signal(s, on_signal) for s in (signal.SIGTERM, signal.SIGINT)}

    def save():
        tmp = ckpt.with_suffix(".tmp")
        tmp.write_bytes(pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL))
        os.replace(tmp, ckpt)

    m = state["machine"]
    step = m.step
    out = m.outputs["Z"]
    seg = {"from_cycle": state["cycle"], "rss": [], "wall_s": 0.0}
    state["segments"].append(seg)
    t0 = time.perf_counter()
    isfinite = np.isfinite
    try:
        while state["cycle"] < cycles:
            n = min(window - state["cycle"] % window, cycles - state["cycle"])
            err = off = 0.0
            got = 0
            for _ in range(n):
                step()
                if out.hli_state == 4:
                    err += m.true_distance - out.set_distance
                    off += out.offset
                    got += 1
            state["cycle"] += n
            state["err"] += err
            state["off"] += off
            state["n"] += got
            if not (isfinite(err) and isfinite(off)):
                state["nonfinite"] += 1
            if state["cycle"] % window == 0 or state["cycle"] == cycles:
                if state["n"]:
                    state["samples"].append((state["cycle"], state["err"] / state["n"], state["off"] / state["n"]))
                state.update(err=0.0, off=0.0, n=0)
                seg["rss"].append(rss_bytes())
            seg["wall_s"] = time.perf_counter() - t0
            seg["to_cycle"] = state["cycle"]
            over = budget_s is not None and seg["wall_s"] >= budget_s
            if state["cycle"] % checkpoint == 0 or state["cycle"] == cycles or over or stop["why"]:
                save()
            if over or stop["why"]:
                break
    finally:
        for s, h in old.items():
            signal.signal(s, h)
    return soak_figures(state, stop["why"] or ("budget" if state["cycle"] < cycles else None))


def soak_figures(state: dict, stopped: str | None) -> dict:
    """The figures of a (possibly partial) resumable soak."""
    m = state["machine"]
    samples = state["samples"]
    errors = np.array([s[1] for s in samples])
    offsets = np.array([s[2] for s in samples])
    segs = [s for s in state["segments"] if s["rss"]]
    wall = sum(s["wall_s"] for s in state["segments"])
    done = sum(s.get("to_cycle", s["from_cycle"]) - s["from_cycle"] for s in state["segments"])
    first = segs[0]["rss"][0] if segs else None
    flat_in = all(max(s["rss"]) <= RSS_GROWTH_LIMIT * s["rss"][0] for s in segs)
    flat_across = all(s["rss"][0] <= RSS_GROWTH_LIMIT * first for s in segs) if segs else False
    drift = float(abs(offsets[-1] - offsets[0])) if len(offsets) > 1 else 0.0
    ev = [{"id": int(e.id), "t": t, "message": e.message} for t, e in m.events if e.severity != "warning"]
    res = {
        "soak_resumable": True, "soak_target_cycles": state["target"], "soak_cycles": state["cycle"],
        "soak_complete": state["cycle"] >= state["target"], "soak_stopped_by": stopped,
        "soak_wall_s": wall, "soak_cycles_per_s": done / wall if wall else None,
        "soak_projected_total_s": state["target"] / (done / wall) if wall and done else None,
        "soak_segments": len(state["segments"]), "soak_windows": len(samples),
        "soak_window_cycles": state["window"],
        "soak_max_abs_window_mean_error_mm": float(np.max(np.abs(errors))) if len(errors) else None,
        "soak_offset_drift_first_to_last_window_mm": drift,
        "soak_nonfinite_windows": state["nonfinite"],
        "soak_rss_first_window_mb": first / 1e6 if first else None,
        "soak_rss_max_mb": max(max(s["rss"]) for s in segs) / 1e6 if segs else None,
        "soak_rss_segments_mb": [[round(s["rss"][0] / 1e6, 2), round(max(s["rss"]) / 1e6, 2),
                                  round(s["rss"][-1] / 1e6, 2)] for s in segs],
        "soak_rss_flat": bool(segs) and flat_in and flat_across,
        "soak_errors": ev, "soak_final_state": int(m.outputs["Z"].hli_state),
        "soak_trace": "none (resumable soak; the streamed trace is checked by the 10^7-cycle run)",
    }
    res["soak_pass"] = bool(
        not ev and state["nonfinite"] == 0 and len(samples) > 0 and res["soak_rss_flat"]
        and res["soak_max_abs_window_mean_error_mm"] <= DRIFT_LIMIT_MM and drift <= DRIFT_LIMIT_MM)
    return res


def _has_data_row(trace: pathlib.Path) -> bool:
    """True once the streamed CSV holds a header and at least one row (reads its first 64 KiB)."""
    try:
        with open(trace, "rb") as f:
            return f.read(1 << 16).count(b"\n") >= 2
    except OSError:
        return False


def interrupted_run(workdir: pathlib.Path, seconds_before_sigint: float) -> dict:
    """``distctrl run`` with a streamed trace, SIGINT after the given time; check the trace left."""
    trace = workdir / "interrupted.csv"
    for stale in (trace, trace.with_name(trace.name + ".meta.json")):
        stale.unlink(missing_ok=True)
    scenario = workdir / "long.toml"
    scenario.write_text(SCENARIO.read_text().replace(
        'program = "const_dist_sheet.nc"',
        'program_text = """\nN10 G90 G0 X50 Y0 Z31\nN20 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]\n'
        'N30 #TIME 3000\nN40 Z[DIST_CTRL OFF]\nN60 M30\n"""').replace("duration = 10.0", "duration = 3100")
        .replace('params = "z_laser.lis"', f'params = "{SCENARIO.parent / "z_laser.lis"}"'))
    # faulthandler: a run that does not stop after SIGINT is aborted and its stack reported
    env = dict(os.environ, PYTHONFAULTHANDLER="1")
    # SIGINT back to its default in the child: a shell starts background jobs (`make stress &`, CI
    # runners) with SIGINT ignored, and Python then installs no KeyboardInterrupt handler
    proc = subprocess.Popen([sys.executable, "-m", "distctrl", "run", str(scenario), "--trace", str(trace)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=workdir, env=env,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    time.sleep(seconds_before_sigint)
    # interrupt a run, not a start-up: on a slow machine the first rows may come later than the
    # delay, so wait (up to 60 s) until the trace holds a data row
    started = time.monotonic()
    while proc.poll() is None and time.monotonic() - started < 60.0 and not _has_data_row(trace):
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    try:
        out, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGABRT)
        out, err = proc.communicate()
        return {"returncode": None, "rows": 0, "consecutive": False, "sidecar": False, "hang": True,
                "delay_s": seconds_before_sigint, "stderr_tail": err.decode(errors="replace")[-3000:]}
    loaded = Trace.from_csv(trace)
    t = loaded.t
    steps = np.diff(t)
    return {"returncode": proc.returncode, "rows": len(loaded),
            "consecutive": bool(len(t) == 0 or (t[0] == 0.0 and np.allclose(steps, 0.001, atol=1e-9))),
            "sidecar": trace.with_name(trace.name + ".meta.json").exists(),
            "hang": False, "delay_s": seconds_before_sigint, "stderr_tail": err.decode(errors="replace")[-300:]}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cycles", type=int, default=1_000_000)
    ap.add_argument("--window", type=int, default=100_000)
    ap.add_argument("--interrupts", type=int, default=3)
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--interrupts-only", action="store_true", help="only part 2, added to --out's part 1")
    ap.add_argument("--out", default=DEFAULT_OUT, help="figures (bench/soak_long.json with --state)")
    ap.add_argument("--state", default=None,
                    help="resumable soak without a trace, checkpointed in this directory (e.g. out/stress)")
    ap.add_argument("--budget", type=float, default=None,
                    help="with --state: stop after about this many seconds (exit 3); the next call continues")
    ap.add_argument("--checkpoint", type=int, default=1_000_000, help="with --state: cycles between checkpoints")
    args = ap.parse_args(argv)
    rng = random.Random(args.seed)
    if args.state is not None:                 # the resumable soak: part 1 only, its own figures file
        res = soak_resumable(args.cycles, args.window, pathlib.Path(args.state), args.budget, args.checkpoint)
        out = pathlib.Path(args.out if args.out != DEFAULT_OUT else ROOT / "bench" / "soak_long.json")
        out.write_text(json.dumps(res, indent=2) + "\n")
        for k, v in res.items():
            print(f"{k:<45} {v}")
        res["interrupts_pass"] = True
        return res
    elif args.interrupts_only:                   # part 2 alone, added to an earlier part 1
        res = json.loads(pathlib.Path(args.out).read_text())
    else:
        res = soak(args.cycles, args.window, None)
        pathlib.Path(args.out).write_text(json.dumps(res, indent=2) + "\n")     # kept if part 2 fails
    runs = []
    with tempfile.TemporaryDirectory() as d:
        for _ in range(args.interrupts):
            runs.append(interrupted_run(pathlib.Path(d), rng.uniform(1.5, 6.0)))
    res["interrupts"] = runs
    res["interrupts_pass"] = all(r["returncode"] == 130 and r["rows"] > 0 and r["consecutive"] and r["sidecar"]
                                 for r in runs)
    for k, v in res.items():
        if k != "interrupts":
            print(f"{k:<45} {v}")
    for r in runs:
        print(f"SIGINT after {r['delay_s']:.2f} s: exit {r['returncode']}, {r['rows']} rows, "
              f"consecutive {r['consecutive']}, sidecar {r['sidecar']}, hang {r['hang']}")
        if r["hang"]:
            print(r["stderr_tail"])
    pathlib.Path(args.out).write_text(json.dumps(res, indent=2) + "\n")
    return res


if __name__ == "__main__":
    result = main()
    if not (result["soak_pass"] and result["interrupts_pass"]):
        sys.exit(1)
    sys.exit(3 if result.get("soak_complete") is False else 0)
