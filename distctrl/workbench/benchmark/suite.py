"""The benchmark's standard suite (issue 41): plates, sensors, drives and feeds from a few documented
parameters (:class:`SuiteParams`, docs/benchmark.md "The suite").

A *plate* (:class:`Plate`) is a surface and a path along it with what the metrics need to know of it:
where the surface is plain and known (the steady windows), where it has voids (holes, kerfs, beyond the
edge) and corners, and the sheet without its voids. A *run* (:class:`RunSpec`) is a plate with a
process (laser: capacitive sensor; plasma: arc voltage), a sensor variant, a drive, a feed and a
contestant; :func:`scenario_dict` makes the simulator's scenario of it (the plates, sensor and drive
models of ``distctrl.sim``: no physics of its own). Units: mm, s, mm/s, m/min for the feeds.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

from ...sim.surface import surface_from_config

__all__ = ["SuiteParams", "Plate", "RunSpec", "Zone", "PLATE_NAMES", "CONTESTANTS", "CONTESTANT_TEXT",
           "NOT_RUN_CONTESTANTS",
           "plates", "runs", "scenario_dict", "program_text", "EXAMPLES"]

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "scenarios"

#: the plates of the suite, in report order
PLATE_NAMES = ("flat", "ramp_2deg", "ramp_5deg", "wavy", "edge", "holes", "kerfs", "corners", "warp")
#: the contestants run now
CONTESTANTS = ("distctrl_examples", "distctrl_examples_pf", "simple_pid")
#: what each contestant is, for the tables
CONTESTANT_TEXT = {
    "distctrl_examples": "distctrl, the examples' list (z_laser.lis / z_plasma.lis), no process functions",
    "distctrl_examples_pf": "the same with the corner lock and the void lock at their defaults",
    "simple_pid": "a plain PID (simple-pid) on the same sensor: Z velocity from the distance error",
}
#: issue 41's contestants that this version does not run (named in every table, with the reason)
NOT_RUN_CONTESTANTS = {
    "distctrl_tuned": "distctrl tuned by `distctrl tune` on the suite: tune does not aim at the suite yet",
    "plasmac_defaults": "LinuxCNC plasmac at QtPlasmaC's defaults through the halrun bench: not wired yet",
    "plasmac_tuned": "plasmac tuned by the same tuner: needs the bench and the suite-aware tuner",
}


@dataclass(frozen=True)
class SuiteParams:
    """The few parameters the whole suite is generated from (docs/benchmark.md)."""

    cycle_time: float = 0.001                 # s: the GEO cycle
    laser_feeds: tuple = (1.0, 5.0, 10.0, 20.0, 30.0, 40.0)     # m/min
    plasma_feeds: tuple = (0.5, 1.0, 2.0, 5.0, 10.0)            # m/min
    kv: float = 60.0                          # 1/s: the Z drive's position-loop gain
    feedforwards: tuple = (0.0, 1.0)          # the Z drive's velocity feed-forward
    laser_set_mm: float = 1.0                 # laser nozzle distance
    plasma_set_mm: float = 1.5                # plasma cut height
    approach_mm: float = 2.0                  # the head starts this far above the set distance
    dwell_s: float = 0.3                      # at rest after the select (the approach), then the cut starts
    laser_noise_mm: float = 0.002             # capacitive sensor noise (1 kHz); 5 kHz: / sqrt(5)
    laser_footprint_mm: float = 3.0           # the capacitive electrode's radius
    plasma_footprint_mm: float = 1.0          # where the arc root may attach
    bursts: tuple = (2.0, 0.02, 0.05, -0.05)  # plume bursts on the flat plate: rate 1/s, s, std mm, offset mm
    ramp_rise_max_mm: float = 8.0             # a ramp rises at most this (inside the lists' max_deviation)
    ramp_time_s: float = 0.4                  # a ramp lasts this long at the feed (rise 1 mm .. the max)
    wave_pp_mm: float = 0.5                   # waviness peak to peak
    wavelength_mm: float = 100.0              # waviness wavelength
    warp_mm: float = 4.0                      # the warp's rise
    warp_length_mm: float = 150.0             # over this length (half a cosine)
    hole_diameter_mm: float = 10.0
    holes: int = 3
    hole_pitch_mm: float = 30.0
    laser_kerf_mm: float = 0.3                # kerf width crossed (laser)
    plasma_kerf_mm: float = 1.5               # kerf width crossed (plasma)
    kerfs: int = 4
    kerf_pitch_mm: float = 20.0
    corner_side_mm: float = 40.0              # the square with four 90 degree corners (on a 2 degree ramp)
    void_depth_mm: float = 40.0               # holes, kerfs, beyond the edge: out of the sensor's reach
    laser_a_mm_s2: float = 10000.0            # X/Y acceleration, laser machine
    plasma_a_mm_s2: float = 1000.0            # X/Y acceleration, plasma machine
    settle_s: float = 0.08                    # the steady window starts this long after a feature / the feed
    in_position_mm: float = 0.1               # approach: in position within this band
    in_position_hold_s: float = 0.02          # ... held this long


@dataclass(frozen=True)
class Zone:
    """A region of the nozzle's X/Y: an X interval (``kind = "x"``: ``lo <= x <= hi``) or a disc around a
    point (``kind = "disc"``: ``(x - lo)^2 + (y - hi)^2 <= r^2``)."""

    kind: str
    lo: float
    hi: float
    r: float = 0.0

    def mask(self, x, y):
        if self.kind == "x":
            return (x >= self.lo) & (x <= self.hi)
        return (x - self.lo) ** 2 + (y - self.hi) ** 2 <= self.r ** 2


@dataclass(frozen=True)
class Plate:
    """A plate of the suite for one process and feed: its surface, the sheet without the voids, the path
    (X/Y points from the start), where the surface is plain (``steady``: X intervals on the straight
    plates), its ``voids`` and ``corners`` zones (the min distance is taken there), the slope under the
    steady zones (mm/mm along the path, for the drive-lag figure)."""

    name: str
    process: str
    surface: dict
    sheet: dict
    path: tuple
    steady: tuple = ()
    voids: tuple = ()
    corners: tuple = ()
    start_height: float = 0.0          # the surface under the start point (mm)


def _flat(base=0.0):
    return {"base": base, "features": []}


def plates(p: SuiteParams, process: str, feed_m_min: float) -> list[Plate]:
    """The suite's plates for ``process`` ("laser" or "plasma") at a feed (lengths follow the feed)."""
    v = feed_m_min * 1000.0 / 60.0
    r_fp = p.laser_footprint_mm if process == "laser" else p.plasma_footprint_mm
    a = p.laser_a_mm_s2 if process == "laser" else p.plasma_a_mm_s2
    lead = max(10.0, v * v / (2 * a) + 5.0)          # accelerate to the feed before the plate's feature
    deep = -p.void_depth_mm
    out = []
    steady_len = max(60.0, min(200.0, v * 0.6))
    out.append(Plate("flat", process, _flat(), _flat(), ((lead + steady_len + lead, 0.0),),
                     steady=(Zone("x", lead, lead + steady_len),)))
    for name, deg in (("ramp_2deg", 2.0), ("ramp_5deg", 5.0)):
        tan = math.tan(math.radians(deg))
        rise = min(p.ramp_rise_max_mm, max(1.0, tan * v * p.ramp_time_s))
        length = rise / tan
        surf = {"base": 0.0, "features": [{"type": "ramp", "axis": "X", "start": lead, "end": lead + length,
                                           "height": rise}]}
        # the steady zone: where the footprint sees the ramp alone, not its kinks
        out.append(Plate(name, process, surf, surf, ((lead + length + 10.0, 0.0),),
                         steady=(Zone("x", lead + r_fp, lead + length - r_fp),)))
    amp = p.wave_pp_mm / 2
    wavy_len = max(2 * p.wavelength_mm, min(4 * p.wavelength_mm, v * 0.6))
    surf = {"base": 0.0, "features": [{"type": "sine", "axis": "X", "amplitude": amp,
                                       "wavelength": p.wavelength_mm}]}
    out.append(Plate("wavy", process, surf, surf, ((lead + wavy_len, 0.0),),
                     steady=(Zone("x", lead, lead + wavy_len),)))
    edge = lead + 60.0
    surf = {"base": 0.0, "features": [{"type": "step", "axis": "X", "at": edge, "height": deep}]}
    out.append(Plate("edge", process, surf, _flat(), ((edge + 10.0, 0.0),),
                     steady=(Zone("x", lead, edge - r_fp),),
                     voids=(Zone("x", edge - r_fp, edge + 10.0),)))
    d = p.hole_diameter_mm
    centres = [lead + 20.0 + i * p.hole_pitch_mm for i in range(p.holes)]
    surf = {"base": 0.0, "features": [{"type": "holes", "diameter": d, "height": deep,
                                       "centers": [[c, 0.0] for c in centres]}]}
    gaps = [Zone("x", lead, centres[0] - d / 2 - r_fp)] + [
        Zone("x", c0 + d / 2 + r_fp, c1 - d / 2 - r_fp) for c0, c1 in zip(centres, centres[1:])]
    out.append(Plate("holes", process, surf, _flat(), ((centres[-1] + 20.0, 0.0),), steady=tuple(gaps),
                     voids=tuple(Zone("x", c - d / 2 - r_fp, c + d / 2 + r_fp) for c in centres)))
    w = p.laser_kerf_mm if process == "laser" else p.plasma_kerf_mm
    starts = [lead + 10.0 + i * p.kerf_pitch_mm for i in range(p.kerfs)]
    surf = {"base": 0.0, "features": [{"type": "step", "axis": "X", "at": s, "height": deep, "width": w}
                                      for s in starts]}
    gaps = [Zone("x", lead, starts[0] - r_fp)] + [Zone("x", s0 + w + r_fp, s1 - r_fp)
                                                 for s0, s1 in zip(starts, starts[1:])]
    out.append(Plate("kerfs", process, surf, _flat(), ((starts[-1] + 10.0, 0.0),), steady=tuple(gaps),
                     voids=tuple(Zone("x", s - r_fp, s + w + r_fp) for s in starts)))
    s = p.corner_side_mm
    tan2 = math.tan(math.radians(2.0))
    surf = {"base": 0.0, "features": [{"type": "tilted_plane", "sx": tan2}]}
    pts = ((s, 0.0), (s, s), (0.0, s), (0.0, 0.0))
    out.append(Plate("corners", process, surf, surf, pts,
                     steady=(), corners=tuple(Zone("disc", cx, cy, r_fp + 5.0) for cx, cy in pts)))
    warp_len = p.warp_length_mm
    surf = {"base": 0.0, "features": [{"type": "sine", "axis": "X", "amplitude": p.warp_mm / 2,
                                       "wavelength": 2 * warp_len, "phase": -math.pi / 2 - 2 * math.pi * lead
                                       / (2 * warp_len)}]}
    out.append(Plate("warp", process, surf, surf, ((lead + warp_len + 10.0, 0.0),),
                     steady=(Zone("x", lead + r_fp, lead + warp_len - r_fp),)))
    return [dataclasses.replace(pl, start_height=_height(pl.surface, 0.0, 0.0)) for pl in out]


def _height(surface_cfg: dict, x: float, y: float) -> float:
    return float(surface_from_config(surface_cfg).height(x, y))


@dataclass(frozen=True)
class RunSpec:
    """One run of the suite: a plate (by name), process, sensor variant ("1kHz", "5kHz" for the laser,
    "arc" for plasma), the Z drive's feed-forward, the feed (m/min) and the contestant."""

    plate: str
    process: str
    sensor: str
    feedforward: float
    feed: float
    contestant: str
    params: SuiteParams = field(default_factory=SuiteParams, compare=False, repr=False)

    @property
    def key(self) -> tuple:
        return (self.plate, self.process, self.sensor, self.feedforward, self.feed, self.contestant)

    def plate_obj(self) -> Plate:
        return next(pl for pl in plates(self.params, self.process, self.feed) if pl.name == self.plate)

    @property
    def set_mm(self) -> float:
        return self.params.laser_set_mm if self.process == "laser" else self.params.plasma_set_mm


#: what --quick runs: a few plates, feeds, one sensor, both drives
QUICK = {"plates": ("ramp_2deg", "holes"), "laser_feeds": (10.0, 30.0), "plasma_feeds": (5.0,),
         "laser_sensors": ("1kHz",)}


def runs(p: SuiteParams, *, quick: bool = False, plates_only: tuple | None = None,
         contestants: tuple = CONTESTANTS, processes: tuple = ("laser", "plasma")) -> list[RunSpec]:
    """Every run of the suite (``quick``: the smoke test's few)."""
    names = QUICK["plates"] if quick else PLATE_NAMES
    if plates_only:
        names = tuple(n for n in names if n in plates_only)
    out = []
    for process in processes:
        feeds = (QUICK["laser_feeds"] if quick else p.laser_feeds) if process == "laser" else \
            (QUICK["plasma_feeds"] if quick else p.plasma_feeds)
        sensors = (QUICK["laser_sensors"] if quick else ("1kHz", "5kHz")) if process == "laser" else ("arc",)
        for name in names:
            for sensor in sensors:
                for ff in p.feedforwards:
                    for feed in feeds:
                        for c in contestants:
                            out.append(RunSpec(name, process, sensor, ff, feed, c, p))
    return out


def program_text(spec: RunSpec, plate: Plate) -> str:
    """The NC program of the distctrl contestant: select above the start, approach at rest (the dwell),
    cut the path at the feed, deselect."""
    p = spec.params
    z0 = plate.start_height + spec.set_mm + p.approach_mm
    lines = ["%BENCH", f"N10 G90 G0 X0 Y0 Z{z0:.4f}",
             "N20 Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]",
             f"N30 Z[DIST_CTRL ON CONST_DIST SET_DIST={spec.set_mm:g}]",
             f"N40 #TIME {p.dwell_s:g}"]
    n = 50
    for i, (x, y) in enumerate(plate.path):
        feed = f" F{spec.feed * 1000.0:g}" if i == 0 else ""
        lines.append(f"N{n} G1 X{x:.4f} Y{y:.4f}{feed}")
        n += 10
    lines += [f"N{n} Z[DIST_CTRL OFF]", f"N{n + 10} M30", ""]
    return "\n".join(lines)


def scenario_dict(spec: RunSpec, plate: Plate) -> dict:
    """The simulator's scenario (``distctrl.sim.scenario.scenario_from_dict``) of a run."""
    p = spec.params
    laser = spec.process == "laser"
    a = p.laser_a_mm_s2 if laser else p.plasma_a_mm_s2
    z0 = plate.start_height + spec.set_mm + p.approach_mm
    lis = EXAMPLES / ("z_laser.lis" if laser else "z_plasma.lis")
    sensor: dict = {"axis": "Z", "variable": "SENSOR", "seed": 41}
    if laser:
        fast = spec.sensor == "5kHz"
        sensor.update(kind="distance", range_max=9.0, footprint_radius=p.laser_footprint_mm,
                      noise_std=p.laser_noise_mm / (math.sqrt(5.0) if fast else 1.0),
                      delay_cycles=0 if fast else 1)
        if plate.name == "flat":
            rate, dur, amp, off = p.bursts
            sensor["bursts"] = {"rate": rate, "duration": dur, "amplitude": amp, "offset": off}
    else:
        # the plasma plate's arc (examples/scenarios/plasma_plate.toml), its slow-down at the run's feed
        sensor.update(kind="arc_voltage", voltage_variable="ARC_VOLTAGE", arc_v0=95.0, arc_k=6.0,
                      arc_ripple=2.0, arc_noise_std=0.3, kerf_jump=30.0,
                      footprint_radius=p.plasma_footprint_mm, range_max=4.5,
                      arc_speed_volts=10.0, arc_cut_speed=spec.feed * 1000.0 / 60.0)
    return {"name": f"{plate.name} {spec.process} {spec.sensor} ff{spec.feedforward:g} {spec.feed:g} m/min",
            "cycle_time": p.cycle_time, "program_text": program_text(spec, plate), "settle_time": 0.0,
            "axes": {"X": {"v_max": 1000.0, "a_max": a}, "Y": {"v_max": 1000.0, "a_max": a},
                     "Z": {"params": str(lis), "start": z0, "kv": p.kv, "v_max": 300.0, "a_max": 20000.0,
                           "feedforward": spec.feedforward}},
            "surface": plate.surface, "sensor": sensor}
