"""Resumable stress campaigns (issue 30): 10^6 hostile inputs per kind, checked one by one.

    python bench/stress.py run nc|params|scenario [--target N] [--budget S] [--state DIR]
    python bench/stress.py status [--state DIR]
    python bench/stress.py show SUITE I        # print input I of a suite (to reproduce an escape)

Input ``i`` of a suite is a pure function of (seed, suite, i) (bench/stress_inputs.py), so the
campaign's state is a counter: ``DIR/<suite>.json`` (default ``out/stress``, or
``$DISTCTRL_STRESS_DIR``) holds the next input, the outcome counts, the escapes and the wall time,
written every few seconds and when the campaign stops. ``run`` continues where the file says;
``--budget S`` (or ``$DISTCTRL_STRESS_BUDGET``) stops after about S seconds with exit 3 (the time
limit's code), SIGTERM / SIGINT stop it after the current input, with the state saved.

Contract per input (the one of tests/reliability/test_input_fuzz.py): accepted, or rejected with the
documented error type naming file and line (NC: and column; scenarios: the key path, or the line for
TOML syntax); accepted programs and scenarios are run for 0.15 s and every cycle of that run is
checked: no NaN or inf in any axis's offset or command position, the offset within max_deviation,
the commanded position inside the software limits whenever the programmed one is. Anything else (an
exception of another type, a message without its position, a violated bound, no result after
``WATCHDOG_S`` of CPU time or ``HANG_WALL_S`` of wall time) is an *escape*: its input index, kind and traceback are saved under
``DIR/escapes/`` and the campaign goes on. Inputs slower than ``SLOW_S`` are counted.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import random
import re
import signal
import sys
import time
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import stress_inputs as gen  # noqa: E402

from distctrl.errors import ParameterError  # noqa: E402
from distctrl.nc import NcSyntaxError, parse_program  # noqa: E402
from distctrl.params import parse_list_text  # noqa: E402
from distctrl.params.channel import CHANNEL_LIST  # noqa: E402
from distctrl.sim.runner import run  # noqa: E402
from distctrl.sim.scenario import ScenarioError, scenario_from_dict, scenario_from_text  # noqa: E402
from tests.reliability import test_input_fuzz as fuzz_suite  # noqa: E402

TARGET = 1_000_000
SEED = 30
RUN_SECONDS = fuzz_suite.RUN_SECONDS
#: a hang: no result after this much CPU time of the campaign's process (ITIMER_PROF); a wall-clock
#: bound made inputs of a process starved on a loaded machine (nice 19, load 25 on 2 cores) look like
#: hangs (replayed: 0.1-1.7 s). A process blocked without using CPU is caught by HANG_WALL_S.
WATCHDOG_S = 30
HANG_WALL_S = 900
SLOW_S = 2.0
SAVE_EVERY_S = 10.0
#: exit codes shared by the CLI (0 ok, 1 escapes found, 3 time limit: the campaign is not complete)
EXIT_ESCAPES, EXIT_TIME_LIMIT = 1, 3


class Escape(Exception):
    """An input broke the contract: ``kind`` names how."""

    def __init__(self, kind: str, detail: str):
        super().__init__(f"{kind}: {detail}")
        self.kind, self.detail = kind, detail


class Hang(Exception):
    pass


def n_lines(text: str) -> int:
    return len(text.splitlines()) or 1


# ------------------------------------------------------------------ the run's per-cycle bounds

class Bounds:
    """plc_program hook: checks every cycle's outputs (before the CNC reads the PLC interface)."""

    def __init__(self):
        self.cycles = 0

    def __call__(self, machine, cycle):
        self.cycles += 1
        for name, out in machine.outputs.items():
            o, c = out.offset, out.command_position
            if not (math.isfinite(o) and math.isfinite(c)):
                raise Escape("nonfinite", f"cycle {cycle} axis {name}: offset {o}, command position {c}")
            ctrl = machine.controllers.get(name)
            if ctrl is None or name not in machine.dc_axes:
                continue
            p = ctrl.params
            if abs(o) > p.max_deviation * (1 + 1e-9) + 1e-9:
                raise Escape("bound", f"cycle {cycle} axis {name}: |offset| {abs(o)} > max_deviation {p.max_deviation}")
            if p.check_sw_limit_switch:
                prog = c - o
                lo, hi = p.sw_limit_min, p.sw_limit_max
                if lo <= prog <= hi and not (lo - 1e-9 <= c <= hi + 1e-9):
                    raise Escape("bound", f"cycle {cycle} axis {name}: command {c} outside [{lo}, {hi}] "
                                          f"(programmed {prog})")


def checked_run(scenario) -> str:
    bounds = Bounds()
    result = run(scenario, keep_trace=False, plc_program=bounds)
    for err in result.errors:
        if not err.get("message"):
            raise Escape("message", f"run-time error without a message: {err}")
    return "runtime_error" if result.errors or result.aborted else "ran"


# ------------------------------------------------------------------ the suites' checks

# the scenario templates the NC inputs run in are the fuzz suite's (tests/reliability), so the
# campaign checks what make test checks, at volume
AXIS_SCENARIO, SCENARIO_3D = fuzz_suite.AXIS_SCENARIO, fuzz_suite.SCENARIO_3D


def check_nc(text: str) -> list[str]:
    try:
        parse_program(text, "fuzz.nc")
    except NcSyntaxError as exc:
        if exc.file != "fuzz.nc" or not exc.message or exc.message.startswith("internal parser error"):
            raise Escape("message", f"NcSyntaxError without file/message: {exc}") from exc
        if exc.line is None or not 1 <= exc.line <= n_lines(text) + 1 or exc.column is None or exc.column < 1:
            raise Escape("position", f"line {exc.line} column {exc.column} of {n_lines(text)} lines: {exc}") from exc
        return ["rejected"]
    base = SCENARIO_3D if "#DIST" in text.upper() or "#KIN" in text.upper() else AXIS_SCENARIO
    scenario = scenario_from_dict({**base, "program_text": text}, base_dir=gen.SCN, source="fuzz.toml")
    return ["accepted", checked_run(scenario)]


def check_params(text: str, channel: bool) -> list[str]:
    try:
        parse_list_text(text, "fuzz.lis", **({"fmt": CHANNEL_LIST} if channel else {}))
    except ParameterError as exc:
        if exc.file != "fuzz.lis" or exc.line is None or not 1 <= exc.line <= n_lines(text) \
                or not str(exc).startswith(f"fuzz.lis:{exc.line}: ") or not str(exc)[len(f"fuzz.lis:{exc.line}: "):].strip():
            raise Escape("position", f"line {exc.line} of {n_lines(text)}: {exc}") from exc
        return ["rejected", "channel" if channel else "axis"]
    return ["accepted", "channel" if channel else "axis"]


def check_scenario(text: str) -> list[str]:
    try:
        scenario = scenario_from_text(text, base_dir=gen.SCN, source="fuzz.toml")
    except ScenarioError as exc:
        if exc.file != "fuzz.toml" or not str(exc).startswith("fuzz.toml") or not exc.key \
                or len(str(exc)) <= len("fuzz.toml: "):
            raise Escape("message", f"ScenarioError without file/key: {exc}") from exc
        if exc.key == "toml" and (exc.line is None or not 1 <= exc.line <= n_lines(text) + 1):
            raise Escape("position", f"TOML error at line {exc.line} of {n_lines(text)}: {exc}") from exc
        return ["rejected"]
    except ParameterError as exc:
        if not exc.file or exc.line is None or not str(exc).strip():
            raise Escape("position", f"ParameterError without file:line: {exc}") from exc
        return ["rejected"]
    except NcSyntaxError as exc:
        if not exc.file or exc.line is None or not exc.message:
            raise Escape("position", f"NcSyntaxError without file/line: {exc}") from exc
        return ["rejected"]
    short = dataclasses.replace(scenario, duration=min(scenario.duration or RUN_SECONDS, RUN_SECONDS), settle_time=0.0)
    try:
        return ["accepted", checked_run(short)]
    except NcSyntaxError as exc:                   # program = a file that does not parse
        if not exc.file or exc.line is None or not exc.message:
            raise Escape("position", f"NcSyntaxError without file/line: {exc}") from exc
        return ["accepted", "run_rejected"]


def make_input(suite: str, i: int, seed: int = SEED):
    r = random.Random(f"{seed}:{suite}:{i}")
    if suite == "nc":
        return gen.nc_input(r)
    if suite == "params":
        return gen.params_input(r)
    return gen.scenario_input(r)


def check(suite: str, item) -> list[str]:
    if suite == "nc":
        return check_nc(item)
    if suite == "params":
        return check_params(*item)
    return check_scenario(item)


TEXT_SUITES = ("nc", "params", "scenario")

# ------------------------------------------------------------------ the campaign loop


def state_dir(arg: str | None) -> Path:
    return Path(arg or os.environ.get("DISTCTRL_STRESS_DIR") or ROOT / "out" / "stress")


def load_state(path: Path, suite: str, seed: int, start: int = 0) -> dict:
    if path.exists():
        st = json.loads(path.read_text())
        if "fixed" in st:                           # the first name of "rechecked"
            st["rechecked"] = {**st.pop("fixed"), **st.get("rechecked", {})}
        if st["seed"] != seed:
            raise SystemExit(f"{path}: a campaign with seed {st['seed']} is under way; remove the file to start "
                             f"one with seed {seed}")
        return st
    return {"suite": suite, "seed": seed, "start": start, "next": start, "counts": {}, "escapes": {},
            "escape_inputs": 0, "wall_s": 0.0, "segments": 0, "slow": 0, "max_input_s": 0.0}


def state_path(sdir: Path, suite: str, start: int) -> Path:
    """``<suite>.json`` for the inputs from 0, ``<suite>@<start>.json`` for a share from ``start`` (a
    second process on the same suite: ``run nc --start 500000``, the first with ``--target 500000``)."""
    return sdir / (f"{suite}.json" if start == 0 else f"{suite}@{start}.json")


def save_state(path: Path, st: dict) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(st, indent=1, sort_keys=True) + "\n")
    os.replace(tmp, path)


def escape_signature(exc: BaseException) -> str:
    if isinstance(exc, Escape):
        return f"{exc.kind}: {exc.detail.split(':')[0][:80]}"
    tb = traceback.extract_tb(exc.__traceback__)
    where = f"{Path(tb[-1].filename).name}:{tb[-1].lineno}" if tb else "?"
    return f"{type(exc).__name__} at {where}"


def run_campaign(suite: str, target: int, budget_s: float | None, sdir: Path, seed: int = SEED,
                 log=print, start: int = 0) -> dict:
    sdir.mkdir(parents=True, exist_ok=True)
    (sdir / "escapes").mkdir(exist_ok=True)
    path = state_path(sdir, suite, start)
    st = load_state(path, suite, seed, start)
    st["target"] = target
    st["segments"] += 1
    stop = {"why": None}

    def on_signal(signum, frame):  # noqa: ARG001
        stop["why"] = signal.Signals(signum).name

    def on_alarm(signum, frame):  # noqa: ARG001
        raise Hang(f"no result after {WATCHDOG_S} s of CPU time" if signum == signal.SIGPROF
                   else f"no result after {HANG_WALL_S} s")

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGTERM, signal.SIGINT)}
    old_alarm = signal.signal(signal.SIGALRM, on_alarm)
    old_prof = signal.signal(signal.SIGPROF, on_alarm)
    counts = st["counts"]
    t0 = time.perf_counter()
    wall0 = st["wall_s"]
    last_save = t0
    try:
        while st["next"] < target and not stop["why"]:
            i = st["next"]
            item = make_input(suite, i, seed)
            started = time.perf_counter()
            signal.setitimer(signal.ITIMER_PROF, WATCHDOG_S)
            signal.alarm(HANG_WALL_S)
            try:
                outcome = check(suite, item)
            except (Escape, Hang, Exception) as exc:      # noqa: BLE001 - every other exception is the finding
                signal.setitimer(signal.ITIMER_PROF, 0)
                signal.alarm(0)
                sig = "hang" if isinstance(exc, Hang) else escape_signature(exc)
                outcome = ["escape"]
                st["escape_inputs"] += 1
                seen = st["escapes"].setdefault(sig, {"count": 0, "first_input": i})
                seen["count"] += 1
                seen.setdefault("inputs", []).append(i) if len(seen.get("inputs", [])) < 1000 else None
                if seen["count"] <= 3:
                    (sdir / "escapes" / f"{suite}-{i}.txt").write_text(
                        f"suite {suite} seed {seed} input {i}\n{sig}\n\n--- input (repr)\n{item!r}\n\n--- traceback\n"
                        + "".join(traceback.format_exception(exc)))
                    log(f"[{suite}] ESCAPE at input {i}: {sig}")
            finally:
                signal.setitimer(signal.ITIMER_PROF, 0)
                signal.alarm(0)
            took = time.perf_counter() - started
            if took > SLOW_S:
                st["slow"] += 1
            st["max_input_s"] = max(st["max_input_s"], took)
            counts["inputs"] = counts.get("inputs", 0) + 1
            for o in outcome:
                counts[o] = counts.get(o, 0) + 1
            st["next"] = i + 1
            now = time.perf_counter()
            st["wall_s"] = wall0 + (now - t0)
            if now - last_save > SAVE_EVERY_S:
                save_state(path, st)
                last_save = now
            if budget_s is not None and now - t0 >= budget_s:
                stop["why"] = "budget"
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old_alarm)
        signal.signal(signal.SIGPROF, old_prof)
        for s, h in old.items():
            signal.signal(s, h)
        st["wall_s"] = wall0 + (time.perf_counter() - t0)
        st["stopped_by"] = stop["why"]
        save_state(path, st)
    return st


def recheck(sdir: Path, seed: int = SEED, log=print) -> dict:
    """Replay every recorded escape with the current code; the escapes of a kind whose every input now
    passes move from ``escapes`` to ``rechecked`` (the campaign's record of what it found: fixed since,
    or not reproduced, which docs/reliability.md tells apart); the others stay."""
    out = {}
    for path in sorted(sdir.glob("*.json")):
        st = json.loads(path.read_text())
        if st.get("suite") not in TEXT_SUITES:
            continue
        suite = st["suite"]
        for sig, seen in list(st["escapes"].items()):
            inputs = seen.get("inputs") or sorted(
                int(m.group(1)) for f in (sdir / "escapes").glob(f"{suite}-*.txt")
                if (m := re.match(r"suite \S+ seed \d+ input (\d+)\n(.*)\n", f.read_text())) and m.group(2) == sig
                and st.get("start", 0) <= int(m.group(1)) < st.get("target", TARGET))
            if len(inputs) != seen["count"]:
                log(f"{path.name}: {sig}: {seen['count']} escapes, {len(inputs)} inputs known: not rechecked")
                continue
            still = []
            for i in inputs:
                try:
                    check(suite, make_input(suite, i, st["seed"]))
                except Exception as exc:  # noqa: BLE001
                    still.append((i, escape_signature(exc)))
            if still:
                log(f"{path.name}: {sig}: {len(still)} of {len(inputs)} still escape, e.g. input {still[0]}")
                continue
            st.setdefault("rechecked", {})[sig] = {"count": seen["count"], "inputs": inputs}
            del st["escapes"][sig]
            st["escape_inputs"] -= seen["count"]
            log(f"{path.name}: {sig}: all {len(inputs)} inputs pass now")
        save_state(path, st)
        out[path.stem] = {"escapes": st["escape_inputs"], "rechecked": st.get("rechecked", {})}
    return out


def figures(st: dict) -> dict:
    start = st.get("start", 0)
    done = st["next"] - start
    rate = done / st["wall_s"] if st["wall_s"] else None
    target = st.get("target", TARGET)
    return {"inputs": done, "range": [start, target], "complete": st["next"] >= target,
            "escapes": st["escape_inputs"], "escape_kinds": {k: v["count"] for k, v in st["escapes"].items()},
            "outcomes": st["counts"], "wall_s": round(st["wall_s"], 1),
            "inputs_per_s": round(rate, 1) if rate else None,
            "projected_total_s": round((target - start) / rate) if rate else None,
            "segments": st["segments"], "slow_inputs": st["slow"], "max_input_s": round(st["max_input_s"], 3),
            "seed": st["seed"], "rechecked": {k: v["count"] for k, v in st.get("rechecked", {}).items()}}


def merge(shares: list[dict]) -> dict:
    """One suite's figures from its shares (processes over disjoint input ranges)."""
    if len(shares) == 1:
        return shares[0]
    out = {"inputs": sum(f["inputs"] for f in shares), "ranges": [f["range"] for f in shares],
           "complete": all(f["complete"] for f in shares), "escapes": sum(f["escapes"] for f in shares),
           "escape_kinds": {}, "outcomes": {}, "process_s": round(sum(f["wall_s"] for f in shares), 1),
           "wall_s": round(max(f["wall_s"] for f in shares), 1), "processes": len(shares),
           "slow_inputs": sum(f["slow_inputs"] for f in shares),
           "max_input_s": max(f["max_input_s"] for f in shares), "seed": shares[0]["seed"], "rechecked": {}}
    for f in shares:
        for k, v in f["escape_kinds"].items():
            out["escape_kinds"][k] = out["escape_kinds"].get(k, 0) + v
        for k, v in f["outcomes"].items():
            out["outcomes"][k] = out["outcomes"].get(k, 0) + v
        for k, v in f.get("rechecked", {}).items():
            out["rechecked"][k] = out["rechecked"].get(k, 0) + v
    out["inputs_per_process_s"] = round(out["inputs"] / out["process_s"], 1) if out["process_s"] else None
    return out


def write_figures(sdir: Path, out: Path) -> dict:
    """bench/reliability.json's "stress" section from every campaign state under ``sdir``."""
    data = json.loads(out.read_text()) if out.exists() else {}
    section = data.setdefault("stress", {})
    shares: dict[str, list[dict]] = {}
    for p in sorted(sdir.glob("*.json")):
        st = json.loads(p.read_text())
        if st.get("suite") in TEXT_SUITES:
            shares.setdefault(st["suite"], []).append(figures(st))
        elif "figures" in st:                      # the serve campaigns (bench/stress_serve.py), soak
            section[p.stem] = st["figures"]
    for suite, fs in shares.items():
        section[suite] = merge(fs)
    soak = ROOT / "bench" / "soak_long.json"             # bench/soak.py --state (the resumable soak)
    if soak.exists():
        section["soak"] = {k.removeprefix("soak_"): v for k, v in json.loads(soak.read_text()).items()
                           if k not in ("soak_rss_segments_mb", "soak_trace")}
    out.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")
    return section


def markdown(sdir: Path) -> str:
    """The campaigns' figures as the table of docs/reliability.md."""
    rows = ["| campaign | done | rate on this machine | escapes (rechecked) |", "| --- | --- | --- | --- |"]
    shares: dict[str, list[dict]] = {}
    other = {}
    for p in sorted(sdir.glob("*.json")):
        st = json.loads(p.read_text())
        if st.get("suite") in TEXT_SUITES:
            shares.setdefault(st["suite"], []).append(figures(st))
        elif "figures" in st:
            other[p.stem] = st["figures"]
    for suite, fs in shares.items():
        f = merge(fs)
        rate = f.get("inputs_per_process_s") or f.get("inputs_per_s")
        rows.append(f"| {suite} | {f['inputs']:,} inputs{' (complete)' if f['complete'] else ''}; "
                    + ", ".join(f"{k} {v:,}" for k, v in sorted(f["outcomes"].items()) if k != "inputs")
                    + f" | {rate} inputs/s per process, {f.get('process_s', f['wall_s'])} process-s |"
                    f" {f['escapes']} ({', '.join(f'{k} x{v}' for k, v in f['rechecked'].items()) or '-'}) |")
    for name, f in sorted(other.items()):
        if name.startswith("atheris"):
            rows.append(f"| {name} | {f['inputs']:,} inputs, {f['coverage_edges']} edges, {f['corpus_files']} corpus files"
                        f" | {f['inputs_per_s']} inputs/s, {f['wall_s']} s | {f['escapes']} |")
        elif "target_counts" in f:
            rows.append(f"| {name} | {f['inputs']:,} inputs, {f['counts'].get('frames', 0):,} frames; "
                        f"{f['health_checks']} health checks | {f['inputs_per_s']} inputs/s, {f.get('frames_per_s')} frames/s,"
                        f" {f['wall_s']} s | {f['escapes']} ({', '.join(f'{k} x{v}' for k, v in f.get('rechecked', {}).items()) or '-'}) |")
    return "\n".join(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="run (or continue) a campaign")
    r.add_argument("suite", choices=TEXT_SUITES)
    r.add_argument("--target", type=int, default=TARGET, help="run up to this input index (exclusive)")
    r.add_argument("--start", type=int, default=0, help="a share of the inputs from this index (own state file)")
    r.add_argument("--budget", type=float, default=float(os.environ["DISTCTRL_STRESS_BUDGET"])
                   if os.environ.get("DISTCTRL_STRESS_BUDGET") else None)
    r.add_argument("--state", default=None)
    r.add_argument("--seed", type=int, default=SEED)
    r.add_argument("--figures", default=str(ROOT / "bench" / "reliability.json"),
                   help="write the stress section here afterwards ('' = do not)")
    s = sub.add_parser("status", help="figures of every campaign under the state directory")
    s.add_argument("--state", default=None)
    s.add_argument("--figures", default="")
    s.add_argument("--markdown", action="store_true", help="a table of the figures for docs/reliability.md")
    c = sub.add_parser("recheck", help="replay the recorded escapes; those that pass now move to 'rechecked'")
    c.add_argument("--state", default=None)
    w = sub.add_parser("show", help="print input I of a suite")
    w.add_argument("suite", choices=TEXT_SUITES)
    w.add_argument("i", type=int)
    w.add_argument("--seed", type=int, default=SEED)
    args = ap.parse_args(argv)
    if args.cmd == "show":
        print(repr(make_input(args.suite, args.i, args.seed)))
        return 0
    sdir = state_dir(args.state)
    if args.cmd == "recheck":
        parse_program("")
        res = recheck(sdir)
        print(json.dumps(res, indent=1))
        return EXIT_ESCAPES if any(v["escapes"] for v in res.values()) else 0
    if args.cmd == "status" and args.markdown:
        print(markdown(sdir))
        return 0
    if args.cmd == "status":
        for p in sorted(sdir.glob("*.json")):
            st = json.loads(p.read_text())
            if st.get("suite") in TEXT_SUITES:
                print(p.stem, json.dumps(figures(st)))
            elif "figures" in st:
                print(p.stem, json.dumps(st["figures"]))
        if args.figures:
            write_figures(sdir, Path(args.figures))
        return 0
    parse_program("")                              # build the parser outside the first input's time
    st = run_campaign(args.suite, args.target, args.budget, sdir, args.seed, start=args.start)
    f = figures(st)
    print(json.dumps(f, indent=1))
    if args.figures:
        write_figures(sdir, Path(args.figures))
    if st["escape_inputs"]:
        return EXIT_ESCAPES
    return 0 if f["complete"] else EXIT_TIME_LIMIT


if __name__ == "__main__":
    sys.exit(main())
