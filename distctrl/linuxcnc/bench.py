"""``distctrl linuxcnc bench PLATE.toml``: LinuxCNC's plasmac in closed loop on distctrl's plate, side by
side with distctrl's own controller and process functions (docs/linuxcnc.md).

plasmac runs in a servo thread of ``halrun`` (1 ms, the QtPlasmaC sample configs' SERVO_PERIOD) between
the two functions of the lock-step gate (hal/distctrl_lockstep.comp); the plant
(:mod:`distctrl.linuxcnc.plant`) is a userspace HAL component of this process (Python's ``hal`` module)
that answers every period. Every period of plasmac sees the plant's answer to the period before: the run
is in virtual time and repeatable; the wall clock's misses are counted (``late_periods``: periods that
began before the plant had answered; ``missed_periods``: waits given up, plasmac ran on stale inputs).

The figures, for every contestant (:func:`bench`):

* ``min_distance_mm`` - the minimum true distance of the nozzle over the metal while the torch cuts
  (a G1 move with the torch on; over holes and kerfs there is no metal);
* ``time_below_half_s`` - how long that distance was below half the cut height (s);
* ``collisions`` - contacts with the metal outside probing;
* ``dives`` - entries below half the cut height while cutting, by where: ``hole_kerf`` (the arc's or
  sensor's footprint left the metal within the last 0.1 s), ``corner`` (the path was below 90 % of the
  cut feed within the last 0.1 s), ``other``.
"""
from __future__ import annotations

import math
import re
import statistics
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..control.filters import FilterConfig
from ..sim import run
from ..sim.plates import CutWatch, select_functions
from ..sim.scenario import load_scenario
from .hal_env import HalSession, LinuxCNCError, import_hal, install_component
from .plant import ARC_REACH, OffsetFollower, PathFollower, arc_sensor, program_moves
from .thc import ThcConfig

__all__ = ["PLASMAC_DEFAULTS", "bench", "run_plasmac", "run_distctrl", "DiveCounter", "SERVO_PERIOD"]

#: s: the servo period of the QtPlasmaC sample configs ([EMCMOT] SERVO_PERIOD = 1000000)
SERVO_PERIOD = 0.001
#: plasmac's settings as QtPlasmaC sets them by default (qtplasmac_handler.py's load_plasma_parameters and
#: load_default_material, metric; [GUI_OPTIONS] Mode = 0 of the sample prefs). ``cut-height`` and
#: ``cut-feed-rate`` are the plate's (its SET_DIST and F); ``pierce-height`` twice the cut height (the
#: touch-off's back-off of the plates: 3 mm at 1.5 mm). Each is overridable (``--set pin=value``).
PLASMAC_DEFAULTS = {
    "mode": 0, "arc-fail-delay": 3.0, "arc-ok-high": 250.0, "arc-ok-low": 60.0, "arc-max-starts": 3,
    "restart-delay": 1.0, "arc-voltage-offset": 0.0, "arc-voltage-scale": 1.0, "cornerlock-threshold": 90.0,
    "float-switch-travel": 1.5, "height-per-volt": 0.1, "voidlock-slope": 500, "pid-p-gain": 10.0,
    "pid-i-gain": 0.0, "pid-d-gain": 0.0, "probe-feed-rate": 300.0, "probe-start-height": 25.0,
    "safe-height": 25.0, "thc-delay": 0.5, "thc-sample-counts": 50, "thc-sample-threshold": 1.0,
    "thc-threshold": 1.0, "pierce-delay": 0.0, "cut-volts": 99.0, "use-auto-volts": 1, "thc-enable": 1,
    "torch-enable": 1, "units-per-mm": 1.0, "feed-override": 1.0, "machine-is-on": 1, "homed": 1,
    "ohmic-probe-enable": 0, "ohmic-max-attempts": 0,
}
#: Z axis's share of velocity and acceleration for external offsets (the sample configs' OFFSET_AV_RATIO)
OFFSET_AV_RATIO = 0.5
#: the plasmac run's trace (every 10th period)
TRACE_COLUMNS = ("t", "x", "y", "z_nozzle", "surface", "arc_voltage", "torch_on", "feed_hold", "state",
                 "z_offset", "cornerlock_is_locked", "voidlock_is_locked")
#: plasmac's state-out while it probes (PROBE_HEIGHT, PROBE_DOWN, PROBE_UP, ZERO_HEIGHT): contact is its job
_PROBING = (1, 2, 3, 4)
_WINDOW = 100                  # periods (0.1 s) of the dive classification


class DiveCounter:
    """Counts the dives of one run (module docstring) from per-period samples."""

    def __init__(self, cut_height: float, cut_feed: float, period: float):
        self.half = 0.5 * cut_height
        self.cut_feed = cut_feed
        self.period = period
        self.min_distance = math.inf
        self.below = 0
        self.dives = {"hole_kerf": 0, "corner": 0, "other": 0}
        self._low = False
        self._since_void = _WINDOW + 1
        self._since_slow = _WINDOW + 1

    def sample(self, cutting: bool, on_metal: bool, distance: float, covered: float, speed: float) -> None:
        self._since_void = 0 if covered < 1.0 else self._since_void + 1
        self._since_slow = 0 if speed < 0.9 * self.cut_feed else self._since_slow + 1
        if not (cutting and on_metal):
            self._low = False
            return
        if distance < self.min_distance:
            self.min_distance = distance
        low = distance < self.half
        if low:
            self.below += 1
            if not self._low:
                where = ("hole_kerf" if self._since_void <= _WINDOW else
                         "corner" if self._since_slow <= _WINDOW else "other")
                self.dives[where] += 1
        self._low = low

    def figures(self) -> dict:
        return {"min_distance_mm": self.min_distance if math.isfinite(self.min_distance) else None,
                "time_below_half_s": self.below * self.period, "dives": dict(self.dives),
                "dives_total": sum(self.dives.values())}


# ------------------------------------------------------------------------------------------ plasmac

_IN_PINS = {  # plant pin -> plasmac input pin (how qtplasmac_comp.hal wires motion/halui/the torch)
    "arc-voltage": "arc-voltage-in", "float-switch": "float-switch", "x-pos": "axis-x-position",
    "y-pos": "axis-y-position", "z-pos": "axis-z-position", "current-vel": "current-velocity",
    "feed-upm": "feed-upm", "motion-type": "motion-type", "z-eoffset": "z-offset-current",
    "eoffset-active": "offsets-active", "spindle-on": "cutting-start", "is-running": "program-is-running",
    "is-idle": "program-is-idle", "cornerlock-enable": "cornerlock-enable", "voidlock-enable": "voidlock-enable",
    "z-min": "axis-z-min-limit", "z-max": "axis-z-max-limit", "x-min": "axis-x-min-limit",
    "x-max": "axis-x-max-limit", "y-min": "axis-y-min-limit", "y-max": "axis-y-max-limit",
    "cut-height": "cut-height", "pierce-height": "pierce-height", "cut-feed-rate": "cut-feed-rate",
    "thc-feed-rate": "thc-feed-rate", "setup-feed-rate": "setup-feed-rate",
}
_OUT_PINS = {  # plasmac output pin -> plant pin
    "z-offset-counts": "counts", "offset-scale": "scale", "z-offset-enable": "z-enable",
    "torch-on": "torch-on", "feed-hold": "feed-hold", "state-out": "state", "ohmic-enable": "probing",
    "cornerlock-is-locked": "cl-locked", "voidlock-is-locked": "vl-locked", "arc-ok-out": "arc-ok",
    "program-pause": "pause",
}


@dataclass
class PlateJob:
    """What the bench needs of a plate scenario."""
    scenario: object
    moves: list
    cut_height: float
    pierce_height: float
    cut_feed: float
    z_prog: float

    @classmethod
    def load(cls, path: str | Path) -> "PlateJob":
        sc = load_scenario(path)
        text = sc.program_text or ""
        z = sc.axes.get("Z")
        if z is None:
            raise LinuxCNCError(f"{path}: the bench needs a Z axis ([axes.Z])")
        moves = program_moves(text, start=(sc.axes["X"].start if "X" in sc.axes else 0.0,
                                         sc.axes["Y"].start if "Y" in sc.axes else 0.0))
        cuts = [m for m in moves if m.cut]
        if not cuts:
            raise LinuxCNCError(f"{path}: no G1 cut (X/Y move) in the plate's program")
        found = re.search(r"SET_DIST\s*=\s*([0-9.]+)", text)
        cut_height = float(found.group(1)) if found else 1.5
        return cls(sc, moves, cut_height, 2.0 * cut_height, max(m.feed for m in cuts), z.start)


#: further plasmac inputs ``--set`` may set (besides :data:`PLASMAC_DEFAULTS` and the plate's own)
_MORE_SETTINGS = ("max-offset", "lowpass-frequency", "voidlock-on-cycles", "voidlock-off-cycles", "ok-sample-counts",
                  "ok-sample-threshold", "puddle-jump-height", "puddle-jump-delay", "cornerlock-enable",
                  "voidlock-enable")
_PLATE_SETTINGS = ("cut-height", "pierce-height", "cut-feed-rate", "thc-feed-rate", "setup-feed-rate")


def check_overrides(overrides: dict, settings: dict | None = None) -> None:
    """Raise :class:`LinuxCNCError` for a ``--set`` key that is not a plasmac setting the bench allows."""
    allowed = set(settings or PLASMAC_DEFAULTS) | set(_MORE_SETTINGS) | set(_PLATE_SETTINGS)
    allowed -= {"cornerlock-enable", "voidlock-enable"}        # the bench switches these itself
    for key in overrides:
        if key not in allowed:
            raise LinuxCNCError(f"--set {key}: not a plasmac setting the bench allows ({', '.join(sorted(allowed))})")


def run_plasmac(job: PlateJob, cornerlock: bool, voidlock: bool, overrides: dict | None = None,
                max_time: float | None = None, hal: HalSession | None = None, thc=None) -> dict:
    """One closed-loop run of plasmac on the plate (module docstring); returns its figures. With ``thc`` (a
    :class:`distctrl.linuxcnc.thc.ThcConfig`) the height control of the cut is distctrl's component
    (hal/distctrl_thc.comp): plasmac sequences the cut (probe, pierce, cut height, end) with its THC off
    (thc-enable 0), distctrl_thc runs in the same thread after it, its offset added to plasmac's."""
    install_component("distctrl_lockstep")
    if thc is not None:
        install_component("distctrl_thc")
    own = hal is None
    hs = HalSession() if own else hal
    if own:
        hs.__enter__()
    try:
        return _run_plasmac(hs, job, cornerlock, voidlock, overrides or {}, max_time, thc)
    finally:
        if own:
            hs.__exit__(None, None, None)


def release_gate(name: str = "distctrl-lockstep.0") -> None:
    """Switch the lock-step gate off at once (shared memory, no halcmd): when the plant stops answering,
    the servo thread must not wait in the gate, where it holds uspace's thread lock and starves halcmd."""
    hal = import_hal()
    try:
        hal.set_p(f"{name}.enable", "0")
    except Exception:           # noqa: BLE001 - not loaded (yet): nothing waits
        pass


def _pin_type(hal, value):
    if isinstance(value, bool):
        return hal.HAL_BIT
    return hal.HAL_FLOAT if isinstance(value, float) else hal.HAL_S32


def _run_plasmac(hs: HalSession, job: PlateJob, cornerlock: bool, voidlock: bool, overrides: dict,
                 max_time: float | None, thc=None) -> dict:
    hal = import_hal()
    sc = job.scenario
    T = SERVO_PERIOD
    if abs(sc.cycle_time - T) > 1e-12:
        raise LinuxCNCError(f"the plate's cycle_time is {sc.cycle_time:g} s; the bench runs plasmac at the "
                            f"sample configs' servo period {T:g} s")
    zc = sc.axes["Z"]
    settings = dict(PLASMAC_DEFAULTS)
    thc_feed = zc.v_max * OFFSET_AV_RATIO * 60.0                  # QtPlasmaC's thcFeedRate (mm/min)
    settings.update({"cut-height": job.cut_height, "pierce-height": job.pierce_height,
                     "cut-feed-rate": job.cut_feed * 60.0, "thc-feed-rate": thc_feed,
                     "setup-feed-rate": 0.8 * thc_feed})
    check_overrides(overrides, settings)
    settings.update(overrides)
    if thc is not None:
        settings["thc-enable"] = 0                 # plasmac holds its cut height; distctrl_thc controls it
    surface = sc.surface
    z_min, z_max = surface.base - 20.0, job.z_prog + 30.0
    limits = {"z-min": z_min, "z-max": z_max, "x-min": -1000.0, "x-max": 5000.0, "y-min": -1000.0,
              "y-max": 5000.0}
    # plasmac and the gate in the servo thread; every setting by setp
    dthc = ["loadrt distctrl_thc", "addf distctrl-thc.0 servo-thread", *thc.setp_lines(T)] if thc is not None else []
    hs.cmd(f"loadrt threads name1=servo-thread period1={int(round(T * 1e9))}", "loadrt plasmac",
           "loadrt distctrl_lockstep", "addf distctrl-lockstep.0.wait servo-thread", "addf plasmac servo-thread",
           *dthc, "addf distctrl-lockstep.0.post servo-thread", "setp distctrl-lockstep.0.enable 1",
           *[f"setp plasmac.{k} {v}" for k, v in settings.items() if f"{k}" not in
             ("cut-height", "pierce-height", "cut-feed-rate", "thc-feed-rate", "setup-feed-rate")])
    comp = hal.component("distctrl-plant")
    kinds = {"arc-voltage": 0.0, "float-switch": False, "x-pos": 0.0, "y-pos": 0.0, "z-pos": 0.0,
             "current-vel": 0.0, "feed-upm": 0.0, "motion-type": 0, "z-eoffset": 0.0, "eoffset-active": False,
             "spindle-on": False, "is-running": False, "is-idle": False, "cornerlock-enable": False,
             "voidlock-enable": False, **{k: 0.0 for k in limits}, "cut-height": 0.0, "pierce-height": 0.0,
             "cut-feed-rate": 0.0, "thc-feed-rate": 0.0, "setup-feed-rate": 0.0}
    for name, value in kinds.items():
        comp.newpin(name, _pin_type(hal, value), hal.HAL_OUT)
    for name in _OUT_PINS.values():
        t = hal.HAL_FLOAT if name == "scale" else hal.HAL_S32 if name in ("counts", "state") else hal.HAL_BIT
        comp.newpin(name, t, hal.HAL_IN)
    comp.newpin("seq", hal.HAL_U32, hal.HAL_IN)
    comp.newpin("ack", hal.HAL_U32, hal.HAL_OUT)
    if thc is not None:
        for name, t in (("dthc-enable", hal.HAL_BIT), ("z-cmd", hal.HAL_FLOAT)):
            comp.newpin(name, t, hal.HAL_OUT)
        for name, t in (("dthc-counts", hal.HAL_S32), ("dthc-scale", hal.HAL_FLOAT), ("dthc-state", hal.HAL_S32),
                        ("dthc-error", hal.HAL_S32), ("dthc-cl", hal.HAL_BIT), ("dthc-vl", hal.HAL_BIT)):
            comp.newpin(name, t, hal.HAL_IN)
    comp.ready()
    try:
        nets = [f"net dp-{p} distctrl-plant.{p} => plasmac.{q}" for p, q in _IN_PINS.items()]
        nets += [f"net dp-o-{q} plasmac.{p} => distctrl-plant.{q}" for p, q in _OUT_PINS.items()]
        nets += ["net dp-seq distctrl-lockstep.0.seq => distctrl-plant.seq",
                 "net dp-ack distctrl-plant.ack => distctrl-lockstep.0.ack"]
        if thc is not None:       # distctrl_thc's pins are plasmac's names: the same signals feed it
            t0 = "distctrl-thc.0"
            nets += [f"net dp-arc-voltage {t0}.arc-voltage-in", f"net dp-current-vel {t0}.current-velocity",
                     f"net dp-z-pos {t0}.axis-z-position", f"net dp-cornerlock-enable {t0}.cornerlock-enable",
                     f"net dp-voidlock-enable {t0}.voidlock-enable",
                     f"net dt-enable distctrl-plant.dthc-enable => {t0}.thc-enable",
                     f"net dt-zc distctrl-plant.z-cmd => {t0}.axis-z-command",
                     f"net dp-feed-upm {t0}.feed-upm",
                     f"net dt-counts {t0}.z-offset-counts => distctrl-plant.dthc-counts",
                     f"net dt-scale {t0}.offset-scale => distctrl-plant.dthc-scale",
                     f"net dt-state {t0}.state => distctrl-plant.dthc-state",
                     f"net dt-error {t0}.error-id => distctrl-plant.dthc-error",
                     f"net dt-cl {t0}.cornerlock-is-locked => distctrl-plant.dthc-cl",
                     f"net dt-vl {t0}.voidlock-is-locked => distctrl-plant.dthc-vl"]
        hs.cmd(*nets)
        return _loop(hs, comp, job, settings, limits, cornerlock, voidlock, max_time, thc)
    finally:
        release_gate()
        try:
            hs.cmd("stop")
        except LinuxCNCError:
            pass
        comp.exit()


def _loop(hs, comp, job: PlateJob, settings: dict, limits: dict, cornerlock: bool, voidlock: bool,
          max_time: float | None, thc=None) -> dict:
    sc = job.scenario
    T = SERVO_PERIOD
    zc = sc.axes["Z"]
    surface = sc.surface
    drive = zc.make_drive(T)
    offset = OffsetFollower(zc.v_max * OFFSET_AV_RATIO, zc.a_max * OFFSET_AV_RATIO, T)
    xa = sc.axes.get("X")
    path = PathFollower(job.moves, a_max=xa.a_max if xa else 1000.0, v_rapid=xa.v_max if xa else 500.0,
                        cycle_time=T)
    sensor, note = arc_sensor(sc, T)
    dives = DiveCounter(job.cut_height, job.cut_feed, T)
    travel = float(settings["float-switch-travel"])
    metal_floor = surface.base - 10.0
    limit_periods = int(round((max_time if max_time is not None else sc.duration) / T))
    # constant inputs
    for k, v in limits.items():
        comp[k] = v
    for k in ("cut-height", "pierce-height", "cut-feed-rate", "thc-feed-rate", "setup-feed-rate"):
        comp[k] = float(settings[k])
    comp["cornerlock-enable"] = cornerlock
    comp["voidlock-enable"] = voidlock
    comp["is-running"] = True
    comp["is-idle"] = False
    comp["z-pos"] = drive.actual
    comp["x-pos"], comp["y-pos"] = path.x, path.y
    comp["feed-upm"] = job.cut_feed * 60.0
    thc_delay = int(round(float(settings["thc-delay"]) / T))     # plasmac's THC delay, for distctrl_thc too
    in_cut = 0
    last_dthc_error = 0
    hs.cmd("start")
    phase = "move"               # move | wait-idle (after a cut, until plasmac is idle again) | done
    k = 0
    collisions, contact, arc_periods, cut_started = 0, False, 0, False
    plasmac_errors: list[str] = []
    max_eoffset_err = 0.0
    wall0 = time.perf_counter()
    z_min_seen = math.inf
    idle_wait = 0
    metal_h = surface.base
    trace: list[tuple] = []
    while k < limit_periods:
        s = comp["seq"]
        if s == k:
            time.sleep(0.00005)
            continue
        if s != k + 1:
            plasmac_errors.append(f"the thread ran {s - k} periods at once at period {k}")
        k = s
        counts, scale = comp["counts"], comp["scale"]
        torch, hold = comp["torch-on"], comp["feed-hold"]
        # motion: the path, the spindle (cutting-start) and the external offset
        move = path.move
        if phase == "move":
            if move is None:
                phase = "done"
            elif move.cut and not comp["spindle-on"]:
                comp["spindle-on"] = True          # M3 at the cut's first point
                cut_started = True
            ended = path.step(hold=(hold and move.cut) or (move.cut and not comp["spindle-on"]))
            if ended and move.cut and (path.move is None or not path.move.cut):
                comp["spindle-on"] = False          # M5 at the cut's end
                phase = "wait-idle"
                idle_wait = 0
        elif phase == "wait-idle":
            idle_wait += 1
            if idle_wait > 5 and comp["state"] == 0 and not comp["torch-on"] and not hold:
                phase = "move" if path.move is not None else "done"
        if phase == "done":
            comp["is-running"] = False
            comp["is-idle"] = True
        target = counts * scale if comp["z-enable"] else offset.value
        if thc is not None:
            # distctrl_thc on from plasmac's THC delay into its CUT state (11) with the torch on; off when the
            # cut ends (its TURNING_OFF runs its offset out to 0)
            in_cut = in_cut + 1 if (comp["state"] == 11 and torch) else 0
            comp["dthc-enable"] = in_cut > thc_delay
            plasmac_target = target
            dthc_error = comp["dthc-error"]
            if dthc_error != last_dthc_error and dthc_error:      # its ERROR (the offset held): reported
                plasmac_errors.append(f"distctrl_thc ERROR {dthc_error} at {k * T:.3f} s (x {path.x:.1f}, "
                                      f"y {path.y:.1f})")
            last_dthc_error = dthc_error
            target = target + comp["dthc-counts"] * comp["dthc-scale"]
        eo = offset.step(target)
        z_cmd = job.z_prog + eo
        if thc is not None:
            # p for both encoders (d + c - a, c = p + the component's own offset): the programmed Z plus
            # plasmac's offset as commanded (counts x scale), before motion's external-offset planner, whose
            # lag, like the drive's, is then out of the loop as P-AXIS-00500 intends (with the planner's
            # output the loop oscillated: measured)
            comp["z-cmd"] = job.z_prog + plasmac_target
        drive.step(z_cmd)
        nozzle = drive.nozzle
        x, y = path.x, path.y
        h = surface.height(x, y)
        on_metal = h > metal_floor
        d = nozzle - h
        if nozzle < z_min_seen:
            z_min_seen = nozzle
        if on_metal:
            metal_h = h
        arc = torch and nozzle - metal_h <= ARC_REACH     # over a kerf/hole the arc reaches the metal beside it
        volts = sensor.read(k, nozzle, h, x, y) if arc else 0.0
        if arc:
            arc_periods += 1
        covered = sensor.covered if arc else 1.0
        cutting = bool(torch and arc and move is not None and move.cut and path.v > 0.0)
        dives.sample(cutting, on_metal, d, covered, path.v)
        touching = on_metal and d <= 0.0
        if touching and not contact and comp["state"] not in _PROBING:
            collisions += 1
        contact = touching
        comp["arc-voltage"] = volts
        comp["float-switch"] = on_metal and d <= -travel
        comp["x-pos"], comp["y-pos"] = x, y
        comp["z-pos"] = drive.actual
        comp["current-vel"] = path.v
        comp["motion-type"] = 0 if path.v == 0.0 else (2 if (move is not None and move.cut) else 1)
        comp["z-eoffset"] = eo
        comp["eoffset-active"] = eo != 0.0
        comp["ack"] = k
        if k % 10 == 0:
            locks = (comp["dthc-cl"], comp["dthc-vl"]) if thc is not None else (comp["cl-locked"], comp["vl-locked"])
            trace.append((k * T, x, y, nozzle, h, volts, int(torch), int(hold), comp["state"], eo,
                          int(locks[0]), int(locks[1])))
        if comp["pause"] and phase != "done":
            plasmac_errors.append(f"plasmac paused the program at {k * T:.3f} s (state {comp['state']}, "
                                  f"x {x:.1f}, y {y:.1f})")
            break
        if phase == "done" and comp["state"] == 0 and offset.value == target:
            break
    wall = time.perf_counter() - wall0
    release_gate()
    gate = {name: hs.getp(f"distctrl-lockstep.0.{name}") for name in ("late", "missed", "wait-max", "seq")}
    fig = dives.figures()
    return {"controller": "plasmac" if thc is None else "distctrl-hal",
            "functions": [f for f, on in (("corner_lock", cornerlock), ("void_lock", voidlock)) if on],
            **fig, "collisions": collisions, "periods": k,
            "late_periods": int(gate["late"], 0), "missed_periods": int(gate["missed"], 0),
            "wait_max_s": float(gate["wait-max"]), "wall_s": wall, "completed": phase == "done",
            "cut_started": cut_started, "arc_s": arc_periods * T, "note": note, "warnings": plasmac_errors[:5],
            "trace": {"columns": list(TRACE_COLUMNS), "rows": trace}}


# ------------------------------------------------------------------------------------------ distctrl

class _DiveWatch:
    """A reading PLC program for distctrl's own runs: the same :class:`DiveCounter` as plasmac's."""

    def __init__(self, axis: str, cut_height: float, cut_feed: float, period: float, metal_floor: float):
        self.watch = CutWatch(axis)
        self.dives = DiveCounter(cut_height, cut_feed, period)
        self.metal_floor = metal_floor
        self.period = period
        self._xy = None

    def __call__(self, machine, cycle: int) -> None:
        self.watch(machine, cycle)
        xy = getattr(machine, "true_xy", None)
        if xy is None:
            return
        speed = 0.0 if self._xy is None else math.hypot(xy[0] - self._xy[0], xy[1] - self._xy[1]) / self.period
        self._xy = xy
        cutting = machine.channel_path.motion_type == 2
        sensor = machine.sensor
        covered = getattr(sensor, "covered", 1.0) if sensor is not None else 1.0
        self.dives.sample(cutting, machine.true_surface > self.metal_floor, machine.true_distance, covered, speed)


def run_distctrl(job: PlateJob, functions: bool) -> dict:
    """distctrl's controller with its process functions (``functions``: all of the plate's, else without
    corner lock and void lock) on the same plate, sensor and arc-voltage model (distctrl.sim)."""
    sc = select_functions(job.scenario, True, drop=() if functions else ("corner_lock", "void_lock"))
    axis = sc.sensor.axis if sc.sensor is not None and sc.sensor.axis else "Z"
    watch = _DiveWatch(axis, job.cut_height, job.cut_feed, sc.cycle_time, sc.surface.base - 10.0)
    t0 = time.perf_counter()
    r = run(sc, plc_program=watch, keep_trace=False)
    wall = time.perf_counter() - t0
    fig = watch.dives.figures()
    return {"controller": "distctrl", "functions": [p.function for p in sc.processes], **fig,
            "collisions": r.metrics["collisions"], "periods": r.cycles if hasattr(r, "cycles") else None,
            "late_periods": 0, "missed_periods": 0, "wall_s": wall, "completed": r.completed,
            "errors": [e["id"] for e in r.errors]}


# ------------------------------------------------------------------------------------------ the bench

def _spread(values: list) -> dict:
    vals = [v for v in values if v is not None]
    if not vals:
        return {"mean": None, "min": None, "max": None, "spread": None}
    return {"mean": statistics.fmean(vals), "min": min(vals), "max": max(vals), "spread": max(vals) - min(vals)}


def thc_config(job: PlateJob):
    """distctrl_thc's settings from the plate: its Z axis list's KP, I_TN, D_TV, filter, v_max and a_max
    (at most the external offset's: OFFSET_AV_RATIO of the Z axis's), max_deviation and both encoders
    (P-AXIS-00500), the cut height as SET_DIST, the PLC's arc-voltage linearisation (the sensor's
    plc_v0/plc_k, else its arc's v0/k; the plasma plate's for a plate without an arc-voltage sensor), the
    void lock at distctrl's defaults for a voltage (500 V/s over 20 ms)."""
    sc = job.scenario
    p = sc.axes["Z"].params
    sensor, _ = arc_sensor(sc, sc.cycle_time)
    s = sc.sensor if (sc.sensor is not None and sc.sensor.kind == "arc_voltage") else None
    v0 = s.plc_v0 if s is not None and s.plc_v0 is not None else sensor.v0
    k = s.plc_k if s is not None and s.plc_k is not None else sensor.k
    a_max = p.a_max if p.a_max > 0 else p.axis_a_max
    # motion's external offset follows within OFFSET_AV_RATIO of the Z axis's limits: a law allowed more
    # would see the offset planner's lag as dead time in its loop (it oscillated after corners: measured)
    zc = sc.axes["Z"]
    cfg = ThcConfig(kp=p.kp, i_tn=p.i_tn, d_tv=p.d_tv, use_both_encoders=bool(p.use_both_encoders),
                    filter=FilterConfig(p.filter_type, p.n_cycles, p.smoothing_factor, p.kalman_sigma,
                                        p.low_pass_filter_order, p.low_pass_filter_fg_f0),
                    v_max=min(p.v_max, zc.v_max * OFFSET_AV_RATIO), a_max=min(a_max, zc.a_max * OFFSET_AV_RATIO),
                    max_deviation=p.max_deviation, set_dist=job.cut_height,
                    arc_v0=v0, arc_k=k)
    cfg.check(sc.cycle_time)
    return cfg


def bench(plate: str | Path, repeat: int = 1, overrides: dict | None = None, max_time: float | None = None,
          progress=None) -> dict:
    """The side-by-side comparison (module docstring): plasmac with corner lock and void lock on and off,
    distctrl with its functions and without corner/void lock; each run ``repeat`` times."""
    if repeat < 1:
        raise LinuxCNCError(f"--repeat {repeat}: at least 1")
    check_overrides(overrides or {})
    job = PlateJob.load(plate)
    cases = [("plasmac", True), ("plasmac", False), ("distctrl-hal", True), ("distctrl-hal", False),
             ("distctrl", True), ("distctrl", False)]
    thc = thc_config(job)
    runs = []
    install_component("distctrl_lockstep")
    with HalSession() as hs:
        for controller, on in cases:
            reps = []
            for i in range(repeat):
                if progress:
                    progress(f"{controller} ({'with' if on else 'without'} corner/void lock) run {i + 1}/{repeat}")
                if controller == "plasmac":
                    reps.append(run_plasmac(job, on, on, overrides, max_time, hal=hs))
                    hs._unload()
                elif controller == "distctrl-hal":
                    reps.append(run_plasmac(job, on, on, overrides, max_time, hal=hs, thc=thc))
                    hs._unload()
                else:
                    reps.append(run_distctrl(job, on))
            first = dict(reps[0])
            first["repeats"] = [{k: r[k] for k in ("min_distance_mm", "time_below_half_s", "collisions",
                                                   "dives_total", "late_periods", "missed_periods", "wall_s")}
                                for r in reps]
            first["spread"] = {k: _spread([r[k] for r in reps]) for k in
                               ("min_distance_mm", "time_below_half_s", "collisions", "dives_total")}
            first["late_periods"] = sum(r["late_periods"] for r in reps)
            first["missed_periods"] = sum(r["missed_periods"] for r in reps)
            runs.append(first)
    return {"command": "linuxcnc bench", "plate": str(plate), "scenario": job.scenario.name,
            "cut_height_mm": job.cut_height, "cut_feed_mm_min": job.cut_feed * 60.0, "repeat": repeat,
            "servo_period_s": SERVO_PERIOD, "lock_step": True, "runs": runs}
