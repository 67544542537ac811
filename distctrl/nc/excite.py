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
from dataclasses import dataclass

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


def check(e: Excitation) -> list[str]:
    """Raise :class:`ExciteError` for an excitation beyond the limits; the warnings (outside the
    recommended ranges) as a list."""
    warnings = []
    if not (e.min_pos < e.max_pos):
        raise ExciteError(f"--min {e.min_pos} must be below --max {e.max_pos}")
    if e.cycle_time <= 0 or e.a_max <= 0 or e.v_max <= 0:
        raise ExciteError("the cycle time, a_max and v_max must be > 0")
    lo, hi = e.work, e.work
    if e.step:
        if e.step <= 0:
            raise ExciteError(f"--steps {e.step}: a step must be > 0 mm")
        hi = max(hi, e.work + e.step)
        if not STEP_SIZE[0] <= e.step <= STEP_SIZE[1]:
            warnings.append(f"--steps {e.step} mm: docs/identify.md recommends {STEP_SIZE[0]}-{STEP_SIZE[1]} mm")
    if e.chirp:
        f0, f1 = e.chirp
        if not (0 < f0 < f1 <= 0.5 / e.cycle_time):
            raise ExciteError(f"--chirp {f0:g}-{f1:g}: need 0 < f0 < f1 <= {0.5 / e.cycle_time:g} Hz "
                              f"(half the cycle rate)")
        if e.amplitude <= 0:
            raise ExciteError(f"--amplitude {e.amplitude}: must be > 0 mm")
        lo, hi = min(lo, e.work - e.amplitude), max(hi, e.work + e.amplitude)
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
    if e.large_step:
        lo, hi = min(lo, e.safe), max(hi, e.safe + e.large_step)
    if e.ramp:
        a, b = e.ramp
        lo, hi = min(lo, a, b), max(hi, a, b)
        if e.ramp_speed <= 0:
            raise ExciteError(f"--ramp-speed {e.ramp_speed}: must be > 0 mm/s")
        if not RAMP_SPEED[0] <= e.ramp_speed <= RAMP_SPEED[1]:
            warnings.append(f"--ramp-speed {e.ramp_speed} mm/s: docs/identify.md recommends "
                            f"{RAMP_SPEED[0]}-{RAMP_SPEED[1]} mm/s")
    lo, hi = min(lo, e.safe), max(hi, e.safe)
    if lo < e.min_pos or hi > e.max_pos:
        raise ExciteError(f"the program would move {e.axis} over {lo:g}..{hi:g} mm, beyond the axis limits "
                          f"--min {e.min_pos:g} / --max {e.max_pos:g}: lower --steps/--amplitude/--large-step "
                          f"or change --work/--safe/--ramp")
    if e.surface is not None:
        low = min(e.work - (e.amplitude * RESONANCE_GAIN if e.chirp else 0.0),
                  min(e.ramp) if e.ramp else e.work)
        if low <= e.surface:
            raise ExciteError(f"the nozzle could reach {low:g} mm (the chirp amplitude x {RESONANCE_GAIN:g} at a "
                              f"resonance, docs/identify.md) at or below the surface {e.surface:g} mm: "
                              f"raise --work or lower --amplitude")
    return warnings


def _num(x: float) -> str:
    text = f"{x:.4f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def program(e: Excitation) -> tuple[str, list[str]]:
    """The NC program text and the warnings; raises :class:`ExciteError` when the limits forbid it."""
    warnings = check(e)
    ax, T = e.axis, e.cycle_time
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

    add("#TIME 1")
    if e.step:
        out.append(f"; steps of {_num(e.step)} mm every {_num(e.step_dwell)} s")
        for k in range(e.step_count):
            add(f"G0 {ax}{_num(e.work + (e.step if k % 2 == 0 else 0.0))}")
            add(f"#TIME {_num(e.step_dwell)}")
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
    if e.ramp:
        a, b = e.ramp
        out.append(f"; slow ramp {_num(a)} -> {_num(b)} mm at {_num(e.ramp_speed)} mm/s, then 1 s at standstill")
        add(f"G0 {ax}{_num(a)}")
        add("#TIME 0.5")
        add(f"G1 {ax}{_num(b)} F{_num(e.ramp_speed * 60)}")
        add("#TIME 1")
    if e.large_step:
        out.append(f"; one large step of {_num(e.large_step)} mm at the safe height")
        add(f"G0 {ax}{_num(e.safe)}")
        add("#TIME 0.5")
        add(f"G0 {ax}{_num(e.safe + e.large_step)}")
        add("#TIME 0.5")
    add(f"G0 {ax}{_num(e.safe)}                 ; retract")
    add("M30")
    return "\n".join(out) + "\n", warnings
