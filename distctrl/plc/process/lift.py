"""Lift between cuts, overlapped with the rapid ("frog jump"): the head rises while X/Y already move.

Between two cuts the head travels at the cut height over a plate with cut-out parts, tipped-up
edges and slag: a collision risk. Lifting before the rapid and lowering after it costs time when
done in separate blocks (``G0 Z..``, ``G0 X.. Y..``, ``G0 Z..``). Cutting controls overlap the lift
with the rapid instead: Beckhoff TF5290 "Lift" (TwinCAT CNC Cutting Plus; ISG functional description
FCT-A11, the lift function, *Advanced Lifting*: the CNC lifts the lift axis during the positioning
blocks independently of the path and lowers it so that it reaches the target height at the start of
the next contour), FANUC's rapid retract/approach of laser controls, the "frog jump" of laser heads.

Two parts, as on a TwinCAT CNC:

* **the CNC part** (:class:`distctrl.sim.lift.LiftMotion`, run by the machine after the interpolator):
  in every G0 block that does not move the lift axis, is at least ``min_distance`` long (TF5290's
  P-CHAN-00244 ``lift_min_dist``) and takes longer than ``settle_time`` (else: "lift suppressed"),
  it superimposes on the axis's programmed position a lift of up to ``height`` at ``v_max`` /
  ``a_max`` (the axis's limits by default): up as soon as distance control no longer tracks and its
  offset stands (FREEZE has braked, an OFF has run out), down again when the time the rapid still
  needs (its velocity profile at the current override) has come down to the time the landing needs
  plus ``settle_time``, so the head is back at the programmed height before the path stops. A short
  rapid gets a lower lift (what fits); where the landing still runs when the path stops, the next
  block waits for it. On a TwinCAT CNC the program marks the range with
  ``Z[LIFT_START POS_LIMIT=..]`` / ``Z[LIFT_END]``; distctrl's NC has no such words, so the
  scenario's ``lift`` table enables it for every G0 block. ``lift_active`` / ``lift_suppressed`` are
  TF5290's CNC objects of that name (GEO, index offsets 0x<AID>0095 / 0x<AID>0094, BOOLEAN), here
  attributes.
* **the PLC part** (:class:`Lift`, this process function): FCT-M3 §5.2, "when the Z axis is lifted,
  distance control must be frozen (FREEZE) or deactivated (OFF), otherwise distance control prevents
  lifting/lowering". While ``lift_active`` it requests the axis's FREEZE hold (:mod:`.hold`), which
  remembers the set value in force and re-activates distance control (FREEZE -> ON / ON_CONST_DIST)
  once the lift has landed. The CNC part starts rising only once distance control no longer tracks
  (``state_r.actual_state`` not ACTIVE / ACTIVE_CONST_DIST): two GEO cycles after the G0 started (a
  TwinCAT PLC would freeze on the M function that ends the cut, before the G0).

Switching the function off (``enabled``) stops new lifts; a lift under way lands, and until it has
landed the function still keeps distance control frozen (``enabled`` reads true until then). The
frozen offset is kept over the rapid, so the head comes down to the height it had at the end of the
cut; distance control, re-activated ``settle_time`` before the rapid ends, then corrects for the
plate under the new position.

ST equivalent of the PLC part (``fbHold`` the axis's hold, :mod:`.hold`; ``bLiftActive`` the CNC
object ``lift_active`` read every cycle)::

    fbHold.bReqLift := bLiftActive;          (* FREEZE while the CNC lifts; ON again after landing *)

and of the CNC part (what the CNC's lift does each GEO cycle; ``lrTau`` the time the G0 still needs,
``lrZ``/``lrW`` lift offset and its velocity, ``lrA``/``lrV`` the lift's limits)::

    IF bNewRapid THEN
        bSuppressed := bLiftAxisInBlock OR lrPathLength < lrMinDist OR lrTau <= lrSettle + 4.0 * lrT;
        IF NOT bSuppressed AND bEnabled THEN eLift := WAITING; END_IF
    END_IF
    CASE eLift OF
    WAITING: IF NOT bRapid OR NOT bEnabled THEN eLift := IDLE;
             ELSIF NOT (nDcState = 1 OR nDcState = 4) AND lrOffsetVelocity = 0.0 THEN eLift := UP; END_IF
    UP:      lrH := lrZ + SEL(lrW > 0.0, 0.0, lrW * lrW / (2.0 * lrA));
             IF lrTau <= SEL(lrW > 0.0, 0.0, lrW / lrA) + TrapezoidTime(lrH, lrV, lrA) + lrSettle + 2.0 * lrT THEN
                 eLift := DOWN;
             END_IF
    END_CASE
    IF eLift = UP THEN MoveTo(lrHeight); ELSIF eLift = DOWN THEN MoveTo(0.0); END_IF   (* v, a limited *)
    IF eLift = DOWN AND lrZ = 0.0 AND lrW = 0.0 THEN eLift := IDLE; END_IF
    bLiftActive := eLift <> IDLE;
"""
from __future__ import annotations

from ...errors.config import require_number
from .base import Key, ProcessFunction, ProcessTable

__all__ = ["Lift", "LIFT_DEFAULTS"]

#: documented defaults (docs/process.md); ``v_max`` / ``a_max`` default to the axis's own limits
LIFT_DEFAULTS = {"height": 5.0, "min_distance": 0.0, "settle_time": 0.05}


class Lift(ProcessFunction):
    """The PLC part: the FREEZE hold while the CNC's lift is active. ``height`` (mm, > 0) the lift
    above the programmed position, ``v_max`` (mm/s) / ``a_max`` (mm/s²) the lift's limits (at most
    the axis's), ``min_distance`` (mm, >= 0) the shortest G0 that is lifted; :attr:`motion` is the
    CNC part the machine attaches and runs."""

    name = "lift"
    KEYS = {
        "height": Key(LIFT_DEFAULTS["height"], "mm the head rises", lo=0.0, hi=1000.0, lo_open=True),
        "min_distance": Key(LIFT_DEFAULTS["min_distance"], "mm of rapid below which the head does not lift",
                            lo=0.0, hi=1.0e6),
        "v_max": Key(None, "mm/s of the lift; default and upper bound the axis's v_max", lo=0.0, lo_open=True),
        "a_max": Key(None, "mm/s² of the lift; default and upper bound the axis's a_max", lo=0.0, lo_open=True),
        "settle_time": Key(LIFT_DEFAULTS["settle_time"], "s after landing before distance control resumes",
                           lo=0.0, hi=1.0),
    }

    @classmethod
    def from_config(cls, table: ProcessTable) -> dict:
        ax = table.axis_cfg
        return {"height": table.read(cls, "height"), "min_distance": table.read(cls, "min_distance"),
                "v_max": table.read(cls, "v_max", ax.v_max, hi=ax.v_max),
                "a_max": table.read(cls, "a_max", ax.a_max, hi=ax.a_max),
                "settle_time": table.read(cls, "settle_time")}

    def __init__(self, axis: str, cycle_time: float, v_max: float, a_max: float,
                 height: float = LIFT_DEFAULTS["height"], min_distance: float = LIFT_DEFAULTS["min_distance"],
                 settle_time: float = LIFT_DEFAULTS["settle_time"], enabled: bool = True):
        self.motion = None
        super().__init__(axis, enabled)
        T = require_number(cycle_time, "lift.cycle_time", lo=0.0, lo_open=True)
        self.height = self.KEYS["height"].check(height, "lift.height")
        self.v_max = self.KEYS["v_max"].check(v_max, "lift.v_max")
        self.a_max = self.KEYS["a_max"].check(a_max, "lift.a_max")
        self.min_distance = self.KEYS["min_distance"].check(min_distance, "lift.min_distance")
        self.settle_time = self.KEYS["settle_time"].check(settle_time, "lift.settle_time")
        self.cycle_time = T
        #: the CNC part (:class:`~distctrl.sim.lift.LiftMotion`), attached by the machine that hosts this
        #: function (:func:`distctrl.sim.lift.attach_lift`) and run by it every GEO cycle, whether or not
        #: this function is enabled; None until then
        self.motion = None
        #: the function requested the hold in its last cycle
        self.requesting = False

    @property
    def finishing(self) -> bool:
        """Switched off during a lift, the function keeps distance control frozen until the head has
        landed (re-activated while the head is up, distance control would pull it down and, with a
        lower velocity limit than the landing, let it dive into the plate when it lands)."""
        return self.motion is not None and self.motion.lift_active

    def step(self, machine, cycle: int) -> None:
        if not self.enabled:
            self.requesting = False
            return
        self.requesting = self.motion is not None and self.motion.lift_active   # the CNC object lift_active
        if self.requesting:
            self.hold.request(self.name)

    def reset(self) -> None:
        """Back to the initial state of the PLC part. The CNC part is not the PLC's: a lift under way
        lands (a jump of the axis would be the alternative)."""
        self.requesting = False

