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
(``[channel] kinematics = "CA"``, the default with the axes X, Y, Z, A, C) runs :meth:`Machine._step_kin`
instead (docs/run-3d.md): the NC's X, Y, Z are transformed (#CS frame, #TRAFO with the CA head and
kinematic 98) into the machine axes, the sensor reports the orthogonal distance of the tool clamping
point, and the channel's :class:`~distctrl.control.controller3d.ChannelDistanceController` adds its
compensation ``δ·e``. Without either the cycle is exactly the axis variant's (:meth:`Machine._step_axes`).
"""
from __future__ import annotations

import math

from ..control import Action, AxisDistanceController, Command, CycleInput, CycleOutput, HliState, SensorSource
from ..control.commands3d import Command3D, CompensationMode
from ..control.controller3d import ChannelDistanceController, Cycle3DInput, Cycle3DOutput
from ..errors import ErrorEvent, ErrorId, ParameterError
from ..errors.three_d import event_to_3d, make_event_3d, severity_and_text
from ..kinematics.frames import Frame
from ..kinematics.kin98 import InclinationViolation, Kinematic98Params
from ..nc.interpreter import NcAbort, NcInterpreter
from ..nc.parser import parse_file, parse_program
from ..nc.program import KinematicsWord, Program, kin_param_var
from ..objects.channel3d import Channel3DValues
from ..objects.units import mm_to_dint_01um, round_saturate
from ..plc.chain import chain
from ..plc.hli import ChannelDistanceStatus, DistanceControlUnit
from ..plc.process.channel import ChannelPathStatus
from ..plc.process.lift import Lift
from .drive import Drive
from .interpolator import AxisLimits, Interpolator
from .lift import attach_lift
from .sensors import Fault
from .status import EventCursor, activity, machine_status

_TRACKING = (int(HliState.ACTIVE), int(HliState.ACTIVE_CONST_DIST))
_VARIABLE = SensorSource.VARIABLE
DC_COLUMNS = ("dc.state", "dc.offset", "dc.sensor", "dc.feedback", "dc.filtered", "dc.target_deviation",
              "dc.pre_limiter", "dc.sloped_delta", "dc.set_pos", "dc.set_dist")
#: trace columns of the channel's 3D distance control: column -> (unit, expression on the machine ``m``
#: and its 3D output ``q``); used by the runner's row builder
DC3D_COLUMNS: dict[str, tuple[str, str]] = {
    "dc3d.state": ("-", "q.core.hli_state"),
    "dc3d.offset": ("mm", "q.core.offset"),
    "dc3d.mode": ("-", "q.mode"),
    "dc3d.delta": ("mm", "q.delta"),
    "dc3d.comp_x": ("mm", "q.compensation[0]"),
    "dc3d.comp_y": ("mm", "q.compensation[1]"),
    "dc3d.comp_z": ("mm", "q.compensation[2]"),
    "dc3d.inclination": ("deg", "m.inclination_deg"),
    "dc3d.virt_tool_length": ("mm", "m.virt_tool_length"),
    "dc3d.set_dist_orth": ("mm", "q.orthogonal_set_distance"),
    "dc3d.sensor": ("mm", "q.core.sensor_value"),
    "dc3d.filtered": ("mm", "q.core.filtered_feedback"),
    "dc3d.set_pos": ("mm", "q.core.set_pos"),
    "true.clamp_x": ("mm", "m.true_clamp[0]"),
    "true.clamp_y": ("mm", "m.true_clamp[1]"),
    "true.clamp_z": ("mm", "m.true_clamp[2]"),
    "true.distance_orth": ("mm", "m.true_distance_orth"),
    "tcp.x": ("mm", "m.tcp_cmd[0]"),
    "tcp.y": ("mm", "m.tcp_cmd[1]"),
    "tcp.z": ("mm", "m.tcp_cmd[2]"),
}
_DEG = math.pi / 180.0
_Z = (0.0, 0.0, 1.0)
#: the kinematic ID of the CA head (FCT-M3 §12.4.2.1: "#TRAFO [9, 98]" on the CA kinematic)
CA_KIN_ID = 9
KIN98_ID = 98
TOOL_LENGTH_VAR = "V.G.WZ_AKT.L"
KIN98_VARS = tuple(kin_param_var(1, KIN98_ID, i) for i in range(4))
_INACTIVE3D = int(HliState.INACTIVE)


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
        self.step = self._step_kin if self.kinematic_path else self._step_axes

    def _init_channel(self, scenario) -> None:
        """3D distance control and kinematics of the channel (docs/run-3d.md)."""
        T = self.T
        #: the channel's 3D distance control (None without FCT_3D_DIST_CTRL)
        self.has_dist_ctrl_3d = bool(scenario.has_3d)
        self.ch3d = ChannelDistanceController(scenario.channel_params, T) if self.has_dist_ctrl_3d else None
        self.in3d = Cycle3DInput()
        self.in3d.commands = []
        self.out3d = Cycle3DOutput()
        #: the head kinematic ("CA") or None
        self.head = scenario.kinematics
        self.kinematic_path = self.ch3d is not None or self.head is not None or self._sensor_orth
        self.kin_chain: tuple[int, ...] = (CA_KIN_ID,)       # selected by #KIN, active with #TRAFO ON
        self.trafo = False
        self.kin98: Kinematic98Params | None = None          # active kinematic 98 (#TRAFO ON with 98)
        self.tool_length = float(self.variables.get(TOOL_LENGTH_VAR, 0.0))
        self.hd1 = 0.0
        self._hd = (0.0, 0.0, 0.0, math.pi)                  # hd2, hd3, hd4 (rad), cos hd2
        self.frame: Frame | None = None                      # #CS ON
        self._R = None                                       # frame rotation as nested tuples
        self._O = (0.0, 0.0, 0.0)
        self.cs_z = _Z
        self.normal = _Z
        self.shift3d = [0.0, 0.0, 0.0]                       # OFF NO_MOVE of the 3D control, machine coords
        self._shift3d_any = False
        self._last_comp = (0.0, 0.0, 0.0)
        self._hd4_reported = False
        #: a #DIST CTRL WAIT block is waiting for the 3D distance control (f_wait_for_finished)
        self.wait_3d = False
        self._var_names: dict[str, str] = {}
        self.notes: list[str] = []
        # trace values of the kinematic path
        self.inclination_deg = 0.0
        self.virt_tool_length = self.tool_length
        self.true_clamp = (0.0, 0.0, 0.0)
        self.true_xy = (0.0, 0.0)
        self.true_distance_orth = 0.0
        self.tcp_cmd = (0.0, 0.0, 0.0)
        self.prog_values = [a.start for a in scenario.axes.values()]
        self._drive_z = self.drives.get("Z")
        self._drive_a = self.drives.get("A")
        self._drive_c = self.drives.get("C")
        self._xyz = tuple(n for n in ("X", "Y", "Z") if n in self.drives)

    # ------------------------------------------------------------------ Channel protocol (NC side)
    @property
    def positions(self) -> dict[str, float]:
        return self.interp.position

    def start_linear(self, target: dict[str, float], feed_mm_min: float | None, ahead=()) -> None:
        self._take_shift()
        if self.trafo:
            self._take_shift3d()
            if self.kin98 is not None and ("A" in target or "C" in target):
                pos = self.interp.position
                theta = _inclination(target.get("C", pos["C"]) * _DEG, target.get("A", pos["A"]) * _DEG)
                if theta > self._hd[2]:
                    raise NcAbort(int(ErrorId.KIN98_MAX_INCLINATION),
                                  InclinationViolation(theta, self._hd[2]).message)
        elif self._shift3d_any:
            self._take_shift3d()
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
        ch = self.ch3d
        if ch is None:
            raise NcAbort(20209, "Unknown Nc-command: #DIST CTRL needs FCT_3D_DIST_CTRL (P-CHAN-00500)")
        if command.is_select:
            if ch.core.state.hli_state == HliState.INACTIVE:
                var = command.sensor_var or ch.core.state.sensor_var or self.sensor_variable
                value = self.variables.get(self._var_name(var)) if var else None
                if value is None or not math.isfinite(value):
                    why = ("no SENSOR_VAR given" if not var else
                           f"{self._var_name(var)} does not exist" if value is None else
                           f"{self._var_name(var)} = {value!r}")
                    ev = make_event_3d(310027, ch.core.state.cycle, command.line, why)
                    self.events.append((self.cycle * self.T, ev))
                    self.stop_program(None)
                    return
        self.in3d.commands.append(command)

    def dist_ctrl_3d_done(self, action: Action) -> bool:
        """WAIT of ``#DIST CTRL``: as the axis command (select reached its target once, OFF INACTIVE)."""
        done = _wait_done(self.out3d.core, action)
        self.wait_3d = not done                      # the diagnosis block's f_wait_for_finished
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
        kind = word.kind
        if word.reinitialises_channel and self.ch3d is not None:
            state = self.ch3d.core.state.hli_state
            if state != HliState.INACTIVE:
                name = {"CHANNEL_INIT": "#CHANNEL INIT"}.get(kind, f"#{kind} {word.switch or ''}".strip())
                raise NcAbort(51062, f"{severity_and_text(51062)[1]}: {name} while 3D distance control is "
                              f"{state.name} (deselect it first, FCT-M3 §12.4.5)")
        if kind == "KIN":
            self.kin_chain = self._chain(word.ids)
            return
        if kind == "TRAFO":
            chain = self._chain(word.ids) if word.ids else self.kin_chain
            if word.ids:
                self.kin_chain = chain
            on = word.switch != "OFF"
            if on:
                state = self._kinematic_state(chain)     # validated before anything changes
                self._reinit(lambda: self._set_trafo(True, state))
            else:
                self._reinit(lambda: self._set_trafo(False, None))
            return
        if kind == "CS":
            frame = Frame.from_cs(*word.cs_frame(lookup)) if word.switch == "ON" else None
            self._reinit(lambda: self._set_frame(frame))
            return
        # #CHANNEL INIT: the programmed position is synchronised with the actual axis positions
        self._reinit(lambda: None, from_actual=True)

    def variables_assigned(self, names: list[str]) -> None:
        """The tool length and kinematic 98's parameters take effect when they change (with #TRAFO ON
        the TCP is kept and the axes move). HD1 (PARAM[0]) is the head's geometry: it also places
        the physical clamping point when the transformation is off."""
        if self.trafo and any(n == TOOL_LENGTH_VAR or n in KIN98_VARS for n in names):
            self._set_trafo(True, self._kinematic_state(self.kin_chain))
            return
        if TOOL_LENGTH_VAR in names:
            self.tool_length = float(self.variables[TOOL_LENGTH_VAR])
        if KIN98_VARS[0] in names:
            self.hd1 = self._read_hd1()

    def _read_hd1(self) -> float:
        """HD1 = V.G.KIN_STEP[1].ID[98].PARAM[0] (1e-4 mm) -> mm; 0 while not assigned."""
        raw = self.variables.get(KIN98_VARS[0], 0.0)
        if not math.isfinite(raw):
            raise NcAbort(int(ErrorId.NC_RUNTIME), f"{KIN98_VARS[0]} = {raw!r} is not a finite number")
        return raw / 10_000

    def _chain(self, ids: tuple[int, ...]) -> tuple[int, ...]:
        if self.head is None:
            raise NcAbort(int(ErrorId.NC_RUNTIME), "no head kinematic in this channel ([channel] kinematics, "
                          "needs the axes X, Y, Z, A, C)")
        ids = tuple(int(i) for i in ids)
        if ids in ((CA_KIN_ID,), (CA_KIN_ID, KIN98_ID)):
            return ids
        if ids == (KIN98_ID,):
            return (CA_KIN_ID, KIN98_ID)                  # "#KIN ID[98]": the head plus kinematic 98
        raise NcAbort(int(ErrorId.NC_RUNTIME), f"kinematic ID[{'.'.join(map(str, ids))}] is not available: "
                      f"this channel has the CA head (ID {CA_KIN_ID}) and kinematic {KIN98_ID} "
                      "(ID[9], ID[9.98], ID[98])")

    def _kinematic_state(self, chain: tuple[int, ...]) -> tuple[float, float, Kinematic98Params | None]:
        """Tool length and kinematic-98 parameters from the variables, validated (NcAbort if not)."""
        if self.head is None:
            raise NcAbort(int(ErrorId.NC_RUNTIME), "#TRAFO: no head kinematic in this channel ([channel] "
                          "kinematics, needs the axes X, Y, Z, A, C)")
        tool_length = float(self.variables.get(TOOL_LENGTH_VAR, 0.0))
        if not math.isfinite(tool_length) or tool_length < 0.0:
            raise NcAbort(int(ErrorId.NC_RUNTIME),
                          f"{TOOL_LENGTH_VAR} = {tool_length!r}: the tool length must be >= 0")
        kin98 = None
        if KIN98_ID in chain:
            missing = [v for v in KIN98_VARS if v not in self.variables]
            if missing:
                raise NcAbort(int(ErrorId.NC_RUNTIME), "kinematic 98 needs its parameters: "
                              + ", ".join(missing) + " not assigned")
            try:
                kin98 = Kinematic98Params.from_raw(*(self.variables[v] for v in KIN98_VARS))
            except ParameterError as exc:
                raise NcAbort(int(ErrorId.NC_RUNTIME), str(exc)) from None
            pos = self.interp.position
            theta = _inclination(pos["C"] * _DEG, pos["A"] * _DEG)
            if theta > kin98.hd4_rad:
                raise NcAbort(int(ErrorId.KIN98_MAX_INCLINATION),
                              InclinationViolation(theta, kin98.hd4_rad).message)
        return tool_length, self._read_hd1(), kin98

    def _set_trafo(self, on: bool, state) -> None:
        self.trafo = on
        if on:
            self.tool_length, self.hd1, kin98 = state
            self.kin98 = kin98
            if kin98 is not None:
                self._hd = (kin98.hd2_rad, kin98.hd3_rad, kin98.hd4_rad, math.cos(kin98.hd2_rad))
        else:
            self.kin98 = None
        if self.ch3d is not None:
            self.ch3d.set_kinematics(self.trafo and self.kin98 is not None, self.tool_length if self.trafo else None)

    def _set_frame(self, frame: Frame | None) -> None:
        self.frame = frame
        if frame is None:
            self._R, self._O, self.cs_z = None, (0.0, 0.0, 0.0), _Z
        else:
            r = frame.rotation
            self._R = tuple(tuple(float(v) for v in row) for row in r)
            self._O = tuple(float(v) for v in frame.origin)
            self.cs_z = (float(r[0, 2]), float(r[1, 2]), float(r[2, 2]))
        # the workpiece normal the set distance refers to: the programmed Z (docs/run-3d.md)
        self.normal = self.cs_z

    def _extension(self, theta: float) -> float:
        """Kinematic 98's factor k(θ) = Lv/L (SPEC §11); 1 without kinematic 98."""
        if self.kin98 is None:
            return 1.0
        hd2, hd3, _, cos_hd2 = self._hd
        if theta <= hd2 or hd3 == hd2:
            return 1.0
        return cos_hd2 / math.cos(theta if theta < hd3 else hd3)

    def _tcp_from_programmed(self, x: float, y: float, z: float) -> tuple[float, float, float]:
        R = self._R
        if R is None:
            return x, y, z
        o = self._O
        return (o[0] + R[0][0] * x + R[0][1] * y + R[0][2] * z,
                o[1] + R[1][0] * x + R[1][1] * y + R[1][2] * z,
                o[2] + R[2][0] * x + R[2][1] * y + R[2][2] * z)

    def _programmed_from_tcp(self, x: float, y: float, z: float) -> tuple[float, float, float]:
        R = self._R
        if R is None:
            return x, y, z
        o = self._O
        x, y, z = x - o[0], y - o[1], z - o[2]
        return (R[0][0] * x + R[1][0] * y + R[2][0] * z,
                R[0][1] * x + R[1][1] * y + R[2][1] * z,
                R[0][2] * x + R[1][2] * y + R[2][2] * z)

    def _head_offset(self, a_deg: float, c_deg: float) -> tuple[float, float, float]:
        """pivot − TCP = (Lv(θ) + HD1)·u(C, A) with #TRAFO ON, else 0."""
        if not self.trafo:
            return 0.0, 0.0, 0.0
        u = _direction(c_deg * _DEG, a_deg * _DEG)
        theta = math.atan2(math.hypot(u[0], u[1]), u[2])
        r = self.tool_length * self._extension(theta) + self.hd1
        return r * u[0], r * u[1], r * u[2]

    def _reinit(self, change, from_actual: bool = False) -> None:
        """Re-initialise the channel position (#TRAFO, #CS, #CHANNEL INIT): the machine axes keep their
        position; the programmed coordinates are recomputed for the new transformation."""
        interp = self.interp
        pos = interp.position
        has = self._xyz
        if from_actual:
            new = {n: self.drives[n].actual for n in self.axis_names}
            machine = tuple(self.drives[n].actual if n in self.drives else 0.0 for n in ("X", "Y", "Z"))
        else:
            new = {}
            p = tuple(pos.get(n, 0.0) for n in ("X", "Y", "Z"))
            tcp = self._tcp_from_programmed(*p)
            tcp = tuple(tcp[i] + self.shift3d[i] for i in range(3))
            h = self._head_offset(pos.get("A", 0.0), pos.get("C", 0.0)) if self.trafo else (0.0, 0.0, 0.0)
            machine = tuple(tcp[i] + h[i] for i in range(3))
        change()
        a = new.get("A", pos.get("A", 0.0))
        c = new.get("C", pos.get("C", 0.0))
        h = self._head_offset(a, c) if self.trafo else (0.0, 0.0, 0.0)
        p = self._programmed_from_tcp(*(machine[i] - h[i] for i in range(3)))
        for i, n in enumerate(("X", "Y", "Z")):
            if n in has:
                new[n] = p[i]
        interp.set_position(new)
        self.shift3d = [0.0, 0.0, 0.0]
        self._shift3d_any = False
        if from_actual:
            for n in self.shift:
                self.shift[n] = 0.0
            self._shift_any = False

    def _take_shift3d(self) -> None:
        """3D OFF NO_MOVE: the channel takes the compensation over as its programmed position."""
        if self._shift3d_any and self.interp.done:
            s = self.shift3d
            R = self._R
            if R is not None:
                s = [R[0][i] * s[0] + R[1][i] * s[1] + R[2][i] * s[2] for i in range(3)]
            pos = self.interp.position
            self.interp.set_position({n: pos[n] + s[i] for i, n in enumerate(("X", "Y", "Z")) if n in pos})
            self.shift3d = [0.0, 0.0, 0.0]
            self._shift3d_any = False

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
        self._hd4_reported = False
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
        self.wait_3d = False
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
                self._take_shift3d()
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

    def _step_kin(self) -> None:
        """One GEO cycle of a channel with kinematics and/or 3D distance control (docs/run-3d.md)."""
        k = self.cycle
        T = self.T
        t = k * T
        interp = self.interp
        line = self._cycle_line(k, t)
        ch3d = self.ch3d
        interp.feed_override = self.channel_override
        prog = interp.step()
        if self.lift_motions:
            self._lift(prog)
        # programmed TCP in machine coordinates (#CS frame), plus a taken-over 3D offset
        x, y, z = self._tcp_from_programmed(prog.get("X", 0.0), prog.get("Y", 0.0), prog.get("Z", 0.0))
        if self._shift3d_any:
            sh = self.shift3d
            x, y, z = x + sh[0], y + sh[1], z + sh[2]
        trafo = self.trafo
        L = self.tool_length
        hd1 = self.hd1
        if trafo:
            # RTCP: pivot = TCP + (Lv(θ) + HD1)·u(C, A), from the programmed orientation
            ux, uy, uz = _direction(prog["C"] * _DEG, prog["A"] * _DEG)
            theta = math.atan2(math.hypot(ux, uy), uz)
            if self.kin98 is not None and theta > self._hd[2] and not self._hd4_reported:
                self._hd4_reported = True
                ev = make_event_3d(int(ErrorId.KIN98_MAX_INCLINATION), k, line,
                                   InclinationViolation(theta, self._hd[2]).message)
                self.events.append((t, ev))
                self.stop_program(None)
            lv = L * self._extension(theta)
            r = lv + hd1
            mx, my, mz = x + r * ux, y + r * uy, z + r * uz
            clamp_prog_z = z + lv * uz
        else:
            mx, my, mz = x, y, z
        # the real geometry: true positions of the tool (the drives' nozzle: motor plus resonance)
        drives = self.drives
        dx, dy, dz = self._drive_x, self._drive_y, self._drive_z
        px = dx.nozzle if dx is not None else 0.0
        py = dy.nozzle if dy is not None else 0.0
        pz = dz.nozzle if dz is not None else 0.0
        da, dc = self._drive_a, self._drive_c
        if da is not None and dc is not None:
            ua = _direction(dc.nozzle * _DEG, da.nozzle * _DEG)
        else:
            ua = _Z
        # the head: the clamping point lies HD1 below the head reference point the axes carry
        cx, cy, cz = px - hd1 * ua[0], py - hd1 * ua[1], pz - hd1 * ua[2]
        if not trafo:
            clamp_prog_z = z - hd1 * ua[2]
        surface = self.surface
        f = surface.height(cx, cy)
        gx, gy = surface.gradient(cx, cy)
        d_orth = (cz - f) / math.sqrt(1.0 + gx * gx + gy * gy)     # (z_c − f)·n_z: exact for planes
        self.true_clamp = (cx, cy, cz)
        self.true_distance_orth = d_orth
        self.true_surface = f
        self.true_distance = cz - f
        sensor_axis = self.sensor_axis
        if self._sensor_orth:
            self.variables[self.sensor_variable] = self.sensor.read(k, d_orth, 0.0)
        elif sensor_axis is not None:
            zs = drives[sensor_axis].nozzle
            surface_z = surface.height(px, py)
            self.true_surface = surface_z
            self.true_distance = zs - surface_z
            value = self.sensor.read(k, zs, surface_z, px, py)
            if self.sensor_variable is None:
                self.inputs[sensor_axis].sensor_increments = value
            else:
                self.variables[self._sensor_out] = value
        theta_a = math.atan2(math.hypot(ua[0], ua[1]), ua[2])
        ext_a = self._extension(theta_a) if trafo else 1.0
        self.inclination_deg = math.degrees(theta_a)
        self.virt_tool_length = L * ext_a
        status = self.channel_status
        status.virt_tool_length_r = mm_to_dint_01um(self.virt_tool_length)
        status.inclination_r = round_saturate(self.inclination_deg * 1e4, -2147483648, 2147483647)
        # the channel's 3D distance control: its compensation δ·e is superimposed this cycle
        if ch3d is not None:
            inp3, out3 = self.in3d, self.out3d
            inp3.programmed_z = clamp_prog_z
            actual_z = dz.actual if dz is not None else 0.0
            inp3.actual_z = actual_z - hd1 * ua[2]
            var = ch3d.core.state.sensor_var or self.sensor_variable
            inp3.sensor_distance = self.variables.get(self._var_name(var), math.nan) if var else math.nan
            inp3.tool_direction = ua
            inp3.extension = ext_a
            inp3.cs_z_axis = self.cs_z
            inp3.normal = self.normal
            inp3.kin98_active = trafo and self.kin98 is not None
            inp3.override = self.channel_override
            inp3.nc_line = line
            ch3d.update(inp3, out3)
            if out3.events:
                for ev in out3.events:
                    self.events.append((t, ev))
                    if ev.severity == "error" and self.nc is not None and self.nc.running:
                        self.stop_program(None)
            core = out3.core
            if core.absorbed_offset and not out3.static:
                # OFF NO_MOVE: the channel takes the last compensation over (no jump)
                lc = self._last_comp
                sh = self.shift3d
                for i in range(3):
                    sh[i] += lc[i]
                self._shift3d_any = True
                x, y, z = x + lc[0], y + lc[1], z + lc[2]
                mx, my, mz = mx + lc[0], my + lc[1], mz + lc[2]
            comp = out3.compensation
            self._last_comp = comp
            if out3.mode == CompensationMode.ACS:
                mz += comp[2]                        # on the physical Z axis, after the transformation
            else:
                mx, my, mz = mx + comp[0], my + comp[1], mz + comp[2]   # TCP + δ·e (MCS, PCS, ECS)
            self.tcp_cmd = (x + comp[0], y + comp[1], z + comp[2])
        else:
            self.tcp_cmd = (x, y, z)
        # the machine axes: X, Y, Z transformed, the others as programmed; then per-axis distance control
        machine = dict(prog)
        if "X" in machine:
            machine["X"] = mx
        if "Y" in machine:
            machine["Y"] = my
        if "Z" in machine:
            machine["Z"] = mz
        self.prog_values = [prog[n] for n in self.axis_names]
        self._axes_cycle(machine, line, t)
        self.cycle = k + 1

    def channel3d_values(self):
        """The channel's 3D distance-control values for the 3D CNC objects and the diagnosis block
        (docs/objects-3d.md, docs/diag.md); None without 3D distance control."""
        if self.ch3d is None:
            return None

        o3 = self.out3d
        ch = self.ch3d
        st = ch.core.state
        f = ch.core.tuning.filter
        state = o3.core.hli_state
        frozen = state == _FREEZE_CODE
        # the MODE in effect: the running select's (or the one a reset's kept offset lies along);
        # OFF while nothing is selected. The MODE the next select uses is the programmed one.
        in_effect = state != _INACTIVE3D or o3.static
        axis_index = self.axis_names.index(ch.direction_axis) if ch.direction_axis in self.axis_names else 0
        sensor_var = st.sensor_var or self.sensor_variable
        return Channel3DValues.from_cycle_output(
            o3.core, offset=o3.delta, m_actual_offset=o3.core.offset, cmd_offset=o3.core.offset,
            cmd_offset_frozen=o3.core.offset if frozen else 0.0, freeze=frozen,
            wait_for_finished=self.wait_3d and self.nc is not None and self.nc.running,
            control_mode=int(st.mode), programmed_set_pos=st.programmed_set_pos,
            programmed_set_dist=st.programmed_set_dist,
            compensation_x=o3.compensation[0], compensation_y=o3.compensation[1], compensation_z=o3.compensation[2],
            inclination_rad=o3.inclination,
            compensation_mode=int(ch.mode) if in_effect else int(CompensationMode.OFF),
            new_compensation_mode=int(ch.mode), direction=ch.direction_axis,
            active_axis_index=axis_index, new_axis_index=axis_index,
            orthogonal_set_distance=o3.orthogonal_set_distance, blend_active=0.0 < o3.blend < 1.0,
            filter_time=ch.filter_time, fg_f0=f.fg_f0, order=f.order,
            tool_length=self.tool_length, virtual_tool_length=self.virt_tool_length,
            sensor_source=st.sensor_source.name, sensor_var=self._var_name(sensor_var) if sensor_var else None,
            ref_shift=st.ref_shift, error=event_to_3d(st.error) if st.error is not None else None,
            hli_state=state, events=list(o3.events),
            pending=dict(st.pending))                 # writes waiting for their adoption (docs/objects-3d.md)

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

    def activity(self) -> tuple:
        """The cheap part of :meth:`status` that changes when a PLC command is taken or refused, a
        state changes or the NC program ends (:func:`distctrl.sim.status.activity`)."""
        return activity(self)

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
_FREEZE_CODE = int(HliState.FREEZE)
#: states distance control stays in after the program until something commands it
_STEADY_CODES = frozenset(int(s) for s in (HliState.ACTIVE, HliState.ACTIVE_CONST_DIST, HliState.FREEZE,
                                           HliState.DRYRUN_CONST_DIST, HliState.DRYRUN_SETPOS))


def _direction(c: float, a: float) -> tuple[float, float, float]:
    """Tool direction of the CA head, ``u(C, A) = (sin C·sin A, −cos C·sin A, cos A)`` (rad; SPEC §11)."""
    sa = math.sin(a)
    return (math.sin(c) * sa, -math.cos(c) * sa, math.cos(a))


def _inclination(c: float, a: float) -> float:
    """θ = angle of u(C, A) to machine +Z (rad, in [0, π])."""
    ux, uy, uz = _direction(c, a)
    return math.atan2(math.hypot(ux, uy), uz)
