"""``distctrl machine show | record | write`` against ``distctrl serve``'s machine (issue 28)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from distctrl.cli import main

from .conftest import serve

ROOT = Path(__file__).resolve().parents[2]
SCN = ROOT / "examples" / "scenarios"


def scenario(program: str):
    from distctrl.sim.scenario import scenario_from_dict
    return scenario_from_dict({
        "name": "client test", "program_text": program,
        "axes": {"X": {"start": 0.0}, "Z": {"params": str(SCN / "z_laser.lis"), "start": 31.5}},
        "surface": {"base": 30.0}, "sensor": {"axis": "Z", "kind": "encoder", "noise_std": 0.001}},
        base_dir=SCN)


@pytest.fixture(scope="module")
def idle():
    sm = serve(scenario("N10 #TIME 3600\nN20 M30\n"))
    yield sm
    sm.stop()


@pytest.fixture(scope="module")
def active():
    sm = serve(scenario("N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]\nN20 #TIME 3600\nN30 M30\n"))
    yield sm
    sm.stop()


def run(*args):
    r = CliRunner().invoke(main, [str(a) for a in args])
    return r, (json.loads(r.stdout) if "--json" in args and r.stdout.strip() else None)


def ads(sm):
    return ["--ads", sm.net_id, "--ip", sm.host]


def pending_after_next_cycles(sm, name: str, timeout_s: float = 20.0):
    """The controller's pending value of ``name`` once the served machine has run two more cycles: a
    CNC-object write is queued into the next cycle's commands (on a busy machine the cycle thread may
    not have run it when the client returns)."""
    import time
    with sm.lock:
        target = sm.machine.cycle + 2
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with sm.lock:
            if sm.machine.cycle >= target:
                return sm.machine.controllers["Z"].state.pending.get(name)
        time.sleep(0.01)
    raise AssertionError(f"the served machine ran no cycle in {timeout_s} s")


def test_show_lists_axes_with_state_and_parameters_in_list_units(idle, tmp_path):
    r, j = run("machine", "show", *ads(idle), "--json", "--out", tmp_path / "machine.lis")
    assert r.exit_code == 0, r.output
    assert [(a["index"], a["state"]) for a in j["axes"]] == [(1, "IDLE"), (2, "IDLE")]
    z = j["axes"][1]["parameters"]
    assert z["kp"] == 0.5 and z["d_tv"] == 0.002 and z["v_max"] == 200000 and z["a_max"] == 20000
    assert z["filter_type"] == "MOVING_AVERAGE" and z["n_cycles"] == 4
    assert j["axes"][1]["details"]["v_max"]["unit"] == "µm/s" and j["channels"] == []
    # the list is what `distctrl params` reads, with the same values
    r, p = run("params", tmp_path / "machine.lis", "--json", "--all")
    assert r.exit_code == 0, r.output


def test_write_shows_the_plan_writes_with_yes_and_restores_from_the_backup(idle, tmp_path):
    lis = tmp_path / "tuned.lis"
    lis.write_text("kenngr.distc.kp 0.7\nkenngr.distc.v_max 150000\nkenngr.distc.max_deviation 80000\n")
    r, plan = run("machine", "write", *ads(idle), "--axis", "Z=2", lis, "--json")
    assert r.exit_code == 0 and plan["outcome"] == "planned" and not plan["written"]
    assert {c["parameter"]: (c["old"], c["new"]) for c in plan["changes"]} == {"kp": (0.5, 0.7),
                                                                             "v_max": (200000, 150000)}
    assert [i["key"] for i in plan["ignored"]] == ["kenngr.distc.max_deviation"]
    assert not list(tmp_path.glob("*.backup*"))                      # nothing written, no backup
    r, done = run("machine", "write", *ads(idle), "--axis", "Z=2", lis, "--yes", "--json")
    assert r.exit_code == 0, r.output
    status = {c["parameter"]: (c["status"], c["read_back"]) for c in done["changes"]}
    # both wait for the next activation; kp's object reads the working value, v_max's the pending one
    assert status == {"v_max": ("pending", "written"), "kp": ("pending", "in_effect")}
    assert sorted(done["pending"]) == ["kp", "v_max"]
    backup = Path(done["backup"])
    assert backup.name == "tuned.backup-axis-Z.lis"
    r, again = run("machine", "write", *ads(idle), "--axis", "Z=2", backup, "--yes", "--json")
    assert r.exit_code == 0, r.output
    # kp 0.7 and v_max 150000 wait: the restore writes the values in effect again over them (issue 39)
    assert {c["parameter"]: c["new"] for c in again["changes"]} == {"v_max": 200000, "kp": 0.5}
    assert pending_after_next_cycles(idle, "v_max") == 200.0
    assert pending_after_next_cycles(idle, "kp") == 0.5


def test_write_refused_while_active_unless_pending(active, tmp_path):
    lis = tmp_path / "tuned.lis"
    lis.write_text("kenngr.distc.kp 0.6\n")
    r, err = run("machine", "write", *ads(active), "--axis", "Z=2", lis, "--yes", "--json")
    assert r.exit_code == 1 and "active" in err["error"] and "--pending" in err["error"]
    assert not list(tmp_path.glob("*.backup*"))
    r, done = run("machine", "write", *ads(active), "--axis", "Z=2", lis, "--yes", "--pending")
    assert r.exit_code == 0, r.output
    assert "pending until the next activation" in r.output and "kp" in r.output
    assert pending_after_next_cycles(active, "kp") == 0.6


def test_record_writes_a_trace_without_gaps(idle, tmp_path):
    from distctrl.trace.reader import load_trace
    out = tmp_path / "rec.csv"
    r, j = run("machine", "record", *ads(idle), "--axis", "Z=2", "--seconds", 1.0, "--out", out, "--json")
    assert r.exit_code == 0, r.output
    assert j["lost_total"] == 0 and j["late"] == 0 and j["rows"] > 200
    tr = load_trace(out)
    assert tr.columns == ["t", "Z.command", "Z.actual", "Z.sensor", "Z.offset", "Z.state"]
    assert np.allclose(np.diff(tr.t), 0.001) and not np.isnan(tr.data).any()
    assert tr["Z.command"][0] == pytest.approx(31.5)
    assert tr.meta["lost"] == {"command": 0, "actual": 0, "sensor": 0, "offset": 0, "state": 0}


@pytest.mark.parametrize("args, code, text", [
    (["--ads", "1.2.3"], 1, "six numbers"),
    (["--ads", "{net}:999"], 1, "ADS error 0x6 (target port not found"),
    (["--ads", "9.9.9.9.1.1"], 1, "ADS error 0x7 (target machine not found - missing ADS route)"),
])
def test_errors_are_one_line_with_the_code(idle, args, code, text):
    args = [a.replace("{net}", idle.net_id) for a in args]
    r, err = run("machine", "show", *args, "--ip", idle.host, "--json")
    assert r.exit_code == code and text in err["error"] and "\n" not in err["error"]


def test_unknown_axis_and_out_of_range_value(idle, tmp_path):
    r, err = run("machine", "show", *ads(idle), "--axis", "Q=9", "--json")
    assert r.exit_code == 1 and "ADS error 0x703 (invalid index offset)" in err["error"]
    lis = tmp_path / "bad.lis"
    lis.write_text("kenngr.distc.v_max 150000.5\n")
    r, err = run("machine", "write", *ads(idle), "--axis", "Z=2", lis, "--json")
    assert r.exit_code == 1 and "SGN32" in err["error"]


def test_unreachable_target(tmp_path):
    r, err = run("machine", "show", "--ads", "127.255.255.253.1.1", "--timeout", 0.5, "--json")
    assert r.exit_code == 1 and "not reachable" in err["error"]


def test_3d_channel_shown_and_written(tmp_path):
    """A channel with 3D distance control (FCT-M3 §12.6 objects, index group 0x121301): shown under
    ``channels`` and written with --channel and a channel list."""
    from distctrl.sim.scenario import load_scenario

    sm = serve(load_scenario(SCN / "dist3d_1.toml"))
    try:
        r, j = run("machine", "show", *ads(sm), "--json")
        assert r.exit_code == 0, r.output
        [ch] = j["channels"]
        assert ch["kind"] == "channel" and ch["index"] == 1
        assert ch["parameters"]["v_max"] == 10000 and ch["details"]["kp"]["key"] == "dist_ctrl[0].kp"
        lis = tmp_path / "ch.lis"
        lis.write_text("configuration.decoder.function FCT_3D_DIST_CTRL\ndist_ctrl[0].v_max 12000\n")
        r, done = run("machine", "write", *ads(sm), "--channel", 1, lis, "--yes", "--pending", "--json")
        assert r.exit_code == 0, r.output
        assert [(c["parameter"], c["old"], c["new"], c["status"]) for c in done["changes"]] == \
            [("v_max", 10000, 12000, "pending")]
        assert "--channel 1" in Path(done["backup"]).read_text()
    finally:
        sm.stop()


@pytest.mark.parametrize("command", [("show",), ("record", "--seconds", 1, "--out", "x.csv"), ("write", "x.lis")])
def test_axis_name_without_index_says_what_to_give(idle, command):
    """issue 28: the CNC objects carry no axis names (FCT-M3 §9.4, TF5200 §7.5 address an axis by its
    index), so `--axis Z` cannot be resolved: the one line says so and names the form and the index."""
    name, *rest = command
    r, err = run("machine", name, *ads(idle), "--axis", "Z", *rest, "--json")
    assert r.exit_code == 1
    msg = err["error"]
    assert "\n" not in msg
    assert "no axis names" in msg and "--axis Z=<index>" in msg and "A_ID" in msg and "machine show" in msg, msg
