"""The kinematic / 3D part of the virtual machine's channel (docs/run-3d.md).

A channel with 3D distance control (``[channel] params`` with FCT_3D_DIST_CTRL), a head kinematic
(``[channel] kinematics = "CA"``, the default with the axes X, Y, Z, A, C) or a sensor measuring the
orthogonal distance of the clamping point runs :meth:`KinematicChannel.step` as its GEO cycle instead
of the axis variant's :meth:`Machine._step_axes <distctrl.sim.machine.Machine._step_axes>`: the NC's
X, Y, Z are transformed (#CS frame, #TRAFO with the CA head and kinematic 98) into the machine axes,
the sensor reports the orthogonal distance of the tool clamping point, and the channel's
:class:`~distctrl.control.controller3d.ChannelDistanceController` adds its compensation ``δ·e``.

:class:`KinematicChannel` is a part the :class:`~distctrl.sim.machine.Machine` owns
(``machine.channel3d``): it holds the transformation's state (#KIN chain, #TRAFO, kinematic 98, #CS
frame, the taken-over 3D offset) and the 3D controller with its cycle input and output; it takes the
NC's ``#KIN`` / ``#TRAFO`` / ``#CS`` / ``#CHANNEL INIT`` and ``#DIST CTRL`` commands through the
machine's channel protocol, and writes the machine's per-cycle ground truth and trace values
(``true_clamp``, ``true_distance_orth``, ``tcp_cmd``, ``inclination_deg``, ``virt_tool_length``,
``prog_values``) as the axis variant writes ``true_distance``. The machine itself keeps the axes, the
sensor, the events, the NC and the per-axis cycle (``_axes_cycle``) both variants end with.
"""
from __future__ import annotations

import math

from ..control import HliState
from ..control.commands3d import Command3D, CompensationMode
from ..control.controller3d import ChannelDistanceController, Cycle3DInput, Cycle3DOutput
from ..errors import ErrorId, ParameterError
from ..errors.three_d import event_to_3d, make_event_3d, severity_and_text
from ..kinematics.frames import Frame
from ..kinematics.kin98 import InclinationViolation, Kinematic98Params
from ..nc.interpreter import NcAbort
from ..nc.program import KinematicsWord, kin_param_var
from ..objects.channel3d import Channel3DValues
from ..objects.units import mm_to_dint_01um, round_saturate

_DEG = math.pi / 180.0
_Z = (0.0, 0.0, 1.0)
#: the kinematic ID of the CA head (FCT-M3 §12.4.2.1: "#TRAFO [9, 98]" on the CA kinematic)
CA_KIN_ID = 9
KIN98_ID = 98
TOOL_LENGTH_VAR = "V.G.WZ_AKT.L"
KIN98_VARS = tuple(kin_param_var(1, KIN98_ID, i) for i in range(4))
_INACTIVE3D = int(HliState.INACTIVE)
_FREEZE_CODE = int(HliState.FREEZE)


def _direction(c: float, a: float) -> tuple[float, float, float]:
    """Tool direction of the CA head, ``u(C, A) = (sin C·sin A, −cos C·sin A, cos A)`` (rad; SPEC §11)."""
    sa = math.sin(a)
    return (math.sin(c) * sa, -math.cos(c) * sa, math.cos(a))


def _inclination(c: float, a: float) -> float:
    """θ = angle of u(C, A) to machine +Z (rad, in [0, π])."""
    ux, uy, uz = _direction(c, a)
    return math.atan2(math.hypot(ux, uy), uz)


class KinematicChannel:
    """The kinematics and 3D distance control of a :class:`~distctrl.sim.machine.Machine`'s channel."""

    def __init__(self, machine, scenario):
        self.m = machine
        T = machine.T
        drives = machine.drives
        #: the channel's 3D distance control (None without FCT_3D_DIST_CTRL)
        self.has_dist_ctrl_3d = bool(scenario.has_3d)
        self.ch3d = ChannelDistanceController(scenario.channel_params, T) if self.has_dist_ctrl_3d else None
        self.in3d = Cycle3DInput()
        self.in3d.commands = []
        self.out3d = Cycle3DOutput()
        #: the head kinematic ("CA") or None
        self.head = scenario.kinematics
        #: the channel runs :meth:`step` (kinematics, 3D distance control or an orthogonal sensor)
        self.active = self.ch3d is not None or self.head is not None or machine._sensor_orth
        self.kin_chain: tuple[int, ...] = (CA_KIN_ID,)       # selected by #KIN, active with #TRAFO ON
        self.trafo = False
        self.kin98: Kinematic98Params | None = None          # active kinematic 98 (#TRAFO ON with 98)
        self.tool_length = float(machine.variables.get(TOOL_LENGTH_VAR, 0.0))
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
        #: the 900020 of a programmed inclination beyond HD4 was reported (once per program)
        self.hd4_reported = False
        #: a #DIST CTRL WAIT block is waiting for the 3D distance control (f_wait_for_finished)
        self.wait_3d = False
        self._drive_x = drives.get("X")
        self._drive_y = drives.get("Y")
        self._drive_z = drives.get("Z")
        self._drive_a = drives.get("A")
        self._drive_c = drives.get("C")
        self._xyz = tuple(n for n in ("X", "Y", "Z") if n in drives)

    # ------------------------------------------------------------------ NC side
    def before_linear(self, target: dict[str, float]) -> None:
        """Before a linear block starts: a taken-over 3D offset becomes the programmed position; with
        kinematic 98 a target orientation beyond HD4 is refused (900020)."""
        if self.trafo:
            self.take_shift3d()
            if self.kin98 is not None and ("A" in target or "C" in target):
                pos = self.m.interp.position
                theta = _inclination(target.get("C", pos["C"]) * _DEG, target.get("A", pos["A"]) * _DEG)
                if theta > self._hd[2]:
                    raise NcAbort(int(ErrorId.KIN98_MAX_INCLINATION),
                                  InclinationViolation(theta, self._hd[2]).message)
        elif self._shift3d_any:
            self.take_shift3d()

    def dist_ctrl_3d(self, command: Command3D) -> None:
        """A ``#DIST CTRL`` command for the channel's 3D distance control (consumed this cycle)."""
        m = self.m
        ch = self.ch3d
        if ch is None:
            raise NcAbort(20209, "Unknown Nc-command: #DIST CTRL needs FCT_3D_DIST_CTRL (P-CHAN-00500)")
        if command.is_select:
            if ch.core.state.hli_state == HliState.INACTIVE:
                var = command.sensor_var or ch.core.state.sensor_var or m.sensor_variable
                value = m.variables.get(m._var_name(var)) if var else None
                if value is None or not math.isfinite(value):
                    why = ("no SENSOR_VAR given" if not var else
                           f"{m._var_name(var)} does not exist" if value is None else
                           f"{m._var_name(var)} = {value!r}")
                    ev = make_event_3d(310027, ch.core.state.cycle, command.line, why)
                    m.events.append((m.cycle * m.T, ev))
                    m.stop_program(None)
                    return
        self.in3d.commands.append(command)

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
        m = self.m
        if self.trafo and any(n == TOOL_LENGTH_VAR or n in KIN98_VARS for n in names):
            self._set_trafo(True, self._kinematic_state(self.kin_chain))
            return
        if TOOL_LENGTH_VAR in names:
            self.tool_length = float(m.variables[TOOL_LENGTH_VAR])
        if KIN98_VARS[0] in names:
            self.hd1 = self._read_hd1()

    def _read_hd1(self) -> float:
        """HD1 = V.G.KIN_STEP[1].ID[98].PARAM[0] (1e-4 mm) -> mm; 0 while not assigned."""
        m = self.m
        raw = m.variables.get(KIN98_VARS[0], 0.0)
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
        m = self.m
        if self.head is None:
            raise NcAbort(int(ErrorId.NC_RUNTIME), "#TRAFO: no head kinematic in this channel ([channel] "
                          "kinematics, needs the axes X, Y, Z, A, C)")
        tool_length = float(m.variables.get(TOOL_LENGTH_VAR, 0.0))
        if not math.isfinite(tool_length) or tool_length < 0.0:
            raise NcAbort(int(ErrorId.NC_RUNTIME),
                          f"{TOOL_LENGTH_VAR} = {tool_length!r}: the tool length must be >= 0")
        kin98 = None
        if KIN98_ID in chain:
            missing = [v for v in KIN98_VARS if v not in m.variables]
            if missing:
                raise NcAbort(int(ErrorId.NC_RUNTIME), "kinematic 98 needs its parameters: "
                              + ", ".join(missing) + " not assigned")
            try:
                kin98 = Kinematic98Params.from_raw(*(m.variables[v] for v in KIN98_VARS))
            except ParameterError as exc:
                raise NcAbort(int(ErrorId.NC_RUNTIME), str(exc)) from None
            pos = m.interp.position
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
        m = self.m
        interp = m.interp
        pos = interp.position
        has = self._xyz
        if from_actual:
            new = {n: m.drives[n].actual for n in m.axis_names}
            machine = tuple(m.drives[n].actual if n in m.drives else 0.0 for n in ("X", "Y", "Z"))
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
            for n in m.shift:
                m.shift[n] = 0.0
            m._shift_any = False

    def take_shift3d(self) -> None:
        """3D OFF NO_MOVE: the channel takes the compensation over as its programmed position."""
        m = self.m
        if self._shift3d_any and m.interp.done:
            s = self.shift3d
            R = self._R
            if R is not None:
                s = [R[0][i] * s[0] + R[1][i] * s[1] + R[2][i] * s[2] for i in range(3)]
            pos = m.interp.position
            m.interp.set_position({n: pos[n] + s[i] for i, n in enumerate(("X", "Y", "Z")) if n in pos})
            self.shift3d = [0.0, 0.0, 0.0]
            self._shift3d_any = False

    # ------------------------------------------------------------------ one cycle
    def step(self) -> None:
        """One GEO cycle of a channel with kinematics and/or 3D distance control (docs/run-3d.md)."""
        m = self.m
        k = m.cycle
        T = m.T
        t = k * T
        interp = m.interp
        line = m._cycle_line(k, t)
        ch3d = self.ch3d
        interp.feed_override = m.channel_override
        prog = interp.step()
        if m.lift_motions:
            m._lift(prog)
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
            if self.kin98 is not None and theta > self._hd[2] and not self.hd4_reported:
                self.hd4_reported = True
                ev = make_event_3d(int(ErrorId.KIN98_MAX_INCLINATION), k, line,
                                   InclinationViolation(theta, self._hd[2]).message)
                m.events.append((t, ev))
                m.stop_program(None)
            lv = L * self._extension(theta)
            r = lv + hd1
            mx, my, mz = x + r * ux, y + r * uy, z + r * uz
            clamp_prog_z = z + lv * uz
        else:
            mx, my, mz = x, y, z
        # the real geometry: true positions of the tool (the drives' nozzle: motor plus resonance)
        drives = m.drives
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
        surface = m.surface
        f = surface.height(cx, cy)
        gx, gy = surface.gradient(cx, cy)
        d_orth = (cz - f) / math.sqrt(1.0 + gx * gx + gy * gy)     # (z_c − f)·n_z: exact for planes
        m.true_clamp = (cx, cy, cz)
        m.true_distance_orth = d_orth
        m.true_surface = f
        m.true_distance = cz - f
        sensor_axis = m.sensor_axis
        if m._sensor_orth:
            m.variables[m.sensor_variable] = m.sensor.read(k, d_orth, 0.0)
        elif sensor_axis is not None:
            zs = drives[sensor_axis].nozzle
            surface_z = surface.height(px, py)
            m.true_surface = surface_z
            m.true_distance = zs - surface_z
            value = m.sensor.read(k, zs, surface_z, px, py)
            if m.sensor_variable is None:
                m.inputs[sensor_axis].sensor_increments = value
            else:
                m.variables[m._sensor_out] = value
        theta_a = math.atan2(math.hypot(ua[0], ua[1]), ua[2])
        ext_a = self._extension(theta_a) if trafo else 1.0
        m.inclination_deg = math.degrees(theta_a)
        m.virt_tool_length = L * ext_a
        status = m.channel_status
        status.virt_tool_length_r = mm_to_dint_01um(m.virt_tool_length)
        status.inclination_r = round_saturate(m.inclination_deg * 1e4, -2147483648, 2147483647)
        # the channel's 3D distance control: its compensation δ·e is superimposed this cycle
        if ch3d is not None:
            inp3, out3 = self.in3d, self.out3d
            inp3.programmed_z = clamp_prog_z
            actual_z = dz.actual if dz is not None else 0.0
            inp3.actual_z = actual_z - hd1 * ua[2]
            var = ch3d.core.state.sensor_var or m.sensor_variable
            inp3.sensor_distance = m.variables.get(m._var_name(var), math.nan) if var else math.nan
            inp3.tool_direction = ua
            inp3.extension = ext_a
            inp3.cs_z_axis = self.cs_z
            inp3.normal = self.normal
            inp3.kin98_active = trafo and self.kin98 is not None
            inp3.override = m.channel_override
            inp3.nc_line = line
            ch3d.update(inp3, out3)
            if out3.events:
                for ev in out3.events:
                    m.events.append((t, ev))
                    if ev.severity == "error" and m.nc is not None and m.nc.running:
                        m.stop_program(None)
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
            m.tcp_cmd = (x + comp[0], y + comp[1], z + comp[2])
        else:
            m.tcp_cmd = (x, y, z)
        # the machine axes: X, Y, Z transformed, the others as programmed; then per-axis distance control
        machine = dict(prog)
        if "X" in machine:
            machine["X"] = mx
        if "Y" in machine:
            machine["Y"] = my
        if "Z" in machine:
            machine["Z"] = mz
        m.prog_values = [prog[n] for n in m.axis_names]
        m._axes_cycle(machine, line, t)
        m.cycle = k + 1

    def channel3d_values(self):
        """The channel's 3D distance-control values for the 3D CNC objects and the diagnosis block
        (docs/objects-3d.md, docs/diag.md); None without 3D distance control."""
        m = self.m
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
        axis_index = m.axis_names.index(ch.direction_axis) if ch.direction_axis in m.axis_names else 0
        sensor_var = st.sensor_var or m.sensor_variable
        return Channel3DValues.from_cycle_output(
            o3.core, offset=o3.delta, m_actual_offset=o3.core.offset, cmd_offset=o3.core.offset,
            cmd_offset_frozen=o3.core.offset if frozen else 0.0, freeze=frozen,
            wait_for_finished=self.wait_3d and m.nc is not None and m.nc.running,
            control_mode=int(st.mode), programmed_set_pos=st.programmed_set_pos,
            programmed_set_dist=st.programmed_set_dist,
            compensation_x=o3.compensation[0], compensation_y=o3.compensation[1], compensation_z=o3.compensation[2],
            inclination_rad=o3.inclination,
            compensation_mode=int(ch.mode) if in_effect else int(CompensationMode.OFF),
            new_compensation_mode=int(ch.mode), direction=ch.direction_axis,
            active_axis_index=axis_index, new_axis_index=axis_index,
            orthogonal_set_distance=o3.orthogonal_set_distance, blend_active=0.0 < o3.blend < 1.0,
            filter_time=ch.filter_time, fg_f0=f.fg_f0, order=f.order,
            tool_length=self.tool_length, virtual_tool_length=m.virt_tool_length,
            sensor_source=st.sensor_source.name, sensor_var=m._var_name(sensor_var) if sensor_var else None,
            ref_shift=st.ref_shift, error=event_to_3d(st.error) if st.error is not None else None,
            hli_state=state, events=list(o3.events),
            pending=dict(st.pending))                 # writes waiting for their adoption (docs/objects-3d.md)

