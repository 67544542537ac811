"""The virtual machine: one channel of axes around the distance-control cycle core.

Per GEO cycle (FCT-M3 Fig. 3: the offset is added after interpolation, before the drive):

1. timed scenario events (PLC commands, override, reset, sensor faults, variables);
2. the NC interpreter starts blocks; DIST_CTRL commands are queued for the axis's controller;
3. the interpolator gives the programmed positions ``p``;
4. the sensor measures the real geometry at the tool's actual position (probe increments, or a
   distance written into its V.E. variable); the tool is each drive's ``nozzle`` (the motor plus the
   deflection of a drive's mechanical resonance, ``resonance_hz``; the motor for a rigid drive), and
   so is the true distance the collision check uses;
5. each distance-controlled axis runs ``AxisDistanceController.update`` -> setpoint ``c = p + o``;
6. each drive follows its setpoint (one-cycle fieldbus delay, P loop, limits) -> actual ``a``.

The machine drives the core and never reaches into it: it only fills ``CycleInput`` and reads
``CycleOutput``.

A channel with 3D distance control (``[channel] params`` with FCT_3D_DIST_CTRL) or a head kinematic
(``[channel] kinematics = "CA"``, the default with the axes X, Y, Z, A, C) runs the GEO cycle of its
kinematic part, :meth:`KinematicChannel.step <distctrl.sim.channel3d.KinematicChannel.step>`
(``sim/channel3d.py``, owned as ``machine.channel3d``), instead (docs/run-3d.md): the NC's X, Y, Z are
transformed (#CS frame, #TRAFO with the CA head and kinematic 98) into the machine axes, the sensor
reports the orthogonal distance of the tool clamping point, and the channel's
:class:`~distctrl.control.controller3d.ChannelDistanceController` adds its compensation ``δ·e``. Both
cycles start with :meth:`Machine._cycle_line` and end with :meth:`Machine._axes_cycle`. Without
either the cycle is exactly the axis variant's (:meth:`Machine._step_axes`).
"""
from __future__ import annotations

import math

from ..control import Action, AxisDistanceController, Command, CycleInput, CycleOutput, HliState, SensorSource
from ..control.commands3d import Command3D
from ..errors import ErrorEvent, ErrorId
from ..nc.interpreter import NcInterpreter
from ..nc.parser import parse_file, parse_program
from ..nc.program import KinematicsWord, Program
from ..plc.chain import chain
from ..plc.hli import ChannelDistanceStatus, DistanceControlUnit
from ..plc.process.channel import ChannelPathStatus
from ..plc.process.lift import Lift
from .channel3d import KinematicChannel
from .drive import Drive
from .interpolator import AxisLimits, Interpolator
from .lift import attach_lift
from .sensors import Fault
from .status import EventCursor, activity, machine_status

_TRACKING = (int(HliState.ACTIVE), int(HliState.ACTIVE_CONST_DIST))
_VARIABLE = SensorSource.VARIABLE


def _wait_done(out: CycleOutput, action: Action) -> bool:
    """WAIT (SPEC §8) on a controller output: a select has reached its target once, OFF has reached
    INACTIVE, FREEZE has braked; an ERROR also ends the wait (the error stops the program anyway)."""
    state = out.hli_state
    if state == int(HliState.ERROR):
        return True
    if action == Action.OFF:
        return state == int(HliState.INACTIVE)
    if action == Action.ON:
        return state in _TRACKING and out.target_reached
    if action == Action.DRYRUN:
        return state in (int(HliState.DRYRUN_SETPOS), int(HliState.DRYRUN_CONST_DIST))
    if action == Action.FREEZE:
        return out.offset_velocity == 0.0
    return True


#: blocks prepared ahead of a G1 block (the chain's braking distance: 16 blocks of an excitation at
#: one block per cycle cover ~16 ms of its motion)
LOOK_AHEAD_BLOCKS = 16


class Machine:
    """A simulated channel built from a :class:`~distctrl.sim.scenario.Scenario`."""

    def __init__(self, scenario, program: Program | None = None, plc_program=None, publish_hli: bool | None = None,
                 controller_factory=None):
        """``controller_factory(name, params, cycle_time)``: builds each axis's controller (default
        :class:`AxisDistanceController`; the closed-loop batch kernel's recorder stands in with it)."""
        self.scenario = scenario
        T = self.T = scenario.cycle_time
        axes = scenario.axes
        self.axis_names = list(axes)
        limits = {n: AxisLimits(a.v_max, a.a_max, a.v_rapid, a.a_rapid) for n, a in axes.items()}
        self.interp = Interpolator(T, limits, start={n: a.start for n, a in axes.items()})
        self.drives = {n: Drive(T, kv=a.kv, v_max=a.v_max, a_max=a.a_max, bus_delay_cycles=a.bus_delay_cycles,
                                resolution=a.resolution, initial_position=a.start,
                                velocity_feedforward=a.feedforward, resonance_hz=a.resonance_hz,
                                damping=a.damping) for n, a in axes.items()}
        make = controller_factory or (lambda name, params, cycle_time: AxisDistanceController(params, cycle_time))
        self.controllers = {n: make(n, a.params, T) for n, a in axes.items()}
        self.inputs = {n: CycleInput(programmed_position=a.start, actual_position=self.drives[n].actual)
                       for n, a in axes.items()}
        self.outputs = {n: CycleOutput() for n in axes}
        #: the HLI DistanceControl control unit of each axis (gpAx[i]^.lr_mc_control.distance_control)
        self.hli = {n: DistanceControlUnit(axis_index=i + 1, distance_control_on=a.params.enabled)
                    for i, (n, a) in enumerate(axes.items())}
        #: the channel's 3D status (gpCh[1]^.bahn_state: virt_tool_length_r, inclination_r); filled by
        #: the 3D distance control, 0 for the axis variant
        self.channel_status = ChannelDistanceStatus()
        #: the channel's path status as the PLC reads it (StateBahn_Data.D_ActiveFeed / D_CommandFeed)
        self.channel_path = ChannelPathStatus(self)
        # the scenario's [[process]] functions (docs/process.md): after the sensor's PLC program,
        # before the run's own; they read state_r every cycle, so it is published every cycle
        process_plc = scenario.make_process_program() if getattr(scenario, "processes", ()) else None
        #: the process functions' program (None without [[process]] tables)
        self.process_program = process_plc
        #: the CNC's lift motions of the scenario's ``lift`` functions (docs/process.md "Lift"): each is
        #: stepped after the interpolator and superimposed on its axis's programmed position
        self.lift_motions = tuple(attach_lift(f) for f in process_plc.functions if isinstance(f, Lift)) \
            if process_plc is not None else ()
        #: fill every unit's state_r every cycle: needed when something reads it while running (a PLC
        #: program, the ADS server); a batch run without readers publishes once at the end
        self.publish_hli = (plc_program is not None or process_plc is not None) if publish_hli is None \
            else publish_hli
        # the PLC program the sensor needs (arc-voltage linearisation) runs first
        sensor_plc = scenario.sensor.make_plc_program() if scenario.sensor is not None else None
        #: the PLC task: called every cycle before the CNC consumes the control units
        self.plc_program = chain(sensor_plc, process_plc, plc_program)
        self._plc_pending: list[tuple[str, int, float]] = []    # scenario PLC commands waiting for the semaphore
        #: axes whose controller runs every cycle (distance control enabled); others only on commands
        self.dc_axes = [n for n, a in axes.items() if a.params.enabled]
        self.surface = scenario.surface
        self.variables: dict[str, float] = {f"V.E.{k}": float(v) for k, v in scenario.variables.items()}
        self.variables["V.G.WZ_AKT.L"] = float(scenario.tool_length)
        # the V.E. variables the process functions hand over to the NC program (the touch-off's request):
        # they exist from the start (0), so the program can wait on them and ADS serves them as symbols
        for f in (process_plc.functions if process_plc is not None else ()):
            for name in f.declares:
                self.variables.setdefault(name, 0.0)
        self.shift = {n: 0.0 for n in axes}            # absorbed offsets the channel has not taken yet
        self.channel_override = 1.0
        self.cycle = 0
        self.events: list[tuple[float, ErrorEvent]] = []   # (t, event) of every controller event
        self.sensor_axis = None
        self.sensor = None
        self.sensor_variable = None
        self._sensor_out = None                       # the V.E. variable the sensor writes
        sc = scenario.sensor
        self._sensor_orth = sc is not None and sc.orthogonal
        if sc is not None:
            self.sensor_axis = None if sc.orthogonal else sc.axis
            p = axes[sc.axis].params if sc.axis is not None else None
            self.sensor = sc.make_sensor(T, p, scenario.surface)   # the probe has its own zero (reading_at_contact)
            if sc.kind != "encoder":
                self.sensor_variable = f"V.E.{sc.variable}"
                self.variables.setdefault(self.sensor_variable, 0.0)
                self._sensor_out = f"V.E.{sc.output_variable}"   # an arc voltage: its voltage variable
                self.variables.setdefault(self._sensor_out, 0.0)
        self.nc = NcInterpreter(program, self, file=scenario.program_file) if program is not None else None
        #: the programs of the scenario's ``start`` events (CNC start, docs/scenarios.md), parsed now so
        #: that a syntax error names its file and line before the run: event index -> (program, file)
        self._start_programs = self._parse_starts(scenario, program)
        self._start_pending: tuple | None = None      # a start waiting for the channel to be free
        starts = [i for i, ev in enumerate(scenario.events) if ev.kind == "start"]
        self._last_start = starts[-1] if starts else -1
        self._path_override = 1.0                     # the channel override the scenario set last
        #: the axis whose sensor writes a V.E. variable (axis variant): a select that keeps reading the
        #: second encoder is warned about once (900031)
        self._variable_sensor_axis = sc.axis if sc is not None and sc.kind != "encoder" and not sc.orthogonal \
            else None
        self._unread_sensor_warned = False
        #: per axis, everything one cycle touches, resolved once (the loop runs 10^5 times a second)
        self._axes = [(n, self.inputs[n], self.outputs[n], self.controllers[n], self.drives[n], n in self.dc_axes,
                       self.hli[n]) for n in self.axis_names]
        self._shift_any = False
        self._drive_x = self.drives.get("X")
        self._drive_y = self.drives.get("Y")
        self._next_event_t = scenario.events[0].t if scenario.events else math.inf
        self._program_end_sent = False
        self._nc_error_reported = False
        self._event_index = 0
        self.true_surface = 0.0
        self.true_distance = 0.0
        self._init_channel(scenario)
        #: the NC's look-ahead (distctrl.nc.interpreter, distctrl.sim.interpolator "Look-ahead"): how many
        #: following G1 blocks on the same line are prepared with each G1 block; the axis variant without
        #: the CNC's lift only (a kinematic path and a lift motion stop at every block end, as before)
        self.look_ahead = LOOK_AHEAD_BLOCKS if not (self.kinematic_path or self.lift_motions) else 0
        #: one GEO cycle: the axis variant's loop, or the channel loop with kinematics / 3D distance control
        self.step = self.channel3d.step if self.kinematic_path else self._step_axes

    def _init_channel(self, scenario) -> None:
        """The channel's kinematics and 3D distance control (docs/run-3d.md): a part the machine owns,
        :class:`~distctrl.sim.channel3d.KinematicChannel`."""
        #: kinematics and 3D distance control of the channel (its own GEO cycle, ``channel3d.step``)
        ch = self.channel3d = KinematicChannel(self, scenario)
        #: the channel's 3D distance control (None without FCT_3D_DIST_CTRL), its cycle input and output
        self.has_dist_ctrl_3d = ch.has_dist_ctrl_3d
        self.ch3d, self.in3d, self.out3d = ch.ch3d, ch.in3d, ch.out3d
        self.kinematic_path = ch.active
        self._var_names: dict[str, str] = {}
        self.notes: list[str] = []
        # trace values of the kinematic path (written by channel3d.step)
        self.inclination_deg = 0.0
        self.virt_tool_length = ch.tool_length
        self.true_clamp = (0.0, 0.0, 0.0)
        self.true_xy = (0.0, 0.0)
        self.true_distance_orth = 0.0
        self.tcp_cmd = (0.0, 0.0, 0.0)
        self.prog_values = [a.start for a in scenario.axes.values()]

    # ------------------------------------------------------------------ Channel protocol (NC side)
    @property
    def positions(self) -> dict[str, float]:
        return self.interp.position

    def start_linear(self, target: dict[str, float], feed_mm_min: float | None, ahead=()) -> None:
        self._take_shift()
        self.channel3d.before_linear(target)
        self.interp.start_linear(target, feed_mm_min, ahead)

    def start_dwell(self, seconds: float) -> None:
        self.interp.start_dwell(seconds)

    def motion_done(self) -> bool:
        if self.lift_motions and any(lm.busy for lm in self.lift_motions):
            return False                      # the CNC's lift lands before the next block starts
        return self.interp.done

    def dist_ctrl(self, axis: str, command: Command) -> None:
        if axis not in self.inputs:
            raise ValueError(f"axis {axis} is not configured in this channel")
        self.inputs[axis].commands.append(command)

    def dist_ctrl_done(self, axis: str, action: Action) -> bool:
        """WAIT (SPEC §8): a select has reached its target once, OFF has reached INACTIVE, FREEZE has
        braked; an ERROR also ends the wait (the error stops the program anyway)."""
        return _wait_done(self.outputs[axis], action)

    # ------------------------------------------------------------------ 3D distance control (NC side)
    def dist_ctrl_3d(self, command: Command3D) -> None:
        """A ``#DIST CTRL`` command for the channel's 3D distance control (consumed this cycle)."""
        self.channel3d.dist_ctrl_3d(command)

    def dist_ctrl_3d_done(self, action: Action) -> bool:
        """WAIT of ``#DIST CTRL``: as the axis command (select reached its target once, OFF INACTIVE)."""
        done = _wait_done(self.out3d.core, action)
        self.channel3d.wait_3d = not done            # the diagnosis block's f_wait_for_finished
        return done

    def _var_name(self, var: str) -> str:
        name = self._var_names.get(var)
        if name is None:
            name = var if var.startswith("V.E.") else "V.E." + var
            self._var_names[var] = name
        return name

    # ------------------------------------------------------------------ kinematics (NC side)
    def kinematics(self, word: KinematicsWord, lookup, line: int | None) -> None:
        """``#KIN``, ``#TRAFO``, ``#CS``, ``#CHANNEL INIT`` (docs/run-3d.md). Refusals raise NcAbort."""
        self.channel3d.kinematics(word, lookup, line)

    def variables_assigned(self, names: list[str]) -> None:
        """The tool length and kinematic 98's parameters take effect when they change (docs/run-3d.md)."""
        self.channel3d.variables_assigned(names)

    def _take_shift(self) -> None:
        """OFF NO_MOVE / reset: the channel takes the absorbed offset over as its position."""
        if any(self.shift.values()) and self.interp.done:
            self.interp.set_position({n: self.interp.position[n] + s for n, s in self.shift.items() if s})
            for n in self.shift:
                self.shift[n] = 0.0
            self._shift_any = False

    # ------------------------------------------------------------------ events
    def apply_event(self, ev) -> None:
        kind, data = ev.kind, ev.data
        if kind == "plc":
            # through the control unit, as a PLC does: command_w + semaphore (retried while busy)
            self._plc_pending.append((data["axis"], data["transition"], float(data.get("position", 0.0))))
        elif kind == "plc_cyclic":
            self.hli[data["axis"]].plc_cyclic(data.get("position"), data.get("distance"))
        elif kind == "override":
            if data.get("axis"):
                self.inputs[data["axis"]].override = float(data["value"])
            else:
                self.channel_override = self._path_override = float(data["value"])
        elif kind == "feed_hold":
            if data.get("axis"):
                self.inputs[data["axis"]].feed_hold = bool(data.get("value", True))
            else:
                self.channel_override = 0.0 if data.get("value", True) else 1.0
        elif kind == "reset":
            self.reset()
        elif kind == "start":
            self._start_pending = self._start_programs[ev.index]
        elif kind == "axis_error":
            self.inputs[data["axis"]].commands.append(Command(Action.AXIS_ERROR))
            self.stop_program(None)
        elif kind == "axis_release":
            # the channel hands the axis over (e.g. to another channel): 70333 if distance control is on
            self.inputs[data["axis"]].commands.append(Command(Action.AXIS_RELEASE))
            if self.ch3d is not None:                   # an axis of the channel's 3D distance control
                self.in3d.commands.append(Command3D(Action.AXIS_RELEASE))
        elif kind == "sensor_fault":
            if self.sensor is not None:
                fault_args = {k: v for k, v in data.items() if k != "kind"}
                self.sensor.inject(Fault(kind=data["kind"], **fault_args), at_cycle=self.cycle)
        elif kind == "variable":
            self.variables[f"V.E.{data['name']}"] = float(data["value"])

    def reset(self) -> None:
        """CNC reset: the program stops, distance control is deselected with its offset absorbed (the
        3D distance control keeps its offset as a static offset, FCT-M3 §12.4.4)."""
        for inp in self.inputs.values():
            inp.commands.append(Command(Action.RESET))
        if self.ch3d is not None:
            self.in3d.commands.append(Command3D(Action.RESET))
        self.stop_program(None)

    @staticmethod
    def _parse_starts(scenario, program) -> dict:
        starts = {}
        for ev in scenario.events:
            if ev.kind != "start":
                continue
            data = ev.data
            if "program" in data:
                starts[ev.index] = (parse_file(data["program"]), data["program"])
            elif "program_text" in data:
                where = f"{scenario.path or '<scenario>'}:events[{ev.index}].start.program_text"
                starts[ev.index] = (parse_program(data["program_text"], file=where), where)
            else:
                if program is None:
                    program = parse_file(scenario.program_file) if scenario.program_file is not None else \
                        parse_program(scenario.program_text, file=f"{scenario.path or '<scenario>'}:program_text")
                starts[ev.index] = (program, scenario.program_file)
        return starts

    def _start(self) -> None:
        """A ``start`` event (docs/scenarios.md): CNC start of the next program, once the channel is
        free — the last program has ended or was stopped (reset, error) and the path stands. A block
        a reset left standing ends where it stands; the channel override is the scenario's again."""
        nc = self.nc
        if nc is not None and nc.running:
            return
        interp = self.interp
        if not interp.done:
            if interp.path_velocity != 0.0:
                return
            interp.cancel()
        program, file = self._start_pending
        self._start_pending = None
        self.nc = NcInterpreter(program, self, file=file)
        self._program_end_sent = False
        self._nc_error_reported = False
        self.channel3d.hd4_reported = False
        self.channel_override = self._path_override

    def _warn_unread_sensor(self, axis: str, t: float, line) -> None:
        if self._unread_sensor_warned:
            return
        self._unread_sensor_warned = True
        var = self.sensor_variable
        self.events.append((t, ErrorEvent(
            id=int(ErrorId.SENSOR_NOT_READ), cycle=self.cycle, line=line, severity="warning",
            message=f"the distance sensor writes {var}, but axis {axis} reads the second encoder "
                    f"(SENSOR_SOURCE={self.controllers[axis].state.sensor_source.name}): nobody reads the sensor; "
                    f"program {axis}[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR={var}] before the select "
                    f"(FCT-M3 §6, PROG DIST_CTRL), or give the scenario's sensor kind = \"encoder\"")))

    def _report_nc_error(self, k: int, t: float) -> None:
        """An NC run-time error stopped the program in cycle ``k`` (docs/run.md): the error is an
        event of that cycle, the motion stops, and a running distance control holds its offset in
        ERROR."""
        err = self.nc.error
        self._nc_error_reported = True
        self.events.append((t, ErrorEvent(id=int(err.id), cycle=k, line=err.line, message=err.message,
                                          severity="error")))
        self.stop_program(None)
        for name in self.dc_axes:
            self.inputs[name].commands.append(Command(Action.CHANNEL_ERROR, line=err.line))
        if self.ch3d is not None:
            self.in3d.commands.append(Command3D(Action.CHANNEL_ERROR, line=err.line))

    def stop_program(self, error) -> None:
        """Stop reading blocks; the running motion decelerates and holds."""
        if self.nc is not None and self.nc.running:
            self.nc.abort(error)
        self.channel3d.wait_3d = False
        self.interp.feed_override = 0.0
        self.channel_override = 0.0

    # ------------------------------------------------------------------ one cycle
    def _cycle_start(self, k: int, t: float):
        """The start of every cycle (both variants): due scenario events, PLC commands waiting for
        the semaphore, the PLC program, and NC blocks while the channel is idle. Returns the NC line."""
        T = self.T
        if t + 0.5 * T >= self._next_event_t:
            events = self.scenario.events
            while self._event_index < len(events) and events[self._event_index].t <= t + 0.5 * T:
                self.apply_event(events[self._event_index])
                self._event_index += 1
            self._next_event_t = events[self._event_index].t if self._event_index < len(events) else math.inf
        if self._plc_pending:
            self._plc_pending = [cmd for cmd in self._plc_pending
                                 if not self.hli[cmd[0]].plc_command(cmd[1], cmd[2])]
        if self.plc_program is not None:
            self.plc_program(self, k)
        if self._start_pending is not None:
            self._start()
        nc = self.nc
        if nc is None:
            return None
        if self.interp.block == "idle":                  # blocks are read only when the channel is idle
            self._take_shift()
            if self.kinematic_path:
                self.channel3d.take_shift3d()
            nc.tick()
            if nc.error is not None and not self._nc_error_reported:
                self._report_nc_error(k, t)
            if nc.ended and not self._program_end_sent:
                self._program_end_sent = True
                for inp in self.inputs.values():
                    inp.commands.append(Command(Action.PROGRAM_END, line=nc.end_line))
                if self.ch3d is not None:
                    self.in3d.commands.append(Command3D(Action.PROGRAM_END, line=nc.end_line))
        return nc.line

    def _axes_cycle(self, setpoints: dict, line, t: float) -> None:
        """Every axis: its distance controller (if enabled or commanded) on top of the setpoint from
        the interpolation (or the kinematic transformation), then its drive."""
        nc = self.nc
        shift = self.shift if self._shift_any else None
        for name, inp, out, ctrl, drive, is_dc, unit in self._axes:
            p = setpoints[name]
            if shift is not None:
                p += shift[name]
            inp.programmed_position = p
            if is_dc or inp.commands or unit.command_semaphore_rw:
                if unit.command_semaphore_rw or unit.cyclic.valid_position or unit.cyclic.valid_distance:
                    unit.prepare(inp)
                inp.actual_position = drive.actual
                inp.nc_line = line
                if inp.commands or ctrl.state.sensor_source is _VARIABLE:
                    var = ctrl.state.sensor_var or self.sensor_variable
                    if var is not None:
                        inp.sensor_variable = self.variables.get(self._var_name(var), float("nan"))
                selecting = name == self._variable_sensor_axis and bool(inp.commands)
                ctrl.update(inp, out)
                if selecting and out.hli_state and ctrl.state.sensor_source is not _VARIABLE:
                    self._warn_unread_sensor(name, t, line)
                if out.events:
                    for ev in out.events:
                        self.events.append((t, ev))
                        if ev.severity == "error" and nc is not None and nc.running:
                            self.stop_program(None)
                if out.absorbed_offset:
                    self.shift[name] += out.absorbed_offset
                    self._shift_any = True
                if self.publish_hli:
                    unit.publish(out)
                drive.step(out.command_position)
            else:
                out.command_position = p
                drive.step(p)

    def _cycle_line(self, k: int, t: float) -> int | None:
        """The NC line of cycle ``k``; runs the cycle start (events, PLC, NC) only when something is due."""
        nc = self.nc
        if (t + 0.5 * self.T >= self._next_event_t or self._plc_pending or self.plc_program is not None
                or (nc is not None and self.interp.block == "idle") or self._start_pending is not None):
            return self._cycle_start(k, t)
        return nc.line if nc is not None else None      # the common cycle: a block runs, nothing due

    def _lift(self, prog: dict) -> None:
        """The CNC's lift (TF5290 Lift, docs/process.md): superimposed on the programmed positions."""
        for lm in self.lift_motions:
            lm.step(self)
            if lm.offset:
                prog[lm.axis] += lm.offset

    def _step_axes(self) -> None:
        """One GEO cycle of the axis variant (no kinematics, no 3D distance control)."""
        k = self.cycle
        T = self.T
        t = k * T
        interp = self.interp
        line = self._cycle_line(k, t)
        interp.feed_override = self.channel_override
        prog = interp.step()
        if self.lift_motions:
            self._lift(prog)
        drives = self.drives
        # the real geometry under the tool: the true nozzle positions (the motor plus a drive's
        # resonant deflection; the motor for a rigid drive), not the quantised motor encoder
        x = self._drive_x.nozzle if self._drive_x is not None else 0.0
        y = self._drive_y.nozzle if self._drive_y is not None else 0.0
        surface_z = self.surface.height(x, y)
        self.true_surface = surface_z
        self.true_xy = (x, y)              # where the tool met that surface (collisions are placed there)
        sensor_axis = self.sensor_axis
        if sensor_axis is not None:
            z = drives[sensor_axis].nozzle
            self.true_distance = z - surface_z
            value = self.sensor.read(k, z, surface_z, x, y)
            if self.sensor_variable is None:
                self.inputs[sensor_axis].sensor_increments = value
            else:
                self.variables[self._sensor_out] = value
        self._axes_cycle(prog, line, t)
        self.cycle = k + 1

    def channel3d_values(self):
        """The channel's 3D distance-control values for the 3D CNC objects and the diagnosis block
        (docs/objects-3d.md, docs/diag.md); None without 3D distance control."""
        return self.channel3d.channel3d_values()

    def publish_all(self) -> None:
        """Fill every control unit's ``state_r`` from the last cycle."""
        for name in self.dc_axes:
            self.hli[name].publish(self.outputs[name])

    # ------------------------------------------------------------------ status
    def status(self) -> dict:
        """A snapshot of plain values that consumers read (per axis the HLI unit, state, offset and
        drive position; the NC line; override; the head over the surface; the process functions):
        :func:`distctrl.sim.status.machine_status`."""
        return machine_status(self)

    #: :func:`distctrl.sim.status.activity` as the method itself, the cheap part of :meth:`status` that
    #: changes when a PLC command is taken or refused, a state changes or the NC program ends (no wrapper:
    #: the served cycle's session log calls it every cycle)
    activity = activity

    def event_cursor(self, *, from_now: bool = False) -> EventCursor:
        """A cursor over :attr:`events` that takes each ``(t, ErrorEvent)`` once
        (:class:`~distctrl.sim.status.EventCursor`); ``from_now``: skip the events there already."""
        return EventCursor(self, len(self.events) if from_now else 0)

    def settled(self) -> bool:
        """At rest once the program has ended: the path stopped, no deselection still running out its
        offset, and every drive at rest. A distance control left tracking (ACTIVE, ACTIVE_CONST_DIST,
        the dry runs) or FREEZE after the program is a steady state that never ends by itself: its
        axis follows the sensor noise and is not waited for. Otherwise an offset still moving (e.g.
        braking into FREEZE or ERROR) is."""
        if not self.interp.done and self.interp.path_velocity != 0.0:
            return False
        if self._start_pending is not None or self._event_index <= self._last_start:
            return False                                 # a program is still to be started
        if any(lm.velocity != 0.0 for lm in self.lift_motions):
            return False
        tracking = set()
        for name in self.dc_axes:
            out = self.outputs[name]
            state = out.hli_state
            if state == _TURNING_OFF_CODE:
                return False
            if state in _STEADY_CODES:
                tracking.add(name)
            elif out.offset_velocity != 0.0:
                return False
        if self.ch3d is not None:
            core = self.out3d.core
            if core.hli_state == _TURNING_OFF_CODE:
                return False
            if core.hli_state in _STEADY_CODES:
                tracking.update(self.drives)             # the compensation may move X, Y and Z
            elif core.offset_velocity != 0.0:
                return False
        # a drive with encoder quantisation may toggle by one increment around a setpoint that is not
        # on its grid for ever: within one increment of its setpoint it is at rest; a resonant drive's
        # nozzle must have stopped ringing too (deflection_rate is 0 for a rigid drive)
        return all(name in tracking or ((abs(d.velocity) < 1e-3 or abs(d.following_error) <= d.resolution + 1e-9)
                                        and abs(d.deflection_rate) < 1e-3)
                   for name, d in self.drives.items())


_TURNING_OFF_CODE = int(HliState.TURNING_OFF)
#: states distance control stays in after the program until something commands it
_STEADY_CODES = frozenset(int(s) for s in (HliState.ACTIVE, HliState.ACTIVE_CONST_DIST, HliState.FREEZE,
                                           HliState.DRYRUN_CONST_DIST, HliState.DRYRUN_SETPOS))
