"""Issue 39: ``distctrl machine`` tells the truth where it touches a machine.

* M4: ``machine show/record/write --port`` reach ``distctrl serve --port N`` (pyads' AdsLib on Linux
  takes HOST:PORT);
* B2: a recording the target stops sending to half way is incomplete: counted, said, exit code 4,
  and what arrived is written;
* M1: what the machine has in effect and what is written and pending, the same in ``show``, the write's
  dry run and its result (a second dry run writes the pending values again; a restore before the
  activation cancels them);
* M3: a list that changes what the CNC objects cannot write (the filter) is refused in one line;
* R11: the dry run while distance control is active says that ``--yes`` will be refused.
"""
from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import pytest
from .conftest import serve_on_port
from .test_machine_cli import run, scenario

IDLE = "N10 #TIME 3600\nN20 M30\n"
ACTIVE = "N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]\nN20 #TIME 3600\nN30 M30\n"


@pytest.fixture
def idle():
    sm = serve_on_port(scenario(IDLE))
    yield sm
    sm.stop()


def ads(sm):
    return ["--ads", sm.net_id, "--ip", sm.host, "--port", sm.port]


def by_field(axis: dict) -> dict:
    return {f: (v["in_effect"], v["pending"]) for f, v in axis["values"].items()}


# ------------------------------------------------------------------------------------------------ M4
def test_machine_commands_reach_serve_on_another_port(idle, tmp_path):
    r, j = run("machine", "show", *ads(idle), "--axis", "Z=2", "--json")
    assert r.exit_code == 0, r.output
    assert j["axes"][0]["parameters"]["kp"] == 0.5
    r, j = run("machine", "record", *ads(idle), "--axis", "Z=2", "--seconds", 0.5, "--out", tmp_path / "r.csv",
               "--json")
    assert r.exit_code == 0 and j["rows"] > 0, r.output
    lis = tmp_path / "k.lis"
    lis.write_text("kenngr.distc.kp 0.6\n")
    r, j = run("machine", "write", *ads(idle), "--axis", "Z=2", lis, "--json")
    assert r.exit_code == 0 and j["changes"][0]["new"] == 0.6, r.output


def test_port_with_nothing_listening_is_one_line(tmp_path):
    from .conftest import closed_port
    port = closed_port()
    r, err = run("machine", "show", "--ads", "127.0.0.1.1.1", "--ip", "127.0.0.1", "--port", port, "--json")
    assert r.exit_code == 1 and f"127.0.0.1:{port} not reachable" in err["error"], r.output


# ------------------------------------------------------------------------------------------------ B2
def target_going_away(monkeypatch):
    """A served machine that stops (the target goes away) once the recording has 200 samples."""
    from distctrl.client import recorder as recorder_mod

    sm = serve_on_port(scenario(IDLE))
    start = recorder_mod.Recorder.start

    def start_then_stop_the_target(self):
        start(self)

        def stop_when_samples_came():
            deadline = time.monotonic() + 60
            while len(self.raw) < 200 and time.monotonic() < deadline:
                time.sleep(0.01)
            sm.stop()
        threading.Thread(target=stop_when_samples_came, daemon=True).start()

    monkeypatch.setattr(recorder_mod.Recorder, "start", start_then_stop_the_target)
    return sm


def test_record_cut_short_by_the_target_is_incomplete(tmp_path, monkeypatch):
    """The audit's B2: the target stops half way through an 8 s recording; the recording said "lost:
    none", complete, exit 0. Now: complete false, the cut said and counted, exit code 4, trace kept."""
    sm = target_going_away(monkeypatch)
    out = tmp_path / "cut.csv"
    try:
        r, j = run("machine", "record", *ads(sm), "--axis", "Z=2", "--seconds", 4, "--signals", "command,state",
                   "--out", out, "--json")
    finally:
        sm.stop()
    assert r.exit_code == 4, r.output
    assert j["complete"] is False and j["outcome"] == "incomplete", j
    assert j["stopped_after_s"] is not None and j["cut_s"] > 0.5 and j["cut_cycles"] > 0, j
    assert "stopped sending" in j["error"] and "of 4 s" in j["error"], j
    assert out.is_file() and j["rows"] > 0
    side = json.loads(out.with_name(out.name + ".meta.json").read_text())
    assert side["complete"] is False and side["meta"]["cut_s"] > 0.5 and side["meta"]["complete"] is False


def test_record_cut_short_text_says_it(tmp_path, monkeypatch):
    sm = target_going_away(monkeypatch)
    try:
        r, _ = run("machine", "record", *ads(sm), "--axis", "Z=2", "--seconds", 3, "--signals", "command",
                   "--out", tmp_path / "c.csv")
    finally:
        sm.stop()
    assert r.exit_code == 4
    assert "the target stopped sending after" in r.stderr and "of 3 s" in r.stderr, r.output
    first = r.stdout.splitlines()[0]       # the cut is not "lost" (lost_total counts none), said apart
    assert "lost: none" in first and "cut off at the end" not in first, r.stdout
    assert "cut off: the target stopped sending after" in r.stdout and "of 3 s (about" in r.stdout, r.stdout


# ------------------------------------------------------------------------------------------------ M1
def test_show_and_write_say_what_is_in_effect_and_what_is_pending(idle, tmp_path):
    lis = tmp_path / "tuned.lis"
    lis.write_text("kenngr.distc.kp 0.7\nkenngr.distc.v_max 150000\n")
    r, done = run("machine", "write", *ads(idle), "--axis", "Z=2", lis, "--yes", "--json")
    assert r.exit_code == 0, r.output
    assert {c["parameter"]: c["status"] for c in done["changes"]} == {"kp": "pending", "v_max": "pending"}

    # show: the values in effect and the written, pending ones, the same way for kp and v_max
    r, j = run("machine", "show", *ads(idle), "--axis", "Z=2", "--json")
    assert r.exit_code == 0, r.output
    z = by_field(j["axes"][0])
    assert z["kp"] == (0.5, 0.7) and z["v_max"] == (200000, 150000), z
    assert z["d_tv"] == (0.002, None)
    r, _ = run("machine", "show", *ads(idle), "--axis", "Z=2")
    kp_line = next(ln for ln in r.stdout.splitlines() if "kenngr.distc.kp " in ln)
    vmax_line = next(ln for ln in r.stdout.splitlines() if "kenngr.distc.v_max" in ln)
    assert "written 0.7 " in kp_line and "pending unless the CNC restarted since" in kp_line, r.stdout
    assert "0.5" in kp_line, r.stdout
    assert "written 150000 " in vmax_line and "200000" in vmax_line, r.stdout

    # a second dry run writes them again: the journal's "pending" is not confirmed by the objects
    r, again = run("machine", "write", *ads(idle), "--axis", "Z=2", lis, "--json")
    assert r.exit_code == 0, again
    assert {c["parameter"]: (c["old"], c["new"], c["pending_before"]) for c in again["changes"]} == {
        "kp": (0.5, 0.7, 0.7), "v_max": (200000, 150000, 150000)}
    r, _ = run("machine", "write", *ads(idle), "--axis", "Z=2", lis)
    assert "written again: the journal had it pending since" in r.stdout, r.stdout

    # the restore before any activation writes the old values again (cancels the pending ones)
    backup = Path(done["backup"])
    r, restored = run("machine", "write", *ads(idle), "--axis", "Z=2", backup, "--yes", "--json")
    assert r.exit_code == 0, r.output
    assert {c["parameter"]: (c["old"], c["new"]) for c in restored["changes"]} == {
        "kp": (0.5, 0.5), "v_max": (200000, 200000)}
    r, j = run("machine", "show", *ads(idle), "--axis", "Z=2", "--json")
    z = by_field(j["axes"][0])
    assert z["kp"] == (0.5, None) and z["v_max"] == (200000, None), z


def test_the_journal_sees_the_activation_adopt_the_values(tmp_path):
    """Against serve the journal ends in truth: after the activation kp reads the written value, so
    the write (v_max with it) is in effect."""
    program = "N10 #WAIT FOR V.E.GO == 1\nN20 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]\nN30 #TIME 3600\nN40 M30\n"
    from distctrl.sim.scenario import scenario_from_dict
    from .test_machine_cli import SCN
    sc = scenario_from_dict({
        "name": "adopt", "program_text": program, "variables": {"GO": 0},
        "axes": {"X": {"start": 0.0}, "Z": {"params": str(SCN / "z_laser.lis"), "start": 31.5}},
        "surface": {"base": 30.0}, "sensor": {"axis": "Z", "kind": "encoder", "noise_std": 0.001}}, base_dir=SCN)
    sm = serve_on_port(sc)
    try:
        lis = tmp_path / "t.lis"
        lis.write_text("kenngr.distc.kp 0.7\nkenngr.distc.v_max 150000\n")
        r, _ = run("machine", "write", *ads(sm), "--axis", "Z=2", lis, "--yes")
        assert r.exit_code == 0, r.output
        with sm.lock:
            sm.machine.variables["V.E.GO"] = 1.0
        deadline = time.monotonic() + 60
        while True:
            r, j = run("machine", "show", *ads(sm), "--axis", "Z=2", "--json")
            if j["axes"][0]["state"] == "ACTIVE" or time.monotonic() > deadline:
                break
            time.sleep(0.05)
        z = by_field(j["axes"][0])
        assert z["kp"] == (0.7, None) and z["v_max"] == (150000, None), z
    finally:
        sm.stop()


# ------------------------------------------------------------------------------------------------ M3
def test_write_refuses_a_list_that_changes_the_filter(idle, tmp_path):
    lis = tmp_path / "tuned.lis"
    lis.write_text("kenngr.distc.kp 0.16\nkenngr.distc.d_tv 0.05\nkenngr.distc.filter_type EXPO_MEAN\n"
                   "kenngr.distc.n_cycles 18\nkenngr.distc.smoothing_factor 0.152\n")
    for extra in ([], ["--yes"]):
        r, err = run("machine", "write", *ads(idle), "--axis", "Z=2", lis, *extra, "--json")
        assert r.exit_code == 1, r.output
        msg = err["error"]
        assert "\n" not in msg
        assert "filter_type" in msg and "MOVING_AVERAGE" in msg and "EXPO_MEAN" in msg, msg
        assert "n_cycles" in msg and "tuned-objects.lis" in msg and "parameter list" in msg, msg
    assert not list(tmp_path.glob("*.backup*"))
    r, j = run("machine", "show", *ads(idle), "--axis", "Z=2", "--json")
    assert j["axes"][0]["parameters"]["kp"] == 0.5


def test_write_accepts_a_list_with_the_machines_filter(idle, tmp_path):
    lis = tmp_path / "tuned.lis"
    lis.write_text("kenngr.distc.kp 0.3\nkenngr.distc.filter_type MOVING_AVERAGE\nkenngr.distc.n_cycles 4\n"
                   "kenngr.distc.smoothing_factor 0.152\n")        # not used by MOVING_AVERAGE: no matter
    r, j = run("machine", "write", *ads(idle), "--axis", "Z=2", lis, "--json")
    assert r.exit_code == 0, r.output
    assert [c["parameter"] for c in j["changes"]] == ["kp"]
    same = {i["key"] for i in j["ignored"] if "the machine has the same" in i["reason"]}
    assert same == {"kenngr.distc.filter_type", "kenngr.distc.n_cycles"}


# ------------------------------------------------------------------------------------------------ R11
def test_dry_run_while_active_says_yes_is_refused(tmp_path):
    sm = serve_on_port(scenario(ACTIVE))
    try:
        lis = tmp_path / "k.lis"
        lis.write_text("kenngr.distc.kp 0.6\n")
        deadline = time.monotonic() + 60
        while True:
            r, j = run("machine", "write", *ads(sm), "--axis", "Z=2", lis, "--json")
            if j["active"] or time.monotonic() > deadline:
                break
            time.sleep(0.05)
        assert j["yes_refused"] is True
        r, _ = run("machine", "write", *ads(sm), "--axis", "Z=2", lis)
        assert "--yes will be refused" in r.stdout and "--pending" in r.stdout, r.stdout
    finally:
        sm.stop()


def test_show_says_the_objects_do_not_tell_which_axes_have_distance_control(idle):
    r, _ = run("machine", "show", *ads(idle))
    assert r.exit_code == 0
    assert "P-AXIS-00328" in r.stdout, r.stdout
