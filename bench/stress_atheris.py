"""Coverage-guided fuzzing with atheris (libFuzzer for Python) beside the generated campaigns (issue 30).

    python bench/stress_atheris.py run nc|params|scenario [--budget S] [--state DIR]
    python bench/stress_atheris.py status [--state DIR]

The same contract as bench/stress.py (its ``check_*`` functions: a documented error naming its
position, or a result whose run keeps every bound), on inputs that libFuzzer mutates towards new
coverage of ``distctrl`` (instrumented on import). The corpus lives in ``DIR/atheris/<suite>/``
(seeded with the shipped examples), so a new call continues from what earlier calls found: the
campaign is resumable by construction. ``--budget S`` (or ``$DISTCTRL_STRESS_BUDGET``; default 600)
is libFuzzer's ``-max_total_time``. An escape is saved under ``DIR/escapes/atheris-<suite>-<n>.txt``
(input and traceback) and the fuzzer goes on; ``DIR/atheris-<suite>.json`` accumulates the executed
inputs (libFuzzer's ``number_of_executed_units``), the coverage reached and the escapes.

atheris is the ``stress`` extra (``pip install -e '.[stress]'``; a manylinux wheel for CPython 3.11).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import time
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

SUITES = ("nc", "params", "scenario")
SEEDS = {"nc": ["examples/*.nc", "examples/scenarios/*.nc"],
         "params": ["examples/*.lis", "examples/scenarios/*.lis"],
         "scenario": ["examples/scenarios/*.toml"]}


def state_dir(arg: str | None) -> Path:
    return Path(arg or os.environ.get("DISTCTRL_STRESS_DIR") or ROOT / "out" / "stress")


def fuzz(suite: str, sdir: Path, libfuzzer_args: list[str]) -> None:
    """In the child: instrument distctrl, then hand TestOneInput to libFuzzer (it exits the process)."""
    import atheris

    with atheris.instrument_imports(include=["distctrl"]):
        import distctrl.nc  # noqa: F401
        import distctrl.params  # noqa: F401
        import distctrl.sim.runner  # noqa: F401
        import distctrl.sim.scenario  # noqa: F401
    import stress

    stress.parse_program("")
    escapes = sdir / "escapes"
    seen: dict[str, int] = {}

    def one(data: bytes) -> None:
        text = data.decode("utf-8", errors="replace")
        # a parameter list is read as an axis list and as a channel list (a byte choosing one let
        # every axis seed starting with '#' be read as a channel list and rejected on its first line)
        for item in ([(text, False), (text, True)] if suite == "params" else [text]):
            check_one(item)

    def check_one(item) -> None:
        try:
            stress.check(suite, item)
        except Exception as exc:  # noqa: BLE001 - the finding; recorded, the fuzzer goes on
            sig = stress.escape_signature(exc)
            seen[sig] = seen.get(sig, 0) + 1
            n = len(list(escapes.glob(f"atheris-{suite}-*.txt")))
            if seen[sig] <= 3:
                (escapes / f"atheris-{suite}-{n}.txt").write_text(
                    f"atheris {suite}\n{sig}\n\n--- input (repr)\n{item!r}\n\n--- traceback\n"
                    + "".join(traceback.format_exception(exc)))
                print(f"ESCAPE {sig}", file=sys.stderr, flush=True)

    atheris.Setup([sys.argv[0], *libfuzzer_args], one)
    atheris.Fuzz()


def run(suite: str, budget: float, sdir: Path) -> dict:
    corpus = sdir / "atheris" / suite
    seeds = sdir / "atheris" / f"{suite}-seeds"
    corpus.mkdir(parents=True, exist_ok=True)
    seeds.mkdir(parents=True, exist_ok=True)
    (sdir / "atheris" / "artifacts").mkdir(exist_ok=True)     # libFuzzer's slow units, crashes
    (sdir / "escapes").mkdir(exist_ok=True)
    for pattern in SEEDS[suite]:
        for p in sorted(ROOT.glob(pattern)):
            (seeds / p.name).write_bytes(p.read_bytes())
    path = sdir / f"atheris-{suite}.json"
    st = json.loads(path.read_text()) if path.exists() else {"suite": f"atheris-{suite}", "runs": 0, "wall_s": 0.0,
                                                           "calls": 0, "escapes": 0, "cov": None, "ft": None}
    before = len(list((sdir / "escapes").glob(f"atheris-{suite}-*.txt")))
    pylib = ROOT / "out" / "pylib"                 # atheris installed with --target (no venv of its own)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), str(pylib) if pylib.is_dir() else "",
                                                                    os.environ.get("PYTHONPATH", "")]))}
    args = [sys.executable, __file__, "_fuzz", suite, "--state", str(sdir), "--", str(corpus), str(seeds),
            f"-max_total_time={int(budget)}", "-print_final_stats=1", "-timeout=60", "-rss_limit_mb=4096",
            "-max_len=4096", "-close_fd_mask=1", f"-artifact_prefix={sdir / 'atheris' / 'artifacts'}/{suite}-"]
    t0 = time.perf_counter()
    log = sdir / f"atheris-{suite}.log"
    with open(log, "a") as f:
        proc = subprocess.run(args, cwd=ROOT, env=env, stdout=f, stderr=subprocess.STDOUT)
    wall = time.perf_counter() - t0
    text = log.read_text(errors="replace")[-200_000:]
    runs = re.findall(r"stat::number_of_executed_units:\s*(\d+)", text)
    cov = re.findall(r"cov: (\d+) ft: (\d+)", text)
    st["calls"] += 1
    st["runs"] += int(runs[-1]) if runs else 0
    st["wall_s"] += wall
    if cov:
        st["cov"], st["ft"] = int(cov[-1][0]), int(cov[-1][1])
    st["escapes"] += len(list((sdir / "escapes").glob(f"atheris-{suite}-*.txt"))) - before
    st["corpus_files"] = len(list(corpus.iterdir()))
    st["last_returncode"] = proc.returncode
    st["figures"] = {"inputs": st["runs"], "escapes": st["escapes"], "wall_s": round(st["wall_s"], 1),
                     "inputs_per_s": round(st["runs"] / st["wall_s"], 1) if st["wall_s"] else None,
                     "coverage_edges": st["cov"], "features": st["ft"], "corpus_files": st["corpus_files"],
                     "calls": st["calls"]}
    path.write_text(json.dumps(st, indent=1) + "\n")
    return st


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "_fuzz":
        sep = argv.index("--")
        ap = argparse.ArgumentParser()
        ap.add_argument("suite")
        ap.add_argument("--state")
        a = ap.parse_args(argv[1:sep])
        fuzz(a.suite, Path(a.state), argv[sep + 1:])
        return 0
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("suite", choices=SUITES)
    r.add_argument("--budget", type=float, default=float(os.environ.get("DISTCTRL_STRESS_BUDGET") or 600))
    r.add_argument("--state", default=None)
    s = sub.add_parser("status")
    s.add_argument("--state", default=None)
    args = ap.parse_args(argv)
    sdir = state_dir(args.state)
    if args.cmd == "status":
        for p in sorted(sdir.glob("atheris-*.json")):
            print(p.stem, json.dumps(json.loads(p.read_text()).get("figures")))
        return 0
    st = run(args.suite, args.budget, sdir)
    print(json.dumps(st["figures"], indent=1))
    return 1 if st["escapes"] else 0


if __name__ == "__main__":
    sys.exit(main())
