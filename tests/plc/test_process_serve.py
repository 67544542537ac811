"""`distctrl serve` runs a scenario's [[process]] functions: the served machine is built from the
scenario, so they run in every cycle it steps (no server started here: the cycles are stepped by hand)."""
from pathlib import Path

from distctrl.ads.devices import serve_over_ads
from distctrl.sim.scenario import load_scenario

EX = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def test_served_machine_runs_the_corner_lock():
    served = serve_over_ads(load_scenario(EX / "process_corner.toml"), port=0, discovery_port=None)
    m = served.machine
    assert m.process_program is not None and m.publish_hli
    for _ in range(2300):                     # past the corner (2.01 .. 2.19 s)
        served.step()
    hold = m.process_program.holds["Z"]
    assert [t for _, t in hold.log] == [2, 4]             # FREEZE at the corner, ON after it
    assert m.hli["Z"].state_r.actual_state == 4           # ACTIVE_CONST_DIST again
    assert m.hli["Z"].state_r.command_source == 1         # re-activated by the PLC
    assert m.true_distance > 1.2


# ------------------------------------------------------------------ switching from an ADS client (pyads)
HOST, NET_ID = "127.0.0.7", "127.0.0.7.1.1"      # an address of this module's own (see tests/test_serve.py)
UNIT = "gpAx[1].lr_mc_control.distance_control"


def _served_void_hold():
    """Z tracks a probe at 1 mm; from t = 0.3 s the probe reads 0.5 mm less for good: the void lock
    freezes and keeps the hold (the level never comes back)."""
    from distctrl.sim.scenario import scenario_from_dict
    return scenario_from_dict({
        "name": "served void hold", "cycle_time": 0.001,
        "program_text": "N10 Z[DIST_CTRL ON CONST_DIST SET_DIST=1.0]\nN20 #TIME 3600\nN30 M30\n",
        "axes": {"Z": {"params": str(EX / "z_probe.lis"), "start": 40.0, "kv": 50.0}},
        "surface": {"base": 39.0},
        "sensor": {"axis": "Z", "kind": "encoder", "range_min": -20.0, "range_max": 20.0},
        "process": [{"function": "void_lock", "axis": "Z", "threshold": 10.0}],
        "events": [{"t": 0.3, "sensor_fault": {"kind": "jump", "value": -0.5}}]}, base_dir=EX)


def test_pyads_switches_a_process_function_off_and_on_while_served():
    import gc

    import pytest
    pyads = pytest.importorskip("pyads")
    from tests.ads import port_free, wait_for
    if not port_free(HOST, 48898):
        pytest.skip("TCP 48898 is in use on this machine (pyads always connects to 48898)")
    sym = "Process.Z.void_lock"
    gc.collect()
    gc.freeze()                               # as tests/test_serve.py: keep full collections short
    try:
        with serve_over_ads(_served_void_hold(), host=HOST, net_id=NET_ID, discovery_port=None) as served:
            plc = pyads.Connection(NET_ID, 851, HOST)
            plc.open()
            try:
                names = {s.name for s in plc.get_all_symbols()}
                assert {f"{sym}.enabled", f"{sym}.hold_request", "Process.Z.hold_active"} <= names

                def state():
                    return plc.read_by_name(f"{UNIT}.state_r.actual_state", pyads.PLCTYPE_UDINT)
                assert plc.read_by_name(f"{sym}.enabled", pyads.PLCTYPE_BOOL) is True
                assert wait_for(lambda: state() == 2, timeout=5.0)          # the void lock's FREEZE
                assert plc.read_by_name(f"{sym}.hold_request", pyads.PLCTYPE_BOOL) is True
                assert plc.read_by_name("Process.Z.hold_active", pyads.PLCTYPE_BOOL) is True
                plc.write_by_name(f"{sym}.enabled", False, pyads.PLCTYPE_BOOL)
                assert wait_for(lambda: state() == 4)                        # released: ACTIVE_CONST_DIST
                assert plc.read_by_name(f"{UNIT}.state_r.command_source", pyads.PLCTYPE_UDINT) == 1
                assert plc.read_by_name(f"{sym}.enabled", pyads.PLCTYPE_BOOL) is False
                assert plc.read_by_name(f"{sym}.hold_request", pyads.PLCTYPE_BOOL) is False
                assert wait_for(lambda: not plc.read_by_name("Process.Z.hold_active", pyads.PLCTYPE_BOOL))
                with served.lock:
                    f = served.machine.process_program.function("void_lock", "Z")
                    assert not f.enabled and f.status()["requesting_hold"] is False
                plc.write_by_name(f"{sym}.enabled", True, pyads.PLCTYPE_BOOL)
                assert plc.read_by_name(f"{sym}.enabled", pyads.PLCTYPE_BOOL) is True
                with pytest.raises(pyads.ADSError) as exc:                  # status: read-only
                    plc.write_by_name(f"{sym}.hold_request", True, pyads.PLCTYPE_BOOL)
                assert exc.value.err_code == 0x704
                with served.lock:
                    assert [t for _, t in served.machine.process_program.holds["Z"].log] == [2, 4]
            finally:
                plc.close()
    finally:
        gc.unfreeze()


def test_served_machine_runs_the_calibration_and_publishes_its_switch():
    served = serve_over_ads(load_scenario(EX / "calibrate_capacitive.toml"), port=0, discovery_port=None)
    m = served.machine
    assert "Process.Z.calibrate.enabled" in served.services["ads"].plc.infos
    f = m.process_program.function("calibrate", "Z")
    while f.phase not in ("DONE", "FAILED") and m.cycle < 30000:
        served.step()
    assert f.phase == "DONE" and set(f.completed.run) == {1, 2}
    # a client switches it off and on again: it calibrates once more (the head is at rest again)
    spec = served.services["ads"].plc.specs["Process.Z.calibrate.enabled"]
    spec.set(b"\x00")
    assert spec.get() == b"\x00" and f.phase == "WAITING"
    spec.set(b"\x01")
    for _ in range(1000):
        served.step()
    assert f.phase == "DOWN" and f.status()["samples"] > 0


# ------------------------------------------------------------------ touch-off and collision retract (h16-touch)
def test_served_machine_runs_the_touch_off():
    served = serve_over_ads(load_scenario(EX / "process_touch.toml"), port=0, discovery_port=None)
    m = served.machine
    f = m.process_program.function("touch_off", "Z")
    for _ in range(1000):                     # the touch-off hands back at 0.873 s
        served.step()
    (res,) = f.log
    assert abs(res["surface"] - 33.2) < 0.05 and res["attempts"] == 1
    assert m.variables["V.E.TOUCH_OFF"] == 0.0 and m.nc.running and m.events == []



def test_the_touch_off_request_is_an_ads_symbol_from_the_start():
    # an HMI / external PLC can watch and write the handshake before the program first assigns it
    served = serve_over_ads(load_scenario(EX / "process_touch.toml"), port=0, discovery_port=None)
    assert served.machine.variables["V.E.TOUCH_OFF"] == 0.0
    info = served.services["ads"].plc.symbols()["V.E.TOUCH_OFF"]
    assert info.type_name == "LREAL" and not info.read_only


def test_served_machine_runs_the_collision_retract():
    served = serve_over_ads(load_scenario(EX / "process_collision.toml"), port=0, discovery_port=None)
    m = served.machine
    f = m.process_program.function("collision_retract", "Z")
    for _ in range(1000):                     # contact at 0.889 s, the retract takes 32 ms
        served.step()
    (c,) = f.log
    assert abs(c["retract"] - 5.0) < 0.15 and c["line"] == 7
    assert [ev.id for _, ev in m.events] == [900053] and m.nc.aborted
    assert m.hli["Z"].state_r.actual_state == 0


def test_served_machine_runs_the_laser_plate_with_every_function():
    # the plate of issue 16 under `distctrl serve` (stepped here): the same figures as `distctrl run`
    served = serve_over_ads(load_scenario(EX / "laser_sheet_short.toml"), port=0, discovery_port=None)
    m = served.machine
    assert [f.name for f in m.process_program.functions] == ["touch_off", "corner_lock", "void_lock", "lift"]
    least = float("inf")
    for _ in range(20000):
        served.step()
        least = min(least, m.true_distance)
        if not m.nc.running:
            break
    assert not m.nc.running and not m.nc.aborted and m.events == []
    assert least >= 0.3 * 1.0                 # SET_DIST 1 mm: never closer than 30 %
