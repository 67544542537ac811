"""ADS on a served machine (``distctrl serve``, docs/serve.md): :class:`AdsEndpoint` attaches an ADS
server with the devices below to a :class:`~distctrl.serve.machine.ServedMachine` (the server and the
cycle share the served machine's lock, so every request sees one consistent cycle):

* AMS port 551 (GEO task): the CNC objects of distance control by index group 0x120300 and index
  offset ``(axis_id << 16) | 0x3xxx`` (docs/objects.md), the TF5200 manual's ``DISTCTRL::v_max`` /
  ``a_max`` at 0x20300 / ``(axis_id << 16) | 0x152``, ``0x153``; with 3D distance control also the channel's
  3D objects, index group 0x121301 (docs/objects-3d.md), writes adopted like the axis objects. Writes to the read/write objects are queued
  into the axis's controller and adopted on the next INACTIVE→active or FREEZE→active transition.
* AMS port 851 (PLC): symbols by name — every field of each axis's HLI DistanceControl control unit
  (``gpAx[i].lr_mc_control.distance_control.command_w.transition`` …, docs/plc.md), the channel's
  3D status (``gpCh[1].bahn_state.virt_tool_length_r``, ``inclination_r``) and the V.E.
  variables (``V.E.NAME``, LREAL), and with ``[[process]]`` tables each function's switch
  ``Process.<axis>.<function>.enabled`` (BOOL) and status. ``state_r`` is read-only; ``command_w`` is locked while the
  semaphore is TRUE (ADS 0x704). Symbols live in index group 0x4020 so that sum commands work.
"""
from __future__ import annotations

import functools
import logging
import struct

from ..objects.channel3d import INDEX_GROUP_3D_BASE, Channel3DObjectContext, find_object_3d
from ..objects.channel3d import read_bytes as read_bytes_3d
from ..objects.channel3d import write_bytes as write_bytes_3d
from ..objects.registry import (
    INDEX_GROUPS,
    AxisObjectContext,
    ObjectAccessError,
    ObjectValueError,
    find_object,
    read_bytes,
    write_bytes,
)
from ..plc.hli import SemaphoreBusyError
from ..plc.symbols import STRUCT_MEMBERS, SymbolSpec, channel_status_symbols, hli_symbols, process_symbols
from ..serve.machine import ServedMachine
from .datatypes import DataType, struct_type
from .discovery import DiscoveryResponder, TargetInfo
from .errors import (
    ADSERR_DEVICE_INVALIDACCESS,
    ADSERR_DEVICE_INVALIDDATA,
    ADSERR_DEVICE_INVALIDGRP,
    ADSERR_DEVICE_INVALIDOFFSET,
    ADSERR_DEVICE_INVALIDPARM,
    ADSERR_DEVICE_INVALIDSIZE,
    AdsError,
)
from .protocol import ADSSTATE_RUN, ADSSTATE_STOP, ADST_REAL64, SymbolInfo
from .server import AdsServer

log = logging.getLogger("distctrl.serve")      # the served session's logger (distctrl.serve.machine)

CNC_PORT = 551
PLC_PORT = 851
SYSTEM_SERVICE_PORT = 10000        # TwinCAT's system service: the target's run mode
#: the PLC runtime's ADS and device state (ADS state UINT at offset 0, device state UINT at 2), as
#: ads-client reads and subscribes to it on every connect
DEVICE_DATA_GROUP = 0xF100
SYSTEM_STATE_GROUP = 0xF0             # the system service's extended state (ads-client reads it first)
#: ADS state, device state, restart index, version, revision, build, platform, OS type, flags, reserved
SYSTEM_STATE = struct.Struct("<HHHBBHBBHH")
PLC_SYMBOL_GROUP = 0x4020          # %M-like memory area for the PLC symbols
DEVICE_OK = 0


def runtime_state(runtime, index_offset: int, length: int) -> bytes:
    """Index group 0xF100 of a runtime port: ADS state (RUN, or STOP while ``runtime`` is paused) and
    device state, 4 bytes; a read beyond them is 0x705."""
    ads_state = ADSSTATE_STOP if runtime is not None and runtime.paused else ADSSTATE_RUN
    state = struct.pack("<HH", ads_state, DEVICE_OK)
    if index_offset + length > len(state) or length == 0:
        raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"0x{DEVICE_DATA_GROUP:X}:0x{index_offset:X} has "
                                                  f"{len(state) - index_offset} bytes, {length} requested")
    return state[index_offset:index_offset + length]


class CncObjectDevice:
    """AMS port 551: the axis CNC objects of the machine's axes (axis_id from 1 in scenario order), and
    the runtime state at 0xF100 as on the PLC port (ads-client's default connect reads it)."""

    name = "distctrl GEO"
    version = (0, 1, 0)

    def __init__(self, machine, runtime=None, contexts: dict | None = None):
        self.machine = machine
        self.runtime = runtime              # the served machine's run/stop switch (None: always RUN)
        #: (index group, index offset) -> (object, axis context) of the axis objects found so far: the
        #: contexts are fixed, so a client's repeated reads skip the search (bounded by objects x axes)
        self._found: dict[tuple[int, int], tuple] = {}
        #: axis_id -> AxisObjectContext: the served machine's (:attr:`ServedMachine.contexts
        #: <distctrl.serve.machine.ServedMachine.contexts>`), or made here for a bare machine
        self.contexts = contexts if contexts is not None else {
            i + 1: AxisObjectContext(i + 1, n, machine.controllers[n], machine.outputs[n],
                                     machine.scenario.axes[n].resolution or 1e-4)
            for i, n in enumerate(machine.axis_names)}

    def _find(self, index_group: int, index_offset: int):
        if self.machine.ch3d is not None and index_group == INDEX_GROUP_3D_BASE | 1:
            # the channel's 3D objects (index group 0x121300 | channel, SPEC §10), values of this cycle
            ctx = Channel3DObjectContext(1, self.machine.channel3d_values())
            found = find_object_3d(index_group, index_offset, {1: ctx})
            if found is None:
                raise AdsError(ADSERR_DEVICE_INVALIDOFFSET, f"index offset 0x{index_offset:X}")
            return found
        found = self._found.get((index_group, index_offset))
        if found is not None:
            return found
        if index_group not in INDEX_GROUPS:          # 0x120300 and the TF5200 aliases' 0x20300
            raise AdsError(ADSERR_DEVICE_INVALIDGRP, f"index group 0x{index_group:X}")
        found = find_object(index_group, index_offset, self.contexts)
        if found is None:
            raise AdsError(ADSERR_DEVICE_INVALIDOFFSET, f"index offset 0x{index_offset:X}")
        self._found[(index_group, index_offset)] = found
        return found

    def read(self, index_group: int, index_offset: int, length: int) -> bytes:
        if index_group == DEVICE_DATA_GROUP:
            return runtime_state(self.runtime, index_offset, length)
        spec, ctx = self._find(index_group, index_offset)
        # a STRING object fills a larger buffer with its own bytes (pyads reads every string type with
        # a 1024-byte buffer); every other object answers only a read of its exact size
        if length != spec.length and not (spec.type == "STRING" and length > spec.length):
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"{spec.name} is {spec.length} bytes, {length} requested")
        return read_bytes_3d(spec, ctx) if isinstance(ctx, Channel3DObjectContext) else read_bytes(spec, ctx)

    def fast_reader(self, index_group: int, index_offset: int, length: int):
        """For the server's read cache (:meth:`~distctrl.ads.server.AdsServer._handle_ams`): a
        function of no arguments giving what :meth:`read` gives for this request, once :meth:`read`
        has answered it (the object and its axis context are fixed from then on); None for requests
        whose answer depends on more than the object (runtime state, the channel's 3D values)."""
        found = self._found.get((index_group, index_offset))
        if found is None or index_group == DEVICE_DATA_GROUP:
            return None
        spec, ctx = found
        if length != spec.length and not (spec.type == "STRING" and length > spec.length):
            return None
        return functools.partial(read_bytes, spec, ctx)

    def write(self, index_group: int, index_offset: int, data: bytes) -> None:
        spec, ctx = self._find(index_group, index_offset)
        try:
            if isinstance(ctx, Channel3DObjectContext):
                command = write_bytes_3d(spec, ctx, data)
                self.machine.in3d.commands.append(command)      # adopted by the shared core's rule
                return
            command = write_bytes(spec, ctx, data)
        except ObjectAccessError as exc:
            raise AdsError(ADSERR_DEVICE_INVALIDACCESS, str(exc)) from None
        except ObjectValueError as exc:
            code = ADSERR_DEVICE_INVALIDSIZE if len(data) != spec.length else ADSERR_DEVICE_INVALIDDATA
            raise AdsError(code, str(exc)) from None
        self.machine.inputs[ctx.axis_name].commands.append(command)    # adopted by the controller's rule

    def symbols(self) -> dict:
        return {}

    def state(self) -> tuple[int, int]:
        return struct.unpack("<HH", runtime_state(self.runtime, 0, 4))


class PlcDevice:
    """AMS port 851: the HLI control units, the V.E. variables and the process functions' switches by
    symbol name."""

    name = "distctrl PLC"
    version = (0, 1, 0)

    def __init__(self, machine, runtime=None):
        self.machine = machine
        self.runtime = runtime              # the served machine's run/stop switch (None: always RUN)
        self.specs: dict[str, object] = {}
        for i, n in enumerate(machine.axis_names):
            self.specs.update(hli_symbols(i + 1, machine.hli[n]))
        self.specs.update(channel_status_symbols(1, machine.channel_status))
        if machine.process_program is not None:      # the [[process]] functions' switches (docs/process.md)
            self.specs.update(process_symbols(machine.process_program))
        for name in sorted(machine.variables):
            if name.startswith("V.E."):
                self.specs[name] = _variable_symbol(machine.variables, name)
        self.infos: dict[str, SymbolInfo] = {}
        self.by_offset: dict[int, object] = {}
        offset = 0
        for name, spec in self.specs.items():
            self.infos[name] = SymbolInfo(name, PLC_SYMBOL_GROUP, offset, spec.size, spec.ads_type, spec.type_name,
                                          spec.comment, read_only=spec.set is None)
            self.by_offset[offset] = spec
            offset += (spec.size + 7) // 8 * 8                  # 8-byte aligned, distinct addresses
        self.types: dict[str, DataType] = {}
        for name, info in self.infos.items():
            members = STRUCT_MEMBERS.get(info.type_name)
            if members and info.type_name not in self.types:
                self.types[info.type_name] = struct_type(
                    info.type_name, [self.infos[f"{name}.{m}"] for m in members], f"{name}.", info.comment)

    def _ads_state(self) -> int:
        return ADSSTATE_STOP if self.runtime is not None and self.runtime.paused else ADSSTATE_RUN

    def _spec(self, index_group: int, index_offset: int):
        if index_group != PLC_SYMBOL_GROUP:
            raise AdsError(ADSERR_DEVICE_INVALIDGRP, f"index group 0x{index_group:X}")
        spec = self.by_offset.get(index_offset)
        if spec is None:
            raise AdsError(ADSERR_DEVICE_INVALIDOFFSET, f"index offset 0x{index_offset:X}")
        return spec

    def read(self, index_group: int, index_offset: int, length: int) -> bytes:
        if index_group == DEVICE_DATA_GROUP:
            return runtime_state(self.runtime, index_offset, length)
        spec = self._spec(index_group, index_offset)
        if length != spec.size:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"{spec.name} is {spec.size} bytes")
        return spec.get()

    def write(self, index_group: int, index_offset: int, data: bytes) -> None:
        spec = self._spec(index_group, index_offset)
        if spec.set is None:
            raise AdsError(ADSERR_DEVICE_INVALIDACCESS, f"{spec.name} is read-only")
        if len(data) != spec.size:
            raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"{spec.name} is {spec.size} bytes")
        try:
            spec.set(bytes(data))
        except SemaphoreBusyError as exc:
            raise AdsError(ADSERR_DEVICE_INVALIDACCESS, str(exc)) from None
        except ValueError as exc:
            raise AdsError(ADSERR_DEVICE_INVALIDDATA, str(exc)) from None

    def symbols(self) -> dict[str, SymbolInfo]:
        return self.infos

    def data_types(self) -> dict[str, DataType]:
        """The structures among the symbols (``STRUCT_MEMBERS``), as ADS clients read them by type name."""
        return self.types

    def state(self) -> tuple[int, int]:
        return self._ads_state(), DEVICE_OK

    def write_control(self, ads_state: int, device_state: int, data: bytes) -> None:
        """WriteControl RUN / STOP, as starting and stopping a PLC: STOP pauses the served machine
        (its cycle holds, the clients still read), RUN resumes it; other states: 0x70B."""
        if self.runtime is None or ads_state not in (ADSSTATE_RUN, ADSSTATE_STOP):
            raise AdsError(ADSERR_DEVICE_INVALIDPARM, f"WriteControl to ADS state {ads_state}: allowed "
                                                      f"{ADSSTATE_RUN} RUN, {ADSSTATE_STOP} STOP")
        self.runtime.set_paused(ads_state == ADSSTATE_STOP)


class SystemServiceDevice:
    """AMS port 10000, TwinCAT's system service: what clients read first to learn the target's run mode
    (ads-client's default connect). RUN while the served machine is up; device info of the target."""

    name = "TwinCAT System"
    version = (3, 1, 4024)

    def read(self, index_group: int, index_offset: int, length: int) -> bytes:
        if index_group == SYSTEM_STATE_GROUP and index_offset == 0:
            if length != SYSTEM_STATE.size:
                raise AdsError(ADSERR_DEVICE_INVALIDSIZE, f"the extended system state has {SYSTEM_STATE.size} "
                                                          f"bytes, {length} requested")
            return SYSTEM_STATE.pack(ADSSTATE_RUN, DEVICE_OK, 0, *self.version, 0, 0, 0, 0)
        raise AdsError(ADSERR_DEVICE_INVALIDGRP, f"index group 0x{index_group:X} of the system service")

    def write(self, index_group: int, index_offset: int, data: bytes) -> None:
        raise AdsError(ADSERR_DEVICE_INVALIDGRP, f"index group 0x{index_group:X} of the system service")

    def symbols(self) -> dict:
        return {}

    def state(self) -> tuple[int, int]:
        return ADSSTATE_RUN, DEVICE_OK


def _variable_symbol(variables: dict, name: str):
    def get() -> bytes:
        return struct.pack("<d", float(variables.get(name, 0.0)))

    def set_(data: bytes) -> None:
        value = struct.unpack("<d", data)[0]
        if value != value or value in (float("inf"), float("-inf")):
            raise ValueError(f"{name} = {value!r} is not a finite number")
        variables[name] = value

    return SymbolSpec(name, 8, ADST_REAL64, "LREAL", get, set_, "V.E. variable (mm or as the program uses it)")


class AdsEndpoint:
    """ADS on a served machine: the three devices (CNC objects on AMS port 551, the PLC on 851, the
    system service on 10000) behind one :class:`~distctrl.ads.server.AdsServer` that holds the served
    machine's lock around every request; by default it also answers route discovery and add-route on
    UDP ``discovery_port`` of ``host`` (:mod:`distctrl.ads.discovery`; if that port cannot be bound,
    one warning and TCP is served). Attaches itself to ``served`` as the service ``"ads"``: started
    and stopped with it."""

    def __init__(self, served, *, host: str = "127.0.0.1", port: int = 48898, allowed=("127.0.0.0/8",),
                 net_id: str = "127.0.0.1.1.1", discovery_port: int | None = 48899):
        self.served = served
        machine = served.machine
        self.cnc = CncObjectDevice(machine, runtime=served, contexts=served.contexts)
        self.plc = PlcDevice(machine, runtime=served)
        self.system = SystemServiceDevice()
        self.server = AdsServer({CNC_PORT: self.cnc, PLC_PORT: self.plc, SYSTEM_SERVICE_PORT: self.system},
                                host=host, port=port, net_id=net_id, allowed=list(allowed), lock=served.lock)
        # route discovery and add-route on UDP (docs/serve.md); None: not answered
        self.discovery = None
        if discovery_port is not None:
            self.discovery = DiscoveryResponder(TargetInfo(net_id, tc_version=self.system.version), discovery_port)
            self.server.attached.append(self.discovery)
        # cyclic notifications on the CNC and PLC ports are sampled by the cycle (every sample of every
        # cycle, stamped with the cycle's time: the start's wall-clock time + cycle x T)
        self.server.cycle_time = served.scenario.cycle_time
        self.server.cycle_ports = frozenset({CNC_PORT, PLC_PORT})
        served.observers.insert(0, self.sample_cycle)
        served.attach("ads", self)

    def sample_cycle(self) -> None:
        """After every cycle, in the cycle thread under the lock: the cycle-synchronous notifications."""
        self.server.sample_cycle(self.served.cycle_filetime())

    def start(self) -> None:
        self.server.start()
        log.info("serving %s on %s:%d (AMS ports %d, %d)", self.served.scenario.name, self.server.host,
                 self.server.port, CNC_PORT, PLC_PORT)

    def stop(self) -> None:
        self.server.stop()


def serve_over_ads(scenario, *, host: str = "127.0.0.1", port: int = 48898, allowed=("127.0.0.0/8",),
                   net_id: str = "127.0.0.1.1.1", discovery_port: int | None = 48899, rt_priority: int = 0,
                   speed: float = 1.0):
    """A :class:`~distctrl.serve.machine.ServedMachine` of ``scenario`` with ADS attached
    (``served.services["ads"]``, an :class:`AdsEndpoint`); not started. ``speed``: machine seconds per
    wall-clock second (:class:`~distctrl.serve.machine.ServedMachine`)."""
    served = ServedMachine(scenario, rt_priority=rt_priority, speed=speed)
    AdsEndpoint(served, host=host, port=port, allowed=allowed, net_id=net_id, discovery_port=discovery_port)
    return served
