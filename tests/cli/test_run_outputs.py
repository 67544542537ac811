"""`distctrl run`'s outputs: the trace size options and outputs that cannot be written (issue 13)."""
from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from click.testing import CliRunner

from distctrl.cli import main
from distctrl.errors import ExitCode
from distctrl.sim.runner import estimate_trace, run
from distctrl.trace import Trace

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
DIST_1 = str(SCN / "dist_1.toml")


def test_decimate_records_every_nth_cycle_and_metrics_see_all(tmp_path):
    whole = run(DIST_1)
    thin = run(DIST_1, trace=tmp_path / "t.csv", decimate=10)
    assert thin.metrics == whole.metrics and thin.cycles == whole.cycles
    back = Trace.from_csv(tmp_path / "t.csv")
    assert back.rows == -(-whole.trace.rows // 10)
    assert back["t"][1] == pytest.approx(10 * whole.cycle_time) and back.meta["decimate"] == 10


def test_max_rows_is_a_ring_buffer_of_the_last_rows(tmp_path):
    r = run(DIST_1, trace=tmp_path / "t.csv", max_rows=500)
    back = Trace.from_csv(tmp_path / "t.csv")
    assert back.rows == 500 and back["t"][-1] == pytest.approx((r.cycles - 1) * r.cycle_time)
    assert back.meta["dropped_rows"] == r.cycles - 500


def test_plot_and_report_keep_a_thinned_trace_not_the_whole_run(tmp_path):
    r = run(DIST_1, keep_at_most=1000)
    assert r.trace.rows <= 1000 and r.trace.meta["kept_every"] >= 2
    res = CliRunner().invoke(main, ["run", DIST_1, "--plot", str(tmp_path / "p.png"), "--report",
                                    str(tmp_path / "rep")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "p.png").stat().st_size > 10_000 and (tmp_path / "rep" / "index.html").exists()


def test_the_size_of_a_long_trace_is_said_before_the_run(tmp_path):
    est = estimate_trace(DIST_1)
    assert est["rows"] == 30_000 and est["csv_bytes"] == est["rows"] * est["columns"] * 19
    assert estimate_trace(DIST_1, decimate=10)["rows"] == 3000 and estimate_trace(DIST_1, max_rows=7)["rows"] == 7
    long = tmp_path / "long.toml"
    text = (SCN / "dist_1.toml").read_text().replace("duration = 30.0", "duration = 3000.0")
    long.write_text(text.replace('program = "../dist_1.nc"', f'program = "{(SCN.parent / "dist_1.nc").as_posix()}"')
                    .replace('params = "z_probe.lis"', f'params = "{(SCN / "z_probe.lis").as_posix()}"'))
    res = CliRunner().invoke(main, ["run", str(long), "--trace", str(tmp_path / "t.csv"), "--json"])
    assert res.exit_code == 0, res.stderr
    assert "up to 3,000,000 rows" in res.stderr and "1.3 GB (CSV)" in res.stderr and "--decimate" in res.stderr
    assert json.loads(res.stdout)["outcome"] == "completed"


@pytest.mark.parametrize("option,path,what", [
    ("--trace", "/proc/distctrl-x.csv", "trace"), ("--plot", "/proc/distctrl-x.png", "plot"),
    ("--report", "/proc/distctrl-rep", "report folder"), ("--trace", "/dev/full", None)])
def test_an_output_that_cannot_be_written_is_one_line_naming_the_path(option, path, what):
    if not os.path.exists("/proc/self") or (path == "/dev/full" and not os.path.exists(path)):
        pytest.skip("needs Linux /proc and /dev/full")
    res = CliRunner().invoke(main, ["run", DIST_1, option, path])
    assert res.exit_code == ExitCode.INVALID_INPUT
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and path in lines[0], res.stderr
    assert "Traceback" not in res.stderr and res.exception is None or isinstance(res.exception, SystemExit)
    if what:
        assert f"the {what}" in lines[0]


def test_decimate_and_max_rows_refuse_nonsense():
    for opt in (["--decimate", "0"], ["--max-rows", "-3"]):
        assert CliRunner().invoke(main, ["run", DIST_1, *opt]).exit_code == ExitCode.INVALID_INPUT


# ----------------------------------------------------------------------------- R6: the demo's comparison from run

PLATE = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "plasma_plate_short.toml"


def _run_json(*args):
    import json

    from click.testing import CliRunner

    from distctrl.cli import main

    r = CliRunner().invoke(main, ["run", str(PLATE), "--json", *args])
    return r, (json.loads(r.stdout) if r.stdout.strip() else None)


def test_run_without_the_process_functions_gives_the_demo_table_figures():
    """R6 (new-user audit): the demo's with/without comparison could not be reproduced with `run`
    (no way to switch the [[process]] tables off, and none of the cut figures). --no-process runs
    the plate as the demo's "without" column, and the JSON has the demo table's figures."""
    from distctrl.sim.plates import plate_figures

    r, doc = _run_json("--no-process")
    assert doc is not None, r.output
    want = plate_figures(PLATE, functions=False)
    cut = doc["cut"]
    assert doc["processes"] == [] and doc["metrics"]["collisions"] == want["collisions"] > 0
    assert doc["metrics"]["min_distance_mm"] == want["min_distance_mm"]
    for key in ("min_cut_distance_mm", "time_below_half_s", "path_time_s", "set_distance_mm"):
        assert cut[key] == want[key], key


def test_run_with_some_process_functions_only():
    r, doc = _run_json("--process", "corner_lock,void_lock")
    assert doc is not None, r.output
    assert doc["processes"] == ["corner_lock", "void_lock"]
    assert doc["cut"]["path_time_s"] is not None


@pytest.mark.parametrize("args, words", [
    (["--process", "corner_lock,nosuch"], ["nosuch", "corner_lock", "void_lock", "touch_off", "lift"]),
    (["--process", "corner_lock", "--no-process"], ["--no-process", "--process"]),
])
def test_run_process_selection_errors_exit_1(args, words):
    r, doc = _run_json(*args)
    assert r.exit_code == 1 and doc["outcome"] == "error"
    for w in words:
        assert w in doc["error"], doc["error"]


def test_run_summary_prints_the_cut_figures():
    from click.testing import CliRunner

    from distctrl.cli import main

    r = CliRunner().invoke(main, ["run", str(PLATE), "--no-process"])
    assert "while cutting (G1): min" in r.stdout and "path time" in r.stdout
    # the time below half is counted over every cycle distance control ran, against the set distance in
    # force (a touch-off's back-off to its pierce height included, docs/process.md): not "while cutting"
    cutting = next(line for line in r.stdout.splitlines() if "while cutting (G1)" in line)
    assert "below" not in cutting, cutting
    assert "while distance control ran: " in r.stdout and "below ½ the set distance in force" in r.stdout
    assert "process functions: none (--no-process)" in r.stdout
