"""The write journal (distctrl.client.journal) on its own: what is in effect and what is pending, for a
target whose objects read like distctrl serve's (kp the value in effect, v_max the written one) and
for a CNC whose objects all show the written value at once (the documents do not say which a real
TwinCAT does, FCT-M3 §9.4, TF5200 §7.5)."""
from __future__ import annotations

from types import SimpleNamespace

from distctrl.base.states import InternalState
from distctrl.client.axes import Unit
from distctrl.client.journal import WriteJournal

IDLE, ACTIVE, FREEZE, DRYRUN = (int(InternalState.IDLE), int(InternalState.ACTIVE), int(InternalState.FREEZE),
                                int(InternalState.DRYRUN))
TARGET = SimpleNamespace(net_id="5.1.2.3.1.1", port=551, ip="192.168.0.10", tcp_port=48898)
Z = Unit("axis", 3, "Z")


def view(values: dict) -> dict:
    return {f: (v["in_effect"], v["pending"]) for f, v in values.items()}


def test_serve_like_objects_pending_until_kp_reads_the_written_value(tmp_path):
    j = WriteJournal(tmp_path / "j.json")
    j.record(TARGET, Z, {"kp": 0.7, "v_max": 150000}, {"kp": 0.5, "v_max": 200000},
             {"kp": "in_effect", "v_max": "written"}, IDLE)
    again = WriteJournal(tmp_path / "j.json")                      # another command, later
    got = again.resolve(TARGET, Z, {"kp": 0.5, "v_max": 150000}, IDLE)
    assert view(got) == {"kp": (0.5, 0.7), "v_max": (200000, 150000)}
    got = again.resolve(TARGET, Z, {"kp": 0.7, "v_max": 150000}, IDLE)   # the activation took both
    assert view(got) == {"kp": (0.7, None), "v_max": (150000, None)}
    assert WriteJournal(tmp_path / "j.json").data == {}


def test_a_cnc_that_shows_the_written_value_needs_an_activation_seen(tmp_path):
    j = WriteJournal(tmp_path / "j.json")
    j.record(TARGET, Z, {"kp": 0.7}, {"kp": 0.5}, {"kp": "written"}, ACTIVE)      # --pending while ACTIVE
    assert view(j.resolve(TARGET, Z, {"kp": 0.7}, ACTIVE)) == {"kp": (0.5, 0.7)}  # no transition seen
    assert view(j.resolve(TARGET, Z, {"kp": 0.7}, DRYRUN)) == {"kp": (0.5, 0.7)}  # DRYRUN adopts nothing
    assert view(j.resolve(TARGET, Z, {"kp": 0.7}, IDLE)) == {"kp": (0.5, 0.7)}    # off: the next ON adopts
    assert view(j.resolve(TARGET, Z, {"kp": 0.7}, FREEZE)) == {"kp": (0.7, None)}  # ... and it came


def test_written_in_freeze_only_the_next_active_adopts(tmp_path):
    j = WriteJournal(tmp_path / "j.json")
    j.record(TARGET, Z, {"kp": 0.7}, {"kp": 0.5}, {"kp": "written"}, FREEZE)
    assert view(j.resolve(TARGET, Z, {"kp": 0.7}, FREEZE)) == {"kp": (0.5, 0.7)}   # still FREEZE
    assert view(j.resolve(TARGET, Z, {"kp": 0.7}, ACTIVE)) == {"kp": (0.7, None)}  # FREEZE -> ACTIVE


def test_a_value_changed_otherwise_drops_out(tmp_path):
    j = WriteJournal(tmp_path / "j.json")
    j.record(TARGET, Z, {"kp": 0.7, "d_tv": 0.01}, {"kp": 0.5, "d_tv": 0.0}, {"kp": "in_effect", "d_tv": "in_effect"},
             IDLE)
    got = j.resolve(TARGET, Z, {"kp": 0.3, "d_tv": 0.0}, IDLE)      # kp set by someone else meanwhile
    assert view(got) == {"kp": (0.3, None), "d_tv": (0.0, 0.01)}


def test_writing_the_value_in_effect_again_cancels(tmp_path):
    j = WriteJournal(tmp_path / "j.json")
    j.record(TARGET, Z, {"kp": 0.7}, {"kp": 0.5}, {"kp": "in_effect"}, IDLE)
    j.record(TARGET, Z, {"kp": 0.5}, {"kp": 0.5}, {"kp": "in_effect"}, IDLE)      # the restore
    assert view(j.resolve(TARGET, Z, {"kp": 0.5}, IDLE)) == {"kp": (0.5, None)}
    assert j.data == {}


def test_other_port_other_axis_other_entry(tmp_path):
    j = WriteJournal(tmp_path / "j.json")
    j.record(TARGET, Z, {"kp": 0.7}, {"kp": 0.5}, {"kp": "in_effect"}, IDLE)
    other = SimpleNamespace(**{**vars(TARGET), "tcp_port": 49150})
    assert view(j.resolve(other, Z, {"kp": 0.5}, IDLE)) == {"kp": (0.5, None)}
    assert view(j.resolve(TARGET, Unit("axis", 2, "Y"), {"kp": 0.5}, IDLE)) == {"kp": (0.5, None)}


def test_an_unreadable_journal_is_an_empty_one(tmp_path):
    p = tmp_path / "j.json"
    p.write_text("{not json")
    assert WriteJournal(p).resolve(TARGET, Z, {"kp": 0.5}, IDLE)["kp"]["pending"] is None
