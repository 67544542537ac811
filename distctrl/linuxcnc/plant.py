"""The machine around plasmac: what motion, the Z joint and the torch would give it, from distctrl's plate.

Per servo period (docs/linuxcnc.md "The plant"):

* **path** - the plate program's X/Y moves (:func:`program_moves`): rapids at the X/Y axes' v_max, cuts
  at their F, each move planned with the axes' a_max and an exact stop at its end (the 90° corners of the
  plates are stops; LinuxCNC would blend them a little with G64). ``feed-hold`` (plasmac's, wired to
  motion.feed-hold) brakes the path at a_max and holds it. Each cut is one torch start: the spindle
  (``spindle.0.on`` -> ``cutting-start``) comes on at the cut's first point and goes off at its end; the next
  rapid waits until plasmac is idle again (torch off, offset back at the safe height).
* **Z** - the programmed Z stays at the plate's start height (QtPlasmaC's G-code filter removes Z moves);
  plasmac moves the torch with the external offset ``z-offset-counts`` x ``offset-scale``, which motion
  follows with the external-offset limits (OFFSET_AV_RATIO 0.5 of the Z axis's velocity and acceleration,
  as the QtPlasmaC sample configs set); the sum drives distctrl's Z drive model (lag, bus delay,
  resonance) and ``axis-z-position`` is its encoder.
* **torch** - with ``torch-on`` and the nozzle within ``ARC_REACH`` mm of the metal the arc burns, and
  ``arc-voltage-in`` is distctrl's arc-voltage model of the plate (the scenario's ``[sensor]`` when it is an
  arc-voltage sensor; else the plasma plate's model on this plate's surface); no arc: 0 V. Arc OK is
  plasmac's own (mode 0: from the voltage).
* **float switch** - the floating head trips after ``float-switch-travel`` mm of contact.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..sim.plates import EXAMPLES
from ..sim.scenario import load_scenario

__all__ = ["Move", "program_moves", "PathFollower", "OffsetFollower", "ARC_REACH", "arc_sensor"]

#: mm: beyond this height over the metal the arc does not transfer (or breaks)
ARC_REACH = 10.0

_WORD = re.compile(r"([GXYZFN])\s*(-?\d+(?:\.\d*)?|-?\.\d+)", re.I)


@dataclass(frozen=True)
class Move:
    """One straight X/Y move: ``cut`` (G1, torch on) or a rapid (G0); ``feed`` mm/s."""
    x0: float
    y0: float
    x1: float
    y1: float
    feed: float
    cut: bool

    @property
    def length(self) -> float:
        return math.hypot(self.x1 - self.x0, self.y1 - self.y0)


def program_moves(program_text: str, start: tuple[float, float] = (0.0, 0.0)) -> list[Move]:
    """The X/Y moves of a plate program (G0/G1 with X, Y, F words; bracketed commands such as
    ``Z[DIST_CTRL ...]``, comments, #-commands and V.E. lines carry no motion and are skipped). Moves
    without X/Y motion are dropped."""
    x, y = start
    modal, feed = 0, 0.0
    moves: list[Move] = []
    for raw in program_text.splitlines():
        line = raw.split(";", 1)[0]
        line = re.sub(r"\[[^\]]*\]", "", line)
        line = re.sub(r"\([^)]*\)", "", line)
        if "#" in line or "V.E." in line.upper() or not line.strip():
            continue
        words = {}
        for letter, value in _WORD.findall(line):
            letter = letter.upper()
            if letter == "G":
                g = int(float(value))
                if g in (0, 1):
                    modal = g
            else:
                words[letter] = float(value)
        if "F" in words:
            feed = words["F"] / 60.0
        nx, ny = words.get("X", x), words.get("Y", y)
        if (nx, ny) != (x, y):
            moves.append(Move(x, y, nx, ny, feed, modal == 1))
        x, y = nx, ny
    return moves


@dataclass
class PathFollower:
    """Runs :class:`Move` s one after the other with an exact stop at each end (module docstring)."""
    moves: list[Move]
    a_max: float
    v_rapid: float
    cycle_time: float
    index: int = 0
    s: float = 0.0
    v: float = 0.0
    x: float = field(init=False)
    y: float = field(init=False)

    def __post_init__(self) -> None:
        m = self.moves[0]
        self.x, self.y = m.x0, m.y0

    @property
    def done(self) -> bool:
        return self.index >= len(self.moves)

    @property
    def move(self) -> Move | None:
        return None if self.done else self.moves[self.index]

    def speed_limit(self, move: Move) -> float:
        return move.feed if move.cut else self.v_rapid

    def step(self, hold: bool) -> bool:
        """One period along the current move (``hold``: brake and stay). True when the move ended."""
        m = self.move
        if m is None:
            return False
        T, a = self.cycle_time, self.a_max
        rem = m.length - self.s
        target = 0.0 if hold else min(self.speed_limit(m), math.sqrt(max(0.0, 2.0 * a * rem)))
        if target > self.v + a * T:
            self.v += a * T
        elif target < self.v - a * T and not (rem <= self.v * T):
            self.v -= a * T
        else:
            self.v = target
        ds = self.v * T
        ended = False
        if self.s + ds >= m.length or (rem < 1e-9 and not hold):
            self.s, self.v, ended = m.length, 0.0, True
        else:
            self.s += ds
        u = self.s / m.length if m.length else 1.0
        self.x = m.x0 + u * (m.x1 - m.x0)
        self.y = m.y0 + u * (m.y1 - m.y0)
        if ended:
            self.index += 1
            self.s = 0.0
        return ended


@dataclass
class OffsetFollower:
    """motion's external offset: follows ``counts x scale`` within ``v_max`` / ``a_max`` (mm/s, mm/s²)."""
    v_max: float
    a_max: float
    cycle_time: float
    value: float = 0.0
    v: float = 0.0

    def step(self, target: float) -> float:
        T, a = self.cycle_time, self.a_max
        err = target - self.value
        dv = a * T
        if abs(err) <= 1e-12 and abs(self.v) <= dv:
            self.value, self.v = target, 0.0           # arrived (plasmac compares the offset to its target)
            return self.value
        # braking curve, and never past the target within one period
        want = math.copysign(min(self.v_max, math.sqrt(2.0 * a * abs(err)), abs(err) / T), err)
        self.v = min(max(want, self.v - dv), self.v + dv)
        nxt = self.value + self.v * T
        self.value = target if (target - nxt) * err <= 0.0 else nxt
        return self.value


def arc_sensor(scenario, cycle_time: float):
    """The arc-voltage model on the scenario's plate: the scenario's own sensor when it is an arc-voltage
    sensor, else the plasma plate's arc model (examples/scenarios/plasma_plate.toml [sensor]) on this
    plate's surface. Returns ``(sensor, note)``."""
    sc = scenario
    note = ""
    if sc.sensor is None or sc.sensor.kind != "arc_voltage":
        ref = load_scenario(EXAMPLES / "plasma_plate.toml").sensor
        note = ("this plate's sensor is not an arc-voltage sensor: plasmac sees the plasma plate's arc-voltage "
                "model (v0, k, ripple, noise, kerf jump, footprint) on this plate's surface")
        s = ref
    else:
        s = sc.sensor
    z = sc.axes[s.axis or "Z"]
    return s.make_sensor(cycle_time, z.params, sc.surface), note
