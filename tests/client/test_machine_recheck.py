"""Issue 39, the new user's re-check of ``distctrl machine``:

1. the journal's "pending" is a claim distctrl cannot verify over the objects (a CNC restart drops the
   pending values and the objects read as before): ``write`` writes every value that differs from
   what is in effect, also one the journal has pending, and ``show`` says what the journal knows;
2. ``write --yes --json`` gives ``values`` as they are after the write;
3. ``show --json`` ``parameters`` are the values in effect, as the text shows them;
4. ``record``'s text does not call a cut "lost" (test_machine_truth.test_record_cut_short_text_says_it);
5. ``--ip HOST:PORT`` says to give ``--port PORT``.
"""
from __future__ import annotations

import pytest
from .conftest import serve_on_port
from .test_machine_cli import pending_after_next_cycles, run, scenario
from .test_machine_truth import IDLE, ads, idle  # noqa: F401 (idle: a fixture)


def restarted(sm):
    """The same served machine stopped and started again on its port (a CNC restart: every pending value
    gone, the objects read the start-up values)."""
    port = sm.port
    sm.stop()
    return serve_on_port(scenario(IDLE), port=port)


# ------------------------------------------------------------------------------------------------ 1
def test_a_value_the_journal_has_pending_is_written_again_after_a_restart(idle, tmp_path):
    lis = tmp_path / "tuned.lis"
    lis.write_text("kenngr.distc.kp 0.25\nkenngr.distc.v_max 140000\n")
    r, _ = run("machine", "write", *ads(idle), "--axis", "Z=2", lis, "--yes", "--json")
    assert r.exit_code == 0, r.output
    sm = restarted(idle)
    try:
        r, _ = run("machine", "show", *ads(sm), "--axis", "Z=2")
        kp_line = next(ln for ln in r.stdout.splitlines() if "kenngr.distc.kp " in ln)
        assert "by distctrl; pending unless the CNC restarted since" in kp_line, r.stdout
        r, plan = run("machine", "write", *ads(sm), "--axis", "Z=2", lis, "--json")
        assert r.exit_code == 0, r.output
        changes = {c["parameter"]: c for c in plan["changes"]}
        assert set(changes) == {"kp", "v_max"}, plan
        assert changes["kp"]["old"] == 0.5 and changes["kp"]["new"] == 0.25
        assert changes["kp"]["journal_pending_since"] is not None, changes["kp"]
        r, _ = run("machine", "write", *ads(sm), "--axis", "Z=2", lis)
        kp_line = next(ln for ln in r.stdout.splitlines() if "kenngr.distc.kp " in ln)
        assert "0.25" in kp_line and "written again: the journal had it pending since" in kp_line, r.stdout
        assert "already written and pending" not in r.stdout
        r, done = run("machine", "write", *ads(sm), "--axis", "Z=2", lis, "--yes", "--json")
        assert r.exit_code == 0 and {c["parameter"] for c in done["changes"]} == {"kp", "v_max"}, r.output
        assert pending_after_next_cycles(sm, "kp") == 0.25        # the served CNC has it pending again
    finally:
        sm.stop()


# ------------------------------------------------------------------------------------------------ 2
def test_write_json_values_are_those_after_the_write(idle, tmp_path):
    first, second = tmp_path / "a.lis", tmp_path / "b.lis"
    first.write_text("kenngr.distc.kp 0.2\n")
    second.write_text("kenngr.distc.kp 0.25\nkenngr.distc.v_max 140000\n")
    r, _ = run("machine", "write", *ads(idle), "--axis", "Z=2", first, "--yes", "--json")
    assert r.exit_code == 0, r.output
    r, done = run("machine", "write", *ads(idle), "--axis", "Z=2", second, "--yes", "--json")
    assert r.exit_code == 0, r.output
    v = done["values"]
    assert (v["kp"]["in_effect"], v["kp"]["pending"]) == (0.5, 0.25), v
    assert (v["v_max"]["in_effect"], v["v_max"]["pending"]) == (200000, 140000), v
    assert {c["parameter"]: c["status"] for c in done["changes"]} == {"kp": "pending", "v_max": "pending"}


# ------------------------------------------------------------------------------------------------ 3
def test_show_json_parameters_are_the_values_in_effect(idle, tmp_path):
    lis = tmp_path / "t.lis"
    lis.write_text("kenngr.distc.kp 0.7\nkenngr.distc.a_max 12000\n")
    r, _ = run("machine", "write", *ads(idle), "--axis", "Z=2", lis, "--yes")
    assert r.exit_code == 0, r.output
    r, j = run("machine", "show", *ads(idle), "--axis", "Z=2", "--json")
    z = j["axes"][0]
    for f in ("kp", "a_max"):
        assert z["parameters"][f] == z["values"][f]["in_effect"], (f, z["parameters"], z["values"])
    assert z["pending"] == {"kp": 0.7, "a_max": 12000}
    assert z["values"]["a_max"]["read"] == 12000          # what the object read stays under values


# ------------------------------------------------------------------------------------------------ 5
@pytest.mark.parametrize("command", [["show"], ["record", "--axis", "Z=2", "--seconds", "1", "--out", "x.csv"]])
def test_ip_with_a_port_says_to_give_port(command):
    r, err = run("machine", *command, "--ads", "127.0.0.1.1.1", "--ip", "127.0.0.1:49305", "--json")
    assert r.exit_code == 1, r.output
    assert "--ip '127.0.0.1:49305'" in err["error"] and "--ip 127.0.0.1 --port 49305" in err["error"], err
