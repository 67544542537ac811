"""What a run says happened (issue 13): when it ends, its outcome word and exit code, and an NC
run-time error stopping the program at the cycle it happened (docs/run.md)."""
from __future__ import annotations

import json

from click.testing import CliRunner

from distctrl.cli import main
from distctrl.errors import ExitCode
from distctrl.sim.runner import run
from distctrl.trace import sidecar_path

from .test_run import SCN
from .test_run import base_scenario as _base


def base_scenario(program_text, *, duration=8.0, **kw):
    """test_run's scenario; ``duration=None``: no duration key (the run's limit is one hour)."""
    sc = _base(program_text, duration=duration if duration is not None else 1.0, **kw)
    if duration is None:
        import dataclasses
        sc = dataclasses.replace(sc, duration=None)
    return sc


def read_sidecar(csv):
    return json.loads(sidecar_path(csv).read_text(encoding="utf-8"))

NOISY = {"axis": "Z", "kind": "encoder", "range_min": -20.0, "range_max": 20.0, "noise_std": 0.002, "seed": 3}


def _end_of_program(r) -> float:
    """Time of the last cycle on which the NC still showed a line before the end (s)."""
    t = r.trace["t"]
    moving = (abs(r.trace["X.prog"][1:] - r.trace["X.prog"][:-1]) > 0)
    return float(t[1:][moving][-1]) if moving.any() else 0.0


def test_a_program_that_leaves_distance_control_active_ends_soon_after_m30():
    """A 1 s program leaving distance control ACTIVE (70332) on a noisy sensor and an encoder grid the
    setpoint is not on: the run ends settle_time (0.5 s) after the program, not at the 1 h limit."""
    r = run(base_scenario("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=1.00003]\nN20 G1 X50 F3000\nN30 M30\n",
                          start_z=41.0, surface={"base": 40.0}, sensor=NOISY, duration=None))
    assert r.outcome == "completed" and r.exit_code == ExitCode.OK
    assert [w["id"] for w in r.warnings] == [70332] and r.final_state == "ACTIVE_CONST_DIST"
    assert r.cycles * r.cycle_time < _end_of_program(r) + 0.5 + 0.5     # settle_time + the drives


def test_a_program_that_leaves_distance_control_frozen_ends_soon_after_m30():
    r = run(base_scenario("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=1.00003]\nN20 G1 X20 F3000\n"
                          "N30 Z[DIST_CTRL FREEZE]\nN40 G1 X40\nN50 M30\n",
                          start_z=41.0, surface={"base": 40.0}, sensor=NOISY, duration=None))
    assert r.outcome == "completed" and r.final_state == "FREEZE"
    assert r.cycles * r.cycle_time < _end_of_program(r) + 0.5 + 0.5     # settle_time + the drives


def test_an_nc_run_time_error_stops_the_program_at_its_cycle_and_distance_control_holds_in_error():
    """G1 without F at N30, 0.3 s into the program: 900010 at that time and line, distance control
    goes to ERROR holding its offset, the motion stops, the run ends settle_time later (exit 2)."""
    r = run(base_scenario("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]\nN20 #TIME 0.3\nN30 G1 X50\nN40 M30\n",
                          start_z=41.0, surface={"base": 40.0}, duration=10.0))
    assert r.outcome == "aborted" and r.exit_code == ExitCode.ABORTED
    assert [(e["id"], e["line"]) for e in r.errors] == [(900010, 3)]
    assert 0.29 < r.errors[0]["t"] < 0.33
    assert r.final_state == "ERROR"
    assert r.cycles * r.cycle_time < 0.33 + 0.5 + 0.2
    tr = r.trace
    k = int(round(0.4 / r.cycle_time))
    assert (tr["Z.dc.state"][k:] == 5).all() and abs(tr["Z.dc.offset"][-1] - tr["Z.dc.offset"][k]) < 1e-12


def test_a_run_stopped_at_its_duration_is_a_time_limit_not_an_error(tmp_path):
    sc = base_scenario("N10 G1 X50 F600\nN20 #TIME 100\nN30 M30\n", duration=1.0)
    r = run(sc)
    assert r.outcome == "time_limit" and r.exit_code == ExitCode.TIME_LIMIT and r.errors == []
    assert not r.completed and not r.aborted
    toml = tmp_path / "long.toml"
    toml.write_text(f'name = "long"\nduration = 0.5\nprogram_text = "N10 #TIME 100\\nN20 M30"\n'
                    f'[axes.Z]\nparams = "{SCN / "z_probe.lis"}"\n')
    res = CliRunner().invoke(main, ["run", str(toml)])
    assert res.exit_code == 3, res.output
    assert "stopped at the time limit (duration 0.5 s)" in res.output and "ABORTED" not in res.output
    js = json.loads(CliRunner().invoke(main, ["run", str(toml), "--json"]).output)
    assert js["outcome"] == "time_limit" and js["exit_code"] == 3


def test_an_interrupted_run_says_so_and_its_trace_sidecar_is_not_complete(tmp_path):
    def plc(machine, cycle):
        if cycle == 300:
            raise KeyboardInterrupt

    csv = tmp_path / "t.csv"
    r = run(base_scenario("N10 G1 X50 F600\nN20 M30\n", duration=10.0), trace=csv, plc_program=plc)
    assert r.outcome == "interrupted" and r.interrupted and r.exit_code == ExitCode.INTERRUPTED
    side = read_sidecar(csv)
    assert side["complete"] is False and side["meta"]["outcome"] == "interrupted"
    assert side["rows"] == 300


def test_a_completed_run_has_a_complete_sidecar_with_its_outcome(tmp_path):
    csv = tmp_path / "t.csv"
    r = run(base_scenario("N10 G1 X5 F600\nN20 M30\n"), trace=csv)
    side = read_sidecar(csv)
    assert r.outcome == "completed" and side["complete"] is True and side["meta"]["outcome"] == "completed"


def test_the_summary_words_follow_the_outcome():
    res = CliRunner().invoke(main, ["run", str(SCN / "dist_1.toml")])
    assert res.exit_code == 0 and ": completed after" in res.output
