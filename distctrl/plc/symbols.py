"""ADS symbols of the HLI DistanceControl control unit (for the ADS server; SPEC §9).

Every field of :class:`~distctrl.plc.hli.DistanceControlUnit` gets a :class:`SymbolSpec` named by its
ST path in readable form. The documents write ``gpAx[axis_idx]^.lr_mc_control...`` (a pointer
dereference) and ``pAC[axis_idx]^^.addr^.McControlLr_Data...``; distctrl drops the ``^``::

    gpAx[<i>].lr_mc_control.distance_control.command_w.transition
    pAC[<i>].addr.McControlLr_Data.MCControl_DistanceControl.CyclicCommand.D_Position

Raw values are little-endian. Symbols whose ``set`` is None are read-only (``state_r``).
``command_semaphor_rw`` (HLI DistanceControl's spelling) is a second symbol of the same element as
``command_semaphore_rw`` (FCT-M3 §8.2, TF5200 §9.2).
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Callable

from ..errors import DistCtrlError
from .hli import ChannelDistanceStatus, DistanceControlUnit

# ADS data type codes (pyads.constants.ADST_*)
ADST_INT32 = 3       # DINT
ADST_REAL64 = 5      # LREAL
ADST_UINT32 = 19     # UDINT
ADST_STRING = 30
ADST_BIT = 33        # BOOL
ADST_BIGTYPE = 65    # structures


class SymbolValueError(DistCtrlError, ValueError):
    """Raw data of the wrong size for a symbol."""


@dataclass(frozen=True)
class SymbolSpec:
    """One ADS symbol: name (ST path), size in bytes, ADS type code, PLC type name, raw getter and
    setter (None = read-only) and a comment."""

    name: str
    size: int
    ads_type: int
    type_name: str
    get: Callable[[], bytes]
    set: Callable[[bytes], None] | None
    comment: str = ""

    @property
    def writable(self) -> bool:
        return self.set is not None

    @property
    def access(self) -> str:
        return "read/write" if self.set is not None else "read"


#: HLI DistanceControl's spelling of ``command_semaphore_rw`` (served as a second name of it)
SEMAPHORE_ALIAS = "command_semaphor_rw"


def axis_unit_path(axis_index: int) -> str:
    return f"gpAx[{axis_index}].lr_mc_control.distance_control"


def cyclic_command_path(axis_index: int) -> str:
    return f"pAC[{axis_index}].addr.McControlLr_Data.MCControl_DistanceControl.CyclicCommand"


def channel_status_path(channel_index: int) -> str:
    return f"gpCh[{channel_index}].bahn_state"


def _sized(data: bytes, size: int, name: str) -> bytes:
    data = bytes(data)
    if len(data) != size:
        raise SymbolValueError(f"{name}: needs {size} bytes, got {len(data)}")
    return data


def _field(obj_get: Callable[[], object], attr: str, fmt: str):
    def get() -> bytes:
        return struct.pack(fmt, getattr(obj_get(), attr))
    return get


def hli_symbols(axis_index: int, unit: DistanceControlUnit) -> dict[str, SymbolSpec]:
    """The symbols of one axis's control unit, keyed by name.

    ``axis_index`` is used verbatim in the paths (distctrl passes the 1-based axis_id, the same number
    as in the CNC objects' index offsets).
    """
    base = axis_unit_path(axis_index)
    cyc = cyclic_command_path(axis_index)
    syms: list[SymbolSpec] = []

    def add(name, size, ads_type, type_name, get, set_, comment):
        syms.append(SymbolSpec(name, size, ads_type, type_name, get, set_, comment))

    # -- command_w (PLC writes; locked while the semaphore is TRUE)
    def set_command(data: bytes) -> None:
        t, p = struct.unpack("<Ii", _sized(data, 8, f"{base}.command_w"))
        unit.write_command(t, p)

    def set_transition(data: bytes) -> None:
        unit.write_command(transition=struct.unpack("<I", _sized(data, 4, f"{base}.command_w.transition"))[0])

    def set_position(data: bytes) -> None:
        unit.write_command(position=struct.unpack("<i", _sized(data, 4, f"{base}.command_w.position"))[0])

    add(f"{base}.command_w", 8, ADST_BIGTYPE, "HLI_DISTANCE_CONTROL_COMMAND",
        lambda: struct.pack("<Ii", unit.command_w.transition, unit.command_w.position), set_command,
        "PLC -> CNC: transition (UDINT) + position (DINT, 0.1 µm); locked while command_semaphore_rw is TRUE")
    add(f"{base}.command_w.transition", 4, ADST_UINT32, "UDINT", _field(lambda: unit.command_w, "transition", "<I"),
        set_transition, "HLI_DIST_CTRL_*: 0 OFF, 1 ON, 2 FREEZE, 3 REF, 4 ON_CONST_DIST, 5 DRYRUN, 6 CONST_DIST")
    add(f"{base}.command_w.position", 4, ADST_INT32, "DINT", _field(lambda: unit.command_w, "position", "<i"),
        set_position, "0.1 µm: SET_POS (ON, DRYRUN), SET_DIST (ON_CONST_DIST, CONST_DIST), REF_POS (REF)")

    # -- enable_w, command_semaphore_rw
    def bool_setter(attr: str, name: str):
        def set_(data: bytes) -> None:
            setattr(unit, attr, _sized(data, 1, name) != b"\x00")
        return set_

    add(f"{base}.enable_w", 1, ADST_BIT, "BOOL", lambda: b"\x01" if unit.enable_w else b"\x00",
        bool_setter("enable_w", f"{base}.enable_w"), "PLC -> CNC: the PLC commands this control unit")
    add(f"{base}.command_semaphore_rw", 1, ADST_BIT, "BOOL",
        lambda: b"\x01" if unit.command_semaphore_rw else b"\x00",
        bool_setter("command_semaphore_rw", f"{base}.command_semaphore_rw"),
        "PLC sets TRUE to hand command_w over; the CNC clears it in the cycle it takes the command "
        "(HLI DistanceControl spells it command_semaphor_rw)")
    # HLI DistanceControl prints the element as .command_semaphor_rw (FCT-M3 §8.2 and TF5200 §9.2:
    # .command_semaphore_rw): the same element under the second name, so that a PLC or HMI written
    # against either document finds it (upload, by name, by handle)
    add(f"{base}.{SEMAPHORE_ALIAS}", 1, ADST_BIT, "BOOL",
        lambda: b"\x01" if unit.command_semaphore_rw else b"\x00",
        bool_setter("command_semaphore_rw", f"{base}.{SEMAPHORE_ALIAS}"),
        "alias of command_semaphore_rw, the same element: HLI DistanceControl's spelling")

    # -- state_r (read-only)
    def state_bytes() -> bytes:
        s = unit.state_r
        return struct.pack("<IiiIi", s.actual_state, s.actual_position, s.actual_offset, s.command_source,
                           s.actual_distance)

    add(f"{base}.state_r", 20, ADST_BIGTYPE, "HLI_DISTANCE_CONTROL_STATE", state_bytes, None,
        "CNC -> PLC: actual_state, actual_position, actual_offset, command_source, actual_distance")
    for attr, fmt, ads, tn, comment in (
            ("actual_state", "<I", ADST_UINT32, "UDINT", "HLI_DIST_CTRL_STATE_*: 0 INACTIVE ... 7 DRYRUN_SETPOS"),
            ("actual_position", "<i", ADST_INT32, "DINT", "0.1 µm: measured workpiece surface (a - d)"),
            ("actual_offset", "<i", ADST_INT32, "DINT", "0.1 µm: current position offset"),
            ("command_source", "<I", ADST_UINT32, "UDINT", "0 NC program, 1 PLC"),
            ("actual_distance", "<i", ADST_INT32, "DINT", "0.1 µm: measured distance to the surface")):
        add(f"{base}.state_r.{attr}", 4, ads, tn, _field(lambda: unit.state_r, attr, fmt), None, comment)

    # -- cyclic command (writing a value marks it valid)
    def set_cyclic(data: bytes) -> None:
        pos, dist = struct.unpack("<ii", _sized(data, 8, cyc))
        c = unit.cyclic
        c.D_Position, c.D_Distance = pos, dist
        c.valid_position = c.valid_distance = True

    def cyclic_setter(attr: str, flag: str):
        def set_(data: bytes) -> None:
            setattr(unit.cyclic, attr, struct.unpack("<i", _sized(data, 4, f"{cyc}.{attr}"))[0])
            setattr(unit.cyclic, flag, True)
        return set_

    add(cyc, 8, ADST_BIGTYPE, "HLIDistanceControlCyclicCommand",
        lambda: struct.pack("<ii", unit.cyclic.D_Position, unit.cyclic.D_Distance), set_cyclic,
        "PLC -> CNC every cycle: D_Position, D_Distance (DINT, 0.1 µm); writing marks both valid")
    add(f"{cyc}.D_Position", 4, ADST_INT32, "DINT", _field(lambda: unit.cyclic, "D_Position", "<i"),
        cyclic_setter("D_Position", "valid_position"),
        "0.1 µm: surface position (SET_POS modes); writing marks it valid")
    add(f"{cyc}.D_Distance", 4, ADST_INT32, "DINT", _field(lambda: unit.cyclic, "D_Distance", "<i"),
        cyclic_setter("D_Distance", "valid_distance"),
        "0.1 µm: set distance (CONST_DIST modes); writing marks it valid")
    for flag in ("valid_position", "valid_distance"):
        def set_flag(data: bytes, flag=flag) -> None:
            setattr(unit.cyclic, flag, _sized(data, 1, f"{cyc}.{flag}") != b"\x00")
        add(f"{cyc}.{flag}", 1, ADST_BIT, "BOOL",
            (lambda flag=flag: b"\x01" if getattr(unit.cyclic, flag) else b"\x00"), set_flag,
            "distctrl extension: TRUE while the PLC specifies this cyclic value; write FALSE to stop")
    return {s.name: s for s in syms}


#: the structures among the symbols: type name -> its members in the order of the raw value (each
#: member is also a symbol of its own, ``<structure symbol>.<member>``); what ADS clients read as the
#: structure's data type (0xF011). The cyclic command's valid_* flags are distctrl extensions
#: outside the structure.
STRUCT_MEMBERS: dict[str, tuple[str, ...]] = {
    "HLI_DISTANCE_CONTROL_COMMAND": ("transition", "position"),
    "HLI_DISTANCE_CONTROL_STATE": ("actual_state", "actual_position", "actual_offset", "command_source",
                                   "actual_distance"),
    "HLIDistanceControlCyclicCommand": ("D_Position", "D_Distance"),
    "HLI_CHANNEL_DISTANCE_STATUS": ("virt_tool_length_r", "inclination_r"),
}


def channel_status_symbols(channel_index: int, status: ChannelDistanceStatus) -> dict[str, SymbolSpec]:
    """The 3D distance-control values of one channel (read-only), also as one structure
    ``gpCh[<i>].bahn_state`` (distctrl's type HLI_CHANNEL_DISTANCE_STATUS: the part of the channel
    status that distance control fills)."""
    base = channel_status_path(channel_index)
    return {s.name: s for s in (
        SymbolSpec(base, 8, ADST_BIGTYPE, "HLI_CHANNEL_DISTANCE_STATUS",
                   lambda: struct.pack("<ii", status.virt_tool_length_r, status.inclination_r), None,
                   "CNC -> PLC: virt_tool_length_r, inclination_r (DINT each)"),
        SymbolSpec(f"{base}.virt_tool_length_r", 4, ADST_INT32, "DINT",
                   _field(lambda: status, "virt_tool_length_r", "<i"), None,
                   "0.1 µm: (virtually extended) tool length"),
        SymbolSpec(f"{base}.inclination_r", 4, ADST_INT32, "DINT",
                   _field(lambda: status, "inclination_r", "<i"), None, "0.0001°: tool inclination angle"),
    )}


# ---------------------------------------------------------------------- process functions (issue 16)
def process_path(axis: str, function: str | None = None) -> str:
    """``Process.<axis>`` or ``Process.<axis>.<function>``: the process functions' PLC variables, named
    as a PLC program ``Process`` with one instance per axis and function."""
    return f"Process.{axis}" if function is None else f"Process.{axis}.{function}"


def process_symbols(program) -> dict[str, SymbolSpec]:
    """The run-time switch and status of every function of a
    :class:`~distctrl.plc.process.ProcessProgram` (docs/process.md, *Switching at run time*):

    * ``Process.<axis>.<function>.enabled`` (BOOL, read/write): the function runs; writing FALSE
      switches it off (its hold request is withdrawn, a FREEZE it held is released by the hold),
      TRUE on again (it starts afresh); ``ProcessProgram.set_enabled``;
    * ``Process.<axis>.<function>.hold_request`` (BOOL, read): it requested the FREEZE hold in the
      last cycle;
    * ``Process.<axis>.hold_active`` (BOOL, read): the axis's hold owns distance control (it commanded
      the FREEZE and has not re-activated yet: FREEZING, FROZEN or RELEASING).
    """
    syms: list[SymbolSpec] = []

    def flag(get) -> Callable[[], bytes]:
        return lambda: b"\x01" if get() else b"\x00"

    for f in program.functions:
        base = process_path(f.axis, f.name)

        def set_enabled(data: bytes, f=f, base=base) -> None:
            program.set_enabled(f.name, f.axis, _sized(data, 1, f"{base}.enabled") != b"\x00")

        syms.append(SymbolSpec(f"{base}.enabled", 1, ADST_BIT, "BOOL", flag(lambda f=f: f.enabled), set_enabled,
                               f"{f.name} on axis {f.axis} runs; FALSE switches it off and withdraws its hold "
                               "request"))
        syms.append(SymbolSpec(f"{base}.hold_request", 1, ADST_BIT, "BOOL", flag(lambda f=f: f.requesting_hold),
                               None, f"{f.name} requested the FREEZE hold in the last cycle"))
    for axis, hold in program.holds.items():
        syms.append(SymbolSpec(f"{process_path(axis)}.hold_active", 1, ADST_BIT, "BOOL",
                               flag(lambda hold=hold: hold.held_by_us), None,
                               f"the process functions' hold owns distance control of {axis} (FREEZE it "
                               "commanded, not re-activated yet)"))
    return {s.name: s for s in syms}
