"""The machine's status snapshot and event cursor (distctrl.sim.status): what the session log, the live
page and the run summary read instead of the machine's internals."""
from __future__ import annotations

import json
from pathlib import Path

from distctrl.serve.machine import ServedMachine
from distctrl.sim.machine import Machine
from distctrl.sim.runner import load_program, run
from distctrl.sim.scenario import load_scenario

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def _machine(name="serve_z.toml"):
    sc = load_scenario(SCN / name)
    return Machine(sc, load_program(sc), publish_hli=True)


def test_the_status_is_plain_values_of_every_axis():
    m = _machine()
    for _ in range(3):
        m.step()
    st = m.status()
    json.dumps(st)                                    # plain values only: no references into the machine
    assert st["cycle"] == 3 and st["t"] == 2 * m.T and st["cycle_time"] == m.T
    assert list(st["axes"]) == m.axis_names
    z = st["axes"]["Z"]
    assert z["index"] == 2 and z["state"] == int(m.outputs["Z"].hli_state) and z["act"] == m.drives["Z"].actual
    assert z["consumed"] == 0 and z["rejected"] == [] and z["rejected_count"] == 0
    assert st["nc"]["state"] in ("running", "ended") and st["events"] == len(m.events)


def test_the_status_follows_a_plc_command_and_a_refused_one():
    m = _machine()
    m.hli["Z"].plc_command("ON_CONST_DIST", 1.0)
    for _ in range(20):
        m.step()
    z = m.status()["axes"]["Z"]
    assert z["consumed"] == 1 and z["state"] == 4 and z["transition"] != 0
    u = m.hli["Z"]                                    # an unknown transition number: consumed, refused
    u.command_w.transition, u.enable_w, u.command_semaphore_rw = 99, True, True
    m.step()
    z = m.status()["axes"]["Z"]
    assert z["consumed"] == 2 and z["rejected_count"] == 1 and "unknown transition 99" in z["rejected"][0]


def test_a_snapshot_does_not_change_with_the_machine():
    m = _machine()
    st = m.status()
    m.hli["Z"].plc_command("ON_CONST_DIST", 1.0)
    for _ in range(20):
        m.step()
    assert st["cycle"] == 0 and st["axes"]["Z"]["consumed"] == 0


def test_an_event_cursor_takes_every_event_once_and_cursors_are_independent():
    m = _machine()
    first = m.event_cursor()
    m.hli["X"].plc_command("ON", 40.0)                # 70336 for the axis without distance control
    for _ in range(5):
        m.step()
    late = m.event_cursor(from_now=True)
    assert first.pending and not late.pending
    new = first.take()
    assert [ev.id for _, ev in new] == [ev.id for _, ev in m.events] and new
    assert first.take() == [] and not first.pending
    m.hli["X"].plc_command("ON", 40.0)
    for _ in range(5):
        m.step()
    again = first.take()
    assert again and again == late.take() and m.event_cursor().take() == m.events


def test_the_run_summary_lists_every_event_of_the_machine(monkeypatch):
    """sim.runner.run collects its errors and warnings with one event cursor over the whole run."""
    taken = []
    original = Machine.event_cursor

    def spy(self, **kw):
        cursor = original(self, **kw)
        taken.append(cursor)
        return cursor

    monkeypatch.setattr(Machine, "event_cursor", spy)
    result = run(load_scenario(SCN / "process_touch.toml"))
    assert len(taken) == 1 and taken[0].seen == len(taken[0]._machine.events)
    events = taken[0]._machine.events
    listed = {(e["id"], e["t"]) for e in result.errors + result.warnings}
    assert {(ev.id, round(t, 9)) for t, ev in events} <= listed


def test_the_served_machine_adds_paused_to_the_status():
    served = ServedMachine(load_scenario(SCN / "serve_z.toml"))
    served.step()
    st = served.status()
    assert st["paused"] is False and st["cycle"] == 1
    served.set_paused(True)
    served.step()                                       # holds while the PLC runtime is stopped
    assert served.status()["paused"] is True and served.status()["cycle"] == 1
    assert set(served.contexts) == {1, 2} and served.contexts[2].axis_name == "Z"


def test_the_activity_changes_when_a_command_is_taken_or_the_state_changes_only():
    """What the session log compares every cycle: equal while nothing it reports happens."""
    m = _machine()
    for _ in range(5):
        m.step()
    before = m.activity()
    m.step()
    assert m.activity() == before
    m.hli["Z"].plc_command("ON_CONST_DIST", 1.0)
    m.step()
    assert m.activity() != before
    z = m.status()["axes"]["Z"]
    assert m.activity()[0] == m.status()["nc"]["state"]
    assert m.activity()[4:7] == (z["consumed"], z["rejected_count"], z["state"])
