"""3D (channel-specific) distance control on the shared cycle core (FCT-M3 ch. 12, SPEC §11).

One law, not a copy: the channel controller owns an :class:`AxisDistanceController` and runs it on
*orthogonal* quantities — the PLC supplies the orthogonal distance ``d`` of the tool clamping point
(laser exit) from the surface (FCT-M3 §12.3), the set distance in use is
``SET_DIST · cos θ`` (times kinematic 98's extension Lv/L, SPEC §11), and the core's offset ``o`` is
the orthogonal compensation wanted. This layer then superimposes it along the MODE's direction
``e`` (ACS/MCS: machine Z, PCS: the programmed Z of an active #CS, ECS: the tool direction u):
the motion ``δ·e`` with ``δ = o / e_z`` changes the orthogonal distance by exactly ``o``
(SPEC §11: a compensation δ along the tool direction changes it by δ·cos θ). MODE=OFF computes the
offset without superimposing it. "Orthogonal" refers to the workpiece normal ``Cycle3DInput.normal``:
machine Z by default; a channel whose workpiece is inclined (robot example §12.4.3.3, programmed in a
#CS) passes the #CS's Z, and θ in ``SET_DIST·cos θ`` and ``δ = o / e_z`` are then taken against it.

Additional rules of the 3D variant: a_max must be > 0 (315001 at select); MODE may not change while
active (51064); ECS needs kinematic 98 active; FILTER_TIME = N > 0 blends activation (weight sin²(π/2·k/N))
and deactivation by OFF (cos²(π/2·k/N) times the core's run-out; not OFF NO_MOVE); reset and program end keep the current offset as a static offset and sensor
changes no longer act (FCT-M3 §12.4.4). Errors of the core are reported with their 3D IDs.

Reset and program end (FCT-M3 §12.4.4, docs/run-3d.md): the offset is *retained* in the core itself,
so what the control reports (the core's offset, ``DIST_CTRL[0]::m_actual_offset``) is always what it
superimposes. Program end while selected: the core stays in its state and holds (override 0: it
brakes within v_max/a_max and stands); a new select with its set value resumes tracking from there.
Program end while TURNING_OFF (already deselected) lets the run-out finish. Reset: the core is
deselected (INACTIVE, set values forgotten) *without* absorbing its offset: the offset brakes within
the limits and stays; a new select takes it over as its start value (bumpless), OFF runs it out to
zero, OFF NO_MOVE hands it to the channel. A FILTER_TIME blend that runs at reset or program end
ends there with its weight folded into the retained offset.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..base.kinds import SensorSource
from ..base.states import HliState
from ..errors import ErrorEvent
from ..errors.three_d import event_to_3d, make_event_3d
from ..params.channel import ChannelParameters
from .commands import Action, Command, ObjectWrite
from .commands3d import CompensationMode
from .controller import AxisDistanceController
from .cycle_io import CycleInput, CycleOutput, Result

_Z = (0.0, 0.0, 1.0)
_RUNNING = (int(HliState.ACTIVE), int(HliState.ACTIVE_CONST_DIST), int(HliState.DRYRUN_SETPOS),
            int(HliState.DRYRUN_CONST_DIST), int(HliState.FREEZE), int(HliState.TURNING_OFF),
            int(HliState.ERROR))
#: |e_z| below this: the direction is (nearly) parallel to the surface, no orthogonal compensation
_MIN_EZ = 1e-3


@dataclass(slots=True)
class Cycle3DInput:
    """Per cycle, from the channel (mm, rad)."""

    programmed_z: float = 0.0               # programmed height of the clamping point (machine Z), mm
    actual_z: float = 0.0                   # actual height of the clamping point, mm
    sensor_distance: float = 0.0            # the V.E. sensor variable: orthogonal distance, mm
    tool_direction: tuple = _Z              # actual unit tool direction u (from the head's angles)
    extension: float = 1.0                  # kinematic 98: virtual / real tool length (1 = none)
    cs_z_axis: tuple = _Z                   # programmed Z of the active #CS, in machine coordinates
    normal: tuple = _Z                      # unit workpiece normal the set distance and the orthogonal
                                            # compensation refer to (machine Z; an inclined workpiece's
                                            # normal, e.g. the #CS's Z in the robot example §12.4.3.3)
    kin98_active: bool = False              # #KIN ID[..98] and #TRAFO ON
    override: float = 1.0
    feed_hold: bool = False
    nc_line: int | None = None
    commands: list = field(default_factory=list)   # Command3D values, consumed


@dataclass(slots=True)
class Cycle3DOutput:
    """What the channel superimposes, and the values behind the 3D objects and status."""

    core: CycleOutput = field(default_factory=CycleOutput)   # the law's values (orthogonal, mm)
    mode: int = 0                           # CompensationMode
    direction: tuple = _Z                   # unit compensation direction e
    delta: float = 0.0                      # compensation along e, mm (weighted by FILTER_TIME)
    compensation: tuple = (0.0, 0.0, 0.0)   # δ·e in machine coordinates, mm (0 for MODE=OFF)
    inclination: float = 0.0                # θ, rad
    orthogonal_set_distance: float = 0.0    # SET_DIST · cos θ · extension, mm
    blend: float = 1.0                      # FILTER_TIME weight 0..1
    static: bool = False                    # reset / program end: the offset is retained, sensor ignored
    events: list = field(default_factory=list)


def _dot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


class ChannelDistanceController:
    """The 3D distance control of one channel (one instance per channel, FCT-M3 §12.8.1)."""

    def __init__(self, params: ChannelParameters, cycle_time: float = 0.001):
        self.params = params
        self.core = AxisDistanceController(params.to_axis_parameters(), cycle_time)
        self.T = cycle_time
        self.mode = CompensationMode.OFF
        self.direction_axis = "Z"
        self.filter_time = 0
        self.blend_k = 0                    # cycles into the current blend
        self.blending_in = False
        self.blending_out = False           # FILTER_TIME blend of a deactivation (OFF) running
        self.blend_from = 1.0               # the weight the deactivation blend starts from
        self._last_weight = 1.0
        self.static = False                 # reset / program end: offset retained, no sensor changes
        self._reselect = False              # a select was passed to the core while static (resume if it took)
        self._kin98_active = False
        self._trafo_tool_length: float | None = None   # tool length while a kinematic transformation is on
        self._core_in = CycleInput()
        self._core_in.commands = []
        # the 3D variant's default sensor source is the V.E. variable (SPEC §2)
        if params.fct_3d_dist_ctrl:
            self._core_in.commands.append(Command(sensor_source=SensorSource.VARIABLE))

    def update(self, inp: Cycle3DInput, out: Cycle3DOutput) -> Result:
        core_in = self._core_in
        events: list[ErrorEvent] = []
        cycle = self.core.state.cycle + 1
        for cmd in inp.commands:
            self._apply(cmd, events, cycle)
        inp.commands.clear()
        u = inp.tool_direction
        n = inp.normal
        # θ for the set distance: the tool's angle to the workpiece normal (= the inclination for a
        # horizontal workpiece, n = machine Z: exactly u[2])
        cos_theta = max(-1.0, min(1.0, _dot(u, n)))
        theta = math.acos(max(-1.0, min(1.0, u[2])))          # the inclination (against machine Z)
        scale = cos_theta * inp.extension
        core_in.programmed_position = inp.programmed_z
        if self.mode == CompensationMode.OFF:
            # computed, not superimposed: the law sees the plant as if its offset were applied, so
            # the computed offset is the one that would be needed (and an open loop cannot run away)
            o_prev = out.core.offset
            core_in.actual_position = inp.actual_z + o_prev
            core_in.sensor_variable = inp.sensor_distance + o_prev
        else:
            core_in.actual_position = inp.actual_z
            core_in.sensor_variable = inp.sensor_distance
        core_in.set_distance_scale = scale
        core_in.override = inp.override
        core_in.feed_hold = inp.feed_hold
        core_in.nc_line = inp.nc_line
        if self.static:
            core_in.override = 0.0                       # sensor changes no longer act: hold
        result = self.core.update(core_in, out.core)
        for ev in out.core.events:
            events.append(event_to_3d(ev))
        if self._reselect:
            # a select after program end / reset: tracking resumes from the retained offset once the
            # core has accepted it (a refused one, e.g. 310026 without a set value, keeps it retained)
            self._reselect = False
            if not any(ev.severity == "error" for ev in out.core.events):
                self.static = False
        state = out.core.hli_state
        # the compensation direction of the MODE
        mode = self.mode
        if mode == CompensationMode.ECS:
            e = u
        elif mode == CompensationMode.PCS:
            e = inp.cs_z_axis
        else:
            e = _Z                                       # ACS / MCS (DIRECTION=Z); OFF: computed only
        e_z = _dot(e, n)                                 # δ along e changes it by δ·e_z
        o = out.core.offset
        delta = o / e_z if abs(e_z) >= _MIN_EZ else 0.0
        # FILTER_TIME: activation and deactivation "smoothed by a sin² filter" (PROG #DIST CTRL): the
        # compensation is weighted by sin²(π/2·k/N) after a select and by cos²(π/2·k/N) after OFF (the
        # core runs its offset out within the limits meanwhile; the product falls to 0 in N cycles)
        w = 1.0
        if self.static:
            pass                                         # retained: no blend runs (folded in at retention)
        elif self.blending_out:
            self.blend_k += 1
            k_n = self.blend_k / self.filter_time
            w = self.blend_from * math.cos(0.5 * math.pi * k_n) ** 2 if k_n < 1.0 else 0.0
        elif self.filter_time > 0 and self.blending_in:
            self.blend_k += 1
            w = math.sin(0.5 * math.pi * min(1.0, self.blend_k / self.filter_time)) ** 2
            if self.blend_k >= self.filter_time:
                self.blending_in = False
        if state == int(HliState.INACTIVE) and not self.static:
            w = 1.0
            self.blending_in = self.blending_out = False
        self._last_weight = w
        delta *= w
        out.mode = int(mode)
        out.direction = tuple(e)
        out.delta = delta
        out.compensation = (0.0, 0.0, 0.0) if mode == CompensationMode.OFF else \
            (delta * e[0], delta * e[1], delta * e[2])
        out.inclination = theta
        out.orthogonal_set_distance = out.core.set_distance
        out.blend = w
        out.static = self.static
        out.events = events
        if any(ev.severity == "error" for ev in events):
            return Result.ERROR
        return Result.WARNING if events else result

    # ------------------------------------------------------------------ commands
    def _apply(self, cmd, events: list, cycle: int) -> None:
        core_cmds = self._core_in.commands
        running = self.core.state.hli_state != HliState.INACTIVE
        if isinstance(cmd, ObjectWrite):
            core_cmds.append(cmd)               # a 3D CNC-object write: the shared core's adoption rule
            return
        if not self.params.fct_3d_dist_ctrl:
            events.append(make_event_3d(51061, cycle, cmd.line,
                                        "configuration.decoder.function FCT_3D_DIST_CTRL (P-CHAN-00500) is not set"))
            return
        if running and cmd.sensor_var is not None and cmd.sensor_var != self.core.state.sensor_var:
            events.append(make_event_3d(310028, cycle, cmd.line,
                                        f"SENSOR_VAR {self.core.state.sensor_var} -> {cmd.sensor_var}"))
            return
        st = self.core.state
        if cmd.action == Action.PROGRAM_END:
            # FCT-M3 §12.4.4: a selected control keeps its offset as a static offset and sensor changes
            # no longer act (the core holds, warning 310021); a deselected one (TURNING_OFF) runs out
            if st.hli_state not in (HliState.INACTIVE, HliState.TURNING_OFF) and not self.static:
                self._retain()
            core_cmds.append(Command(cmd.action, line=cmd.line))
            return
        if cmd.action == Action.RESET:
            if st.hli_state != HliState.INACTIVE or st.offset != 0.0 or st.velocity != 0.0:
                self._reset_keeping_offset(core_cmds)
            else:
                core_cmds.append(Command(cmd.action, line=cmd.line))   # nothing to keep: the core's reset
            return
        retained = self.static and not running        # a reset's offset, still applied while INACTIVE
        if cmd.mode is not None and cmd.mode != self.mode:
            if running or retained:
                events.append(make_event_3d(51064, cycle, cmd.line, f"{self.mode.name} -> {cmd.mode.name}"))
                return
            self.mode = cmd.mode
        if cmd.direction is not None:
            if cmd.direction != "Z":
                events.append(make_event_3d(310015, cycle, cmd.line,
                                            f"DIRECTION={cmd.direction}: only Z is supported"))
                return
            self.direction_axis = cmd.direction
        if cmd.filter_time is not None:
            self.filter_time = int(cmd.filter_time)
        if cmd.action in (Action.ON, Action.DRYRUN):
            if self.params.a_max <= 0:
                events.append(make_event_3d(315001, cycle, cmd.line,
                                            "dist_ctrl[0].a_max (P-CHAN-00803) must be > 0"))
                return
            if self.mode == CompensationMode.ECS and not self._kin98_active:
                events.append(make_event_3d(310015, cycle, cmd.line,
                                            "MODE=ECS needs kinematic 98 active (#KIN ID[98], #TRAFO ON)"))
                return
            if self.static:
                self._reselect = True                     # resume from the retained offset (no blend-in)
            elif not running:
                self.blend_k = 0
                self.blending_in = self.filter_time > 0
            if self.mode == CompensationMode.OFF:
                # SPEC §12: MODE=OFF (the default) is kept, but the user is told nothing moves
                events.append(make_event_3d(900023, cycle, cmd.line))
            self._check_tool_length(cmd, events, cycle)
        if cmd.action == Action.OFF:
            if retained and (st.offset != 0.0 or st.velocity != 0.0):
                # the reset's retained offset: OFF runs it out to zero within the limits, OFF NO_MOVE
                # hands it to the channel, as for a selected control (FCT-M3 §12.4.4)
                st.hli_state = HliState.TURNING_OFF
            self.static = False
            if self.filter_time > 0 and running and not cmd.no_move and not self.blending_out:
                self.blend_from = self._last_weight
                self.blend_k = 0
                self.blending_in, self.blending_out = False, True
        core_cmds.append(cmd.core_command())

    def set_kinematics(self, kin98_active: bool, tool_length: float | None = None) -> None:
        """The channel tells whether kinematic 98 is active (#KIN ID[..98] with #TRAFO ON) and, while a
        kinematic transformation is on, its tool length (mm; None: no transformation)."""
        self._kin98_active = bool(kin98_active)
        self._trafo_tool_length = tool_length

    def _check_tool_length(self, cmd, events: list, cycle: int) -> None:
        """FCT-M3 §12.1.2: with a kinematic transformation the set distance must equal the tool length
        (the transformation plans the motion for it); a CONST_DIST select with another one warns."""
        length = self._trafo_tool_length
        if length is None or not cmd.const_dist:
            return
        set_dist = cmd.set_dist if cmd.set_dist is not None else self.core.state.programmed_set_dist
        if set_dist is not None and abs(set_dist - length) > 1e-9 * max(1.0, abs(length)):
            events.append(make_event_3d(900024, cycle, cmd.line,
                                        f"SET_DIST {set_dist:g} mm, tool length {length:g} mm"))

    def _retain(self) -> None:
        """Reset / program end: keep the offset applied now as a static offset. A running FILTER_TIME
        blend ends here: its weight is folded into the core's offset (and velocity), so the applied
        compensation does not jump and the core's offset is what is applied from now on."""
        w = self._last_weight
        if w != 1.0:
            st = self.core.state
            st.offset *= w
            st.velocity *= w
        self.blending_in = self.blending_out = False
        self._last_weight = 1.0
        self.static = True

    def _reset_keeping_offset(self, core_cmds: list) -> None:
        """FCT-M3 §12.4.4 reset: "the program stops within the dynamic limits. The previous offset due
        to distance control is retained, i.e. no further sensor changes are carried out." The core is
        deselected as by its own RESET (INACTIVE, set values forgotten, SPEC §8) but its offset is not
        absorbed: INACTIVE holds, so a moving offset brakes within the limits and then stays. Done on
        the core's public state before its cycle, so the commands queued after the reset act after it;
        selects, deselects and set values queued before it in the same cycle are cancelled by it."""
        core_cmds[:] = [c for c in core_cmds if not (isinstance(c, Command) and (
            c.action != Action.NONE or c.set_pos is not None or c.set_dist is not None))]
        self._retain()
        self.core.deselect_holding_offset()
        st = self.core.state
        if st.offset == 0.0 and st.velocity == 0.0:
            self.static = False                        # nothing to keep

