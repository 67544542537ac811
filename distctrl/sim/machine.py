"""The virtual machine: one channel of axes around the distance-control cycle core.

Per GEO cycle (seeds/000 Fig. 3: the offset is added after interpolation, before the drive):

1. timed scenario events (PLC commands, override, reset, sensor faults, variables);
2. the NC interpreter starts blocks; DIST_CTRL commands are queued for the axis's controller;
3. the interpolator gives the programmed positions ``p``;
4. the sensor measures the real geometry at the tool's actual position (probe increments, or a
   distance written into its V.E. variable);
5. each distance-controlled axis runs ``AxisDistanceController.update`` -> setpoint ``c = p + o``;
6. each drive follows its setpoint (one-cycle fieldbus delay, P loop, limits) -> actual ``a``.

The machine drives the core and never reaches into it: it only fills ``CycleInput`` and reads
``CycleOutput``.
"""
from __future__ import annotations

import math

from ..control import (Action, AxisDistanceController, Command, CycleInput, CycleOutput, HliState,
                       SensorSource)
from ..errors import ErrorEvent
from ..nc.interpreter import NcInterpreter
from ..nc.program import Program
from ..plc.hli import ChannelDistanceStatus, DistanceControlUnit
from .drive import Drive
from .interpolator import AxisLimits, Interpolator
from .sensors import DistanceSensor, EncoderProbe, Fault

_TRACKING = (int(HliState.ACTIVE), int(HliState.ACTIVE_CONST_DIST))
_VARIABLE = SensorSource.VARIABLE
DC_COLUMNS = ("dc.state", "dc.offset", "dc.sensor", "dc.feedback", "dc.filtered", "dc.target_deviation",
              "dc.pre_limiter", "dc.sloped_delta", "dc.set_pos", "dc.set_dist")


class Machine:
    """A simulated channel built from a :class:`~distctrl.sim.scenario.Scenario`."""

    def __init__(self, scenario, program: Program | None = None, plc_program=None, publish_hli: bool | None = None):
        self.scenario = scenario
        T = self.T = scenario.cycle_time
        axes = scenario.axes
        self.axis_names = list(axes)
        limits = {n: AxisLimits(a.v_max, a.a_max, a.v_rapid, a.a_rapid) for n, a in axes.items()}
        self.interp = Interpolator(T, limits, start={n: a.start for n, a in axes.items()})
        self.drives = {n: Drive(T, kv=a.kv, v_max=a.v_max, a_max=a.a_max, bus_delay_cycles=a.bus_delay_cycles,
                                resolution=a.resolution, initial_position=a.start) for n, a in axes.items()}
        self.controllers = {n: AxisDistanceController(a.params, T) for n, a in axes.items()}
        self.inputs = {n: CycleInput(programmed_position=a.start, actual_position=self.drives[n].actual)
                       for n, a in axes.items()}
        self.outputs = {n: CycleOutput() for n in axes}
        #: the HLI DistanceControl control unit of each axis (gpAx[i]^.lr_mc_control.distance_control)
        self.hli = {n: DistanceControlUnit(axis_index=i + 1) for i, n in enumerate(axes)}
        #: the channel's 3D status (gpCh[1]^.bahn_state: virt_tool_length_r, inclination_r); filled by
        #: the 3D distance control, 0 for the axis variant
        self.channel_status = ChannelDistanceStatus()
        #: a PLC program: called every cycle before the CNC consumes the control units
        self.plc_program = plc_program
        #: fill every unit's state_r every cycle: needed when something reads it while running (a PLC
        #: program, the ADS server); a batch run without readers publishes once at the end
        self.publish_hli = plc_program is not None if publish_hli is None else publish_hli
        self._plc_pending: list[tuple[str, int, float]] = []    # scenario PLC commands waiting for the semaphore
        #: axes whose controller runs every cycle (distance control enabled); others only on commands
        self.dc_axes = [n for n, a in axes.items() if a.params.enabled]
        self.surface = scenario.surface
        self.variables: dict[str, float] = {f"V.E.{k}": float(v) for k, v in scenario.variables.items()}
        self.variables["V.G.WZ_AKT.L"] = float(scenario.tool_length)
        self.shift = {n: 0.0 for n in axes}            # absorbed offsets the channel has not taken yet
        self.channel_override = 1.0
        self.cycle = 0
        self.events: list[tuple[float, ErrorEvent]] = []   # (t, event) of every controller event
        self.sensor_axis = None
        self.sensor = None
        self.sensor_variable = None
        sc = scenario.sensor
        if sc is not None:
            self.sensor_axis = sc.axis
            p = axes[sc.axis].params
            if sc.kind == "encoder":
                self.sensor = EncoderProbe(T, range_min=sc.range_min, range_max=sc.range_max,
                                           resolution_num=p.encoder_resolution_num,
                                           resolution_denom=p.encoder_resolution_denom,
                                           sign_reversal=p.sensor_sign_reversal, ref_offset=p.ref_offset,
                                           noise_std=sc.noise_std, delay_cycles=sc.delay_cycles, seed=sc.seed,
                                           faults=sc.faults)
            else:
                self.sensor = DistanceSensor(T, range_max=sc.range_max, characteristic=sc.characteristic,
                                             noise_std=sc.noise_std, delay_cycles=sc.delay_cycles, seed=sc.seed,
                                             faults=sc.faults)
                self.sensor_variable = f"V.E.{sc.variable}"
                self.variables.setdefault(self.sensor_variable, 0.0)
        self.nc = NcInterpreter(program, self, file=scenario.program_file) if program is not None else None
        #: per axis, everything one cycle touches, resolved once (the loop runs 10^5 times a second)
        self._axes = [(n, self.inputs[n], self.outputs[n], self.controllers[n], self.drives[n], n in self.dc_axes,
                       self.hli[n]) for n in self.axis_names]
        self._shift_any = False
        self._drive_x = self.drives.get("X")
        self._drive_y = self.drives.get("Y")
        self._next_event_t = scenario.events[0].t if scenario.events else math.inf
        self._program_end_sent = False
        self._event_index = 0
        self.true_surface = 0.0
        self.true_distance = 0.0

    # ------------------------------------------------------------------ Channel protocol (NC side)
    @property
    def positions(self) -> dict[str, float]:
        return self.interp.position

    def start_linear(self, target: dict[str, float], feed_mm_min: float | None) -> None:
        self._take_shift()
        self.interp.start_linear(target, feed_mm_min)

    def start_dwell(self, seconds: float) -> None:
        self.interp.start_dwell(seconds)

    def motion_done(self) -> bool:
        return self.interp.done

    def dist_ctrl(self, axis: str, command: Command) -> None:
        if axis not in self.inputs:
            raise ValueError(f"axis {axis} is not configured in this channel")
        self.inputs[axis].commands.append(command)

    def dist_ctrl_done(self, axis: str, action: Action) -> bool:
        """WAIT (SPEC §8): a select has reached its target once, OFF has reached INACTIVE, FREEZE has
        braked; an ERROR also ends the wait (the error stops the program anyway)."""
        out = self.outputs[axis]
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
                self.channel_override = float(data["value"])
        elif kind == "feed_hold":
            if data.get("axis"):
                self.inputs[data["axis"]].feed_hold = bool(data.get("value", True))
            else:
                self.channel_override = 0.0 if data.get("value", True) else 1.0
        elif kind == "reset":
            self.reset()
        elif kind == "axis_error":
            self.inputs[data["axis"]].commands.append(Command(Action.AXIS_ERROR))
            self.stop_program(None)
        elif kind == "axis_release":
            # the channel hands the axis over (e.g. to another channel): 70333 if distance control is on
            self.inputs[data["axis"]].commands.append(Command(Action.AXIS_RELEASE))
        elif kind == "sensor_fault":
            if self.sensor is not None:
                fault_args = {k: v for k, v in data.items() if k != "kind"}
                self.sensor.inject(Fault(kind=data["kind"], **fault_args), at_cycle=self.cycle)
        elif kind == "variable":
            self.variables[f"V.E.{data['name']}"] = float(data["value"])

    def reset(self) -> None:
        """CNC reset: the program stops, distance control is deselected with its offset absorbed."""
        for inp in self.inputs.values():
            inp.commands.append(Command(Action.RESET))
        self.stop_program(None)

    def stop_program(self, error) -> None:
        """Stop reading blocks; the running motion decelerates and holds."""
        if self.nc is not None and self.nc.running:
            self.nc.abort(error)
        self.interp.feed_override = 0.0
        self.channel_override = 0.0

    # ------------------------------------------------------------------ one cycle
    def step(self) -> None:
        """One GEO cycle."""
        k = self.cycle
        T = self.T
        t = k * T
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
        nc = self.nc
        line = None
        interp = self.interp
        if nc is not None:
            if interp.block == "idle":                   # blocks are read only when the channel is idle
                self._take_shift()
                nc.tick()
                if nc.ended and not self._program_end_sent:
                    self._program_end_sent = True
                    for inp in self.inputs.values():
                        inp.commands.append(Command(Action.PROGRAM_END, line=nc.end_line))
            line = nc.line
        interp.feed_override = self.channel_override
        prog = interp.step()
        drives = self.drives
        # the real geometry under the tool: true mechanical positions, not the quantised encoder
        x = self._drive_x.position if self._drive_x is not None else 0.0
        y = self._drive_y.position if self._drive_y is not None else 0.0
        surface_z = self.surface.height(x, y)
        self.true_surface = surface_z
        sensor_axis = self.sensor_axis
        if sensor_axis is not None:
            z = drives[sensor_axis].position
            self.true_distance = z - surface_z
            value = self.sensor.read(k, z, surface_z)
            if self.sensor_variable is None:
                self.inputs[sensor_axis].sensor_increments = value
            else:
                self.variables[self.sensor_variable] = value
        shift = self.shift if self._shift_any else None
        for name, inp, out, ctrl, drive, is_dc, unit in self._axes:
            p = prog[name]
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
                        if not var.startswith("V.E."):
                            var = "V.E." + var
                        inp.sensor_variable = self.variables.get(var, float("nan"))
                ctrl.update(inp, out)
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
        self.cycle = k + 1

    def publish_all(self) -> None:
        """Fill every control unit's ``state_r`` from the last cycle."""
        for name in self.dc_axes:
            self.hli[name].publish(self.outputs[name])

    # ------------------------------------------------------------------ status
    def settled(self) -> bool:
        """Motion at rest and no distance-control offset moving."""
        if not self.interp.done and self.interp.path_velocity != 0.0:
            return False
        for name in self.dc_axes:
            out = self.outputs[name]
            if out.offset_velocity != 0.0 or out.hli_state == int(HliState.TURNING_OFF):
                return False
        return all(abs(d.velocity) < 1e-3 for d in self.drives.values())     # 1 µm/s: at rest
