"""Soft real-time pacing: run a cycle function once per cycle time of wall-clock time.

The cycle core never reads a clock; this is the edge that does. Cycle k is due at
``t0 + k * T``; the loop sleeps until then, runs the step (holding ``lock`` so that an ADS thread
reads consistent cycle data), and records how late each cycle started. Python on a general-purpose
OS is soft real time: a late cycle is run at once (catching up back to back); if the loop falls
more than ``max_lag`` behind (e.g. the process was stopped), it resynchronises and counts a resync.
"""
from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass, field


@dataclass
class JitterStats:
    """Lateness of cycle starts against the schedule (s)."""

    cycles: int = 0
    resyncs: int = 0
    late_over_one_cycle: int = 0
    _samples: list = field(default_factory=list, repr=False)

    def add(self, lateness: float, cycle_time: float) -> None:
        self.cycles += 1
        if lateness > cycle_time:
            self.late_over_one_cycle += 1
        if len(self._samples) < 200_000:
            self._samples.append(lateness)

    def summary(self) -> dict:
        s = sorted(self._samples)
        if not s:
            return {"cycles": 0}
        pick = lambda q: s[min(len(s) - 1, int(q * len(s)))]   # noqa: E731
        return {"cycles": self.cycles, "lateness_median_us": pick(0.5) * 1e6, "lateness_p99_us": pick(0.99) * 1e6,
                "lateness_max_us": s[-1] * 1e6, "late_over_one_cycle": self.late_over_one_cycle,
                "resyncs": self.resyncs}


def sched_fifo(priority: int) -> str:
    """Put the calling thread on the real-time policy SCHED_FIFO at ``priority`` (1..99) where the OS
    allows it; what it runs with: ``"SCHED_FIFO <priority>"`` or ``"normal (... not allowed: why)"``."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError, ValueError) as exc:
        why = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
        return f"normal (SCHED_FIFO {priority} not allowed: {why})"
    return f"SCHED_FIFO {priority}"


class RealTimeLoop:
    """Calls ``step()`` every ``cycle_time`` seconds of wall-clock time until ``stop()``."""

    def __init__(self, step, cycle_time: float, lock: threading.Lock | None = None, max_lag: float = 0.1,
                 clock=time.perf_counter, sleep=time.sleep, rt_priority: int = 0):
        self.step = step
        self.cycle_time = float(cycle_time)
        self.lock = lock or threading.Lock()
        self.max_lag = max_lag
        self.clock, self.sleep = clock, sleep
        self.stats = JitterStats()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None
        #: ask for the real-time policy SCHED_FIFO at this priority (1..99) for the cycle thread; 0: no
        self.rt_priority = int(rt_priority)
        #: what the cycle thread runs with: "SCHED_FIFO 10", or "normal (...why...)"
        self.scheduling = "normal"

    def run(self, max_cycles: int | None = None) -> JitterStats:
        """Run in the calling thread until stopped or ``max_cycles`` cycles have run."""
        T = self.cycle_time
        t0 = self.clock()
        k = 0                                        # cycles since the schedule's start t0
        ran = 0
        while not self._stop.is_set() and (max_cycles is None or ran < max_cycles):
            due = t0 + k * T
            now = self.clock()
            if due - now > 0:
                self.sleep(due - now)
                now = self.clock()
            lateness = now - due
            if lateness > self.max_lag:              # fell far behind: start a new schedule
                self.stats.resyncs += 1
                t0, k = now, 0
                due, lateness = now, 0.0
            with self.lock:
                self.step()
            self.stats.add(max(lateness, 0.0), T)
            k += 1
            ran += 1
        return self.stats

    def start(self, max_cycles: int | None = None) -> None:
        """Run in a background thread (an exception there is kept in ``error`` and stops the loop)."""
        def target():
            self._set_scheduling()
            try:
                self.run(max_cycles)
            except BaseException as exc:          # noqa: BLE001 - reported to the owner, not lost
                self.error = exc
        self._thread = threading.Thread(target=target, name="distctrl-geo-cycle", daemon=True)
        self._thread.start()

    def _set_scheduling(self) -> None:
        """The real-time policy for the calling (cycle) thread, where the OS allows it (Linux: root,
        CAP_SYS_NICE or an rtprio limit). Another process's load (a browser drawing the live page)
        then no longer delays the cycle's wake-up; the thread sleeps between cycles, and the kernel's
        real-time throttling (sched_rt_runtime_us) bounds what a runaway could take."""
        if self.rt_priority > 0:
            self.scheduling = sched_fifo(self.rt_priority)

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()
