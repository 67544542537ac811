"""Closed-loop batch kernel: one scenario, many parameter sets, the full plant, compiled with numba.

:func:`prepare` records from a scenario everything that does not depend on the Z control (the
programmed position of the distance-controlled axis, the surface height under the tool, the probe's
noise samples, the cycle distance control is switched on); :func:`closed_loop` replays one cycle
after the other exactly as :meth:`Machine._step_axes <distctrl.sim.machine.Machine._step_axes>`
and :meth:`AxisDistanceController.update <distctrl.control.controller.AxisDistanceController.update>`
do for a running select; :func:`run_batch` runs it for many parameter sets in parallel
(``numba.prange`` over the sets).

Per cycle ``k`` (the order of the machine and of the cycle core)::

    sensor   x = -(z_true - surface[k]) + noise[k]        (EncoderProbe: clamp to the stroke,
             y = floor((x - ref_offset) * incr_per_mm + 0.5), dead time ring)
             or the point distance sensor: x = z_true - surface[k] + noise[k],
             y = physics.distance_reading(x, ...)          (DistanceSensor: range, characteristic,
                                                            resolution; dead time ring)
    core     s = law.encoder_reading(y, ...)               (delayed one cycle without optimized scheduling)
             or s = -y (SENSOR_SOURCE=VARIABLE: the variable holds the distance in mm)
             monitoring 70329 / 70330 / 70576 (from the select on)
             feedback per mode, law.filter_seed (first active cycle), law.filter_step,
             law.pid_step, law.adaptive_acceleration (and _braking_), law.slope_limit, law.bound_velocity,
             law.advance_offset, 70331 / SW limit, law.integrator_after_limiter
    drive    c = p + o  -> bus delay ring, kv loop, feed-forward, v/a limits, quantisation;
             a resonant drive: physics.resonance_step moves the nozzle (what the probe sees next cycle)

The law is *only* called (``law.*``, registered with numba by :mod:`distctrl.batch.kernel`), and so
is the plant's arithmetic (``physics.*``: the probe's and the distance sensor's conversion, the drive's
limits, quantisation and resonance); the sequence of sensor and drive steps is written out here and
mirrors :mod:`distctrl.sim.sensors` / :mod:`distctrl.sim.drive` operation for operation, so a batch of one equals
:func:`distctrl.sim.runner.run` bit for bit (tests/batch/test_closed_loop.py).

Restrictions (checked by :func:`prepare`, a :class:`ClosedLoopError` says which one):

* the axis variant only: no 3D distance control, no head kinematics (no CA axes set), sensor
  ``kind = "encoder"`` (the probe) or ``kind = "distance"`` (the point distance sensor: no
  ``footprint_radius``, no ``bursts``; the program switches to it with ``SENSOR_SOURCE=VARIABLE``,
  ``SENSOR_VAR`` naming its variable, with or before the select), ``mode = "axis"``; no
  ``kind = "arc_voltage"``;
* no scenario ``events``, no sensor ``faults`` and no ``[[process]]`` functions (PLC programs);
* the program's DIST_CTRL commands address the sensor axis only; before the select only value-
  setting commands (``SET_POS=``/``SET_DIST=`` without an action), then one ``ON`` (SET_POS or
  CONST_DIST) from the NC; no ``WAIT`` (its end depends on the control), no tuning words in the
  blocks (``KP=``, ``FILTER_TYPE=`` ... would override the parameter set), no ``SENSOR_SOURCE``
  (but ``VARIABLE`` for the distance sensor), ``REF``, ``DRYRUN``, ``CHECK_POS``;
* the run ends before the next command reaches the axis (``OFF``, program end, ...): with
  ``cycles=None`` the replay ends before the cycle it arrives in (or at ``duration``); a larger explicit
  ``cycles`` is refused;
* the NC program must not abort and the other axes must not raise events.

A parameter set that raises a controller error in the replay (70329, 70330, 70576, 70331, SW
limit) stops there: the scalar machine would stop the program, which the recorded path cannot
follow. Its outputs are NaN from the error cycle on and ``errors[i] = (cycle, error id)``.

Per parameter set everything the law uses may differ (gains, limits, filter, adaptive
acceleration, optimized scheduling, both encoders, bounds, monitoring limits, the encoder
conversion; the probe is built per set with that set's resolution, sign and reference offset, as
the machine does). The plant (drives, including a drive's mechanical resonance, the sensor: probe
stroke or distance sensor range, characteristic and resolution, noise, dead time) is the scenario's.
"""
from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass, field
from types import SimpleNamespace

import numba
import numpy as np
from numba import njit, prange

from ..base.kinds import SensorSource
from ..base.states import CommandSource
from ..control import law
from ..control.commands import Action, Command
from ..control.controller import _MAX_I_GAIN, AxisDistanceController
from ..control.cycle_io import CycleOutput
from ..params.axis import AxisParameters
from ..sim import physics
from ..sim.drive import Drive
from ..sim.machine import Machine
from ..sim.runner import MAX_RUN_SECONDS, load_program
from ..sim.scenario import Scenario, load_scenario
from ..sim.sensors import NOISE_BLOCK
from . import kernel as _kernel  # registers law.* with numba; the law-constant columns
from . import soa
from .design import check_cycle_time, filter_coefficients, filter_config
from .jitcache import cached
from .layout import (Q_T, Q_KP, Q_I_GAIN, Q_D_GAIN, Q_V_MAX, Q_A_BASE, Q_W_V, Q_W_A, Q_A_FLOOR, Q_ADAPTIVE,
                     Q_A_MIN, Q_DEV_A_MIN, Q_DEV_A_MAX, Q_OPTIMIZED, Q_BOTH, Q_MAX_DEV, Q_CHECK_SW, Q_SW_MIN,
                     Q_SW_MAX, Q_JUMP, Q_S_HI, Q_S_LO, Q_MM_PER_INCR, Q_SIGN_REV, Q_REF_OFF, Q_MODULO,
                     Q_MIN_POS, Q_MAX_POS, Q_PROBE_IPM, Q_PROBE_REF, Q_LEN, PACKED_LEN, PL_Z0, PL_ACT0, PL_KV,
                     PL_VMAX, PL_DV, PL_BUS, PL_RES, PL_FF, PL_RMIN, PL_RMAX, PL_DELAY, PL_NOISE, PL_K_ON,
                     PL_MODE, PL_SET, PL_RESONANT, PL_P11, PL_P12, PL_P21, PL_P22, PL_SENSOR, PL_K_FIRST,
                     PL_DRES, PL_NCHAR, PL_LEN, SENSOR_PROBE, SENSOR_DISTANCE, MODE_SET_POS, MODE_CONST_DIST,
                     _E_JUMP, _E_RUN_MAX, _E_RUN_MIN, _E_MAX_DEV, _E_SW, _LAND, plant_constants,
                     sensor_constants, resonance_constants)

__all__ = ["ClosedLoopError", "LoopInputs", "prepare", "pack_sets", "pack_columns", "closed_loop", "run_batch",
           "Q_LEN", "PACKED_LEN"]


class ClosedLoopError(ValueError):
    """The scenario (or a parameter set) is outside what the closed-loop kernel replays."""


# ----------------------------------------------------------------------------- prepare

@dataclass
class LoopInputs:
    """What :func:`prepare` recorded: the Z-independent inputs of one scenario, per cycle."""

    scenario: object
    axis: str                      # the distance-controlled (sensor) axis
    cycle_time: float
    n_cycles: int
    k_on: int                      # the cycle whose update applies the ON command
    mode: int                      # MODE_SET_POS / MODE_CONST_DIST
    set_value: float               # SET_POS or SET_DIST, mm
    prog: np.ndarray               # programmed position of the axis per cycle, mm
    surface: np.ndarray            # surface height under the tool per cycle, mm
    noise: np.ndarray              # noise_std * standard normal per cycle, mm (zeros without noise)
    plant: np.ndarray              # PL_* vector
    params: AxisParameters         # the scenario's parameters of the axis
    notes: list = field(default_factory=list)


class _Recorder:
    """Stands in for the axis's controller during :func:`prepare`: records the programmed position
    and the commands, commands the programmed position (offset 0), never raises an event."""

    def __init__(self):
        self.state = SimpleNamespace(sensor_source=SensorSource.SECOND_ENCODER, sensor_var=None)
        self.prog: list[float] = []
        self.commands: list[tuple[int, object]] = []

    def update(self, inp, out: CycleOutput):
        k = len(self.prog)
        self.prog.append(inp.programmed_position)
        for cmd in inp.commands:
            self.commands.append((k, cmd))
        inp.commands.clear()
        out.command_position = inp.programmed_position
        out.absorbed_offset = 0.0
        out.events = []
        return 0


_TUNING_FIELDS = ("kp", "i_tn", "d_tv", "filter_type", "n_cycles", "fg_f0", "order", "smooth_fact",
                  "kalman_sigma", "sensor_source", "sensor_var", "ref_position")


def _noise(sensor_cfg, n: int) -> np.ndarray:
    """The probe's noise samples of cycles 0..n-1, drawn as EncoderProbe draws them."""
    if not sensor_cfg.noise_std:
        return np.zeros(n)
    noise_seq, _ = np.random.SeedSequence(sensor_cfg.seed).spawn(2)
    rng = np.random.default_rng(noise_seq)
    blocks = [rng.standard_normal(NOISE_BLOCK) for _ in range((n + NOISE_BLOCK - 1) // NOISE_BLOCK)]
    normal = np.concatenate(blocks)[:n] if blocks else np.zeros(0)
    return sensor_cfg.noise_std * normal


_SENSORS = "it runs kind = 'encoder' (the probe) and kind = 'distance' (the point sensor), mode 'axis'"


def _check_sensor(sensor) -> None:
    """The sensors the kernels model: the encoder probe and the point distance sensor, on the axis."""
    if sensor is None:
        raise ClosedLoopError(f"the closed-loop kernel needs a [sensor] on the distance-controlled axis: {_SENSORS}")
    if sensor.orthogonal:
        raise ClosedLoopError(f"[sensor] mode = '{sensor.mode}' (3D distance control) is not modelled by the "
                              f"closed-loop kernel: {_SENSORS}")
    if sensor.kind == "arc_voltage":
        raise ClosedLoopError("[sensor] kind = 'arc_voltage': the plasma arc voltage and its PLC linearisation "
                              f"are not modelled by the closed-loop kernel: {_SENSORS}")
    if sensor.kind not in ("encoder", "distance"):
        raise ClosedLoopError(f"[sensor] kind = '{sensor.kind}' is not modelled by the closed-loop kernel: {_SENSORS}")
    if sensor.kind == "distance":
        if sensor.footprint_radius > 0.0:
            raise ClosedLoopError(f"[sensor] footprint_radius = {sensor.footprint_radius:g} mm: the capacitive "
                                  f"edge effect is not modelled by the closed-loop kernel: {_SENSORS}, "
                                  "footprint_radius = 0")
        if sensor.bursts is not None:
            raise ClosedLoopError("[sensor] bursts: plume/spark noise bursts are not modelled by the closed-loop "
                                  f"kernel: {_SENSORS}, without bursts")
        if getattr(sensor, "linearisation", None) is not None:
            raise ClosedLoopError("[sensor] linearisation: the PLC's linearisation table is not modelled by the "
                                  f"closed-loop kernel: {_SENSORS}, without a linearisation")


def _variable_source(cmd, kc: int, sensor_var: str, k_first):
    """The distance sensor: the cycle the control switches to SENSOR_SOURCE=VARIABLE (``k_first``
    so far, or ``kc`` for this command's switch); other sources and variables are refused."""
    if cmd.sensor_var is not None:
        var = cmd.sensor_var if cmd.sensor_var.startswith("V.E.") else "V.E." + cmd.sensor_var
        if var != sensor_var:
            raise ClosedLoopError(f"DIST_CTRL line {cmd.line}: SENSOR_VAR={cmd.sensor_var}, but the distance "
                                  f"sensor writes {sensor_var}")
    if cmd.sensor_source is not None:
        if cmd.sensor_source == SensorSource.DEFAULT or SensorSource(cmd.sensor_source) != SensorSource.VARIABLE:
            raise ClosedLoopError(f"DIST_CTRL line {cmd.line}: SENSOR_SOURCE other than VARIABLE is not replayed "
                                  f"(the distance sensor writes {sensor_var})")
        if k_first is None:
            return kc
    return k_first


def prepare(scenario, cycles: int | None = None) -> LoopInputs:
    """Record the Z-independent inputs of ``scenario`` (a Scenario or a TOML path) for the kernel.

    Runs the scenario's machine once with a recorder in place of the distance-controlled axis's
    controller (the axis just follows its programmed path; the other axes, interpolator and NC
    run as they would). ``cycles``: how many cycles to replay; default: up to ``duration`` (or
    one hour), stopping before the next command after the select. Raises
    :class:`ClosedLoopError` for scenarios outside the restrictions (module docstring).
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    sc = scenario
    sensor = sc.sensor
    _check_sensor(sensor)
    distance = sensor.kind == "distance"
    sensor_var = f"V.E.{sensor.variable}" if distance else None
    if sensor.faults:
        raise ClosedLoopError("sensor faults are not modelled by the closed-loop kernel ([sensor] faults)")
    if sc.events:
        raise ClosedLoopError(f"scenario events are not replayed by the closed-loop kernel ({len(sc.events)} "
                              "events: PLC commands, overrides, faults, resets ...)")
    if getattr(sc, "processes", ()):
        raise ClosedLoopError(f"[[process]] functions are not replayed by the closed-loop kernel "
                              f"({', '.join(p.function for p in sc.processes)}: PLC programs that command "
                              "distance control; run the scenario with distctrl run)")
    axis = sensor.axis
    if not sc.axes[axis].params.enabled:
        raise ClosedLoopError(f"distance control is not enabled on the sensor axis {axis}")
    rec = _Recorder()
    machine = Machine(sc, load_program(sc), controller_factory=lambda name, params, cycle_time:
                      rec if name == axis else AxisDistanceController(params, cycle_time))
    if machine.kinematic_path:
        raise ClosedLoopError("3D distance control / head kinematics (CA) are not modelled by the "
                              "closed-loop "
                              "kernel (the axis variant only)")
    T = sc.cycle_time
    limit_s = sc.duration if sc.duration is not None else MAX_RUN_SECONDS
    max_cycles = int(round(limit_s / T))
    if cycles is not None:
        if int(cycles) != cycles or cycles < 1:
            raise ClosedLoopError(f"cycles = {cycles!r}: a positive integer")
        if cycles > max_cycles:
            raise ClosedLoopError(f"cycles = {cycles} beyond the scenario's duration ({max_cycles} cycles)")
        max_cycles = int(cycles)


    def no_wait(ax, action):
        raise ClosedLoopError(f"DIST_CTRL ... WAIT (line {machine.nc.line}) is not replayable: when the "
                              "next block starts depends on the control")

    orig_dist_ctrl = machine.dist_ctrl

    def dist_ctrl(ax, command):
        if ax != axis:
            raise ClosedLoopError(f"DIST_CTRL on axis {ax} (line {command.line}): only the sensor axis "
                                  f"{axis} "
                                  "may be distance-controlled")
        orig_dist_ctrl(ax, command)

    machine.dist_ctrl_done = no_wait
    machine.dist_ctrl = dist_ctrl
    prog_values, surface = [], []
    k_on = None
    stop = max_cycles
    programmed_set_pos = programmed_set_dist = None
    k_first = None if distance else 0        # the distance sensor: the cycle of SENSOR_SOURCE=VARIABLE
    mode = MODE_SET_POS
    set_value = 0.0
    n_seen = 0
    for k in range(max_cycles):
        machine.step()
        prog_values.append(rec.prog[-1])
        surface.append(machine.true_surface)
        if machine.nc is not None and machine.nc.aborted:
            err = machine.nc.error
            raise ClosedLoopError(f"the NC program aborted at cycle {k}: {err.message if err else 'aborted'}")
        if machine.events:
            t, ev = machine.events[0]
            raise ClosedLoopError(f"event {ev.id} at t = {t:g} s on another axis: {ev.message}")
        new = rec.commands[n_seen:]
        n_seen = len(rec.commands)
        ended = False
        for kc, cmd in new:
            if k_on is not None:           # the next command after the select: the replay ends before it
                ended = True
                break
            if not isinstance(cmd, Command):
                raise ClosedLoopError(f"cycle {kc}: {type(cmd).__name__} is not replayed (only NC commands)")
            bad = [f for f in _TUNING_FIELDS if getattr(cmd, f) is not None
                   and not (distance and f in ("sensor_source", "sensor_var"))]
            if bad:
                words = ", ".join(b.upper() for b in bad)
                raise ClosedLoopError(f"DIST_CTRL line {cmd.line}: {words} in the block "
                                      "is not replayed (tuning belongs to the parameter sets)")
            if distance:
                k_first = _variable_source(cmd, kc, sensor_var, k_first)
            if cmd.set_pos is not None:
                programmed_set_pos = float(cmd.set_pos)
            if cmd.set_dist is not None:
                programmed_set_dist = float(cmd.set_dist)
            if cmd.action == Action.NONE:
                continue
            if cmd.action != Action.ON:
                raise ClosedLoopError(f"cycle {kc}: {cmd.action.name} before the select is not replayed "
                                      "(the first action must be ON)")
            if cmd.source != CommandSource.NC:
                raise ClosedLoopError("only an ON from the NC program is replayed")
            if k_first is None:
                raise ClosedLoopError(f"DIST_CTRL line {cmd.line}: the distance sensor writes {sensor_var}, but the "
                                      f"control reads the second encoder: program {axis}[DIST_CTRL "
                                      f"SENSOR_SOURCE=VARIABLE SENSOR_VAR={sensor_var}] with or before the select "
                                      "(FCT-M3 §6, PROG DIST_CTRL)")
            if cmd.const_dist:
                if programmed_set_dist is None:
                    raise ClosedLoopError(f"DIST_CTRL line {cmd.line}: ON CONST_DIST without SET_DIST")
                mode, set_value = MODE_CONST_DIST, programmed_set_dist
            else:
                if programmed_set_pos is None:
                    raise ClosedLoopError(f"DIST_CTRL line {cmd.line}: ON without SET_POS")
                mode, set_value = MODE_SET_POS, programmed_set_pos
            if not math.isfinite(set_value):
                raise ClosedLoopError(f"DIST_CTRL line {cmd.line}: set value {set_value!r} not finite")
            k_on = kc
        if ended:
            if cycles is not None and k < cycles:
                raise ClosedLoopError(f"cycles = {cycles}: a command reaches axis {axis} at cycle {k} "
                                      f"({new[-1][1].action.name}); at most {k} cycles are replayable")
            stop = k
            break
    if k_on is None:
        raise ClosedLoopError(f"distance control is never selected on axis {axis} within "
                              f"{len(prog_values)} cycles")
    n = stop
    ax = sc.axes[axis]

    drive = Drive(T, kv=ax.kv, v_max=ax.v_max, a_max=ax.a_max,
                  bus_delay_cycles=ax.bus_delay_cycles, resolution=ax.resolution,
                  initial_position=ax.start, velocity_feedforward=ax.feedforward,
                  resonance_hz=ax.resonance_hz, damping=ax.damping)
    chars = sensor.characteristic if distance and sensor.characteristic else ()
    plant = np.zeros(PL_LEN + 2 * len(chars))
    plant[PL_Z0] = drive.position
    plant[PL_ACT0] = drive.actual
    plant[PL_KV] = drive.kv
    plant[PL_VMAX] = drive.v_max
    plant[PL_DV] = drive._dv_max
    plant[PL_BUS] = drive.bus_delay_cycles
    plant[PL_RES] = drive.resolution
    plant[PL_FF] = drive.velocity_feedforward
    plant[PL_RMIN] = 0.0 if distance else sensor.range_min
    plant[PL_RMAX] = sensor.range_max
    plant[PL_SENSOR] = SENSOR_DISTANCE if distance else SENSOR_PROBE
    plant[PL_K_FIRST] = k_first
    plant[PL_DRES] = sensor.resolution if distance else 0.0
    plant[PL_NCHAR] = len(chars)
    for j, (true_mm, reported_mm) in enumerate(chars):
        plant[PL_LEN + j] = true_mm
        plant[PL_LEN + len(chars) + j] = reported_mm
    plant[PL_DELAY] = sensor.delay_cycles
    plant[PL_NOISE] = 1.0 if sensor.noise_std else 0.0
    plant[PL_K_ON] = k_on
    plant[PL_MODE] = mode
    plant[PL_SET] = set_value
    if drive.resonance_phi is not None:
        plant[PL_RESONANT] = 1.0
        plant[PL_P11], plant[PL_P12], plant[PL_P21], plant[PL_P22] = drive.resonance_phi
    return LoopInputs(sc, axis, T, n, k_on, mode, set_value, np.asarray(prog_values[:n], dtype=np.float64),
                      np.asarray(surface[:n], dtype=np.float64), _noise(sensor, n), plant, ax.params)


# ----------------------------------------------------------------------------- packing

def pack_sets(inputs: LoopInputs, param_sets, probe=None) -> np.ndarray:
    """``(n_sets, PACKED_LEN)`` rows ``[fc | prm]`` for a list of :class:`AxisParameters`.

    The law's constants are those of :meth:`AxisDistanceController._derive
    <distctrl.control.controller.AxisDistanceController>` and ``law_constants()``, computed for all
    sets at once with the same operations (so kernel and cycle core cannot disagree; no controller
    object per set: tests/batch/test_pack.py checks the rows bit for bit against the controller's);
    the filter's coefficients come from :func:`distctrl.batch.design.filter_coefficients`, designed
    once per distinct filter; the probe from ``inputs.scenario``'s sensor with the set's encoder
    resolution and sign reversal (as the machine builds it), once per distinct pair. Columns of
    ``prm`` (offset ``law.FC_LEN``) that are plain numbers (``Q_KP``, ``Q_I_GAIN`` = T/i_tn,
    ``Q_D_GAIN`` = law.derivative_gain(kp, d_tv, T): edit it with Q_KP, ``Q_V_MAX``, ``Q_A_BASE`` ...)
    may be edited in the array for a sweep; the filter (``fc``) only through this function. ``probe``: the
    probe constants of every set when known (a worker's inputs have no scenario to build them from).
    """
    T = inputs.cycle_time
    sets = list(param_sets)
    n = len(sets)
    for i, p in enumerate(sets):
        if not isinstance(p, AxisParameters):
            raise ClosedLoopError(f"param_sets[{i}]: an AxisParameters, not {type(p).__name__}")
        if not p.enabled:
            raise ClosedLoopError(f"param_sets[{i}]: distance control not enabled (P-AXIS-00328)")
    rows = np.zeros((n, PACKED_LEN))
    if not n:
        return rows
    check_cycle_time(T)
    # the filter: one design per distinct configuration (it raises what the controller raised)
    fc_of: dict = {}
    fc_rows = np.empty(n, dtype=np.int64)
    tables = []
    for i, p in enumerate(sets):
        cfg = filter_config(p)
        j = fc_of.get(cfg)
        if j is None or tables[j][0] != _types(cfg):
            tables.append((_types(cfg), filter_coefficients(cfg, T)))
            j = fc_of[cfg] = len(tables) - 1
        fc_rows[i] = j
    rows[:, :law.FC_LEN] = np.stack([t[1] for t in tables])[fc_rows]

    def col(name, dtype=np.float64):
        return np.fromiter((getattr(p, name) for p in sets), dtype=dtype, count=n)

    def flag(name):
        return np.fromiter((bool(getattr(p, name)) for p in sets), dtype=bool, count=n)

    def probes(q):
        found: dict = {}
        for i, p in enumerate(sets):
            key = (p.encoder_resolution_num, p.encoder_resolution_denom, p.sensor_sign_reversal)
            pr = found.get(key) if probe is None else probe
            if pr is None:
                pr = found[key] = _probe_constants(inputs, p)
            q[i, Q_PROBE_IPM], q[i, Q_PROBE_REF] = pr

    _fill_prm(inputs, rows[:, law.FC_LEN:], col, flag, probes)
    return rows


#: the AxisParameters fields :func:`pack_columns` takes from columns (the rest from the base set)
PACKED_COLUMN_FIELDS = frozenset({"kp", "i_tn", "d_tv", "filter_type", "n_cycles", "smoothing_factor", "kalman_sigma",
                                  "low_pass_filter_order", "low_pass_filter_fg_f0", "v_max", "a_max"})


def pack_columns(inputs: LoopInputs, base: AxisParameters, columns: dict, present: dict, fc: np.ndarray,
                 probe=None) -> np.ndarray:
    """:func:`pack_sets` of the sets ``base`` with the values of ``columns`` (field -> array of the sets'
    values; ``present[field]``: a bool mask of the sets that take it, None: all), without a parameter
    object per set (issue 27): ``fc`` are the sets' filter coefficient rows
    (:func:`distctrl.batch.design.design_rows`). Only the fields of :data:`PACKED_COLUMN_FIELDS` may be
    columns; the rows are those :func:`pack_sets` builds for the same sets, bit for bit
    (tests/batch/test_pack.py). ``probe``: the base set's probe constants (increments per mm, reference
    offset) when known (a worker's inputs have no scenario to build it from)."""
    unknown = set(columns) - PACKED_COLUMN_FIELDS
    if unknown:
        raise ClosedLoopError(f"pack_columns: fields {sorted(unknown)} are not packed from columns (pack_sets)")
    if not base.enabled:
        raise ClosedLoopError("param_sets: distance control not enabled (P-AXIS-00328)")
    n = len(fc)
    rows = np.zeros((n, PACKED_LEN))
    if not n:
        return rows
    check_cycle_time(inputs.cycle_time)
    rows[:, :law.FC_LEN] = fc

    def col(name, dtype=np.float64):
        v = getattr(base, name)
        if name in columns:
            m = present.get(name)
            c = np.asarray(columns[name], dtype=dtype)
            return c.copy() if m is None else np.where(m, c, np.asarray(v, dtype=dtype))
        return np.full(n, v, dtype=dtype)

    def flag(name):
        return np.full(n, bool(getattr(base, name)))

    def probes(q):
        q[:, Q_PROBE_IPM], q[:, Q_PROBE_REF] = probe if probe is not None else _probe_constants(inputs, base)

    _fill_prm(inputs, rows[:, law.FC_LEN:], col, flag, probes)
    return rows


def _probe_constants(inputs: LoopInputs, p) -> tuple[float, float]:
    """The probe the machine builds for the set ``p``: (increments per mm, reference offset)."""
    probe = inputs.scenario.sensor.make_sensor(inputs.cycle_time, p)
    return probe.increments_per_mm, probe.ref_offset


def derivative_gains(kp: np.ndarray, d_tv: np.ndarray, T: float) -> np.ndarray:
    """:func:`law.derivative_gain` of every (kp, d_tv), with its operations (bit for bit, tests/batch/test_pack.py)."""
    kp = np.asarray(kp, dtype=np.float64)
    d_tv = np.asarray(d_tv, dtype=np.float64)
    g_max = law.D_ROOM_SHARE * (1.0 - kp)
    use = (d_tv > 0.0) & (g_max > 0.0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        x = kp * d_tv / T
        g = x / (1.0 + x / g_max)
    return np.where(use, g, 0.0)


def _fill_prm(inputs: LoopInputs, q: np.ndarray, col, flag, probes) -> None:
    """The ``prm`` columns of the sets from their parameters' columns (``col(name)``, ``flag(name)``):
    the law's constants of :meth:`AxisDistanceController._derive` and ``law_constants()``, operation for
    operation, for all sets at once; ``probes(q)`` fills the probe's two columns."""
    T = inputs.cycle_time
    kp, i_tn, d_tv = col("kp"), col("i_tn"), col("d_tv")
    a_max, axis_a_max = col("a_max"), col("axis_a_max")
    adaptive = flag("use_adaptive_acceleration")
    a_min = col("a_min")
    # AxisDistanceController._derive, operation for operation (IEEE results do not depend on numpy vs Python)
    a_base = np.where(a_max > 0, a_max, axis_a_max)
    with np.errstate(divide="ignore", invalid="ignore"):
        i_gain = np.where(i_tn > 0, np.minimum(T / np.where(i_tn > 0, i_tn, 1.0), _MAX_I_GAIN), 0.0)
    d_gain = derivative_gains(kp, d_tv, T)
    v_wd, a_wd = col("v_weight_down"), col("a_weight_down")
    w_v = np.where(v_wd > 0, v_wd, 1.0)
    w_a = np.where(a_wd > 0, a_wd, 1.0)
    a_floor = np.where(adaptive, np.minimum(a_base, a_min), a_base) * np.minimum(1.0, w_a)
    q[:, Q_T] = T
    q[:, Q_KP] = kp
    q[:, Q_I_GAIN] = i_gain
    q[:, Q_D_GAIN] = d_gain
    q[:, Q_V_MAX] = col("v_max")
    q[:, Q_A_BASE] = a_base
    q[:, Q_W_V] = w_v
    q[:, Q_W_A] = w_a
    q[:, Q_A_FLOOR] = a_floor
    q[:, Q_ADAPTIVE] = adaptive
    q[:, Q_A_MIN] = a_min
    q[:, Q_DEV_A_MIN] = col("dist_error_a_min")
    q[:, Q_DEV_A_MAX] = col("dist_error_a_max")
    q[:, Q_OPTIMIZED] = flag("optimized_scheduling")
    q[:, Q_BOTH] = flag("use_both_encoders")
    q[:, Q_MAX_DEV] = col("max_deviation")
    q[:, Q_CHECK_SW] = flag("check_sw_limit_switch")
    q[:, Q_SW_MIN] = col("sw_limit_min")
    q[:, Q_SW_MAX] = col("sw_limit_max")
    min_pos, max_pos, tol = col("min_pos"), col("max_pos"), col("tolerance")
    q[:, Q_JUMP] = col("max_act_value_change") * T
    q[:, Q_S_HI] = max_pos - tol
    q[:, Q_S_LO] = min_pos + tol
    q[:, Q_MM_PER_INCR] = col("sensor_mm_per_increment")
    q[:, Q_SIGN_REV] = flag("sensor_sign_reversal")
    q[:, Q_REF_OFF] = col("ref_offset") + 0.0            # + the state's ref_shift, 0 before any REF
    q[:, Q_MODULO] = flag("sensor_modulo")
    q[:, Q_MIN_POS] = min_pos
    q[:, Q_MAX_POS] = max_pos
    if inputs.plant[PL_SENSOR] == SENSOR_PROBE:          # (the distance sensor delivers mm)
        probes(q)


def _types(cfg) -> tuple:
    """The types of a filter configuration's values (4 == 4.0, but the design refuses a float n)."""
    return tuple(type(getattr(cfg, f)) for f in ("filter_type", "n_cycles", "smoothing_factor", "kalman_sigma",
                                                 "order", "fg_f0"))


# ----------------------------------------------------------------------------- kernel

@cached
@njit(cache=True, nogil=True, error_model="numpy")
def closed_loop(fc, prm, plant, prog, surface, noise, out_offset, out_distance, out_error):
    """The closed loop of one parameter set over ``len(out_offset)`` cycles.

    ``fc``: the law's filter coefficients, ``prm``: the ``Q_*`` vector, ``plant``: the ``PL_*``
    vector, ``prog`` / ``surface`` / ``noise``: per cycle (mm). Writes ``out_offset`` (the trace's
    ``<axis>.dc.offset``), ``out_distance`` (``true.distance``) and ``out_error`` = (cycle, id) of
    the first controller error (-1, 0 without); outputs are NaN from the error cycle on.
    """
    n = out_offset.shape[0]
    out_error[0] = -1
    out_error[1] = 0
    # law constants of this set
    T = prm[Q_T]
    kp = prm[Q_KP]
    i_gain = prm[Q_I_GAIN]
    d_gain = prm[Q_D_GAIN]
    v_max = prm[Q_V_MAX]
    a_base = prm[Q_A_BASE]
    w_v = prm[Q_W_V]
    w_a = prm[Q_W_A]
    a_floor = prm[Q_A_FLOOR]
    adaptive = prm[Q_ADAPTIVE] != 0.0
    a_min = prm[Q_A_MIN]
    dev_a_min = prm[Q_DEV_A_MIN]
    dev_a_max = prm[Q_DEV_A_MAX]
    optimized = prm[Q_OPTIMIZED] != 0.0
    both = prm[Q_BOTH] != 0.0
    max_dev = prm[Q_MAX_DEV]
    check_sw = prm[Q_CHECK_SW] != 0.0
    sw_min = prm[Q_SW_MIN]
    sw_max = prm[Q_SW_MAX]
    jump_limit = prm[Q_JUMP]
    s_hi = prm[Q_S_HI]
    s_lo = prm[Q_S_LO]
    mm_per_incr = prm[Q_MM_PER_INCR]
    sign_rev = prm[Q_SIGN_REV] != 0.0
    ref_off = prm[Q_REF_OFF]
    modulo = prm[Q_MODULO] != 0.0
    min_pos = prm[Q_MIN_POS]
    max_pos = prm[Q_MAX_POS]
    probe_ipm = prm[Q_PROBE_IPM]
    probe_ref = prm[Q_PROBE_REF]
    # plant and select
    z_pos = plant[PL_Z0]
    z_act = plant[PL_ACT0]
    z_vel = 0.0
    kv, dr_vmax, dr_dv, nbus, res, ff, r_min, r_max, ndel, has_noise, k_on, const_dist, set_value = \
        plant_constants(plant)
    resonant, p11, p12, p21, p22 = resonance_constants(plant)
    distance, k_first, dres, char_x, char_y = sensor_constants(plant)
    z_noz = z_pos                             # Drive.nozzle: what the probe sees
    defl = 0.0                                # Drive.deflection, deflection_rate
    defl_rate = 0.0

    ring = np.empty(nbus + 1)                 # Drive.setpoint_history: starts full of the start position
    for j in range(nbus + 1):
        ring[j] = z_pos
    ring_w = 0
    prev_sp = z_pos
    dline = np.empty(ndel if ndel > 0 else 1)  # the probe's dead time
    dline_i = 0
    fs = np.zeros(law.FS_LEN)
    buf = np.zeros(law.MAX_N)

    o = 0.0
    vel = 0.0
    integral = 0.0
    m_prev = 0.0
    need_seed = True
    a_bound_state = a_floor
    s_delayed = 0.0
    last_s = 0.0
    s_wrapped = 0.0                                 # modulo encoder: last wrapped / continuous reading
    s_unwrapped = 0.0
    for k in range(n):
        # ---- machine: the sensor reads the true geometry (EncoderProbe.read, DistanceSensor.read)
        sz = surface[k]
        z = z_noz
        out_distance[k] = z - sz
        if distance:
            x = 1.0 * (z - sz)
            if has_noise:
                x += noise[k]
            y = physics.distance_reading(x, r_max, char_x, char_y, dres)
        else:
            x = -1.0 * (z - sz)
            if has_noise:
                x += noise[k]
            y = physics.probe_increments(x, r_min, r_max, probe_ref, probe_ipm)
        if ndel > 0:
            if k == 0:
                for j in range(ndel):
                    dline[j] = y
            yo = dline[dline_i]
            dline[dline_i] = y
            dline_i = dline_i + 1 if dline_i + 1 < ndel else 0
            y = yo
        # ---- cycle core (AxisDistanceController.update)
        pr = prog[k]
        act = z_act
        if distance:                                # SENSOR_SOURCE=VARIABLE: the variable holds d (mm)
            s_now = -y + 0.0                        # (AxisDistanceController._read_sensor; no REF)
            if modulo:
                s_now = min_pos + (s_now - min_pos) % (max_pos - min_pos)
        else:
            s_now = law.encoder_reading(y, mm_per_incr, sign_rev, ref_off, modulo, min_pos, max_pos)
        # k <= k_first: no earlier reading (the first cycle; the distance sensor: the cycle the control
        # switches to the variable, which restarts the reading's history)
        if modulo:                                  # AxisDistanceController._unwrap
            if k > k_first:
                s_unwrapped = law.modulo_unwrap(s_now, s_wrapped, s_unwrapped, min_pos, max_pos)
            else:
                s_unwrapped = s_now
            s_wrapped = s_now
            s_now = s_unwrapped
        if optimized:
            s = s_now
        else:
            s = s_now if k <= k_first else s_delayed   # no earlier reading
            s_delayed = s_now
        running = k >= k_on
        err_id = 0
        if running:
            s_window = law.modulo_wrap(s, min_pos, max_pos) if modulo else s
            if k > k_first and abs(s - last_s) > jump_limit:
                err_id = _E_JUMP
            elif s_window > s_hi:
                err_id = _E_RUN_MAX
            elif s_window < s_lo:
                err_id = _E_RUN_MIN
        if err_id != 0:
            out_error[0] = k
            out_error[1] = err_id
            for j in range(k, n):
                out_offset[j] = np.nan
                out_distance[j] = np.nan
            return
        last_s = s
        d = -s
        feedback = law.feedback_value(const_dist, both, d, act, pr + o)
        target_dev = 0.0
        e = 0.0
        u = 0.0
        i_cand = integral
        if running:
            if need_seed:
                law.filter_seed(fc, fs, buf, feedback)
                need_seed = False
                m_prev = -feedback if const_dist else feedback
            filtered = law.filter_step(fc, fs, buf, feedback)
            target_dev, e, m = law.mode_error(const_dist, filtered, set_value, o)
            u, i_cand = law.pid_step(kp, i_gain, d_gain, integral, m_prev, e, m)
            m_prev = m
            u, i_cand = law.finite_step(u, i_cand, integral)
        # slope limiter and bounds (override 1, no feed hold: hold = not running)
        v_lim = v_max * 1.0
        a_lim = a_base
        a_brake = a_base
        if adaptive and running:
            a_lim = law.adaptive_acceleration(abs(e), a_min, a_base, dev_a_min, dev_a_max)
            a_brake = law.adaptive_braking_acceleration(abs(e), a_min, a_base, dev_a_min, dev_a_max)
        if running:
            u_lim = u
            e_lim = e
        else:
            u_lim = 0.0
            e_lim = 0.0
        v, a_applied, v_applied = law.slope_limit(u_lim, e_lim, vel, T, v_lim, a_lim, a_brake, w_v, w_a)
        lo = -max_dev
        hi = max_dev
        if check_sw:
            lo_sw = sw_min - pr
            if lo_sw > lo:
                lo = lo_sw
            hi_sw = sw_max - pr
            if hi_sw < hi:
                hi = hi_sw
        if vel == 0.0:
            a_bound = a_floor
        else:
            a_bound = a_bound_state if a_bound_state > a_floor else a_floor
        a_bound_state = a_bound
        v = law.bound_velocity(v, o, T, lo, hi, a_bound)
        o_new = law.advance_offset(o, v, T, lo, hi)
        if running:
            wanted = o + u_lim
            if wanted > hi + _LAND and hi - o_new <= _LAND:
                err_id = _E_MAX_DEV if hi >= max_dev - _LAND else _E_SW
            elif wanted < lo - _LAND and o_new - lo <= _LAND:
                err_id = _E_MAX_DEV if lo <= -max_dev + _LAND else _E_SW
            if err_id != 0:
                out_error[0] = k
                out_error[1] = err_id
                for j in range(k, n):
                    out_offset[j] = np.nan
                    out_distance[j] = np.nan
                return
            integral = law.integrator_after_limiter(integral, i_cand, u_lim, v, e, T)
        vel = (o_new - o) * (1.0 / T)
        o = o_new
        out_offset[k] = o_new
        cmd = pr + o_new + 0.0
        # ---- drive (Drive.step)
        ring[ring_w] = cmd
        ring_w = ring_w + 1 if ring_w < nbus else 0
        c = ring[ring_w]
        dv = kv * (c - z_act)
        if ff != 0.0:
            dv += ff * (c - prev_sp) * (1.0 / T)
        prev_sp = c
        dv = physics.limit_velocity(dv, dr_vmax, z_vel, dr_dv)
        z_pos = z_pos + dv * T
        if resonant:
            defl, defl_rate = physics.resonance_step(defl, defl_rate, dv - z_vel, p11, p12, p21, p22)
            z_noz = z_pos + defl
        else:
            z_noz = z_pos
        z_vel = dv
        z_act = physics.quantise(z_pos, res, 1.0 / res) if res != 0.0 else z_pos


@cached
@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def _closed_loop_batch(packed, plant, prog, surface, noise, out_offset, out_distance, out_error):
    for i in prange(packed.shape[0]):
        closed_loop(packed[i, :law.FC_LEN], packed[i, law.FC_LEN:], plant, prog, surface, noise,
                    out_offset[i], out_distance[i], out_error[i])


@cached
@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def run_blocks(packed, lanes, counts, rest, plant, prog, surface, noise, out_offset, out_distance, out_error):
    """All blocks (:func:`distctrl.batch.soa.block_loop`) and then the other rows (:func:`closed_loop`), in
    parallel."""
    for j in prange(lanes.shape[0]):
        soa.block_loop(packed, lanes[j], counts[j], plant, prog, surface, noise, out_offset, out_distance,
                       out_error)
    for r in prange(rest.shape[0]):
        i = rest[r]
        closed_loop(packed[i, :law.FC_LEN], packed[i, law.FC_LEN:], plant, prog, surface, noise, out_offset[i],
                    out_distance[i], out_error[i])


@contextmanager
def numba_threads(threads: int | None):
    """numba's thread count for the parallel kernels called in this block by this thread (numba keeps it per
    calling thread), restored afterwards; ``None``: leave it as it is."""
    if threads is None:
        yield
        return
    old = numba.get_num_threads()
    numba.set_num_threads(int(threads))
    try:
        yield
    finally:
        numba.set_num_threads(old)


def run_batch(inputs: LoopInputs, param_sets, *, cycles: int | None = None, threads: int | None = None,
              return_errors: bool = False, vectorised: bool = True, out=None):
    """Run the closed loop of ``inputs`` for every parameter set, in parallel over the sets.

    MOVING_AVERAGE sets (without a modulo encoder) run in blocks through the vectorised
    :func:`distctrl.batch.soa.block_loop`, the others one by one through :func:`closed_loop`; both
    give the same numbers bit for bit. ``vectorised=False``: every set through :func:`closed_loop`.

    ``param_sets``: a list of :class:`AxisParameters`, or rows from :func:`pack_sets` (an array of
    shape ``(n_sets, PACKED_LEN)``). ``cycles``: at most ``inputs.n_cycles`` (default all).
    ``threads``: numba threads for this call (default: numba's setting). Returns
    ``(offset, distance)`` of shape ``(n_sets, cycles)``, plus ``errors`` (n_sets, 2) = (cycle, id),
    cycle -1 without error, when ``return_errors``.

    ``out``: ``(offset, distance)``, two float64 arrays of shape ``(n_sets, cycles)`` to write
    into and return instead of new ones. A caller that runs many batches can reuse them: fresh
    memory costs the operating system a page fault and zeroing on first touch (docs/batch.md).
    """
    if isinstance(param_sets, np.ndarray):
        packed = np.ascontiguousarray(param_sets, dtype=np.float64)
        if packed.ndim != 2 or packed.shape[1] != PACKED_LEN:
            raise ClosedLoopError(f"packed parameter sets must have shape (n_sets, {PACKED_LEN}), "
                                  f"not {packed.shape}")
    else:
        packed = pack_sets(inputs, list(param_sets))
    n = inputs.n_cycles if cycles is None else int(cycles)
    if not 0 < n <= inputs.n_cycles:
        raise ClosedLoopError(f"cycles = {cycles!r}: 1 ... {inputs.n_cycles}")
    n_sets = packed.shape[0]
    if out is None:
        out_offset = np.empty((n_sets, n))
        out_distance = np.empty((n_sets, n))
    else:
        out_offset, out_distance = out
        for name, a in (("offset", out_offset), ("distance", out_distance)):
            if not (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.shape == (n_sets, n)
                    and a.flags.writeable):
                raise ClosedLoopError(f"out {name}: a writeable float64 array of shape {(n_sets, n)} is needed, "
                                      f"not {getattr(a, 'dtype', type(a).__name__)} {getattr(a, 'shape', '')}")
        if np.shares_memory(out_offset, out_distance):
            raise ClosedLoopError("out: the offset and distance arrays overlap")
    out_error = np.empty((n_sets, 2), dtype=np.int64)
    lanes, counts, rest = soa.plan_blocks(packed)
    with numba_threads(threads):
        if vectorised:
            run_blocks(packed, lanes, counts, rest, inputs.plant, inputs.prog, inputs.surface, inputs.noise,
                       out_offset, out_distance, out_error)
        else:
            _closed_loop_batch(packed, inputs.plant, inputs.prog, inputs.surface, inputs.noise,
                               out_offset, out_distance, out_error)
    if return_errors:
        return out_offset, out_distance, out_error
    return out_offset, out_distance
