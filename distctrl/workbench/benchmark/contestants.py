"""The benchmark's contestants: each runs one :class:`~.suite.RunSpec` and returns a :class:`Track`, the
per-cycle nozzle positions the metrics read (the same for every contestant).

* ``distctrl_examples``: the virtual machine (``distctrl.sim.runner.run``) with the examples' lists
  (examples/scenarios/z_laser.lis: KP 0.5, MOVING_AVERAGE 4, both encoders; z_plasma.lis for plasma:
  KP 0.1, MOVING_AVERAGE 20) and the NC program of :func:`~.suite.program_text`.
* ``distctrl_examples_pf``: the same with the cutting-process functions :data:`PROCESS_FUNCTIONS` at
  their defaults (corner lock, void / kerf-crossing lock; docs/process.md).
* ``simple_pid``: a plain PID (the ``simple-pid`` package) on the same sensor model, the same drives,
  surface and path (the simulator's models, stepped in the machine's order): the PID's output is the Z
  velocity (mm/s), integrated into the Z setpoint (clamped to the list's ±max_deviation about the start,
  the travel distctrl has); it sees only the sensor (no encoder coupling). Gains
  :data:`PID_GAINS`, picked once by hand for a stable loop on the 1 kHz laser sensor, not tuned on the
  suite: it is the naive baseline.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...sim.interpolator import Interpolator
from ...sim.runner import run
from ...sim.scenario import scenario_from_dict
from .suite import RunSpec, scenario_dict

__all__ = ["Track", "run_contestant", "PID_GAINS", "PROCESS_FUNCTIONS"]

#: the cutting-process functions of ``distctrl_examples_pf``, at their defaults (docs/process.md)
PROCESS_FUNCTIONS = ("corner_lock", "void_lock")

#: the plain PID's gains per process: Kp (1/s), Ki (1/s^2), Kd (-), output limit (mm/s)
PID_GAINS = {"laser": (25.0, 150.0, 0.0, 200.0), "plasma": (10.0, 40.0, 0.0, 100.0)}


@dataclass
class Track:
    """What a contestant did, one entry per cycle: time (s), the nozzle's X, Y, Z (mm); ``k_select`` the
    first cycle the height control ran, ``k_motion`` the first cycle the path moved, ``k_end`` the last
    (None: never); ``outcome`` the run's outcome (``completed``, ``aborted``, ...), ``errors``
    the control errors (id and message)."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    k_select: int | None
    k_motion: int | None
    k_end: int | None
    outcome: str
    errors: list
    held: np.ndarray | None = None        # per cycle: the height control held (FREEZE); None: no such state


def _first(mask) -> int | None:
    idx = np.flatnonzero(mask)
    return int(idx[0]) if idx.size else None


def run_distctrl(spec: RunSpec) -> Track:
    plate = spec.plate_obj()
    cfg = scenario_dict(spec, plate)
    if spec.contestant == "distctrl_examples_pf":
        cfg["process"] = [{"function": f, "axis": "Z"} for f in PROCESS_FUNCTIONS]
    sc = scenario_from_dict(cfg)
    res = run(sc)
    tr = res.trace
    x, y, z = (np.asarray(tr[c], dtype=float) for c in ("X.act", "Y.act", "Z.act"))
    state = np.asarray(tr["Z.dc.state"])
    moving = np.hypot(np.diff(x, prepend=x[0]), np.diff(y, prepend=y[0])) > 0
    # the path's end: the last cycle X/Y moved while the height control ran (the drives' lag runs out after
    # the deselect, which lowers the head to the programmed Z)
    k_end = np.flatnonzero(moving & np.isin(state, (1, 2, 4)))
    return Track(np.asarray(tr["t"], dtype=float), x, y, z, _first(np.isin(state, (1, 2, 4))), _first(moving),
                 int(k_end[-1]) if k_end.size else None, res.outcome,
                 [{"id": e["id"], "message": e["message"]} for e in res.errors], state == 2)


def run_pid(spec: RunSpec) -> Track:
    from simple_pid import PID          # the [bench] extra (also a test dependency)

    plate = spec.plate_obj()
    sc = scenario_from_dict(scenario_dict(spec, plate))
    T = sc.cycle_time
    sensor = sc.make_sensor()
    drives = sc.make_drives()
    surface = sc.surface
    interp = Interpolator(T, {n: sc.axes[n].limits() for n in ("X", "Y")}, start={"X": 0.0, "Y": 0.0})
    kp, ki, kd, vlim = PID_GAINS[spec.process]
    pid = PID(kp, ki, kd, setpoint=spec.set_mm, sample_time=None, output_limits=(-vlim, vlim))
    arc = spec.process == "plasma"
    v0, kvolt = (sensor.v0, sensor.k) if arc else (0.0, 1.0)
    dwell = int(round(spec.params.dwell_s / T))
    path = list(plate.path)
    feed = spec.feed * 1000.0
    # the run lasts: the dwell, the path at the feed with generous braking, 0.2 s after
    length = sum(np.hypot(x1 - x0, y1 - y0) for (x0, y0), (x1, y1) in zip([(0.0, 0.0)] + path, path))
    n_max = dwell + int((length / (feed / 60.0) + 0.5 * len(path) + 1.0) / T)
    rows = np.zeros((n_max, 4))
    zset = drives["Z"].position
    # the travel of the list's offset range (max_deviation about the programmed Z), without its error stop
    reach = sc.axes["Z"].params.max_deviation
    z_bottom, z_top = zset - reach, zset + reach
    previous_volts = None
    k_motion = None
    k_end = None
    k_last = None
    after = int(round(0.2 / T))
    n = 0
    for k in range(n_max):
        if k >= dwell and interp.done:
            if path:
                xe, ye = path.pop(0)
                interp.start_linear({"X": xe, "Y": ye}, feed)
            elif k_end is None:
                k_end = k
            elif k - k_end >= after:
                break
        prog = interp.step()
        x, y = drives["X"].nozzle, drives["Y"].nozzle
        zn = drives["Z"].nozzle
        s = surface.height(x, y)
        value = sensor.read(k, zn, s, x, y)
        if arc:      # the PLC's linearisation of the previous cycle's voltage, as the machine runs it
            measured = (previous_volts - v0) / kvolt if previous_volts is not None else (value - v0) / kvolt
            previous_volts = value
        else:
            measured = value
        zset = min(z_top, max(z_bottom, zset + pid(measured, dt=T) * T))
        drives["X"].step(prog["X"])
        drives["Y"].step(prog["Y"])
        drives["Z"].step(zset)
        if interp.path_velocity > 0:
            k_motion = k if k_motion is None else k_motion
            k_last = k
        rows[n] = (k * T, x, y, zn)
        n += 1
    rows = rows[:n]
    return Track(rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], 0, k_motion, k_last,
                 "completed" if k_end is not None else "time_limit", [])


RUNNERS = {"distctrl_examples": run_distctrl, "distctrl_examples_pf": run_distctrl, "simple_pid": run_pid}


def run_contestant(spec: RunSpec) -> Track:
    return RUNNERS[spec.contestant](spec)
