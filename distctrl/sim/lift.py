"""The CNC part of the lift between cuts (TF5290 "Lift", docs/process.md "Lift"): :class:`LiftMotion`
superimposes a lift on an axis's programmed position during G0 blocks. The PLC part, the process
function :class:`~distctrl.plc.process.lift.Lift` (its module docstring describes both parts), keeps
distance control frozen while the lift is active; the machine attaches a motion to each ``lift``
function (:func:`attach_lift`) and steps it after the interpolator.
"""
from __future__ import annotations

from ..base.states import HliState
from ..plc.process.lift import Lift
from .interpolator import brake_velocity, trapezoid_time

__all__ = ["LiftMotion", "attach_lift"]

IDLE, WAITING, UP, DOWN = "IDLE", "WAITING", "UP", "DOWN"
_TRACKING = (int(HliState.ACTIVE), int(HliState.ACTIVE_CONST_DIST))
#: the landing is planned this many cycles early (the discrete profiles need up to a cycle more)
_MARGIN_CYCLES = 2


class LiftMotion:
    """The CNC's lift of ``axis`` during G0 blocks (module docstring), one :meth:`step` per GEO cycle.

    ``offset`` (mm) is superimposed on the axis's programmed position; ``velocity`` (mm/s) is its
    rate. ``lift_active`` / ``lift_suppressed``: TF5290's CNC objects. ``log``: ``(cycle, event)``
    with the events ``"start"`` (rising), ``"down"`` (landing begins), ``"landed"`` (the highest
    offset of that lift in :attr:`peaks`), ``"suppressed"``.
    """

    def __init__(self, axis: str, cycle_time: float, height: float, v_max: float, a_max: float,
                 min_distance: float = 0.0, settle_time: float = 0.0, function=None):
        self.axis = axis
        self.settle_time = settle_time
        self.T = cycle_time
        self.height = height
        self.v_max = v_max
        self.a_max = a_max
        self.min_distance = min_distance
        self._dv = a_max * cycle_time
        #: the process function that switches new lifts on and off (its ``enabled``)
        self.function = function
        self.offset = 0.0
        self.velocity = 0.0
        self.phase = IDLE
        self.lift_active = False
        self.lift_suppressed = False
        self._was_rapid = False
        self.log: list[tuple[int, str]] = []
        #: the highest offset (mm) of every lift that landed
        self.peaks: list[float] = []
        self._top = 0.0

    @property
    def busy(self) -> bool:
        """The axis is lifted or moving: the next block waits (the CNC's lift must land first)."""
        return self.offset != 0.0 or self.velocity != 0.0

    def land_time(self) -> float:
        """Time (s) to bring the lift from its offset and velocity back to 0 at rest."""
        w = self.velocity
        a = self.a_max
        h = self.offset
        t = 0.0
        if w > 0.0:
            h += w * w / (2.0 * a)
            t = w / a
        return t + trapezoid_time(h, self.v_max, a)

    def step(self, machine) -> None:
        interp = machine.interp
        cycle = machine.cycle
        rapid = interp.block == "rapid"
        switched_on = getattr(self.function, "switched_on", True)
        if rapid and not self._was_rapid:                       # a G0 block started this cycle
            self.lift_suppressed = False
            if self.phase == IDLE and switched_on:
                if (self.axis in interp.moving_axes or interp.path_length < self.min_distance
                        or interp.remaining_time() <= self.settle_time + (_MARGIN_CYCLES + 2) * self.T):
                    self.lift_suppressed = True
                    self.log.append((cycle, "suppressed"))
                else:
                    self.phase = WAITING
        self._was_rapid = rapid
        phase = self.phase
        if phase == WAITING:
            if not rapid or not switched_on:                    # nothing lifted yet: no lift
                phase = IDLE
            else:
                out = machine.outputs[self.axis]
                if out.hli_state not in _TRACKING and out.offset_velocity == 0.0:   # FREEZE has braked
                    phase = UP
                    self.log.append((cycle, "start"))
        if phase == UP:
            tau = interp.remaining_time() if rapid else 0.0
            if tau <= self.land_time() + self.settle_time + _MARGIN_CYCLES * self.T:
                phase = DOWN
                self.log.append((cycle, "down"))
        if phase == UP:
            self._move(self.height)
        elif phase == DOWN:
            self._move(0.0)
            if self.offset == 0.0 and self.velocity == 0.0:
                phase = IDLE
                self.peaks.append(self._top)
                self._top = 0.0
                self.log.append((cycle, "landed"))
        if self.offset > self._top:
            self._top = self.offset
        self.phase = phase
        self.lift_active = phase != IDLE

    def _move(self, target: float) -> None:
        """One cycle towards ``target`` within v_max / a_max, landing on it exactly (the
        interpolator's discrete braking, :func:`~distctrl.sim.interpolator.brake_velocity`)."""
        T = self.T
        dv = self._dv
        d = target - self.offset
        if d == 0.0:
            self.velocity = 0.0          # the last step was at most a*T: stopping is within a_max
            return
        s = 1.0 if d > 0.0 else -1.0
        r = abs(d)
        vs = self.velocity * s           # velocity towards the target
        v = min(self.v_max, vs + dv)
        if v > 0.0 and r < T * (v + v * v / dv):
            v = min(v, brake_velocity(r, dv, T))
        if v < vs - dv:
            v = vs - dv
        if v * T >= r - 1e-12:
            self.offset = target
            self.velocity = s * r / T
            return
        self.offset += s * v * T
        self.velocity = s * v

    def __repr__(self) -> str:
        return f"LiftMotion(axis={self.axis!r}, phase={self.phase}, offset={self.offset:.4f})"


def attach_lift(function: Lift) -> LiftMotion:
    """The CNC part of the PLC's ``lift`` function: a :class:`LiftMotion` with its parameters, attached
    as ``function.motion`` (the PLC part reads its ``lift_active``) and returned for the machine to step."""
    function.motion = LiftMotion(function.axis, function.cycle_time, function.height, function.v_max,
                                 function.a_max, function.min_distance, function.settle_time, function)
    return function.motion
