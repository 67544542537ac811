"""FREEZE and re-activation through the HLI control unit: the part every lock shares.

The lock functions (corner lock, void lock, the sampling of the automatic set value) only *request*
a hold; :class:`FreezeHold` (one per axis) turns the requests into HLI commands, as an integrator
writes one sequence FB per axis and ORs the lock requests into it:

* IDLE: a request while ``state_r.actual_state`` is ACTIVE (1) or ACTIVE_CONST_DIST (4) remembers the
  mode and the set value in force (the CNC objects ``DIST_CTRL::set_pos`` 0x3104 / ``set_distance``
  0x3103, SGN64 in 0.01 nm) and commands FREEZE (``command_w.transition`` = 2) -> FREEZING;
* FREEZING: the next cycle shows FREEZE (2) -> FROZEN; anything else (the command was refused, the NC
  switched off) -> IDLE;
* FROZEN: no request left -> ON (1, SET_POS) or ON_CONST_DIST (4, SET_DIST) with the remembered set
  value, or the one a function put in :attr:`FreezeHold.set_value` (the automatic set value)
  -> RELEASING; the state left FREEZE by another command (NC OFF, RESET, an error) -> IDLE (the hold
  never re-activates what someone else switched off);
* RELEASING: the next cycle shows a running state -> IDLE; FREEZE again -> FROZEN (retried).

FREEZE holds the offset (braked within the axis's limits; docs/states.md); the re-activation is the
documents' FREEZE -> ON, which re-adopts CNC-object writes (FCT-M3 §7.6). A hold that the NC program
itself commanded (``Z[DIST_CTRL FREEZE]``) is never released here. Commands go through the
semaphore handshake (FCT-M3 §8.2): while ``command_semaphore_rw`` is TRUE the command waits.

ST equivalent (one instance per axis; ``bReq`` the OR of the lock requests)::

    CASE eHold OF
    IDLE:      IF bReq AND (stState.actual_state = 1 OR stState.actual_state = 4) THEN
                   bConstDist := stState.actual_state = 4;
                   lrSet := SEL(bConstDist, lrSetPosObj, lrSetDistObj);   (* CNC objects 0x3104 / 0x3103 *)
                   nCmd := 2; eHold := FREEZING;
               END_IF
    FREEZING:  IF nCmd = 0 THEN eHold := SEL(stState.actual_state = 2, IDLE, FROZEN); END_IF
    FROZEN:    IF stState.actual_state <> 2 THEN eHold := IDLE;
               ELSIF NOT bReq THEN nCmd := SEL(bConstDist, 1, 4); eHold := RELEASING; END_IF
    RELEASING: IF nCmd = 0 THEN eHold := SEL(stState.actual_state = 2, IDLE, FROZEN); END_IF
    END_CASE
    (* send: only while the semaphore is free; nCmd = 0 once the CNC has taken it *)
    IF nCmd <> 0 AND NOT dc.command_semaphore_rw THEN
        dc.command_w.transition := nCmd;
        dc.command_w.position := LREAL_TO_DINT(lrSet * 10000.0);   (* mm -> 0.1 um *)
        dc.enable_w := TRUE; dc.command_semaphore_rw := TRUE; nCmd := 0; bSent := TRUE;
    END_IF
"""
from __future__ import annotations

from ...base.states import HliState, HliTransition
from .plc_io import read_object

__all__ = ["FreezeHold", "IDLE", "FREEZING", "FROZEN", "RELEASING", "RUNNING_TRACKING"]

IDLE, FREEZING, FROZEN, RELEASING = "IDLE", "FREEZING", "FROZEN", "RELEASING"
_ACTIVE = int(HliState.ACTIVE)
_ACTIVE_CD = int(HliState.ACTIVE_CONST_DIST)
_FREEZE = int(HliState.FREEZE)
_T_FREEZE = int(HliTransition.FREEZE)
_T_ON = int(HliTransition.ON)
_T_ON_CD = int(HliTransition.ON_CONST_DIST)
#: the states a lock may freeze: distance control tracks the surface
RUNNING_TRACKING = (_ACTIVE, _ACTIVE_CD)
_MM_PER_NM001 = 1e-8
_SET_POS = "DIST_CTRL::set_pos"
_SET_DIST = "DIST_CTRL::set_distance"


class FreezeHold:
    """The FREEZE / re-activation sequence of one axis (module docstring). Requesters call
    :meth:`request` with their name every cycle they want the hold; :meth:`step` runs once per cycle
    after them (the :class:`~distctrl.plc.process.ProcessProgram` does both)."""

    def __init__(self, axis: str):
        self.axis = axis
        #: (cycle, transition) of every command this hold sent (diagnosis, tests; kept by reset())
        self.log: list[tuple[int, int]] = []
        #: functions that move the axis themselves for now (touch-off, collision retract): while any
        #: is listed the hold sends nothing, drops the requests and forgets its phase (an interlock;
        #: the functions add and remove themselves, reset() keeps it)
        self.inhibitors: set[str] = set()
        self.reset()

    def reset(self) -> None:
        """Back to IDLE with no request and no command pending (the log is kept). A FREEZE the hold
        commanded stays in force: the hold no longer owns it, as after another command."""
        self.phase = IDLE
        self.const_dist = False
        #: mm: the set value the re-activation commands (SET_POS or SET_DIST)
        self.set_value = 0.0
        self._requests: set[str] = set()
        self._requested_now: set[str] = set()
        self._pending: tuple[int, float] | None = None
        self._sent = False

    # ------------------------------------------------------------------ requesters
    def request(self, who: str) -> None:
        """``who`` wants the hold in this cycle."""
        self._requested_now.add(who)

    def withdraw(self, who: str) -> None:
        """``who`` takes back its request (e.g. its sampling ended this cycle, or it was switched off):
        the hold releases at its next step unless another function still requests it."""
        self._requested_now.discard(who)
        self._requests.discard(who)

    def requested_by(self, who: str) -> bool:
        """``who`` requested the hold in the last cycle (or in this one, before the hold's step)."""
        return who in self._requests or who in self._requested_now

    @property
    def requested(self) -> bool:
        return bool(self._requests)

    @property
    def held_by_us(self) -> bool:
        """The hold is ours (FREEZING, FROZEN or RELEASING)."""
        return self.phase != IDLE

    def _read_set_value(self, machine, const_dist: bool) -> float:
        return read_object(machine, self.axis, _SET_DIST if const_dist else _SET_POS) * _MM_PER_NM001

    # ------------------------------------------------------------------ once per cycle
    def step(self, machine, cycle: int) -> None:
        self._requests, self._requested_now = self._requested_now, set()
        if self.inhibitors:
            self.phase = IDLE
            self._pending = None
            return
        unit = machine.hli[self.axis]
        state = unit.state_r.actual_state
        if self._pending is not None:                     # waiting for the semaphore
            self._send(unit, cycle)
            return
        want = bool(self._requests)
        phase = self.phase
        if phase == IDLE:
            if want and state in RUNNING_TRACKING:
                self.const_dist = state == _ACTIVE_CD
                self.set_value = self._read_set_value(machine, self.const_dist)
                self._pending = (_T_FREEZE, 0.0)
                self.phase = FREEZING
                self._send(unit, cycle)
        elif phase == FREEZING or phase == RELEASING:
            self.phase = FROZEN if state == _FREEZE else IDLE
            if self.phase == FROZEN and not want:
                self._release(unit, cycle)
        elif phase == FROZEN:
            if state != _FREEZE:
                self.phase = IDLE
            elif not want:
                self._release(unit, cycle)

    def _release(self, unit, cycle: int) -> None:
        self._pending = (_T_ON_CD if self.const_dist else _T_ON, self.set_value)
        self.phase = RELEASING
        self._send(unit, cycle)

    def _send(self, unit, cycle: int) -> None:
        transition, position = self._pending
        if unit.plc_command(transition, position):
            self.log.append((cycle, transition))
            self._pending = None

    def __repr__(self) -> str:
        return f"FreezeHold(axis={self.axis!r}, phase={self.phase}, requests={sorted(self._requests)})"
