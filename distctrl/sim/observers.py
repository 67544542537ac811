"""What a run watches every cycle besides the trace: observers of the running machine.

:func:`distctrl.sim.runner.run` steps the machine and records the trace row; everything else it
learns about the run comes from its observers, small objects with

* ``after_cycle(k, line)``: called after cycle ``k`` (``line``: the NC line or None); a true result
  ends the run in this cycle (a collision with ``stop_on_collision``). ``None`` instead of a function:
  the observer has nothing to watch in this run;
* ``finish()``: the run has ended (also after Ctrl-C);
* ``errors()``, ``warnings()`` (dicts ``{id, line, t, message}``), ``metrics()`` (its part of the run's
  metrics) and ``notes()``: what it adds to the :class:`~distctrl.sim.runner.RunResult`.

:class:`TrackingObserver` takes the distance error while distance control tracks (docs/run.md,
Metrics) into :class:`_Metrics`; :class:`ContactObserver` watches the true distance of the tool for
contact and collisions (900030) with :class:`_Contact`; :class:`ProgressObserver` draws a progress
bar on a terminal. A new per-cycle measurement of a run is a new observer here and one entry in
``run``'s list of observers.

``after_cycle`` is a closure over what it reads, built once per run: it runs 10^5 times a second, and
the closure's variables are read as fast as the locals of the loop it was cut out of.
"""
from __future__ import annotations

import math
import sys
from collections import deque

import numpy as np

from ..errors import ErrorId

COLLISION_ID = int(ErrorId.COLLISION)
COLLISION_TEXT = "Collision"
OSCILLATION_ID = int(ErrorId.OSCILLATION)
OSCILLATION_TEXT = "Oscillation"
#: an oscillation repeats itself: over the last ``PERIODIC_SECONDS`` of tracking (at least
#: ``PERIODIC_PERIODS`` periods), its periodicity (:func:`_periodicity`) is at least ``PERIODIC_MIN``
#: (the examples' limit cycles and resonances: 0.69-0.91; noise through a calm loop in the plasma and
#: process examples: -0.03-0.33; docs/run.md)
PERIODIC_MIN = 0.5
PERIODIC_SECONDS = 3
PERIODIC_PERIODS = 4
SETTLE_BAND_MM = 0.01           # settle_time: |distance error| within this band ...
SETTLE_HOLD_S = 0.1             # ... for this long


def _no_sheet_distance(sensor) -> float | None:
    """The true distance beyond which the sensor sees no sheet (mm): its ``field_range`` (distance, arc
    voltage) or the end of its range; None without a sensor."""
    if sensor is None:
        return None
    fr = getattr(sensor, "field_range", None)
    return float(fr) if fr is not None else float(sensor.range_max)


class _SampledSetValue:
    """What a set value sampled by ``auto_set_value`` means: the true height the head had while the
    function sampled it. The function averages the *measured* distance (or surface) and makes the mean
    SET_DIST (SET_POS); with a miscalibrated sensor that number is in the sensor's terms. While it samples
    this keeps the mean of ``true distance - nominal wanted distance(sampled value)``; afterwards, while the
    set value in force is the sampled one, :meth:`correction` adds it to the nominal wanted distance, so
    the error is taken against the height the head was meant to hold (docs/run.md, Metrics)."""

    __slots__ = ("fn", "n_log", "sum_d", "sum_p", "n", "value", "const_dist", "delta", "true_mean", "taken")

    def __init__(self, fn):
        self.fn = fn
        self.n_log = len(fn.log) if fn is not None else 0
        self.sum_d = self.sum_p = 0.0
        self.n = 0
        self.value = None              # the sampled set value (mm, the sensor's terms)
        self.const_dist = True
        self.delta = 0.0               # true - nominal, mean over the sampling
        self.true_mean = None          # the true distance while sampling (mm)
        self.taken = 0                 # cycles the correction applied in

    def step(self, true_distance: float, out, inp) -> None:
        fn = self.fn
        done_now = len(fn.log) != self.n_log
        if fn.phase == "SAMPLING" or done_now:
            self.sum_d += true_distance
            self.sum_p += inp.programmed_position
            self.n += 1
        elif fn.phase == "WAITING":
            self.sum_d = self.sum_p = 0.0
            self.n = 0
        if done_now:
            self.n_log = len(fn.log)
            v = fn.log[-1][1]
            self.value, self.const_dist = v, fn.const_dist
            n = max(self.n, 1)
            self.true_mean = self.sum_d / n
            nominal = v if fn.const_dist else self.sum_p / n - v
            self.delta = self.true_mean - nominal
            self.sum_d = self.sum_p = 0.0
            self.n = 0

    def holds(self, state: int) -> bool:
        """Whether the function has the axis this cycle: it waits or samples, or the cut starts now (the
        PLC sees the select one cycle later: the set value in force this cycle is the placeholder too)."""
        fn = self.fn
        if fn.phase != "DONE":
            return True
        return (state == 4 or state == 1) and fn.enabled and fn.last_state == 0

    def correction(self, const_dist: bool, set_value: float) -> float:
        """mm to add to the nominal wanted distance (0 unless the sampled value is in force)."""
        v = self.value
        if v is None or const_dist != self.const_dist or abs(set_value - v) > 1e-4:    # HLI: 0.1 µm
            return 0.0
        self.taken += 1
        return self.delta


def _metric_notes(metrics, no_sheet, sampled) -> list[str]:
    """What the distance error leaves out or takes as its reference, said in the run's notes."""
    out = []
    if metrics.excluded_off_sheet:
        n = metrics.excluded_off_sheet
        out.append(f"distance error: {n} active cycle{'s' * (n != 1)} off the sheet (the surface under the tool "
                   f"farther than the sensor's reach, {no_sheet:g} mm: a hole, a kerf, past the edge) "
                   f"{'are' if n != 1 else 'is'} not counted: nothing to track there")
    if metrics.excluded_process:
        n = metrics.excluded_process
        names = ", ".join(sorted(metrics.process_names))
        out.append(f"distance error: {n} active cycle{'s' * (n != 1)} in which a process function had the axis "
                   f"({names}: it moved the axis itself, or held it until it had sampled the set value) "
                   f"{'are' if n != 1 else 'is'} not counted")
    if sampled is not None and sampled.taken:
        word = "SET_DIST" if sampled.const_dist else "SET_POS"
        out.append(f"distance error: while the {word} that auto_set_value sampled ({sampled.value:.4g} mm in the "
                   f"sensor's terms) was in force, the error is taken against the true distance the head had "
                   f"while it sampled ({sampled.true_mean:.4g} mm), the height meant")
    return out


class _Metrics:
    """Distance error while distance control tracks (ACTIVE / ACTIVE_CONST_DIST): RMS, max, the
    settle time and the oscillation of the last second.

    The settle time counts whole cycles from the first tracking cycle to the *last* entry into
    ±band, and only if the error then stayed inside for the hold time until tracking ended (a loop
    that leaves the band again, or ends outside it, has not settled: null). The oscillation is taken
    over the last second of tracking: amplitude = half the peak-to-peak distance error; frequency from
    the crossings of its mean (null when the amplitude is inside the band or it does not make two
    whole periods)."""

    __slots__ = ("T", "n", "sq", "max", "band", "hold", "k_start", "inside", "k_entry", "second",
                 "paused", "since_window", "episode", "episodes", "surface", "history", "excluded_off_sheet",
                 "excluded_process", "process_names")

    def __init__(self, band: float, hold_cycles: int, T: float):
        self.T = T
        self.n = 0
        self.sq = 0.0
        self.max = 0.0
        self.band, self.hold = band, hold_cycles
        self.k_start = None           # the first tracking cycle
        self.inside = 0               # cycles inside the band since the last entry
        self.k_entry = None           # the cycle of the last entry into the band
        self.second = max(2, int(round(1.0 / T)))                     # cycles in a second
        # the errors of the last PERIODIC_SECONDS of tracking (the last second is judged; the whole
        # for periodicity), and the surface under the tool in the last second
        self.history = deque(maxlen=PERIODIC_SECONDS * self.second)
        self.surface = deque(maxlen=self.second)
        self.paused = False
        self.since_window = 0         # tracking samples since the last whole-second window was judged
        self.episode: dict | None = None      # the oscillation going on (whole seconds of tracking)
        self.episodes: list[dict] = []
        self.excluded_off_sheet = 0   # active cycles off the sheet (beyond the sensor's reach): not tracking
        self.excluded_process = 0     # active cycles in which a process function moved the axis
        self.process_names: set[str] = set()      # ... and which functions those were

    def add(self, k: int, line, err: float, surface: float = 0.0) -> None:
        if self.k_start is None:
            self.k_start = k
        if self.paused:             # tracking resumed: the band has to be entered anew
            self.paused = False
            self.inside = 0
        if err == err:
            self.n += 1
            self.sq += err * err
            a = abs(err)
            if a > self.max:
                self.max = a
            self.history.append(err)
            self.surface.append(surface)
            self.since_window += 1
            if self.since_window == self.second:
                self._judge_window(k, line)
            if a <= self.band:
                if self.inside == 0:
                    self.k_entry = k
                self.inside += 1
            else:
                self.inside = 0

    def gap(self) -> None:
        """Tracking paused (FREEZE, a deselection). If it resumes, the band has to be entered anew;
        if it never does, the settle time is that of the last tracking stretch."""
        self.paused = True

    def _judge_window(self, k: int, line) -> None:
        """Every whole second of tracking: is the error oscillating? Consecutive oscillating seconds
        are one episode (a warning 900032 with its start, end, frequency and largest amplitude)."""
        self.since_window = 0
        freq, amp = self.oscillation()
        ep = self.episode
        if freq is not None:
            if ep is None:
                self.episode = {"k0": k - min(len(self.history), self.second) + 1, "k1": k, "line": line, "freq": freq, "amp": amp}
            else:
                ep["k1"] = k
                if amp > ep["amp"]:
                    ep["amp"], ep["freq"] = amp, freq
        elif ep is not None:
            self.episodes.append(ep)
            self.episode = None

    def oscillation_warnings(self) -> list[dict]:
        eps = self.episodes + ([self.episode] if self.episode is not None else [])
        return [{"id": OSCILLATION_ID, "line": None if e["line"] in (None, -1) else e["line"],
                 "t": round(e["k0"] * self.T, 9),
                 "message": f"{OSCILLATION_TEXT}: the distance error oscillated at {e['freq']:.1f} Hz, up to "
                            f"±{e['amp']:.3f} mm, from t = {e['k0'] * self.T:.3f} s to {e['k1'] * self.T:.3f} s "
                            f"(whole seconds of tracking)"} for e in eps]

    def settle_time(self) -> float | None:
        if self.k_start is None or self.inside < self.hold:
            return None
        return (self.k_entry - self.k_start) * self.T

    def oscillation(self) -> tuple[float | None, float | None]:
        """(frequency or None, amplitude) of the distance error over the last second of tracking.

        An oscillation: the amplitude is above the band, the error makes two whole periods around its
        mean, it is not the surface's own waviness followed with a lag (the error swings more than
        the surface under the tool does, or at more than twice the surface's frequency), and it
        repeats itself (:func:`_periodicity` over the last seconds at least ``PERIODIC_MIN``)."""
        recent = list(self.history)[-self.second:]        # the last second of tracking
        if len(recent) < 2:
            return None, None
        amplitude, crossings = _swing(recent)
        if amplitude <= self.band or crossings < 4:
            return None, amplitude
        surface_amplitude, surface_crossings = _swing(self.surface)
        if amplitude <= surface_amplitude and crossings <= 2 * surface_crossings:
            return None, amplitude              # the loop follows a wavy surface: a tracking error
        if _periodicity(self.history, len(recent) * 2.0 / crossings) < PERIODIC_MIN:
            return None, amplitude              # a random wander (noise through the loop), not periodic
        return crossings / (2.0 * len(recent) * self.T), amplitude

    def result(self) -> dict:
        freq, amp = self.oscillation()
        return {"distance_error_rms": math.sqrt(self.sq / self.n) if self.n else None,
                "distance_error_max": self.max if self.n else None,
                "settle_time": self.settle_time(), "tracking_cycles": self.n,
                "settle_band_mm": self.band, "settle_hold_s": SETTLE_HOLD_S,
                "oscillation_frequency_hz": freq, "oscillation_amplitude_mm": amp,
                "oscillations": len(self.episodes) + (self.episode is not None),
                "excluded_off_sheet_cycles": self.excluded_off_sheet,
                "excluded_process_cycles": self.excluded_process}


def _periodicity(values, period: float) -> float:
    """How well ``values`` (the last seconds of the error) repeat themselves with a period of about
    ``period`` samples, from 0 to 1: half the difference of their normalised autocorrelation (mean
    removed; each lag's mean of products over the mean square) at the best lag ``L`` from half to one
    and a half times ``period`` (the period from one second's crossings is coarse, and noise adds
    crossings), at most half the values, and at ``L / 2``; 0 while the values hold fewer than
    ``PERIODIC_PERIODS`` periods. A periodic error, also in noise, is
    about 1 (in phase after a period, in antiphase after half of one); a random wander and a slow
    drift or decay are about 0 (alike or unalike at both lags)."""
    e = np.asarray(values, dtype=float)
    n = len(e)
    e = e - e.mean()
    power = float(np.dot(e, e)) / n
    if power <= 0.0 or n < PERIODIC_PERIODS * period:
        return 0.0                      # too few periods yet to tell (judged again a second later)
    lo, hi = max(2, int(0.5 * period)), min(n // 2, int(1.5 * period) + 1)
    spectrum = np.fft.rfft(e, 2 * n)
    sums = np.fft.irfft(spectrum * np.conj(spectrum), 2 * n)[:hi + 1]      # sum of e[t] e[t + lag]
    r = sums / (n - np.arange(hi + 1)) / power
    best = lo + int(np.argmax(r[lo:hi + 1]))
    return float(0.5 * (r[best] - r[best // 2]))


def _swing(values) -> tuple[float, int]:
    """(half the peak-to-peak, crossings of the mean): crossings count with a hysteresis of a quarter
    of the amplitude (noise does not count)."""
    e = list(values)
    amplitude = 0.5 * (max(e) - min(e))
    mean = sum(e) / len(e)
    h = 0.25 * amplitude
    side, crossings = 0, 0
    for x in e:
        s = 1 if x > mean + h else (-1 if x < mean - h else 0)
        if s and s != side:
            crossings += side != 0
            side = s
    return amplitude, crossings


class _Contact:
    """The true distance of the tool to the surface over the whole run: its minimum, the time at or
    below zero, and the collisions (the true distance at or below ``-depth``): one warning 900030 per
    contact, stamped when it began, with the place and the deepest point."""

    __slots__ = ("T", "depth", "min", "below", "hits", "current")

    def __init__(self, T: float, depth: float):
        self.T, self.depth = T, depth
        self.min = math.inf
        self.below = 0
        self.hits: list[dict] = []
        self.current: dict | None = None

    def add(self, k: int, d: float, x: float, y: float, line) -> bool:
        """Record one cycle; True when a collision begins in it."""
        if d < self.min:
            self.min = d
        if d <= 0.0:
            self.below += 1
        cur = self.current
        if d <= -self.depth:
            if cur is None:
                self.current = {"k": k, "x": x, "y": y, "line": line, "deepest": d, "cycles": 1}
                return True
            cur["cycles"] += 1
            if d < cur["deepest"]:
                cur["deepest"] = d
        elif cur is not None:
            self.hits.append(cur)
            self.current = None
        return False

    def finish(self) -> None:
        if self.current is not None:
            self.hits.append(self.current)
            self.current = None

    def warnings(self, severity: str = "warning") -> list[dict]:
        out = []
        for h in self.hits:
            limit = f" (collision depth {self.depth:g} mm)" if self.depth else ""
            out.append({"id": COLLISION_ID, "line": None if h["line"] in (None, -1) else h["line"],
                        "t": round(h["k"] * self.T, 9), "severity": severity,
                        "message": f"{COLLISION_TEXT}: at X={h['x']:.3f} mm Y={h['y']:.3f} mm the tool went "
                                   f"{-h['deepest']:.3f} mm into the surface for {h['cycles'] * self.T:.3f} s"
                                   f"{limit}"})
        return out

    def result(self) -> dict:
        return {"min_distance_mm": self.min if math.isfinite(self.min) else None,
                "time_below_zero_s": self.below * self.T, "collisions": len(self.hits)}


# --- the observers ----------------------------------------------------------------------------------
class TrackingObserver:
    """The tracking metrics of a run: the distance error of the distance-controlled axis ``dc_axis``
    (or of the channel's 3D distance control) while it tracks, into :class:`_Metrics` (``.tracking``).

    The error is the true distance minus the wanted one: SET_DIST in ACTIVE_CONST_DIST, the programmed
    position above SET_POS in ACTIVE; in 3D the orthogonal distance of the clamping point. Cycles off
    the sheet (beyond the sensor's reach) and cycles in which a process function has the axis are
    counted apart, not as tracking (docs/run.md, Metrics)."""

    def __init__(self, machine, scenario, dc_axis: str | None):
        T = scenario.cycle_time
        metrics = self.tracking = _Metrics(SETTLE_BAND_MM, int(round(SETTLE_HOLD_S / T)), T)
        out3d = machine.out3d if machine.ch3d is not None else None
        in3d = machine.in3d
        dc_out = machine.outputs[dc_axis] if dc_axis is not None else None
        dc_inp = machine.inputs[dc_axis] if dc_axis is not None else None
        add_metric = metrics.add
        # cycles in which a process function moves the axis itself (touch-off probe, collision retract:
        # ACTIVE_CONST_DIST with a set distance that is not the cut's) are not tracking: not in the metrics
        proc = getattr(machine, "process_program", None)
        hold = proc.holds.get(dc_axis) if proc is not None and dc_axis is not None else None
        moved_by_process = hold.inhibitors if hold is not None else frozenset()
        # tracking means over the sheet: where the surface under the tool is beyond the sensor's reach (a
        # hole, past the sheet's edge) there is nothing to track; and a set value auto_set_value sampled in
        # the sensor's terms means the true height the head had while it sampled (docs/run.md, Metrics)
        no_sheet = self.no_sheet = _no_sheet_distance(scenario.sensor) if out3d is None else None
        sampled = _SampledSetValue(proc.function("auto_set_value", dc_axis)) \
            if proc is not None and dc_axis is not None and out3d is None else None
        if sampled is not None and sampled.fn is None:
            sampled = None
        self.sampled = sampled

        def after_cycle_3d(k, line):
            # 3D: the orthogonal distance of the clamping point; wanted = SET_DIST·cos θ·Lv/L in
            # CONST_DIST, the programmed clamping-point height above SET_POS in SURFACE mode
            state = out3d.core.hli_state
            if state == 4:
                add_metric(k, line, machine.true_distance_orth - out3d.orthogonal_set_distance,
                           machine.true_surface)
            elif state == 1:
                add_metric(k, line, machine.true_distance - (in3d.programmed_z - out3d.core.set_pos),
                           machine.true_surface)
            elif metrics.inside:
                metrics.gap()

        def after_cycle_axis(k, line):
            state = dc_out.hli_state
            if sampled is not None:
                sampled.step(machine.true_distance, dc_out, dc_inp)
            if moved_by_process or (sampled is not None and sampled.holds(state)):
                # a process function has the axis: it moves it (touch-off, collision retract), or
                # auto_set_value holds it to sample (the set value in force is a placeholder)
                if state == 4 or state == 1:
                    metrics.excluded_process += 1
                    metrics.process_names.update(moved_by_process or ("auto_set_value",))
                if metrics.inside:
                    metrics.gap()
            elif (state == 4 or state == 1) and no_sheet is not None and machine.true_distance > no_sheet:
                metrics.excluded_off_sheet += 1
                metrics.gap()
            elif state == 4:
                wanted = dc_out.set_distance
                if sampled is not None:
                    wanted += sampled.correction(True, dc_out.set_distance)
                add_metric(k, line, machine.true_distance - wanted, machine.true_surface)
            elif state == 1:
                wanted = dc_inp.programmed_position - dc_out.set_pos
                if sampled is not None:
                    wanted += sampled.correction(False, dc_out.set_pos)
                add_metric(k, line, machine.true_distance - wanted, machine.true_surface)
            elif metrics.inside:
                metrics.gap()

        #: nothing to watch without a distance-controlled axis or a 3D channel
        self.after_cycle = after_cycle_3d if out3d is not None else (
            after_cycle_axis if dc_out is not None else None)

    def finish(self) -> None:
        pass

    def errors(self) -> list[dict]:
        return []

    def warnings(self) -> list[dict]:
        return self.tracking.oscillation_warnings()

    def metrics(self) -> dict:
        return self.tracking.result()

    def notes(self) -> list[str]:
        return _metric_notes(self.tracking, self.no_sheet, self.sampled)


class ContactObserver:
    """The true distance of the tool over the run (:class:`_Contact`, ``.contact``): its minimum, the
    time at or below zero and the collisions, warnings 900030 (errors that end the run in their cycle
    with ``stop_on_collision``). The ground truth exists with a sensor (axis variant) or a kinematic
    path; without it nothing is watched and the metrics say so (None)."""

    def __init__(self, machine, scenario, stop_on_collision: bool = False):
        self.stop_on_collision = stop_on_collision
        contact = self.contact = _Contact(scenario.cycle_time,
                                          scenario.sensor.collision_depth if scenario.sensor is not None else 0.0)
        kinematic = machine.kinematic_path
        add = contact.add

        def after_cycle(k, line):
            d_true = machine.true_distance
            if d_true <= 0.0 or d_true < contact.min:
                if kinematic:
                    cx, cy = machine.true_clamp[0], machine.true_clamp[1]
                else:
                    # where the tool's nozzle met the surface this cycle (not the motor after
                    # the drive's step: a cycle's travel later, and off by a resonance's deflection)
                    cx, cy = machine.true_xy
                if add(k, d_true, cx, cy, line) and stop_on_collision:
                    contact.finish()
                    return True                  # the collision ends the run in this cycle
            elif contact.current is not None:
                add(k, d_true, 0.0, 0.0, line)
            return False

        has_truth = scenario.sensor is not None or machine.kinematic_path
        self.after_cycle = after_cycle if has_truth else None

    def finish(self) -> None:
        self.contact.finish()

    def _hits(self, as_errors: bool) -> list[dict]:
        if as_errors != self.stop_on_collision:
            return []
        out = self.contact.warnings("error" if self.stop_on_collision else "warning")
        for item in out:
            del item["severity"]
        return out

    def errors(self) -> list[dict]:
        return self._hits(True)

    def warnings(self) -> list[dict]:
        return self._hits(False)

    def metrics(self) -> dict:
        return self.contact.result()

    def notes(self) -> list[str]:
        return []


class ProgressObserver:
    """A rich progress bar on a terminal (nothing otherwise), updated every 2000 cycles."""

    def __init__(self, total: int | None, T: float):
        self.T = T
        self.bar = None
        self.after_cycle = None
        if sys.stderr.isatty():
            # rich's progress bar (0.1 s of import) only on a terminal
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

            self.bar = Progress(TextColumn("simulating"), BarColumn(), TextColumn("{task.fields[t]:.2f} s"),
                                TimeElapsedColumn(), transient=True)
            self.bar.start()
            self.task = self.bar.add_task("run", total=total, t=0.0)
            self.after_cycle = self._after_cycle

    def _after_cycle(self, k: int, line) -> bool:
        if k % 2000 == 0:
            self.bar.update(self.task, completed=k, t=k * self.T)
        return False

    def finish(self) -> None:
        if self.bar is not None:
            self.bar.stop()

    def errors(self) -> list[dict]:
        return []

    def warnings(self) -> list[dict]:
        return []

    def metrics(self) -> dict:
        return {}

    def notes(self) -> list[str]:
        return []
