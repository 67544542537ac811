"""The excitation program of ``distctrl excite``: an NC program in the ISG dialect (docs/nc.md) that
moves one axis so that ``distctrl identify`` gets what it needs (docs/identify.md "What to record"):

1. **steps** of the set position (``G0``, every ``step_dwell`` s, alternating up and down around the
   working height), and one large step at a safe height;
2. a **chirp** of the set position, ``f0``..``f1`` Hz, sampled at the CNC cycle: one ``G1`` block per
   sample that changes the position (0.1 µm), each with the feed that covers it in the time since the
   last one (``F`` = distance / time), so the program carries its own time base: a CNC that runs a
   block per cycle and does not stop between blocks in the same direction (look-ahead; distctrl's NC
   does) plays it at the written rate. Above ``f_acc`` the amplitude falls as ``1/f^2`` so that the
   sine's acceleration stays within :data:`ACCEL_SHARE` of the axis's ``a_max``;
3. a slow **ramp** over the sensor's range, then a dwell at standstill.

It starts with a rapid approach to the working height from the safe height and ends with a retract to
it and ``M30``. Distance control stays off: the program contains no ``[DIST_CTRL ON]``.

Pure: text in, text out; the checks raise :class:`ExciteError` (an edge error naming the option).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..errors import DistCtrlError

#: docs/identify.md's recommended ranges
CHIRP_AMPLITUDE = (0.02, 0.05)       # mm
STEP_SIZE = (0.2, 0.5)               # mm
RAMP_SPEED = (0.2, 0.5)              # mm/s
#: nozzle amplitude at a resonance, as a multiple of the motor's (1/(2 zeta), zeta ~0.05)
RESONANCE_GAIN = 10.0
#: the share of the axis's a_max the chirp's sine may use ((2 pi f)^2 x amplitude); the rest is margin
#: for the drive's following error and the chirp's sweep
ACCEL_SHARE = 0.8


def accel_corner(amplitude: float, a_max: float) -> float:
    """The frequency (Hz) above which a sine of ``amplitude`` (mm) would need more than
    :data:`ACCEL_SHARE` x ``a_max``: the chirp's amplitude falls as ``1/f^2`` above it."""
    return math.sqrt(ACCEL_SHARE * a_max / amplitude) / (2 * math.pi)


class ExciteError(DistCtrlError, ValueError):
    """An excitation the given limits do not allow, or an option out of its range."""


@dataclass(frozen=True)
class Excitation:
    axis: str = "Z"
    work: float = 0.0               # working height (machine coordinates, mm): steps and chirp around it
    safe: float = 10.0              # safe height for approach, retract and the large step
    min_pos: float = -math.inf      # the axis's limits the program must stay within
    max_pos: float = math.inf
    a_max: float = 5000.0           # mm/s², the axis's acceleration (per-cycle G1 blocks)
    v_max: float = 100.0            # mm/s, the axis's velocity
    cycle_time: float = 0.001
    step: float | None = 0.3        # mm; None: no steps
    step_count: int = 10
    step_dwell: float = 0.5
    large_step: float = 3.0         # mm, at the safe height (0: none)
    chirp: tuple[float, float] | None = (1.0, 150.0)
    chirp_seconds: float = 20.0
    amplitude: float = 0.05
    ramp: tuple[float, float] | None = None   # (from, to) positions, mm
    ramp_speed: float = 0.3
    surface: float | None = None    # the sheet's height (machine coordinates): distance checks


def _bounds(lo: float, lo_open: bool, hi: float, option: str) -> str:
    """``allowed a <= --option <= b`` (``<`` for an open end), or why nothing is allowed."""
    if lo > hi or (lo_open and lo == hi):
        return (f"no {option} fits ({_num(lo)} .. {_num(hi)} mm is empty): widen --min/--max, lower "
                f"--steps/--amplitude/--large-step or move --surface")
    return f"allowed {_num(lo)} {'<' if lo_open else '<='} {option} <= {_num(hi)}"


def check(e: Excitation) -> list[str]:
    """Raise :class:`ExciteError` for an excitation beyond the limits; the warnings (outside the
    recommended ranges) as a list.

    Every height the program commands is checked against the axis limits and, with ``surface``,
    against the sheet: the working band (``work``, ``work + step``, ``work`` ± the chirp amplitude), the
    safe height and its large step (approach, large step, retract), the ramp's ends. The safe height is
    above the working band. A refusal names the option, its value and the range it may take."""
    warnings = []
    if not (e.min_pos < e.max_pos):
        raise ExciteError(f"--min {_num(e.min_pos)}: must be below --max {_num(e.max_pos)}")
    if e.cycle_time <= 0 or e.a_max <= 0 or e.v_max <= 0:
        raise ExciteError("the cycle time, a_max and v_max must be > 0")
    up = down = 0.0              # the working band around --work: work - down .. work + up
    if e.step:
        if e.step <= 0:
            raise ExciteError(f"--steps {e.step}: a step must be > 0 mm")
        up = max(up, e.step)
        if not STEP_SIZE[0] <= e.step <= STEP_SIZE[1]:
            warnings.append(f"--steps {e.step} mm: docs/identify.md recommends {STEP_SIZE[0]}-{STEP_SIZE[1]} mm")
    if e.chirp:
        f0, f1 = e.chirp
        if not (0 < f0 < f1 <= 0.5 / e.cycle_time):
            raise ExciteError(f"--chirp {f0:g}-{f1:g}: need 0 < f0 < f1 <= {0.5 / e.cycle_time:g} Hz "
                              f"(half the cycle rate)")
        if e.amplitude <= 0:
            raise ExciteError(f"--amplitude {e.amplitude}: must be > 0 mm")
        up, down = max(up, e.amplitude), max(down, e.amplitude)
        if not CHIRP_AMPLITUDE[0] <= e.amplitude <= CHIRP_AMPLITUDE[1]:
            warnings.append(f"--amplitude {e.amplitude} mm: docs/identify.md recommends "
                            f"{CHIRP_AMPLITUDE[0]}-{CHIRP_AMPLITUDE[1]} mm (the drive's following error stays small)")
        f_acc = accel_corner(e.amplitude, e.a_max)
        if f1 > f_acc:
            warnings.append(f"--amplitude {e.amplitude} mm needs more than {ACCEL_SHARE:.0%} of --a-max {e.a_max:g} "
                            f"mm/s² above {f_acc:.1f} Hz: the chirp's amplitude falls as 1/f² there, to "
                            f"{e.amplitude * (f_acc / f1) ** 2:.4f} mm at {f1:g} Hz")
        v_peak = 2 * math.pi * min(f1, f_acc) * e.amplitude
        if v_peak > e.v_max:
            raise ExciteError(f"--amplitude {e.amplitude} mm at {f1:g} Hz needs {v_peak:.1f} mm/s, beyond the axis's "
                              f"v_max {e.v_max:g} mm/s: lower the amplitude or the top frequency")
    if e.ramp and e.ramp_speed <= 0:
        raise ExciteError(f"--ramp-speed {e.ramp_speed}: must be > 0 mm/s")
    if e.ramp and not RAMP_SPEED[0] <= e.ramp_speed <= RAMP_SPEED[1]:
        warnings.append(f"--ramp-speed {e.ramp_speed} mm/s: docs/identify.md recommends "
                        f"{RAMP_SPEED[0]}-{RAMP_SPEED[1]} mm/s")
    _check_heights(e, up, down)
    return warnings


def _check_heights(e: Excitation, up: float, down: float) -> None:
    """The heights against the limits, the surface and each other (see :func:`check`); ``up``/``down``:
    the working band around ``work`` (steps, chirp amplitude)."""
    lim_min, lim_max = f"--min {_num(e.min_pos)}", f"--max {_num(e.max_pos)}"
    sheet = f"the surface --surface {_num(e.surface)}" if e.surface is not None else ""
    # the lowest the nozzle may get: the chirp's amplitude x RESONANCE_GAIN at a resonance, else the band
    ring = e.amplitude * RESONANCE_GAIN if e.chirp else 0.0
    below = max(ring, down)
    # --work: the band within the limits and above the sheet
    w_lo, w_open = e.min_pos + down, False
    if e.surface is not None and e.surface + below >= w_lo:
        w_lo, w_open = e.surface + below, True
    w_hi = e.max_pos - up
    allowed = _bounds(w_lo, w_open, w_hi, "--work")
    if e.work > w_hi:
        raise ExciteError(f"--work {_num(e.work)}: the working heights reach {_num(e.work + up)} mm "
                          f"(+{_num(up)} mm of --steps/--amplitude), beyond the axis limit {lim_max}; "
                          f"{allowed}")
    if e.work - down < e.min_pos:
        raise ExciteError(f"--work {_num(e.work)}: the chirp reaches {_num(e.work - down)} mm, beyond the "
                          f"axis limit {lim_min}; {allowed}")
    if e.surface is not None and e.work - below <= e.surface:
        cause = (f"the nozzle could reach {_num(e.work - below)} mm (the chirp amplitude "
                 f"{_num(e.amplitude)} mm x {RESONANCE_GAIN:g} at a resonance, docs/identify.md), at or "
                 f"below {sheet}" if ring else f"the working height is at or below {sheet}")
        raise ExciteError(f"--work {_num(e.work)}: {cause}; {allowed}")
    # --safe: above the working band and the sheet; with its large step within --max
    top = e.work + up
    s_lo = max(top, e.surface) if e.surface is not None else top
    allowed = _bounds(s_lo, True, e.max_pos - (e.large_step or 0.0), "--safe")
    if e.safe <= s_lo:
        where = (f"at or below {sheet}" if e.surface is not None and e.safe <= e.surface else
                 f"not above the working heights (--work {_num(e.work)}"
                 + (f" + {_num(up)} mm of --steps/--amplitude = {_num(top)} mm)" if up else ")"))
        raise ExciteError(f"--safe {_num(e.safe)}: the safe height (approach, large step, retract) is "
                          f"{where}; {allowed}")
    if e.safe > e.max_pos:
        raise ExciteError(f"--safe {_num(e.safe)}: beyond the axis limit {lim_max}; {allowed}")
    if e.large_step and e.safe + e.large_step > e.max_pos:
        raise ExciteError(f"--large-step {_num(e.large_step)}: the large step from --safe {_num(e.safe)} "
                          f"reaches {_num(e.safe + e.large_step)} mm, beyond the axis limit {lim_max}; "
                          f"{_bounds(0.0, False, e.max_pos - e.safe, '--large-step')}")
    if e.ramp:
        above_sheet = e.surface is not None and e.surface >= e.min_pos
        r_lo, r_open = (e.surface, True) if above_sheet else (e.min_pos, False)
        for end in e.ramp:
            if end < r_lo or (r_open and end == r_lo) or end > e.max_pos:
                where = (f"at or below {sheet}" if r_open and end <= r_lo else
                         f"beyond the axis limit {lim_max if end > e.max_pos else lim_min}")
                raise ExciteError(f"--ramp {_num(e.ramp[0])}:{_num(e.ramp[1])}: {_num(end)} mm is {where}; "
                                  f"{_bounds(r_lo, r_open, e.max_pos, 'FROM, TO')}")


def _num(x: float) -> str:
    text = f"{x:.4f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _as_written(e: Excitation) -> Excitation:
    """``e`` with its heights at the 0.1 µm the program writes them with: the checks see the written Z."""
    def r(x: float) -> float:
        return float(_num(x))

    return replace(e, work=r(e.work), safe=r(e.safe),
                   large_step=r(e.large_step) if e.large_step else e.large_step,
                   ramp=(r(e.ramp[0]), r(e.ramp[1])) if e.ramp else None)


@dataclass(frozen=True)
class ExciteProgram:
    text: str                 # the NC program
    warnings: list[str]       # outside docs/identify.md's recommended ranges
    seconds: float            # running time: dwells, chirp, ramp and the rapids at v_max (no acceleration)


def program(e: Excitation) -> tuple[str, list[str]]:
    """The NC program text and the warnings; raises :class:`ExciteError` when the limits forbid it."""
    p = build(e)
    return p.text, p.warnings


def build(e: Excitation) -> ExciteProgram:
    """The NC program, its warnings and running time; raises :class:`ExciteError` when the limits or the
    surface forbid it (every height it commands is checked, :func:`check`)."""
    e = _as_written(e)
    warnings = check(e)
    ax, T = e.axis, e.cycle_time
    # the running time: the rapids at v_max from the safe height on (where the program starts from is unknown)
    clock = {"s": 0.0, "z": e.safe}

    def move(z: float, speed: float | None = None) -> None:
        clock["s"] += abs(z - clock["z"]) / (speed or e.v_max)
        clock["z"] = z

    def wait(seconds: float) -> None:
        clock["s"] += seconds

    feed = _num(e.v_max * 60.0)
    out = [f"%EXCITE_{ax}",
           f"; distctrl excite: the excitation of axis {ax} for distctrl identify (docs/identify.md)",
           "; distance control stays OFF throughout: run it above a flat sheet, record with distctrl machine record",
           f"N10 G90 G0 {ax}{_num(e.safe)}                 ; safe height",
           f"N20 G0 {ax}{_num(e.work)}                 ; approach the working height"]
    n = 30

    def add(text: str) -> None:
        nonlocal n
        out.append(f"N{n} {text}")
        n += 10

    move(e.work)
    add("#TIME 1")
    wait(1.0)
    if e.step:
        out.append(f"; steps of {_num(e.step)} mm every {_num(e.step_dwell)} s")
        for k in range(e.step_count):
            add(f"G0 {ax}{_num(e.work + (e.step if k % 2 == 0 else 0.0))}")
            add(f"#TIME {_num(e.step_dwell)}")
            move(e.work + (e.step if k % 2 == 0 else 0.0))
            wait(e.step_dwell)
    if e.chirp:
        f0, f1 = e.chirp
        steps = int(round(e.chirp_seconds / T))
        f_acc = accel_corner(e.amplitude, e.a_max)
        out.append(f"; chirp {f0:g}-{f1:g} Hz in {e.chirp_seconds:g} s, amplitude {_num(e.amplitude)} mm"
                   + (f" (falling as 1/f^2 above {f_acc:.1f} Hz to {e.amplitude * (f_acc / f1) ** 2:.4f} mm: "
                      f"{ACCEL_SHARE:.0%} of a_max {e.a_max:g} mm/s^2)" if f1 > f_acc else ""))
        out.append(f"; sampled every {T * 1e3:g} ms: a block per change, its F = its distance / its time")
        out.append(f"; played at {f0:g}-{f1:g} Hz by a CNC that runs a block per cycle without stopping between")
        out.append("; blocks in the same direction (distctrl's NC does); a slower CNC plays it slower: check the recording")
        add(f"G1 F{feed}")
        k_rate = (f1 - f0) / e.chirp_seconds
        last, last_z, last_k = _num(e.work), float(_num(e.work)), 0
        f_max = e.v_max * 60.0
        for k in range(1, steps + 1):
            t = k * T
            fade = min(1.0, t / 0.1, (e.chirp_seconds - t) / 0.1)     # 0.1 s fade in and out
            f = f0 + k_rate * t
            amp = e.amplitude * (1.0 if f <= f_acc else (f_acc / f) ** 2)
            z = e.work + amp * max(fade, 0.0) * math.sin(2 * math.pi * (f0 * t + 0.5 * k_rate * t * t))
            text = _num(z)
            if text != last:
                zk = float(text)
                # the feed that covers the step in the (k - last_k) cycles since the last block, rounded up
                fk = min(math.ceil(round(abs(zk - last_z) / ((k - last_k) * T) * 60.0 * 1e4, 3)) / 1e4, f_max)
                out.append(f"{ax}{text} F{_num(fk)}")
                last, last_z, last_k = text, zk, k
        add(f"G0 {ax}{_num(e.work)}")
        add("#TIME 0.5")
        move(e.work)
        wait(steps * T + 0.5)
    if e.ramp:
        a, b = e.ramp
        out.append(f"; slow ramp {_num(a)} -> {_num(b)} mm at {_num(e.ramp_speed)} mm/s, then 1 s at standstill")
        add(f"G0 {ax}{_num(a)}")
        add("#TIME 0.5")
        add(f"G1 {ax}{_num(b)} F{_num(e.ramp_speed * 60)}")
        add("#TIME 1")
        move(a)
        move(b, e.ramp_speed)
        wait(1.5)
    if e.large_step:
        out.append(f"; one large step of {_num(e.large_step)} mm at the safe height")
        add(f"G0 {ax}{_num(e.safe)}")
        add("#TIME 0.5")
        add(f"G0 {ax}{_num(e.safe + e.large_step)}")
        add("#TIME 0.5")
        move(e.safe)
        move(e.safe + e.large_step)
        wait(1.0)
    add(f"G0 {ax}{_num(e.safe)}                 ; retract")
    add("M30")
    move(e.safe)
    return ExciteProgram("\n".join(out) + "\n", warnings, clock["s"])
