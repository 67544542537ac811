"""The HLI DistanceControl control unit of one axis (HLI DistanceControl, FCT-M3 §8, SPEC §9).

``gpAx[i]^.lr_mc_control.distance_control`` is modelled as :class:`DistanceControlUnit`: the PLC
writes ``command_w`` + ``enable_w`` and sets ``command_semaphore_rw``; the CNC, once per GEO cycle
before the controller update, consumes the command (:meth:`DistanceControlUnit.consume`) and clears
the semaphore in the same cycle; after the update it publishes ``state_r``
(:meth:`DistanceControlUnit.publish`). Lengths on the HLI are DINT in 0.1 µm; they are converted to
mm here, once (SPEC §1). On a rotary axis (P-AXIS-00018 ACHSTYP_ROTATOR) the same DINTs are 0.0001°
("0.1 µm or 0.0001°", HLI DistanceControl) and the controller works in degrees: the factor is the same.

Cyclic command (``pAC[i]^^.addr^.McControlLr_Data.MCControl_DistanceControl.CyclicCommand``):
``D_Position`` / ``D_Distance`` (DINT, 0.1 µm). The documents do not say how the CNC knows the PLC is
writing them; here every write of a cyclic value (:meth:`plc_cyclic`, or the ADS symbol) also sets
its ``valid_*`` flag, and only valid values are handed to the controller, which re-reads them every
cycle while the PLC owns a running select (the value belonging to the running mode is used).
:meth:`plc_cyclic_stop` (or writing FALSE to the flag symbol) ends the cyclic specification.
A valid ``D_Position`` is also the REF_POS of a REF the PLC commands (FCT-M3 §8.2: "HLI_DIST_CTRL_REF:
Reference position of the workpiece surface (REF_POS)"), taken in the cycle the REF is consumed
(the controller does it: the value reaches it as ``CycleInput.cyclic_set_pos``; docs/plc.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..control.commands import Command
from ..control.cycle_io import CycleInput, CycleOutput
from ..base.states import HliTransition
from ..errors import DistCtrlError
from ..objects.units import INT32_MAX, INT32_MIN, UINT32_MAX, mm_to_dint_01um

#: mm per DINT unit of an HLI length (0.1 µm)
MM_PER_UNIT = 1e-4


class SemaphoreBusyError(DistCtrlError):
    """The PLC tried to update ``command_w`` while ``command_semaphore_rw`` is TRUE (FCT-M3 §8.2:
    "The commanded values can only be updated by the PLC if this element has the value FALSE")."""


@dataclass
class HliDistanceControlCommand:
    """HLI_DISTANCE_CONTROL_COMMAND (``command_w``)."""

    transition: int = 0      # UDINT, HLI_DIST_CTRL_* (0 OFF ... 6 CONST_DIST)
    position: int = 0        # DINT, 0.1 µm: SET_POS (ON, DRYRUN), SET_DIST (ON_CONST_DIST, CONST_DIST), REF_POS


@dataclass
class HliDistanceControlState:
    """HLI_DISTANCE_CONTROL_STATE (``state_r``); lengths DINT in 0.1 µm."""

    actual_state: int = 0     # UDINT, HLI_DIST_CTRL_STATE_* (0 INACTIVE ... 7 DRYRUN_SETPOS)
    actual_position: int = 0  # DINT, measured workpiece surface a - d
    actual_offset: int = 0    # DINT, current position offset of distance control
    command_source: int = 0   # UDINT, 0 NC program / 1 PLC
    actual_distance: int = 0  # DINT, measured distance d of the tool to the surface


@dataclass
class HliCyclicCommand:
    """HLIDistanceControlCyclicCommand; ``valid_*`` say the PLC is writing that value (distctrl's choice)."""

    D_Position: int = 0       # DINT, 0.1 µm: surface position (SET_POS modes)
    D_Distance: int = 0       # DINT, 0.1 µm: set distance (CONST_DIST modes)
    valid_position: bool = False
    valid_distance: bool = False


@dataclass
class RejectedCommand:
    """A ``command_w`` the CNC consumed but could not map (unknown transition number)."""

    transition: int
    position: int
    reason: str


@dataclass
class ChannelDistanceStatus:
    """3D distance control per channel (``gpCh[i]^.bahn_state``): filled by the 3D variant."""

    virt_tool_length_r: int = 0   # DINT, 0.1 µm: (virtually extended) tool length
    inclination_r: int = 0        # DINT, 0.0001°: tool inclination angle


def transition_number(transition: int | str) -> int:
    """A transition given as number or name (``"ON"``, ``"ON_CONST_DIST"``, ``"HLI_DIST_CTRL_ON"``)."""
    if isinstance(transition, str):
        key = transition.strip().upper().replace(" ", "")
        if key.startswith("HLI_DIST_CTRL_"):
            key = key[len("HLI_DIST_CTRL_"):]
        try:
            return int(HliTransition[key])
        except KeyError:
            raise ValueError(f"unknown transition {transition!r}; allowed: "
                             + ", ".join(f"{t.name} ({int(t)})" for t in HliTransition)) from None
    if isinstance(transition, bool) or not isinstance(transition, int) or not 0 <= transition <= UINT32_MAX:
        raise ValueError(f"transition {transition!r} is not a UDINT")
    return transition


def _dint_from_mm(value_mm: float, what: str) -> int:
    if not isinstance(value_mm, (int, float)) or isinstance(value_mm, bool) or not math.isfinite(value_mm):
        raise ValueError(f"{what} = {value_mm!r} mm is not a finite number")
    return mm_to_dint_01um(value_mm)


class DistanceControlUnit:
    """``gpAx[axis_idx]^.lr_mc_control.distance_control`` of one axis."""

    def __init__(self, axis_index: int = 1, distance_control_on: bool = True):
        self.axis_index = axis_index
        #: P-AXIS-00328 of the axis: state_r's positions are entered only when it is on (HLI
        #: DistanceControl, state_r "Characteristics"); they stay 0 otherwise
        self.distance_control_on = distance_control_on
        self.command_w = HliDistanceControlCommand()
        self.enable_w = False
        self.command_semaphore_rw = False
        self.state_r = HliDistanceControlState()
        self.cyclic = HliCyclicCommand()
        self.rejected: list[RejectedCommand] = []
        self.consumed: int = 0          # commands taken by the CNC (statistics, tests)

    # ------------------------------------------------------------------ PLC side
    def plc_command(self, transition: int | str, position_mm: float = 0.0) -> bool:
        """Write ``command_w`` (position in 0.1 µm, DINT-saturated), set ``enable_w`` and the semaphore.

        Only while the semaphore is FALSE; returns False and writes nothing while it is still TRUE.
        Any UDINT transition number may be written (the CNC rejects unknown ones); names are checked here.
        """
        if self.command_semaphore_rw:
            return False
        number = transition_number(transition)
        position = _dint_from_mm(position_mm, "position")
        self.command_w = HliDistanceControlCommand(number, position)
        self.enable_w = True
        self.command_semaphore_rw = True
        return True

    def write_command(self, transition: int | None = None, position: int | None = None) -> None:
        """Raw update of ``command_w`` (UDINT / DINT in 0.1 µm) as an ADS write does it; refused with
        :class:`SemaphoreBusyError` while the semaphore is TRUE."""
        if self.command_semaphore_rw:
            raise SemaphoreBusyError(f"axis {self.axis_index}: command_w is locked while command_semaphore_rw "
                                     "is TRUE (the CNC has not consumed the last command)")
        if transition is not None:
            if isinstance(transition, bool) or not isinstance(transition, int) or not 0 <= transition <= UINT32_MAX:
                raise ValueError(f"transition {transition!r} is not a UDINT")
            self.command_w.transition = transition
        if position is not None:
            if isinstance(position, bool) or not isinstance(position, int) or not INT32_MIN <= position <= INT32_MAX:
                raise ValueError(f"position {position!r} is not a DINT")
            self.command_w.position = position

    def plc_cyclic(self, position_mm: float | None = None, distance_mm: float | None = None) -> None:
        """Write ``CyclicCommand.D_Position`` / ``D_Distance`` (mm -> 0.1 µm) and mark them valid."""
        if position_mm is not None:
            self.cyclic.D_Position = _dint_from_mm(position_mm, "D_Position")
            self.cyclic.valid_position = True
        if distance_mm is not None:
            self.cyclic.D_Distance = _dint_from_mm(distance_mm, "D_Distance")
            self.cyclic.valid_distance = True

    def plc_cyclic_stop(self) -> None:
        """The PLC stops specifying cyclic values (the last commanded set value stays)."""
        self.cyclic.valid_position = False
        self.cyclic.valid_distance = False

    # ------------------------------------------------------------------ CNC side
    def consume(self) -> Command | None:
        """Take ``command_w`` when ``enable_w`` and ``command_semaphore_rw`` are TRUE; clear the
        semaphore in the same call. An unknown transition number is consumed too (semaphore cleared)
        but only recorded in :attr:`rejected`; None is returned then and when there is nothing to take."""
        if not (self.enable_w and self.command_semaphore_rw):
            return None
        transition, position = self.command_w.transition, self.command_w.position
        self.command_semaphore_rw = False
        self.consumed += 1
        try:
            HliTransition(transition)
        except ValueError:
            self.rejected.append(RejectedCommand(transition, position,
                                                 f"unknown transition {transition}; allowed: 0..6"))
            return None
        return Command.from_hli(transition, position * MM_PER_UNIT)

    def cyclic_inputs(self) -> tuple[float | None, float | None]:
        """``(cyclic_set_pos_mm, cyclic_set_dist_mm)`` for this cycle's CycleInput (None = not written)."""
        c = self.cyclic
        return (c.D_Position * MM_PER_UNIT if c.valid_position else None,
                c.D_Distance * MM_PER_UNIT if c.valid_distance else None)

    def prepare(self, inp: CycleInput) -> Command | None:
        """Before the controller update: queue the consumed command into ``inp.commands`` and set the
        cyclic values of ``inp``. Returns the queued command (or None)."""
        cmd = self.consume()
        if cmd is not None:
            inp.commands.append(cmd)
        inp.cyclic_set_pos, inp.cyclic_set_dist = self.cyclic_inputs()
        return cmd

    def publish(self, out: CycleOutput) -> None:
        """After the controller update: fill ``state_r`` from the output (mm -> 0.1 µm, DINT-saturated).
        Without distance control in the axis parameters only ``actual_state`` is entered."""
        s = self.state_r
        s.actual_state = int(out.hli_state)
        if not self.distance_control_on:
            return
        s.actual_position = mm_to_dint_01um(out.surface_position)
        s.actual_offset = mm_to_dint_01um(out.offset)
        s.command_source = int(out.command_source)
        s.actual_distance = mm_to_dint_01um(out.measured_distance)
