"""ADS symbols of the HLI control unit: names (ST paths), sizes, types, access, raw little-endian bytes."""
from __future__ import annotations

import struct

import pytest

from distctrl.control import Action, CommandSource, CycleOutput
from distctrl.control.commands import Command
from distctrl.plc import (ChannelDistanceStatus, DistanceControlUnit, SemaphoreBusyError, SymbolSpec,
                          channel_status_symbols, hli_symbols)

BASE = "gpAx[1].lr_mc_control.distance_control"
CYC = "pAC[1].addr.McControlLr_Data.MCControl_DistanceControl.CyclicCommand"

# name -> (size, PLC type, writable), from HLI DistanceControl and FCT-M3 §8.2
EXPECTED = {
    f"{BASE}.command_w": (8, "HLI_DISTANCE_CONTROL_COMMAND", True),
    f"{BASE}.command_w.transition": (4, "UDINT", True),
    f"{BASE}.command_w.position": (4, "DINT", True),
    f"{BASE}.enable_w": (1, "BOOL", True),
    f"{BASE}.command_semaphore_rw": (1, "BOOL", True),
    f"{BASE}.command_semaphor_rw": (1, "BOOL", True),        # HLI DistanceControl's spelling, same element
    f"{BASE}.state_r": (20, "HLI_DISTANCE_CONTROL_STATE", False),
    f"{BASE}.state_r.actual_state": (4, "UDINT", False),
    f"{BASE}.state_r.actual_position": (4, "DINT", False),
    f"{BASE}.state_r.actual_offset": (4, "DINT", False),
    f"{BASE}.state_r.command_source": (4, "UDINT", False),
    f"{BASE}.state_r.actual_distance": (4, "DINT", False),
    CYC: (8, "HLIDistanceControlCyclicCommand", True),
    f"{CYC}.D_Position": (4, "DINT", True),
    f"{CYC}.D_Distance": (4, "DINT", True),
    f"{CYC}.valid_position": (1, "BOOL", True),
    f"{CYC}.valid_distance": (1, "BOOL", True),
}


def ads_codes():
    c = pytest.importorskip("pyads.constants")
    return {"UDINT": c.ADST_UINT32, "DINT": c.ADST_INT32, "BOOL": c.ADST_BIT, "LREAL": c.ADST_REAL64,
            "STRING": c.ADST_STRING}


def test_every_field_has_a_symbol_with_the_documented_path_type_and_access():
    syms = hli_symbols(1, DistanceControlUnit())
    assert set(syms) == set(EXPECTED)
    codes = ads_codes()
    for name, (size, type_name, writable) in EXPECTED.items():
        s = syms[name]
        assert isinstance(s, SymbolSpec) and s.name == name
        assert (s.size, s.type_name, s.writable) == (size, type_name, writable), name
        assert s.access == ("read/write" if writable else "read")
        assert s.ads_type == codes.get(type_name, 65), name             # structures: ADST_BIGTYPE
        assert len(s.get()) == size and s.comment


def test_axis_index_appears_in_the_paths():
    syms = hli_symbols(3, DistanceControlUnit(3))
    assert "gpAx[3].lr_mc_control.distance_control.command_w.transition" in syms
    assert "pAC[3].addr.McControlLr_Data.MCControl_DistanceControl.CyclicCommand.D_Distance" in syms


def test_plc_writes_through_symbols_and_the_cnc_consumes():
    unit = DistanceControlUnit()
    syms = hli_symbols(1, unit)
    syms[f"{BASE}.command_w.transition"].set(struct.pack("<I", 4))
    syms[f"{BASE}.command_w.position"].set(struct.pack("<i", 15000))
    syms[f"{BASE}.enable_w"].set(b"\x01")
    syms[f"{BASE}.command_semaphore_rw"].set(b"\x01")
    assert syms[f"{BASE}.command_w"].get() == struct.pack("<Ii", 4, 15000)
    with pytest.raises(SemaphoreBusyError):                           # locked until the CNC took it
        syms[f"{BASE}.command_w.position"].set(struct.pack("<i", 1))
    with pytest.raises(SemaphoreBusyError):
        syms[f"{BASE}.command_w"].set(struct.pack("<Ii", 0, 0))
    assert unit.consume() == Command(Action.ON, const_dist=True, set_dist=1.5, source=CommandSource.PLC)
    assert syms[f"{BASE}.command_semaphore_rw"].get() == b"\x00"
    syms[f"{BASE}.command_w"].set(struct.pack("<Ii", 3, -20000))     # whole structure
    assert (unit.command_w.transition, unit.command_w.position) == (3, -20000)


def test_state_r_symbols_are_read_only_and_little_endian():
    unit = DistanceControlUnit()
    syms = hli_symbols(1, unit)
    unit.publish(CycleOutput(hli_state=1, surface_position=40.0, offset=0.2, command_source=1,
                             measured_distance=-0.0001))
    assert syms[f"{BASE}.state_r.actual_state"].get() == b"\x01\x00\x00\x00"
    assert syms[f"{BASE}.state_r.actual_position"].get() == struct.pack("<i", 400000)
    assert syms[f"{BASE}.state_r.actual_offset"].get() == struct.pack("<i", 2000)
    assert syms[f"{BASE}.state_r.command_source"].get() == struct.pack("<I", 1)
    assert syms[f"{BASE}.state_r.actual_distance"].get() == b"\xff\xff\xff\xff"
    assert syms[f"{BASE}.state_r"].get() == struct.pack("<IiiIi", 1, 400000, 2000, 1, -1)
    for name, s in syms.items():
        if ".state_r" in name:
            assert s.set is None


def test_cyclic_symbols_mark_the_values_valid():
    unit = DistanceControlUnit()
    syms = hli_symbols(1, unit)
    assert unit.cyclic_inputs() == (None, None)
    syms[f"{CYC}.D_Distance"].set(struct.pack("<i", 12345))
    assert unit.cyclic_inputs() == (None, pytest.approx(1.2345))
    assert syms[f"{CYC}.valid_distance"].get() == b"\x01"
    syms[f"{CYC}.valid_distance"].set(b"\x00")
    assert unit.cyclic_inputs() == (None, None)
    syms[CYC].set(struct.pack("<ii", -400000, 5000))
    assert unit.cyclic_inputs() == (pytest.approx(-40.0), pytest.approx(0.5))
    assert syms[f"{CYC}.D_Position"].get() == struct.pack("<i", -400000)


def test_wrong_sizes_raise():
    syms = hli_symbols(1, DistanceControlUnit())
    for name, s in syms.items():
        if s.set is not None:
            with pytest.raises(ValueError):
                s.set(b"\x00" * (s.size + 1))


def test_channel_status_symbols():
    status = ChannelDistanceStatus(virt_tool_length_r=1234567, inclination_r=-300000)
    syms = channel_status_symbols(1, status)
    assert set(syms) == {"gpCh[1].bahn_state", "gpCh[1].bahn_state.virt_tool_length_r",
                         "gpCh[1].bahn_state.inclination_r"}
    assert syms["gpCh[1].bahn_state.virt_tool_length_r"].get() == struct.pack("<i", 1234567)
    assert syms["gpCh[1].bahn_state.inclination_r"].get() == struct.pack("<i", -300000)
    assert syms["gpCh[1].bahn_state"].get() == struct.pack("<ii", 1234567, -300000)   # the structure
    members = [s for n, s in syms.items() if n != "gpCh[1].bahn_state"]
    assert all(s.set is None and s.type_name == "DINT" and s.size == 4 for s in members)
    assert syms["gpCh[1].bahn_state"].set is None


# ---------------------------------------------------------------- the HLI description's spelling (M4)
# HLI DistanceControl names the element ".command_semaphor_rw", FCT-M3 §8.2 and TF5200 §9.2
# ".command_semaphore_rw": both names are served, for the same element, so a PLC or HMI written
# against either document works.
ALIAS = f"{BASE}.command_semaphor_rw"


def test_the_hli_spelling_command_semaphor_rw_is_the_same_element():
    unit = DistanceControlUnit()
    syms = hli_symbols(1, unit)
    alias, canonical = syms[ALIAS], syms[f"{BASE}.command_semaphore_rw"]
    assert (alias.size, alias.type_name, alias.ads_type, alias.writable) == (1, "BOOL", 33, True)
    assert "command_semaphore_rw" in alias.comment and "HLI DistanceControl" in alias.comment
    unit.write_command(1, 400000)
    unit.enable_w = True
    alias.set(b"\x01")                                             # the PLC hands over by the HLI name
    assert unit.command_semaphore_rw is True and canonical.get() == b"\x01"
    with pytest.raises(SemaphoreBusyError):
        syms[f"{BASE}.command_w.position"].set(struct.pack("<i", 1))
    assert unit.consume() is not None
    assert alias.get() == b"\x00" == canonical.get()              # cleared by the CNC: both names


def _plc_device(unit):
    from types import SimpleNamespace

    from distctrl.ads.devices import PlcDevice
    machine = SimpleNamespace(axis_names=["Z"], hli={"Z": unit}, channel_status=ChannelDistanceStatus(),
                              process_program=None, variables={})
    return PlcDevice(machine)


def test_the_hli_spelling_works_with_pyads_by_name_by_handle_and_in_the_upload():
    pyads = pytest.importorskip("pyads")
    from distctrl.ads import AdsServer
    from tests.ads import port_free
    host, net_id = "127.0.0.9", "127.0.0.9.1.1"     # an address of this test's own (see tests/test_serve.py)
    if not port_free(host, 48898):
        pytest.skip("TCP 48898 is in use on this machine (pyads always connects to 48898)")
    unit = DistanceControlUnit(1)
    srv = AdsServer({851: _plc_device(unit)}, host=host, port=48898, net_id=net_id)
    srv.start()
    try:
        plc = pyads.Connection(net_id, 851, host)
        plc.open()
        try:
            upload = {s.name: s for s in plc.get_all_symbols()}
            assert {ALIAS, f"{BASE}.command_semaphore_rw"} <= set(upload)
            assert upload[ALIAS].plc_type == pyads.PLCTYPE_BOOL
            # a PLC written against HLI DistanceControl: command_w, enable_w, then command_semaphor_rw
            plc.write_by_name(f"{BASE}.command_w.transition", 1, pyads.PLCTYPE_UDINT)
            plc.write_by_name(f"{BASE}.command_w.position", 400000, pyads.PLCTYPE_DINT)
            plc.write_by_name(f"{BASE}.enable_w", True, pyads.PLCTYPE_BOOL)
            plc.write_by_name(ALIAS, True, pyads.PLCTYPE_BOOL)
            assert unit.command_semaphore_rw is True
            assert plc.read_by_name(f"{BASE}.command_semaphore_rw", pyads.PLCTYPE_BOOL) is True
            with pytest.raises(pyads.ADSError):                      # locked while the semaphore is TRUE
                plc.write_by_name(f"{BASE}.command_w.position", 1, pyads.PLCTYPE_DINT)
            assert unit.consume() == Command(Action.ON, set_pos=40.0, source=CommandSource.PLC)
            handle = plc.get_handle(ALIAS)
            try:
                assert plc.read_by_name("", pyads.PLCTYPE_BOOL, handle=handle) is False   # the CNC cleared it
                plc.write_by_name("", True, pyads.PLCTYPE_BOOL, handle=handle)
                assert unit.command_semaphore_rw is True
            finally:
                plc.release_handle(handle)
            assert plc.read_by_name(ALIAS.upper(), pyads.PLCTYPE_BOOL) is True     # case-insensitive, as TwinCAT
        finally:
            plc.close()
    finally:
        srv.stop()
