"""The page's hub and scope without a browser: the ring buffer, thinning, the trigger, the markers and
the export, on a served machine stepped by hand."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from distctrl.ads.devices import serve_over_ads
from distctrl.sim.scenario import scenario_from_dict
from distctrl.ui.hub import MachineHub

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


@pytest.fixture()
def hub():
    sc = scenario_from_dict({
        "name": "hub", "program_text": "N10 #TIME 3600\nN20 M30\n",
        "axes": {"Z": {"params": str(SCN / "z_probe.lis"), "start": 40.0, "kv": 50.0}},
        "surface": {"base": 40.0},
        "sensor": {"axis": "Z", "kind": "encoder", "range_min": -20.0, "range_max": 20.0}}, base_dir=SCN)
    served = serve_over_ads(sc, port=0, discovery_port=None)
    return MachineHub(served, buffer_s=0.5)          # a ring of 500 cycles


def run(hub, cycles: int) -> None:
    for _ in range(cycles):
        hub.served.step()
    hub.pump()


def test_the_ring_keeps_the_last_cycles_in_order_and_thins_by_absolute_index(hub):
    run(hub, 1234)
    assert hub.rows == 1234
    cursor, rows = hub.rows_since(0)
    assert cursor == 1234 and len(rows) == 500                       # the ring's capacity
    t = rows[:, hub.column("t")]
    assert np.allclose(np.diff(t), 0.001) and t[-1] == pytest.approx(1.233)
    _, thin = hub.rows_since(1000, step=10)                          # rows 1000, 1010, ... 1230
    assert np.allclose(thin[:, 0], np.arange(1000, 1234, 10) * 0.001)
    cursor2, none = hub.rows_since(cursor)
    assert cursor2 == cursor and len(none) == 0
    _, objs = hub.object_rows_since(0)
    assert len(objs) == 50 and np.allclose(np.diff(objs[:, 0]), 0.01)   # a snapshot every 10 cycles


def test_scope_trigger_on_a_state_change_stops_half_a_window_later(hub):
    from distctrl.ui.scope import Scope

    scope = Scope(hub, Path("."))
    scope.window.value = 0.2
    scope.trig_signal.value = "Z.dc.state"
    scope.trig_mode.value = "state change"
    scope._arm()
    run(hub, 50)
    scope.keep()
    assert not scope.pause.active and scope._trig_armed
    assert hub.plc_command("Z", "ON", 40.0)[0]
    run(hub, 60)
    scope.keep()
    assert "triggered at t = " in scope.info.text and not scope._trig_armed
    t_trig = float(scope.info.text.split("t = ")[1].split(" s")[0])
    assert 0.05 <= t_trig <= 0.11
    assert "trigger" in scope.markers.data["label"] and "Z ACTIVE" in scope.markers.data["label"]
    run(hub, 120)                                     # half the 0.2 s window after the trigger
    scope.keep()
    assert scope.pause.active


def test_scope_trigger_on_a_rising_edge_through_a_level(hub):
    from distctrl.ui.scope import Scope

    scope = Scope(hub, Path("."))
    scope.trig_signal.value = "Z.dc.state"
    scope.trig_level.value = 0.5
    scope.trig_mode.value = "rising edge"
    scope._arm()
    run(hub, 30)
    scope.keep()
    assert scope._trig_armed
    hub.plc_command("Z", "ON", 40.0)
    run(hub, 30)
    scope.keep()
    assert "rising edge of Z.dc.state through 0.5 -" in scope.info.text


def test_export_holds_the_objects_between_their_samples(hub, tmp_path):
    from distctrl.trace import Trace

    run(hub, 300)
    path = hub.export_csv(tmp_path, ["Z.obj.DIST_CTRL::kp", "Z.dc.offset"])
    trace = Trace.from_csv(path)
    assert len(trace) == 300 and trace.columns[-1] == "Z.obj.DIST_CTRL.kp"
    assert trace.unit("Z.obj.DIST_CTRL.kp") == "-"
    assert np.all(trace["Z.obj.DIST_CTRL.kp"] == hub.machine.scenario.axes["Z"].params.kp)
    assert hub.exports[path.name] == path and (tmp_path / (path.name + ".meta.json")).is_file()


def test_actions_answer_with_a_message_and_never_raise(hub):
    assert hub.plc_command("Q", "ON", 1.0) == (False, "unknown axis 'Q' or transition 'ON'")
    assert not hub.plc_command("Z", "ON", float("nan"))[0]
    assert hub.plc_command("Z", "ON", 40.0)[0]
    ok, msg = hub.plc_command("Z", "OFF", 0.0)          # the CNC has not taken ON yet
    assert not ok and "command_semaphore_rw is still TRUE" in msg
    assert not hub.set_override(2.0)[0]
    assert not hub.write_object(1, "DIST_CTRL::state", 1)[0]         # read-only
    ok, msg = hub.write_object(1, "DIST_CTRL::kp", 5.0)
    assert not ok and "kp" in msg
    assert hub.write_object(1, "DIST_CTRL::kp", 0.4)[0]
    assert not hub.sensor_fault("melt", 1.0, None)[0]
    assert not hub.set_process("corner_lock", "Z", False)[0]          # no [[process]] here


def test_rows_dropped_by_a_full_queue_keep_their_cycle_index(hub):
    run(hub, 100)
    for _ in range(700):                    # the page thread held up: more than the 500-row queue
        hub.served.step()
    hub.pump()
    assert hub.rows == 800
    _, rows = hub.rows_since(0)
    assert len(rows) == 500 and rows[0, 0] == pytest.approx(0.3) and rows[-1, 0] == pytest.approx(0.799)


def test_the_channel_3d_objects_are_in_the_table_and_writable():
    from distctrl.sim.scenario import load_scenario
    from distctrl.ui.hub import CHANNEL, object_table

    served = serve_over_ads(load_scenario(SCN / "dist3d_1.toml"), port=0, discovery_port=None)
    hub = MachineHub(served, buffer_s=0.5)
    run(hub, 20)
    table = object_table(hub)
    rows = [i for i, a in enumerate(table["axis"]) if a == "0 channel 1"]
    assert len(rows) == 25 and {table["group"][i] for i in rows} == {"0x121301"}
    kp = next(i for i in rows if table["name"][i] == "DIST_CTRL[0]::kp")
    assert table["pending"][kp] == "adopted"
    assert "ch1.obj.DIST_CTRL[0]::kp" in hub.object_signals
    ok, msg = hub.write_object(CHANNEL, "DIST_CTRL[0]::kp", 0.3)
    assert ok, msg
    run(hub, 20)
    table = object_table(hub)
    assert table["pending"][kp] == "pending 0.3"
    assert not hub.write_object(CHANNEL, "DIST_CTRL[0]::kp", 9.0)[0]
